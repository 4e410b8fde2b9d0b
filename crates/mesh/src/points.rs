//! A mesh as an oriented point cloud: the points a fit takes from a mesh file, so that a broken
//! mesh (holes, a ragged scan, an STL from another program) can be rebuilt into a closed one.
//!
//! The points are the vertices the triangles use — a vertex no triangle uses is not on the
//! surface the mesh describes — or, for a mesh without triangles (an OBJ of vertices only),
//! every vertex; a mesh of fewer than [`MIN_MESH_POINTS`] vertices also gets points inside
//! its triangles. Their normals, in this order ([`NormalSource`]):
//! 1. the mesh's own per-vertex normals (a PLY with `nx ny nz`, an OBJ whose every vertex
//!    names one `vn`), made unit; where one is zero or not finite, the next rule decides;
//! 2. the triangles' winding, where it is consistent (each edge shared by two triangles runs
//!    opposite ways in them, and by no more than two): each vertex's area-weighted face normal
//!    ([`TriMesh::winding_normals`]). In a closed mesh, each closed part wound inward (negative
//!    volume) is turned over on its own; an open mesh has no inside to measure and is taken as
//!    wound (counter-clockwise seen from outside, zeroset's and STL's convention) — but of
//!    parts modelled apart that meet along seams (their border vertices repeated), those wound
//!    against the parts they meet are turned over, the fewer triangles turned. Where the
//!    winding holds, this is exact information a nearest-neighbour estimate can only
//!    approximate (thin parts, sparse CAD vertices);
//! 3. none otherwise — inconsistent winding, non-manifold edges, a vertex used only by
//!    triangles without area, a mesh without triangles and normals — for the caller to
//!    estimate (as `zeroset reconstruct` does, with `zeroset_bases::normals`).
//!
//! ```
//! use zeroset_mesh::TriMesh;
//! use zeroset_mesh::points::{NormalSource, mesh_points};
//!
//! // A tetrahedron wound inward (every triangle clockwise seen from outside), and a vertex
//! // no triangle uses.
//! let v = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [9.0; 3]];
//! let inward = TriMesh::new(v, vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])?;
//! let p = mesh_points(inward);
//! assert_eq!((p.positions.len() - p.sampled, p.left_out), (4, 1));
//! assert_eq!(p.source, NormalSource::Winding { turned: 1, closed_parts: 1 });
//! // Turned over: the normal at the apex (0, 0, 1) points up and out...
//! let n = p.normals.unwrap();
//! assert!(n[3][2] > 0.5);
//! // ...and so do those of the points sampled inside the 4 triangles (4 vertices are
//! // too few to fit): each along its face's outward normal.
//! assert!(p.sampled > 5000);
//! let centroid = [0.25; 3];
//! assert!(p.positions[4..].iter().zip(&n[4..]).all(|(x, n)| {
//!     (0..3).map(|a| (x[a] - centroid[a]) * n[a]).sum::<f64>() > 0.0
//! }));
//! # Ok::<(), zeroset_mesh::MeshError>(())
//! ```

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::fmt;

use zeroset_field_core::Point;
use zeroset_field_core::geometry::{cross, dot, norm, sub};

use crate::trimesh::{area_vector, unit_or_zero};
use crate::{TriMesh, check, components};

/// The points of a mesh and their normals; see the [module docs](self).
#[derive(Debug, Clone, PartialEq)]
pub struct MeshPoints {
    /// The vertices the triangles use (every vertex of a mesh without triangles), in their
    /// order in the mesh.
    pub positions: Vec<Point<3>>,
    /// One unit normal per position, or `None` ([`source`](Self::source) says why).
    pub normals: Option<Vec<Point<3>>>,
    /// Where the normals came from, or why there are none.
    pub source: NormalSource,
    /// Vertices left out because no triangle uses them.
    pub left_out: usize,
    /// Points sampled inside the triangles, after the vertices in
    /// [`positions`](Self::positions) (0 for a mesh of at least [`MIN_MESH_POINTS`] vertices).
    pub sampled: usize,
}

/// The fewest points a mesh with triangles gives. A mesh of fewer vertices — a CAD part's few,
/// large triangles: a cube's 8 corners, a cylinder's long slivers — also gets
/// `MIN_MESH_POINTS` points inside its triangles, each triangle its share by area, spread over
/// it evenly (an R₂ sequence), with the face's normal where the winding gives the normals, so
/// that a fit sees its faces.
/// A scan's dense mesh has enough vertices already and is taken as it is.
pub const MIN_MESH_POINTS: usize = 10_000;

/// Where [`MeshPoints::normals`] came from, or why there are none. Its `Display` is a phrase
/// that follows "normals" in a sentence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum NormalSource {
    /// The mesh's own per-vertex normals, made unit.
    File,
    /// The winding of a closed mesh, with `turned` of its `closed_parts` turned over (wound
    /// inward).
    Winding {
        /// Closed parts wound inward, turned over.
        turned: usize,
        /// Closed parts (edge-connected components).
        closed_parts: usize,
    },
    /// The winding of an open mesh, as wound.
    WindingOpen,
    /// The winding of an open mesh of several parts, `turned` of them turned over to agree
    /// with the parts they meet along seams (edges at the same positions in two parts), and
    /// `inward` closed parts (no boundary edge, no seam) wound inward turned over.
    WindingOpenParts {
        /// Parts turned over to agree along seams.
        turned: usize,
        /// Closed parts turned over, wound inward.
        inward: usize,
        /// Parts (edge-connected components).
        parts: usize,
    },
    /// None: the winding is inconsistent or edges are non-manifold.
    Inconsistent {
        /// Edges used twice the same way.
        inconsistent_edges: usize,
        /// Edges used by more than two triangles.
        non_manifold_edges: usize,
    },
    /// None: vertices lie only on triangles without area.
    Flat {
        /// Such vertices.
        vertices: usize,
    },
    /// None: a mesh without triangles and without normals.
    NoTriangles,
}

impl fmt::Display for NormalSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::File => write!(f, "from the file"),
            Self::Winding { turned: 0, .. } => write!(f, "from the triangles' winding"),
            Self::Winding {
                turned,
                closed_parts,
            } => write!(
                f,
                "from the triangles' winding, turned over on {turned} of {closed_parts} closed \
                 part(s) wound inward"
            ),
            Self::WindingOpen => write!(f, "from the triangles' winding (an open mesh: as wound)"),
            Self::WindingOpenParts {
                turned,
                inward,
                parts,
            } => {
                write!(
                    f,
                    "from the triangles' winding (an open mesh: as wound, but "
                )?;
                if turned > 0 {
                    write!(
                        f,
                        "{turned} of its {parts} parts turned over to agree with the parts they \
                         meet along seams"
                    )?;
                }
                if inward > 0 {
                    let and = if turned > 0 { " and " } else { "" };
                    write!(f, "{and}{inward} closed part(s) wound inward turned over")?;
                }
                write!(f, ")")
            }
            Self::Inconsistent {
                inconsistent_edges,
                non_manifold_edges,
            } => write!(
                f,
                "not taken from the triangles: their winding is inconsistent at \
                 {inconsistent_edges} edge(s) and {non_manifold_edges} edge(s) are non-manifold"
            ),
            Self::Flat { vertices } => write!(
                f,
                "not taken from the triangles: {vertices} vertex(es) lie only on triangles \
                 without area"
            ),
            Self::NoTriangles => write!(f, "none (no triangle to take them from)"),
        }
    }
}

/// Whether `mesh`'s triangles use fewer than half of its vertices: a point cloud that carries
/// a few faces (a marker, a patch some program added) rather than a mesh — taking the
/// triangles' vertices ([`mesh_points`]) would drop most of its points. Readers of point
/// clouds read such a file's vertices as a cloud.
pub fn is_mostly_unused(mesh: &TriMesh) -> bool {
    let mut used = vec![false; mesh.num_vertices()];
    for t in mesh.triangles() {
        for &v in t {
            if let Some(u) = used.get_mut(v as usize) {
                *u = true;
            }
        }
    }
    let used = used.iter().filter(|&&u| u).count();
    mesh.num_triangles() > 0 && 2 * used < mesh.num_vertices()
}

/// The points of `mesh` and their normals; see the [module docs](self).
pub fn mesh_points(mesh: TriMesh) -> MeshPoints {
    let all = mesh.num_vertices();
    let mesh = if mesh.is_empty() {
        mesh
    } else {
        mesh.retain_triangles(|_| true)
    };
    let left_out = all - mesh.num_vertices();
    let (mut normals, source, sign) = normals(&mesh);
    let (inside, inside_normals) = sample_triangles(&mesh, normals.as_deref(), &sign);
    let sampled = inside.len();
    let (mut positions, _, _) = mesh.into_parts();
    positions.extend(inside);
    if let Some(n) = &mut normals {
        n.extend(inside_normals);
    }
    MeshPoints {
        positions,
        normals,
        source,
        left_out,
        sampled,
    }
}

/// The normals of `mesh`'s vertices, where they came from, and each triangle's orientation
/// (`-1` for a part turned over; empty where the normals are not the winding's).
fn normals(mesh: &TriMesh) -> (Option<Vec<Point<3>>>, NormalSource, Vec<f64>) {
    let unit: Option<Vec<Point<3>>> = mesh
        .normals()
        .iter()
        .map(|n| {
            let length = norm(n);
            (length > 0.0 && length.is_finite()).then(|| n.map(|x| x / length))
        })
        .collect();
    if let Some(unit) = unit.filter(|u| !u.is_empty()) {
        return (Some(unit), NormalSource::File, Vec::new());
    }
    if mesh.is_empty() {
        return (None, NormalSource::NoTriangles, Vec::new());
    }
    let report = check(mesh);
    if report.inconsistent_edges > 0 || report.non_manifold_edges > 0 {
        let source = NormalSource::Inconsistent {
            inconsistent_edges: report.inconsistent_edges,
            non_manifold_edges: report.non_manifold_edges,
        };
        return (None, source, Vec::new());
    }
    let mut normals = mesh.winding_normals();
    let flat = normals.iter().filter(|n| **n == [0.0; 3]).count();
    if flat > 0 {
        return (None, NormalSource::Flat { vertices: flat }, Vec::new());
    }
    let (labels, parts) = components(mesh);
    let volume = part_volumes(mesh, &labels, parts);
    if report.boundary_edges > 0 {
        let mut turn = seam_turns(mesh, &labels, parts);
        let turned = turn.iter().filter(|&&t| t).count();
        // Closed parts meet no other along seams: each faces out by its own volume.
        let closed = closed_parts(mesh, &labels, parts);
        let mut inward = 0;
        for part in 0..parts {
            if closed[part] && volume[part] < 0.0 {
                turn[part] = true;
                inward += 1;
            }
        }
        if turned + inward == 0 {
            return (
                Some(normals),
                NormalSource::WindingOpen,
                vec![1.0; mesh.num_triangles()],
            );
        }
        let sign: Vec<f64> = labels
            .iter()
            .map(|&part| if turn[part as usize] { -1.0 } else { 1.0 })
            .collect();
        turn_vertices(mesh, &sign, &mut normals);
        return (
            Some(normals),
            NormalSource::WindingOpenParts {
                turned,
                inward,
                parts,
            },
            sign,
        );
    }
    let sign: Vec<f64> = labels
        .iter()
        .map(|&part| {
            if volume[part as usize] < 0.0 {
                -1.0
            } else {
                1.0
            }
        })
        .collect();
    turn_vertices(mesh, &sign, &mut normals);
    let source = NormalSource::Winding {
        turned: volume.iter().filter(|v| **v < 0.0).count(),
        closed_parts: parts,
    };
    (Some(normals), source, sign)
}

/// Each part's signed volume (`labels` per triangle), from a corner of the box (for fewer
/// cancelling digits): the volume it encloses where it is closed.
fn part_volumes(mesh: &TriMesh, labels: &[u32], parts: usize) -> Vec<f64> {
    let origin = mesh.bounds().map_or([0.0; 3], |b| b.min());
    let mut volume = vec![0.0; parts];
    for (t, &part) in labels.iter().enumerate() {
        let [a, b, c] = mesh.corners(t).map(|p| sub(&p, &origin));
        volume[part as usize] += dot(&a, &cross(&b, &c)) / 6.0;
    }
    volume
}

/// Which parts (`labels` per triangle) have no boundary edge (an edge of one triangle).
fn closed_parts(mesh: &TriMesh, labels: &[u32], parts: usize) -> Vec<bool> {
    let mut uses: HashMap<(u32, u32), u32> = HashMap::new();
    for tri in mesh.triangles() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut closed = vec![true; parts];
    for (tri, &part) in mesh.triangles().iter().zip(labels) {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if uses[&(a.min(b), a.max(b))] == 1 {
                closed[part as usize] = false;
            }
        }
    }
    closed
}

/// Negates the normals of the vertices of the triangles whose `sign` is negative (turned
/// over).
fn turn_vertices(mesh: &TriMesh, sign: &[f64], normals: &mut [Point<3>]) {
    let mut turn = vec![false; normals.len()];
    for (tri, &s) in mesh.triangles().iter().zip(sign) {
        if s < 0.0 {
            for &v in tri {
                turn[v as usize] = true;
            }
        }
    }
    for (n, turn) in normals.iter_mut().zip(&turn) {
        if *turn {
            *n = n.map(|x| -x);
        }
    }
}

/// Which of an open mesh's `parts` (edge-connected components, `labels` per triangle) to turn
/// over so that they agree along their seams: where two parts have an edge at the same two
/// positions (a patch modelled apart, its border vertices repeated), the edge runs opposite
/// ways in the two triangles if the parts are wound alike, as one welded surface would be.
/// A seam edge is one of exactly two triangles, in different parts. Parts joined by seams
/// are signed against each other (each pair by the majority of its seam edges, along a
/// breadth-first tree from the lowest part); of each group so joined whose pairs all agree
/// with that signing, the side with fewer triangles is turned, the file's winding being the
/// majority's. A part without seams, or in a group whose seams contradict each other round
/// a loop, keeps its winding.
fn seam_turns(mesh: &TriMesh, labels: &[u32], parts: usize) -> Vec<bool> {
    let mut turn = vec![false; parts];
    if parts < 2 {
        return turn;
    }
    // Positions welded: equal coordinates, one id (the first vertex's order).
    let mut ids: HashMap<[u64; 3], u32> = HashMap::new();
    let welded: Vec<u32> = mesh
        .vertices()
        .iter()
        .map(|p| {
            let next = ids.len() as u32;
            // + 0.0 makes −0 the same position as 0.
            *ids.entry(p.map(|x| (x + 0.0).to_bits())).or_insert(next)
        })
        .collect();
    // Each welded edge's uses: (part, runs from the lower id to the higher).
    let mut edges: HashMap<(u32, u32), Vec<(u32, bool)>> = HashMap::new();
    for (tri, &part) in mesh.triangles().iter().zip(labels) {
        for e in 0..3 {
            let (a, b) = (welded[tri[e] as usize], welded[tri[(e + 1) % 3] as usize]);
            if a != b {
                edges
                    .entry((a.min(b), a.max(b)))
                    .or_default()
                    .push((part, a < b));
            }
        }
    }
    // Of each pair of parts meeting along seams: edges wound alike, and against each other.
    // Only an edge of exactly two triangles says how its two sides are wound: where more
    // meet (two boxes sharing an edge), every pairing but one is no seam of a surface.
    let mut pairs: BTreeMap<(u32, u32), (usize, usize)> = BTreeMap::new();
    for uses in edges.values() {
        if let &[(p, dp), (q, dq)] = uses.as_slice()
            && p != q
        {
            let votes = pairs.entry((p.min(q), p.max(q))).or_default();
            if dp != dq {
                votes.0 += 1;
            } else {
                votes.1 += 1;
            }
        }
    }
    let mut adjacent: Vec<Vec<(u32, bool)>> = vec![Vec::new(); parts];
    for (&(p, q), &(alike, against)) in &pairs {
        if alike != against {
            adjacent[p as usize].push((q, against > alike));
            adjacent[q as usize].push((p, against > alike));
        }
    }
    let mut triangles = vec![0usize; parts];
    for &part in labels {
        triangles[part as usize] += 1;
    }
    let mut parity: Vec<Option<bool>> = vec![None; parts];
    for root in 0..parts {
        if parity[root].is_some() {
            continue;
        }
        parity[root] = Some(false);
        let mut group = vec![root];
        let mut queue = VecDeque::from([root]);
        while let Some(p) = queue.pop_front() {
            let flipped = parity[p].expect("set before queued");
            for &(q, against) in &adjacent[p] {
                let q = q as usize;
                if parity[q].is_none() {
                    parity[q] = Some(flipped ^ against);
                    group.push(q);
                    queue.push_back(q);
                }
            }
        }
        // A group whose seams disagree round a loop (a part that would be turned and kept)
        // says nothing reliable: it keeps its winding.
        let consistent = group.iter().all(|&p| {
            adjacent[p]
                .iter()
                .all(|&(q, against)| parity[q as usize] == parity[p].map(|x| x ^ against))
        });
        if !consistent {
            continue;
        }
        let weight = |side: bool| -> usize {
            group
                .iter()
                .filter(|&&p| parity[p] == Some(side))
                .map(|&p| triangles[p])
                .sum()
        };
        let side = weight(true) > weight(false);
        for &p in &group {
            turn[p] = parity[p] == Some(!side);
        }
    }
    turn
}

/// `count` barycentric coordinates `(u, v)` spread evenly over a triangle: the centroid for
/// one, else the first points of the R₂ sequence (Roberts 2018: the unit square's most even
/// additive recurrence, `α = (1/φ₂, 1/φ₂²)` with `φ₂` the plastic number) folded onto the
/// triangle `u + v ≤ 1` and drawn towards its centroid by half their spacing, `1/√(2·count)` in
/// barycentric units (as a lattice of `count` points keeps from the edges), so that no point
/// lies on an edge, where a neighbouring triangle's points would nearly repeat it. (Drawn in
/// by a fixed 20%, a cube's 12 triangles left bands without points along its edges, and its
/// volume came out 0.984.)
fn spread_in_triangle(count: usize) -> impl Iterator<Item = (f64, f64)> {
    const PLASTIC: f64 = 1.324_717_957_244_746;
    const ALPHA: (f64, f64) = (1.0 / PLASTIC, 1.0 / (PLASTIC * PLASTIC));
    let shrink = (1.0 - 1.5 / (2.0 * count as f64).sqrt()).max(0.0);
    (1..=count).map(move |i| {
        if count == 1 {
            return (1.0 / 3.0, 1.0 / 3.0);
        }
        let (mut u, mut v) = (
            (0.5 + i as f64 * ALPHA.0).fract(),
            (0.5 + i as f64 * ALPHA.1).fract(),
        );
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let third = 1.0 / 3.0;
        (third + shrink * (u - third), third + shrink * (v - third))
    })
}

/// [`MIN_MESH_POINTS`] points inside the triangles of `mesh` (none for a mesh of that many
/// vertices), each triangle its share by area, with normals (the triangle's, or the file's
/// interpolated) where the vertices have them.
fn sample_triangles(
    mesh: &TriMesh,
    vertex_normals: Option<&[Point<3>]>,
    sign: &[f64],
) -> (Vec<Point<3>>, Vec<Point<3>>) {
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    let areas: Vec<f64> = (0..mesh.num_triangles())
        .map(|t| 0.5 * norm(&area_vector(&mesh.corners(t))))
        .collect();
    let total: f64 = areas.iter().sum();
    if mesh.num_vertices() >= MIN_MESH_POINTS || !(total > 0.0 && total.is_finite()) {
        return (points, normals);
    }
    // Each triangle gets its share of N points by area, rounded so that the shares add up
    // (systematic rounding of the running sum): a sliver of a CAD export (a cylinder's side
    // as 60 × 0.6 triangles) gets its points too, where a lattice fine enough for N over the
    // whole area put none inside it (a cup's walls and a plate's hole walls came out missing).
    let per_area = MIN_MESH_POINTS as f64 / total;
    let mut running = 0.0f64;
    for (t, &area) in areas.iter().enumerate() {
        let before = (running * per_area + 0.5).floor();
        running += area;
        let count = ((running * per_area + 0.5).floor() - before) as usize;
        if count == 0 {
            continue;
        }
        let [a, b, c] = mesh.corners(t);
        let face = unit_or_zero(&area_vector(&[a, b, c]));
        let tri = mesh.triangles()[t];
        for (u, v) in spread_in_triangle(count) {
            let w = 1.0 - u - v;
            points.push(std::array::from_fn(|x| w * a[x] + u * b[x] + v * c[x]));
            if let Some(n) = vertex_normals {
                let normal = if sign.is_empty() {
                    // The file's normals, interpolated (the face's where they cancel).
                    let [na, nb, nc] = tri.map(|v| n[v as usize]);
                    let m =
                        unit_or_zero(&std::array::from_fn(|x| w * na[x] + u * nb[x] + v * nc[x]));
                    if m == [0.0; 3] { face } else { m }
                } else {
                    face.map(|x| sign[t] * x)
                };
                normals.push(normal);
            }
        }
    }
    (points, normals)
}
