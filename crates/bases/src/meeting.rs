//! Where one sampled place carries two normals that point apart (`n₁ · n₂ < 0`): two sheets of
//! the surface meeting there, or one sheet sampled twice with one normal flipped.
//!
//! Meshes touch themselves (a cow's ear against its head, two solids sharing a point, a wall
//! pinched to nothing), and their vertices then repeat at one position with normals pointing
//! apart; a repeated sample of one sheet may instead carry a flipped normal. The points around
//! tell the two apart. Of the place's nearest other points, those whose normal agrees with `n₁`
//! vote for the first sheet and those agreeing with `n₂` (and not `n₁`) for the second:
//!
//! - only one normal has voters: **one sheet**, whose side is that normal;
//! - both have: **two sheets**, and `ahead = Σ (q − p) · n₁` over the second sheet's voters
//!   says where the second sheet lies: ahead of the first normal (`> 0`: two solids touching,
//!   the place is outside between them) or behind it (`< 0`: a wall pinched to nothing, the
//!   place is inside the wall on both sides).
//!
//! The RBF's off-surface points take their side from this ([`crate::rbf::Constraints`]); MRAS
//! fits a gradient of the two normals' mean there ([`crate::mras::fit_mras`]).

use zeroset_field_core::Point;
use zeroset_field_core::geometry::dot;

/// How two normals pointing apart at one place meet (see the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Meeting {
    /// One sheet with a flipped normal: `first` when the first normal is the sheet's side.
    OneSheet {
        /// Whether the first normal is the one the neighbours agree with.
        first: bool,
    },
    /// Two sheets: `ahead = Σ (q − p) · n₁` over the second sheet's points around.
    Sheets {
        /// `> 0`: two solids touching; `< 0`: a wall pinched to nothing; `0`: no evidence.
        ahead: f64,
    },
}

/// How the sheets meet at `p`, where normals `first` and `second` point apart, from the
/// `(position, normal)` of the nearest other points (neither `p` itself nor its repeats).
pub(crate) fn meeting<const D: usize>(
    p: &Point<D>,
    first: &Point<D>,
    second: &Point<D>,
    neighbours: impl IntoIterator<Item = (Point<D>, Point<D>)>,
) -> Meeting {
    let (mut own, mut other, mut ahead) = (0, 0, 0.0);
    for (q, facing) in neighbours {
        if dot(&facing, first) > 0.0 {
            own += 1;
        } else if dot(&facing, second) > 0.0 {
            other += 1;
            ahead += dot(&std::array::from_fn(|a| q[a] - p[a]), first);
        }
    }
    match (own, other) {
        (0, 1..) => Meeting::OneSheet { first: false },
        (1.., 0) => Meeting::OneSheet { first: true },
        _ => Meeting::Sheets { ahead },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const UP: Point<3> = [0.0, 0.0, 1.0];
    const DOWN: Point<3> = [0.0, 0.0, -1.0];

    #[test]
    fn neighbours_of_one_side_make_one_sheet() {
        let plane = [([1.0, 0.0, 0.0], UP), ([0.0, 1.0, 0.0], UP)];
        assert_eq!(
            meeting(&[0.0; 3], &UP, &DOWN, plane),
            Meeting::OneSheet { first: true }
        );
        assert_eq!(
            meeting(&[0.0; 3], &DOWN, &UP, plane),
            Meeting::OneSheet { first: false }
        );
    }

    #[test]
    fn the_second_sheet_lies_ahead_or_behind() {
        // Two balls touching at the origin, one above (its lower cap faces down) and one below
        // (its upper cap faces up): the first normal is the lower ball's, up, and the upper
        // ball's points lie ahead of it.
        let touching = [([0.1, 0.0, -0.01], UP), ([0.1, 0.0, 0.01], DOWN)];
        assert!(matches!(
            meeting(&[0.0; 3], &UP, &DOWN, touching),
            Meeting::Sheets { ahead } if ahead > 0.0
        ));
        // A wall pinched at the origin: its lower face (normal down) below, upper face above.
        let pinched = [([0.1, 0.0, 0.01], UP), ([0.1, 0.0, -0.01], DOWN)];
        assert!(matches!(
            meeting(&[0.0; 3], &UP, &DOWN, pinched),
            Meeting::Sheets { ahead } if ahead < 0.0
        ));
        // Neighbours facing neither way: no evidence.
        let sideways = [([0.1, 0.0, 0.0], [1.0, 0.0, 0.0])];
        assert_eq!(
            meeting(&[0.0; 3], &UP, &DOWN, sideways),
            Meeting::Sheets { ahead: 0.0 }
        );
    }
}
