//! Polygons with more than three corners as triangles, for the readers of formats that allow
//! them (OFF, OBJ, PLY). A convex polygon is fanned from its first corner (`i1 i2 i3`,
//! `i1 i3 i4`, …); a non-convex one — an L-shaped face, the letters of a CAD logo — is cut
//! by ear clipping (Meisters 1975) in the plane of its Newell normal, since a fan from a
//! corner that does not see the whole polygon lays triangles outside it, facing the other
//! way. The triangles keep the polygon's winding. A polygon that is degenerate in its plane
//! (no area, or self-intersecting so that no ear is left) is fanned, as before.

use zeroset_field_core::Point;
use zeroset_field_core::geometry::{cross, dot, sub};

/// Appends the triangles of the polygon with `corners` (indices into `positions`) to
/// `triangles`: a fan where it is convex or its positions are not all known, ear clipping
/// otherwise; see the [module docs](self).
pub(crate) fn triangulate(corners: &[u32], positions: &[Point<3>], triangles: &mut Vec<[u32; 3]>) {
    let fan = |triangles: &mut Vec<[u32; 3]>, corners: &[u32]| {
        for k in 1..corners.len().saturating_sub(1) {
            triangles.push([corners[0], corners[k], corners[k + 1]]);
        }
    };
    if corners.len() <= 3 || corners.iter().any(|&c| c as usize >= positions.len()) {
        return fan(triangles, corners);
    }
    let Some(flat) = projected(corners, positions) else {
        return fan(triangles, corners);
    };
    let turn = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    let n = corners.len();
    if (0..n).all(|i| turn(flat[i], flat[(i + 1) % n], flat[(i + 2) % n]) >= 0.0) {
        return fan(triangles, corners);
    }
    // Ear clipping: the first corner (in order) that turns left and whose triangle holds no
    // other remaining corner is cut off, until three are left.
    let mut left: Vec<usize> = (0..n).collect();
    let start = triangles.len();
    while left.len() > 3 {
        let m = left.len();
        let ear = (0..m).find(|&k| {
            let (a, b, c) = (left[(k + m - 1) % m], left[k], left[(k + 1) % m]);
            turn(flat[a], flat[b], flat[c]) > 0.0
                && left.iter().all(|&o| {
                    o == a || o == b || o == c || !inside(flat[o], flat[a], flat[b], flat[c])
                })
        });
        let Some(k) = ear else {
            // Self-intersecting: no ear left. Fan the whole polygon instead.
            triangles.truncate(start);
            return fan(triangles, corners);
        };
        let (a, b, c) = (left[(k + m - 1) % m], left[k], left[(k + 1) % m]);
        triangles.push([corners[a], corners[b], corners[c]]);
        left.remove(k);
    }
    triangles.push([corners[left[0]], corners[left[1]], corners[left[2]]]);
}

/// The polygon's corners in the plane across its Newell normal's largest component,
/// counter-clockwise seen along the normal; `None` where the polygon has no area.
fn projected(corners: &[u32], positions: &[Point<3>]) -> Option<Vec<[f64; 2]>> {
    let at = |k: usize| positions[corners[k % corners.len()] as usize];
    let origin = at(0);
    let normal = (0..corners.len()).fold([0.0; 3], |s, k| {
        let c = cross(&sub(&at(k), &origin), &sub(&at(k + 1), &origin));
        [s[0] + c[0], s[1] + c[1], s[2] + c[2]]
    });
    let axis = (0..3).max_by(|&a, &b| normal[a].abs().total_cmp(&normal[b].abs()))?;
    let area = dot(&normal, &normal);
    if area.is_nan() || area == 0.0 {
        return None;
    }
    // The other two axes, in the order that keeps the polygon counter-clockwise.
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let (u, v) = if normal[axis] > 0.0 { (u, v) } else { (v, u) };
    Some(
        (0..corners.len())
            .map(|k| {
                let p = at(k);
                [p[u], p[v]]
            })
            .collect(),
    )
}

/// Whether `p` lies inside or on the counter-clockwise triangle `a b c`.
fn inside(p: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> bool {
    let side =
        |x: [f64; 2], y: [f64; 2]| (y[0] - x[0]) * (p[1] - x[1]) - (y[1] - x[1]) * (p[0] - x[0]);
    side(a, b) >= 0.0 && side(b, c) >= 0.0 && side(c, a) >= 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Twice the signed area of each triangle, in the plane z = 0.
    fn areas(triangles: &[[u32; 3]], p: &[Point<3>]) -> Vec<f64> {
        triangles
            .iter()
            .map(|t| {
                cross(
                    &sub(&p[t[1] as usize], &p[t[0] as usize]),
                    &sub(&p[t[2] as usize], &p[t[0] as usize]),
                )[2]
            })
            .collect()
    }

    #[test]
    fn a_convex_polygon_is_fanned_and_a_non_convex_one_clipped_inside_it() {
        // A square: the fan, as before.
        let square = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let mut t = Vec::new();
        triangulate(&[0, 1, 2, 3], &square, &mut t);
        assert_eq!(t, vec![[0, 1, 2], [0, 2, 3]]);
        // An L of area 3 starting at a corner that does not see the whole of it: a fan lays
        // a triangle outside, facing the other way (twice its area −1).
        let l = [
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 2.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 0.0],
        ];
        let corners = [0, 1, 2, 3, 4, 5];
        let mut fan = Vec::new();
        for k in 1..5 {
            fan.push([0, k, k + 1]);
        }
        assert!(areas(&fan, &l).iter().any(|&a| a < 0.0));
        for (points, facing) in [
            (l.to_vec(), 1.0),
            (l.iter().map(|p| [p[1], p[0], 0.0]).collect(), -1.0),
        ] {
            let mut t = Vec::new();
            triangulate(&corners, &points, &mut t);
            assert_eq!(t.len(), 4);
            let a = areas(&t, &points);
            // Every triangle faces as the polygon does, and they tile its area.
            assert!(a.iter().all(|&a| a * facing > 0.0), "{a:?}");
            assert!(
                (a.iter().sum::<f64>() * facing - 6.0).abs() < 1e-12,
                "{a:?}"
            );
        }
        // Tilted out of its plane's axes (the L turned about x by 60°): the same.
        let (s, c) = (60f64.to_radians().sin(), 60f64.to_radians().cos());
        let tilted: Vec<Point<3>> = l.iter().map(|p| [p[0], c * p[1], s * p[1]]).collect();
        let mut t = Vec::new();
        triangulate(&corners, &tilted, &mut t);
        let normal = |t: &[u32; 3]| {
            cross(
                &sub(&tilted[t[1] as usize], &tilted[t[0] as usize]),
                &sub(&tilted[t[2] as usize], &tilted[t[0] as usize]),
            )
        };
        assert!(t.iter().all(|t| dot(&normal(t), &[0.0, -s, c]) > 0.0));
        // Corners not read yet, or no area: the fan.
        let mut t = Vec::new();
        triangulate(&[0, 1, 2, 9], &square, &mut t);
        assert_eq!(t, vec![[0, 1, 2], [0, 2, 9]]);
        let line = [[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
        let mut t = Vec::new();
        triangulate(&[0, 1, 2, 3], &line, &mut t);
        assert_eq!(t, vec![[0, 1, 2], [0, 2, 3]]);
    }
}
