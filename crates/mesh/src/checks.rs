//! Mesh checks: counts, topology and orientation of a [`TriMesh`].
//!
//! [`check`] returns a [`MeshReport`]: the edges (boundary, non-manifold, inconsistently
//! oriented), degenerate triangles, connected components, the Euler characteristic of the used
//! part, whether the mesh is closed, its signed volume and its area. [`boundary_loops`] counts
//! the holes.
//!
//! An edge is an unordered pair of distinct vertices that some triangle has as a side. Edges
//! are found by sorting the triangles' sides, so a check costs `O(F log F)` and the report does
//! not depend on hash order: the same mesh gives the same report.

use zeroset_field_core::Point;
use zeroset_field_core::geometry::{cross, dot, norm, sub};

use crate::TriMesh;

/// What [`check`] finds; see the [module docs](self).
#[derive(Debug, Clone, PartialEq)]
pub struct MeshReport {
    /// All vertices, including those no triangle uses.
    pub vertices: usize,
    /// Vertices used by at least one triangle.
    pub used_vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Distinct edges (unordered pairs of distinct vertices that are a triangle's side).
    pub edges: usize,
    /// Edges with exactly one triangle.
    pub boundary_edges: usize,
    /// Edges with three or more triangles.
    pub non_manifold_edges: usize,
    /// Edges with two triangles that traverse them in the same direction: the two triangles
    /// disagree on orientation (one of them is flipped).
    pub inconsistent_edges: usize,
    /// Triangles of zero area: a repeated vertex, or three collinear corners (an exactly zero
    /// cross product in `f64`).
    pub degenerate_triangles: usize,
    /// Connected components of the triangles, two triangles being connected when they share an
    /// edge (sharing only a vertex does not connect them).
    pub components: usize,
    /// `V − E + F` with `V` the used vertices: 2 for a sphere, 2 − 2g for a closed surface of
    /// genus g, one less per hole.
    pub euler_characteristic: i64,
    /// At least one triangle, no boundary edge and no non-manifold edge.
    pub closed: bool,
    /// The signed volume `Σ (a − o) · ((b − o) × (c − o)) / 6` over the triangles `(a, b, c)`,
    /// with `o` the mean of the used vertices: positive for a closed mesh wound outward (the
    /// divergence theorem). For an open mesh it depends on `o` and is only indicative.
    pub signed_volume: f64,
    /// The total area of the triangles.
    pub area: f64,
}

impl MeshReport {
    /// Closed, with every edge traversed in opposite directions by its two triangles: the mesh
    /// bounds a solid and its triangles agree on orientation.
    pub fn is_oriented_closed(&self) -> bool {
        self.closed && self.inconsistent_edges == 0
    }
}

impl std::fmt::Display for MeshReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} vertices ({} used), {} triangles, {} edges ({} boundary, {} non-manifold, {} \
             inconsistent), {} degenerate triangles, {} component(s), Euler characteristic {}, \
             {}, signed volume {:.6e}, area {:.6e}",
            self.vertices,
            self.used_vertices,
            self.triangles,
            self.edges,
            self.boundary_edges,
            self.non_manifold_edges,
            self.inconsistent_edges,
            self.degenerate_triangles,
            self.components,
            self.euler_characteristic,
            if self.closed { "closed" } else { "open" },
            self.signed_volume,
            self.area,
        )
    }
}

/// One triangle side: the edge `(lo, hi)`, whether the triangle traverses it from `lo` to
/// `hi`, and the triangle.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Side {
    lo: u32,
    hi: u32,
    forward: bool,
    triangle: u32,
}

/// All sides of all triangles with two distinct ends, sorted by edge.
fn sorted_sides(mesh: &TriMesh) -> Vec<Side> {
    let mut sides = Vec::with_capacity(mesh.num_triangles() * 3);
    for (t, tri) in mesh.triangles().iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if a != b {
                sides.push(Side {
                    lo: a.min(b),
                    hi: a.max(b),
                    forward: a < b,
                    triangle: t as u32,
                });
            }
        }
    }
    sides.sort_unstable();
    sides
}

/// Groups of sides on the same edge.
fn edge_groups(sides: &[Side]) -> impl Iterator<Item = &[Side]> {
    sides.chunk_by(|a, b| (a.lo, a.hi) == (b.lo, b.hi))
}

/// A union–find over `n` items.
struct Dsu(Vec<u32>);

impl Dsu {
    fn new(n: usize) -> Self {
        Self((0..n as u32).collect())
    }

    fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let parent = self.0[x as usize];
            self.0[x as usize] = self.0[parent as usize];
            x = parent;
        }
        x
    }

    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            // The smaller root wins: deterministic.
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            self.0[hi as usize] = lo;
        }
    }
}

/// Checks `mesh`; see [`MeshReport`].
///
/// ```
/// use zeroset_mesh::{TriMesh, checks::check};
///
/// // A tetrahedron wound outward.
/// let v = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
/// let t = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
/// let report = check(&TriMesh::new(v, t)?);
/// assert!(report.closed && report.inconsistent_edges == 0);
/// assert_eq!(report.euler_characteristic, 2);
/// assert!((report.signed_volume - 1.0 / 6.0).abs() < 1e-12);
/// # Ok::<(), zeroset_mesh::MeshError>(())
/// ```
pub fn check(mesh: &TriMesh) -> MeshReport {
    let vertices = mesh.vertices();
    let mut used = vec![false; vertices.len()];
    for tri in mesh.triangles() {
        for &v in tri {
            used[v as usize] = true;
        }
    }
    let used_vertices = used.iter().filter(|u| **u).count();

    let sides = sorted_sides(mesh);
    let mut dsu = Dsu::new(mesh.num_triangles());
    let (mut edges, mut boundary, mut non_manifold, mut inconsistent) = (0, 0, 0, 0);
    for group in edge_groups(&sides) {
        edges += 1;
        match group.len() {
            1 => boundary += 1,
            2 => {
                if group[0].forward == group[1].forward {
                    inconsistent += 1;
                }
            }
            _ => non_manifold += 1,
        }
        for s in &group[1..] {
            dsu.union(group[0].triangle, s.triangle);
        }
    }
    let components = (0..mesh.num_triangles() as u32)
        .filter(|&t| dsu.find(t) == t)
        .count();

    // The mean of the used vertices, as origin of the volume sum.
    let mut origin = [0.0; 3];
    for (p, _) in vertices.iter().zip(&used).filter(|(_, u)| **u) {
        for k in 0..3 {
            origin[k] += p[k];
        }
    }
    if used_vertices > 0 {
        origin = origin.map(|c| c / used_vertices as f64);
    }
    let (mut volume, mut area, mut degenerate) = (0.0, 0.0, 0);
    for (t, tri) in mesh.triangles().iter().enumerate() {
        let [a, b, c] = mesh.corners(t).map(|p| sub(&p, &origin));
        let n = cross(&sub(&b, &a), &sub(&c, &a));
        let twice_area = norm(&n);
        if twice_area == 0.0 || tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            degenerate += 1;
        }
        area += 0.5 * twice_area;
        volume += dot(&a, &cross(&b, &c)) / 6.0;
    }

    let triangles = mesh.num_triangles();
    MeshReport {
        vertices: vertices.len(),
        used_vertices,
        triangles,
        edges,
        boundary_edges: boundary,
        non_manifold_edges: non_manifold,
        inconsistent_edges: inconsistent,
        degenerate_triangles: degenerate,
        components,
        euler_characteristic: used_vertices as i64 - edges as i64 + triangles as i64,
        closed: triangles > 0 && boundary == 0 && non_manifold == 0,
        signed_volume: volume,
        area,
    }
}

/// The connected components of `mesh` (triangles joined by shared edges): a label per
/// triangle, numbered `0, 1, …` in the order of each component's first triangle, and their
/// count.
///
/// ```
/// use zeroset_mesh::{TriMesh, checks::components};
///
/// let v = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]];
/// let m = TriMesh::new(v, vec![[0, 1, 2], [4, 5, 6], [1, 3, 2]])?;
/// assert_eq!(components(&m), (vec![0, 1, 0], 2));
/// # Ok::<(), zeroset_mesh::MeshError>(())
/// ```
pub fn components(mesh: &TriMesh) -> (Vec<u32>, usize) {
    let sides = sorted_sides(mesh);
    let mut dsu = Dsu::new(mesh.num_triangles());
    for group in edge_groups(&sides) {
        for s in &group[1..] {
            dsu.union(group[0].triangle, s.triangle);
        }
    }
    let n = mesh.num_triangles();
    let mut of_root = vec![u32::MAX; n];
    let mut labels = Vec::with_capacity(n);
    let mut count = 0u32;
    for t in 0..n as u32 {
        let root = dsu.find(t) as usize;
        if of_root[root] == u32::MAX {
            of_root[root] = count;
            count += 1;
        }
        labels.push(of_root[root]);
    }
    (labels, count as usize)
}

/// Which components of `mesh` (labels and count from [`components`]) have no point of
/// `points` within `radius` of any of their vertices: zero-set pieces no data supports, such
/// as the sheets an off-surface RBF fit can grow far from its points.
///
/// ```
/// use zeroset_mesh::{TriMesh, checks::{components, unsupported_components}};
///
/// let v = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]];
/// let m = TriMesh::new(v, vec![[0, 1, 2], [3, 4, 5]])?;
/// let (labels, count) = components(&m);
/// let far = unsupported_components(&m, &labels, count, &[[0.1, 0.1, 0.0]], 0.5);
/// assert_eq!(far, vec![false, true]);
/// # Ok::<(), zeroset_mesh::MeshError>(())
/// ```
pub fn unsupported_components(
    mesh: &TriMesh,
    labels: &[u32],
    count: usize,
    points: &[Point<3>],
    radius: f64,
) -> Vec<bool> {
    use std::collections::HashMap;
    let cell = |p: &Point<3>| -> [i64; 3] { p.map(|v| (v / radius).floor() as i64) };
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    if radius > 0.0 && radius.is_finite() {
        for (i, p) in points.iter().enumerate() {
            if p.iter().all(|v| v.is_finite()) {
                grid.entry(cell(p)).or_default().push(i as u32);
            }
        }
    }
    let near = |v: &Point<3>| -> bool {
        let c = cell(v);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                        continue;
                    };
                    if list.iter().any(|&i| {
                        let q = points[i as usize];
                        let d2: f64 = (0..3).map(|a| (q[a] - v[a]).powi(2)).sum();
                        d2 <= radius * radius
                    }) {
                        return true;
                    }
                }
            }
        }
        false
    };
    let mut supported = vec![false; count];
    for (t, tri) in mesh.triangles().iter().enumerate() {
        let l = labels[t] as usize;
        if !supported[l] && tri.iter().any(|&v| near(&mesh.vertices()[v as usize])) {
            supported[l] = true;
        }
    }
    supported.into_iter().map(|s| !s).collect()
}

/// How many of `points` each component of `mesh` (labels and count from [`components`]) is
/// fitted to: a point counts for the component of its nearest vertex, if that vertex lies
/// within `radius`. A point near two components counts once, for the nearer, so a small
/// closed piece beside the surface is credited only with the points nearer to it than to the
/// surface — a blob an implicit fit grows around a stray point a few spacings off the surface
/// gets 1. The nearest vertex stands for the nearest surface, which takes vertices about as
/// dense as a marching-cubes mesh's (one per voxel crossed) and `radius` a few of its voxels.
/// Non-finite points count for none; a vertex that no triangle uses is not searched.
///
/// `O((V + P) log V)`, the points in parallel; the same counts on any number of threads (each
/// point's nearest vertex is found exactly, in a tree built the same way every time).
///
/// ```
/// use zeroset_mesh::{TriMesh, checks::{component_support, components}};
///
/// let v = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]];
/// let m = TriMesh::new(v, vec![[0, 1, 2], [3, 4, 5]])?;
/// let (labels, count) = components(&m);
/// let points = [[0.1, 0.1, 0.0], [0.9, 0.0, 0.1], [5.2, 5.1, 5.0], [20.0, 0.0, 0.0]];
/// assert_eq!(component_support(&m, &labels, count, &points, 0.5), vec![2, 1]);
/// # Ok::<(), zeroset_mesh::MeshError>(())
/// ```
pub fn component_support(
    mesh: &TriMesh,
    labels: &[u32],
    count: usize,
    points: &[Point<3>],
    radius: f64,
) -> Vec<usize> {
    use crate::trim::Tree;
    use kiddo::SquaredEuclidean;
    use rayon::prelude::*;

    let mut support = vec![0; count];
    // The label of each vertex a triangle uses (a vertex shared by two components, touching
    // at it only, takes the first triangle's).
    let mut label_of = vec![u32::MAX; mesh.num_vertices()];
    for (tri, &l) in mesh.triangles().iter().zip(labels) {
        for &v in tri {
            if label_of[v as usize] == u32::MAX {
                label_of[v as usize] = l;
            }
        }
    }
    let (used, used_labels): (Vec<Point<3>>, Vec<u32>) = mesh
        .vertices()
        .iter()
        .zip(&label_of)
        .filter(|(p, l)| **l != u32::MAX && p.iter().all(|v| v.is_finite()))
        .map(|(p, &l)| (*p, l))
        .unzip();
    if used.is_empty() || !(radius > 0.0 && radius.is_finite()) || used.len() > u32::MAX as usize {
        return support;
    }
    let Ok(tree) = Tree::new_from_slice(&used) else {
        return support;
    };
    let nearest: Vec<Option<u32>> = points
        .par_iter()
        .map(|p| {
            if !p.iter().all(|v| v.is_finite()) {
                return None;
            }
            let found = tree
                .query(p)
                .nearest_one::<SquaredEuclidean<f64>>()
                .execute();
            (found.distance <= radius * radius).then(|| used_labels[found.item as usize])
        })
        .collect();
    for l in nearest.into_iter().flatten() {
        if let Some(s) = support.get_mut(l as usize) {
            *s += 1;
        }
    }
    support
}

/// The number of boundary loops (holes): the connected components of the graph of boundary
/// edges (edges with one triangle). Two holes that touch at a vertex count as one loop.
pub fn boundary_loops(mesh: &TriMesh) -> usize {
    let sides = sorted_sides(mesh);
    let mut dsu = Dsu::new(mesh.num_vertices());
    let mut on_boundary = vec![false; mesh.num_vertices()];
    for group in edge_groups(&sides) {
        if let [s] = group {
            dsu.union(s.lo, s.hi);
            on_boundary[s.lo as usize] = true;
            on_boundary[s.hi as usize] = true;
        }
    }
    (0..mesh.num_vertices() as u32)
        .filter(|&v| on_boundary[v as usize] && dsu.find(v) == v)
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_cube() -> TriMesh {
        let mut v = Vec::new();
        for i in 0..8 {
            v.push([(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64]);
        }
        // Outward: counter-clockwise seen from outside.
        let quads = [
            [0, 2, 3, 1], // z = 0, normal -z
            [4, 5, 7, 6], // z = 1, normal +z
            [0, 1, 5, 4], // y = 0, normal -y
            [2, 6, 7, 3], // y = 1, normal +y
            [0, 4, 6, 2], // x = 0, normal -x
            [1, 3, 7, 5], // x = 1, normal +x
        ];
        let t = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        TriMesh::new(v, t).unwrap()
    }

    #[test]
    fn cube_is_closed_with_unit_volume() {
        let r = check(&unit_cube());
        assert_eq!(
            (r.vertices, r.used_vertices, r.triangles, r.edges),
            (8, 8, 12, 18)
        );
        assert_eq!(r.euler_characteristic, 2);
        assert!(r.closed && r.is_oriented_closed());
        assert_eq!(r.components, 1);
        assert!((r.signed_volume - 1.0).abs() < 1e-12, "{r}");
        assert!((r.area - 6.0).abs() < 1e-12);
        assert_eq!(boundary_loops(&unit_cube()), 0);
    }

    #[test]
    fn degenerate_and_empty() {
        let v = vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        let m = TriMesh::new(v, vec![[0, 1, 2], [0, 0, 1]]).unwrap();
        let r = check(&m);
        assert_eq!(r.degenerate_triangles, 2);
        let r = check(&TriMesh::default());
        assert!(!r.closed);
        assert_eq!((r.components, r.edges, r.euler_characteristic), (0, 0, 0));
    }

    #[test]
    fn non_manifold_edge_is_counted() {
        // Three triangles on the edge 0–1.
        let v = vec![
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let m = TriMesh::new(v, vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]]).unwrap();
        let r = check(&m);
        assert_eq!(r.non_manifold_edges, 1);
        assert_eq!(r.components, 1);
        assert!(!r.closed);
    }

    #[test]
    fn support_credits_each_point_to_the_nearest_component_only() {
        // A square sheet z = 1 triangulated every 0.1 (vertices as dense as a marching-cubes
        // mesh's, as the function assumes) sampled by a 5 × 5 grid, and a small cube 0.2 above
        // it (a blob around one stray point at its centre): the grid points under the blob lie
        // within the radius of both, but nearer to the sheet.
        let mut vertices: Vec<Point<3>> = (0..121)
            .map(|k| [0.1 * (k % 11) as f64, 0.1 * (k / 11) as f64, 1.0])
            .collect();
        let mut triangles = Vec::new();
        for j in 0..10 {
            for i in 0..10 {
                let v = j * 11 + i;
                triangles.push([v, v + 1, v + 12]);
                triangles.push([v, v + 12, v + 11]);
            }
        }
        let blob = unit_cube();
        vertices.extend(
            blob.vertices()
                .iter()
                .map(|p| [0.45 + 0.1 * p[0], 0.45 + 0.1 * p[1], 1.2 + 0.1 * p[2]]),
        );
        triangles.extend(blob.triangles().iter().map(|t| t.map(|v| v + 121)));
        let mesh = TriMesh::new(vertices, triangles).unwrap();
        let (labels, count) = components(&mesh);
        assert_eq!(count, 2);
        let mut points: Vec<Point<3>> = (0..25)
            .map(|k| [0.25 * (k % 5) as f64, 0.25 * (k / 5) as f64, 1.0])
            .collect();
        points.push([0.5, 0.5, 1.25]);
        points.push([f64::NAN, 0.0, 0.0]);
        points.push([9.0, 9.0, 9.0]);
        assert_eq!(
            component_support(&mesh, &labels, count, &points, 0.5),
            vec![25, 1]
        );
        // Both are supported in the sense of unsupported_components (a point within reach).
        let far = unsupported_components(&mesh, &labels, count, &points, 0.5);
        assert_eq!(far, vec![false, false]);
        // A radius (0.08) within which every grid point has a sheet vertex (at most 0.071
        // away) but the stray no blob corner (0.087): it counts for none.
        assert_eq!(
            component_support(&mesh, &labels, count, &points, 0.08),
            vec![25, 0]
        );
        // No radius: nothing counts.
        assert_eq!(
            component_support(&mesh, &labels, count, &points, 0.0),
            vec![0, 0]
        );
        assert_eq!(
            component_support(&mesh, &labels, count, &points, f64::NAN),
            vec![0, 0]
        );
    }
}
