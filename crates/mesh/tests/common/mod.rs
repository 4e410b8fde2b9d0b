//! Meshes shared by the integration tests: unit cubes wound outward and the bunny's path.

#![allow(dead_code)] // each test binary uses its own share

use std::path::{Path, PathBuf};

use zeroset_mesh::TriMesh;

/// The unit cube `[0, 1]³`, 12 triangles wound outward.
pub fn unit_cube() -> TriMesh {
    cube_at([0.0; 3])
}

pub fn cube_at(o: [f64; 3]) -> TriMesh {
    let v = (0..8)
        .map(|i| {
            [
                o[0] + (i & 1) as f64,
                o[1] + ((i >> 1) & 1) as f64,
                o[2] + ((i >> 2) & 1) as f64,
            ]
        })
        .collect();
    TriMesh::new(v, cube_triangles(0)).unwrap()
}

pub fn cube_triangles(offset: u32) -> Vec<[u32; 3]> {
    let quads: [[u32; 4]; 6] = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .map(|t| t.map(|v| v + offset))
        .collect()
}

/// The Stanford bunny mesh in the repository's `data/` folder (or `$ZEROSET_DATA`).
pub fn bunny_path() -> PathBuf {
    std::env::var_os("ZEROSET_DATA")
        .map_or_else(
            || Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data"),
            PathBuf::from,
        )
        .join("bun_zipper.ply")
}

/// A tetrahedron with its right-angled corner at `o`, wound outward, with per-vertex normals
/// (the corner directions from the centroid).
pub fn tetrahedron_at(o: [f64; 3]) -> TriMesh {
    let v = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ]
    .map(|p: [f64; 3]| [o[0] + p[0], o[1] + p[1], o[2] + p[2]])
    .to_vec();
    let n = vec![
        [-0.5, -0.5, -0.5],
        [0.75, -0.25, -0.25],
        [-0.25, 0.75, -0.25],
        [-0.25, -0.25, 0.75],
    ];
    TriMesh::new(v, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
        .unwrap()
        .with_normals(n)
        .unwrap()
}
