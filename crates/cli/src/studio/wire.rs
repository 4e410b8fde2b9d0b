//! The binary forms in which the studio sends meshes (`ZSM1`) and point sets (`ZSP1`) to the
//! page: little-endian `f32` positions relative to an offset, `i16` unit normals, `u32`
//! indices, so that a 20k-triangle surface is a few hundred kilobytes and the page hands the
//! arrays to WebGL without parsing numbers. The layout is in `docs/studio.md`.

use serde_json::Value;
use zeroset_field_core::geometry::Point;
use zeroset_mesh::TriMesh;

/// A mesh: `ZSM1`, the JSON `report` (padded to 4 bytes, its vertex and triangle counts added),
/// vertex and triangle counts, positions minus `offset`, normals, indices.
pub(crate) fn mesh(mut report: Value, mesh: &TriMesh, offset: Point<3>) -> Vec<u8> {
    let (vertices, normals, triangles) = (mesh.vertices(), mesh.normals(), mesh.triangles());
    report["vertices"] = vertices.len().into();
    report["triangles"] = triangles.len().into();
    let mut json = report.to_string().into_bytes();
    json.resize(json.len().next_multiple_of(4), b' ');
    let normal_bytes = (6 * vertices.len()).next_multiple_of(4);
    let mut out = Vec::with_capacity(
        16 + json.len() + 12 * vertices.len() + normal_bytes + 12 * triangles.len(),
    );
    out.extend_from_slice(b"ZSM1");
    push_u32(&mut out, json.len());
    out.extend_from_slice(&json);
    push_u32(&mut out, vertices.len());
    push_u32(&mut out, triangles.len());
    for p in vertices {
        for axis in 0..3 {
            out.extend_from_slice(&((p[axis] - offset[axis]) as f32).to_le_bytes());
        }
    }
    let start = out.len();
    let missing = std::iter::repeat([0.0; 3]);
    for n in normals.iter().copied().chain(missing).take(vertices.len()) {
        for c in n {
            out.extend_from_slice(&snorm16(c).to_le_bytes());
        }
    }
    out.resize(start + normal_bytes, 0);
    for t in triangles {
        for &i in t {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    out
}

/// A point set: `ZSP1`, the count, positions minus `offset`.
pub(crate) fn points(points: &[Point<3>], offset: Point<3>) -> Vec<u8> {
    let mut out = Vec::with_capacity(8 + 12 * points.len());
    out.extend_from_slice(b"ZSP1");
    push_u32(&mut out, points.len());
    for p in points {
        for axis in 0..3 {
            out.extend_from_slice(&((p[axis] - offset[axis]) as f32).to_le_bytes());
        }
    }
    out
}

/// A length as a little-endian `u32`. Meshes with more than `u32::MAX` vertices are refused by
/// marching cubes, so lengths fit.
fn push_u32(out: &mut Vec<u8>, n: usize) {
    let n = u32::try_from(n).unwrap_or(u32::MAX);
    out.extend_from_slice(&n.to_le_bytes());
}

/// A component of a unit normal as a normalised `i16` (`round(32767·v)`, clamped; NaN → 0).
fn snorm16(v: f64) -> i16 {
    if v.is_nan() {
        0
    } else {
        (v.clamp(-1.0, 1.0) * 32767.0).round() as i16
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mesh_layout_is_the_documented_one() {
        let mesh = TriMesh::new(
            vec![[1.0, 2.0, 3.0], [2.0, 2.0, 3.0], [1.0, 3.0, 3.0]],
            vec![[0, 1, 2]],
        )
        .unwrap()
        .with_normals(vec![[0.0, 0.0, 1.0]; 3])
        .unwrap();
        let bytes = super::mesh(serde_json::json!({"a": 1}), &mesh, [1.0, 2.0, 3.0]);
        assert_eq!(&bytes[..4], b"ZSM1");
        let j = u32::from_le_bytes(bytes[4..8].try_into().unwrap()) as usize;
        assert_eq!(j % 4, 0);
        let report: Value = serde_json::from_slice(&bytes[8..8 + j]).unwrap();
        assert_eq!(report["vertices"], 3);
        assert_eq!(report["triangles"], 1);
        let mut at = 8 + j;
        let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        assert_eq!((word(at), word(at + 4)), (3, 1));
        at += 8;
        let x1 = f32::from_le_bytes(bytes[at + 12..at + 16].try_into().unwrap());
        assert_eq!(x1, 1.0, "positions are relative to the offset");
        at += 36;
        let nz = i16::from_le_bytes(bytes[at + 4..at + 6].try_into().unwrap());
        assert_eq!(nz, 32767);
        at += 20; // 18 bytes of normals, padded to 20
        assert_eq!((word(at), word(at + 4), word(at + 8)), (0, 1, 2));
        assert_eq!(bytes.len(), at + 12);
    }

    #[test]
    fn points_layout_and_snorm() {
        let bytes = points(&[[0.5, 0.0, 0.0]], [0.0; 3]);
        assert_eq!(&bytes[..8], b"ZSP1\x01\0\0\0");
        assert_eq!(bytes.len(), 20);
        assert_eq!(snorm16(-2.0), -32767);
        assert_eq!(snorm16(f64::NAN), 0);
    }
}
