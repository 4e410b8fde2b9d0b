//! Indexed triangle meshes.
//!
//! A [`TriMesh`] is a list of vertices (shared by the triangles that use them: a welded mesh),
//! optional per-vertex normals, and triangles as index triples. zeroset's convention: a
//! triangle `(a, b, c)` is wound counter-clockwise seen from outside, so `(b − a) × (c − a)`
//! points out of the solid, where the field is positive.

use zeroset_field_core::geometry::{cross, norm, sub};
use zeroset_field_core::{Aabb, Point};

use crate::{MeshError, Result};

/// An indexed triangle mesh in 3-D; see the [module docs](self).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    vertices: Vec<Point<3>>,
    normals: Vec<Point<3>>,
    triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// A mesh of `vertices` and `triangles`, checked: every index is a vertex and every
    /// coordinate finite. Vertices no triangle uses are allowed (scanned meshes have them).
    ///
    /// # Errors
    /// [`MeshError::InvalidMesh`] naming the first bad triangle or vertex.
    pub fn new(vertices: Vec<Point<3>>, triangles: Vec<[u32; 3]>) -> Result<Self> {
        if let Some((i, p)) = vertices
            .iter()
            .enumerate()
            .find(|(_, p)| p.iter().any(|v| !v.is_finite()))
        {
            return Err(MeshError::InvalidMesh {
                detail: format!("vertex {i} has a non-finite coordinate: {p:?}"),
            });
        }
        let n = vertices.len();
        if let Some((t, tri)) = triangles
            .iter()
            .enumerate()
            .find(|(_, tri)| tri.iter().any(|&v| v as usize >= n))
        {
            return Err(MeshError::InvalidMesh {
                detail: format!("triangle {t} {tri:?} refers to a vertex beyond the {n} given"),
            });
        }
        Ok(Self {
            vertices,
            normals: Vec::new(),
            triangles,
        })
    }

    /// The same mesh with one normal per vertex.
    ///
    /// # Errors
    /// [`MeshError::InvalidMesh`] if the count differs from the vertices' or a normal is not
    /// finite.
    pub fn with_normals(mut self, normals: Vec<Point<3>>) -> Result<Self> {
        if normals.len() != self.vertices.len() {
            return Err(MeshError::InvalidMesh {
                detail: format!(
                    "{} normals for {} vertices",
                    normals.len(),
                    self.vertices.len()
                ),
            });
        }
        if let Some(i) = normals
            .iter()
            .position(|p| p.iter().any(|v| !v.is_finite()))
        {
            return Err(MeshError::InvalidMesh {
                detail: format!("normal {i} is not finite"),
            });
        }
        self.normals = normals;
        Ok(self)
    }

    /// The vertices.
    pub fn vertices(&self) -> &[Point<3>] {
        &self.vertices
    }

    /// The per-vertex normals (empty when there are none).
    pub fn normals(&self) -> &[Point<3>] {
        &self.normals
    }

    /// The triangles, as vertex indices.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The mesh taken apart without copying: `(vertices, triangles, normals)` (normals empty
    /// when there are none).
    pub fn into_parts(self) -> (Vec<Point<3>>, Vec<[u32; 3]>, Vec<Point<3>>) {
        (self.vertices, self.triangles, self.normals)
    }

    /// The mesh of the triangles `t` with `keep(t)`, and only the vertices (and normals) they
    /// use, in their order.
    ///
    /// ```
    /// use zeroset_mesh::TriMesh;
    ///
    /// let v = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]];
    /// let m = TriMesh::new(v, vec![[0, 1, 2], [3, 4, 5]])?;
    /// let kept = m.retain_triangles(|t| t == 1);
    /// assert_eq!(kept.triangles(), &[[0, 1, 2]]);
    /// assert_eq!(kept.vertices()[0], [5.0, 5.0, 5.0]);
    /// # Ok::<(), zeroset_mesh::MeshError>(())
    /// ```
    pub fn retain_triangles(&self, keep: impl Fn(usize) -> bool) -> TriMesh {
        let mut index = vec![u32::MAX; self.vertices.len()];
        let (mut vertices, mut normals, mut triangles) = (Vec::new(), Vec::new(), Vec::new());
        for (t, tri) in self.triangles.iter().enumerate() {
            if !keep(t) {
                continue;
            }
            triangles.push(tri.map(|v| {
                let v = v as usize;
                if index[v] == u32::MAX {
                    index[v] = vertices.len() as u32;
                    vertices.push(self.vertices[v]);
                    if !self.normals.is_empty() {
                        normals.push(self.normals[v]);
                    }
                }
                index[v]
            }));
        }
        TriMesh {
            vertices,
            normals,
            triangles,
        }
    }

    /// The mesh turned over: each triangle's winding reversed and each vertex normal negated
    /// (the same surface, its other side out).
    ///
    /// ```
    /// use zeroset_mesh::TriMesh;
    ///
    /// let v = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    /// let m = TriMesh::new(v, vec![[0, 1, 2]])?.with_normals(vec![[0.0, 0.0, 1.0]; 3])?;
    /// let turned = m.clone().turned_over();
    /// assert_eq!(turned.triangles(), &[[0, 2, 1]]);
    /// assert_eq!(turned.normals()[0], [0.0, 0.0, -1.0]);
    /// assert_eq!(turned.turned_over(), m);
    /// # Ok::<(), zeroset_mesh::MeshError>(())
    /// ```
    #[must_use]
    pub fn turned_over(self) -> TriMesh {
        TriMesh {
            vertices: self.vertices,
            normals: self.normals.into_iter().map(|n| n.map(|x| -x)).collect(),
            triangles: self
                .triangles
                .into_iter()
                .map(|[a, b, c]| [a, c, b])
                .collect(),
        }
    }

    /// The number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// The number of triangles.
    pub fn num_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// Whether the mesh has no triangle.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The box around the vertices (`None` without vertices).
    pub fn bounds(&self) -> Option<Aabb<3>> {
        Aabb::from_points(&self.vertices)
    }

    /// How far storing the vertices as 32-bit floats (binary STL always, PLY `float`) would
    /// move them, as a fraction of the box's diagonal: the largest `|x − f32(x)|` over the
    /// coordinates, divided by the diagonal. About 3·10⁻⁸ for a mesh about the origin; large
    /// for one far from it (georeferenced coordinates: a 15 m building at 4·10⁶ m, f32's step
    /// there 0.5 m, gives 10⁻²); infinite for a coordinate beyond the `f32` range, and 0 for a
    /// mesh without extent.
    ///
    /// ```
    /// use zeroset_mesh::TriMesh;
    ///
    /// let near = TriMesh::new(vec![[0.1, 0.2, 0.3], [1.1, 0.2, 0.3], [0.1, 1.2, 0.3]], vec![[0, 1, 2]])?;
    /// assert!(near.f32_rounding() < 1e-7);
    /// let far = TriMesh::new(vec![[4e6, 0.2, 0.3], [4e6 + 1.1, 0.2, 0.3], [4e6, 1.2, 0.3]], vec![[0, 1, 2]])?;
    /// assert!(far.f32_rounding() > 0.05);
    /// # Ok::<(), zeroset_mesh::MeshError>(())
    /// ```
    pub fn f32_rounding(&self) -> f64 {
        let Some(diagonal) = self.bounds().map(|b| b.diagonal()) else {
            return 0.0;
        };
        let worst = self
            .vertices
            .iter()
            .flatten()
            .map(|&x| {
                let y = x as f32;
                if y.is_finite() {
                    (x - f64::from(y)).abs()
                } else {
                    f64::INFINITY
                }
            })
            .fold(0.0, f64::max);
        if worst == 0.0 { 0.0 } else { worst / diagonal }
    }

    /// The corners of triangle `t`.
    pub fn corners(&self, t: usize) -> [Point<3>; 3] {
        self.triangles[t].map(|v| self.vertices[v as usize])
    }

    /// Each vertex's unit normal from the winding of the triangles around it: the sum of
    /// their vectors `(b − a) × (c − a)` (so weighted by area), normalised; `[0, 0, 0]` for a
    /// vertex no triangle with area uses. They point out of the solid when the triangles are
    /// wound counter-clockwise seen from outside (zeroset's convention, and STL's).
    ///
    /// ```
    /// use zeroset_mesh::TriMesh;
    ///
    /// // Two triangles of the plane z = 0, wound counter-clockwise seen from +z, and a loose
    /// // vertex.
    /// let v = vec![[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [5.0; 3]];
    /// let m = TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3]])?;
    /// let n = m.winding_normals();
    /// assert!(n[..4].iter().all(|n| *n == [0.0, 0.0, 1.0]));
    /// assert_eq!(n[4], [0.0; 3]);
    /// # Ok::<(), zeroset_mesh::MeshError>(())
    /// ```
    pub fn winding_normals(&self) -> Vec<Point<3>> {
        let mut sums = vec![[0.0; 3]; self.vertices.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            let area = area_vector(&self.corners(t));
            for &v in tri {
                let sum = &mut sums[v as usize];
                for a in 0..3 {
                    sum[a] += area[a];
                }
            }
        }
        sums.iter().map(unit_or_zero).collect()
    }
}

/// `(b − a) × (c − a)` of a triangle's corners: twice its area along its normal.
pub(crate) fn area_vector([a, b, c]: &[Point<3>; 3]) -> Point<3> {
    cross(&sub(b, a), &sub(c, a))
}

/// `n / |n|`, or zero where `|n|` is 0 or not finite.
pub(crate) fn unit_or_zero(n: &Point<3>) -> Point<3> {
    let length = norm(n);
    if length > 0.0 && length.is_finite() {
        n.map(|x| x / length)
    } else {
        [0.0; 3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_indices_and_coordinates_are_refused() {
        let v = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let m = TriMesh::new(v.clone(), vec![[0, 1, 2]]).unwrap();
        assert_eq!((m.num_vertices(), m.num_triangles()), (3, 1));
        assert_eq!(m.corners(0)[1], [1.0, 0.0, 0.0]);
        assert!(TriMesh::new(v.clone(), vec![[0, 1, 3]]).is_err());
        assert!(TriMesh::new(vec![[f64::NAN; 3]], vec![]).is_err());
        assert!(m.clone().with_normals(vec![[0.0, 0.0, 1.0]]).is_err());
        assert!(m.with_normals(vec![[0.0, 0.0, 1.0]; 3]).is_ok());
        assert!(TriMesh::default().is_empty());
    }
}
