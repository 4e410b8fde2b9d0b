//! Bad input gets a specific error, never a panic.

use zeroset_field_core::Error as FieldError;
use zeroset_field_core::analytic::Sphere;
use zeroset_field_core::geometry::Aabb;
use zeroset_field_core::grid::Grid;
use zeroset_field_core::mask::{BoxMask, Face, Side};
use zeroset_restore::RestoreError;
use zeroset_restore::denoise::Denoise;
use zeroset_restore::protrusion::Protrusion;

fn grid(n: usize) -> Grid<3> {
    Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [n; 3]).unwrap()
}

#[test]
fn masks_outside_or_of_zero_width_are_refused_when_built() {
    let g = grid(8);
    let e = BoxMask::from_corners(&g, [-0.5, -0.5, -0.5], [0.5, 0.5, 1.5]).unwrap_err();
    assert!(
        matches!(e, FieldError::MaskOutsideBox { axis: 2, .. }),
        "{e}"
    );
    // Zero width between two sample centres: no sample inside.
    let e = BoxMask::from_corners(&g, [0.01, -0.5, -0.5], [0.02, 0.5, 0.5]).unwrap_err();
    assert!(matches!(e, FieldError::EmptyMask { axis: 0, .. }), "{e}");
}

#[test]
fn a_mask_covering_the_whole_grid_is_refused() {
    let g = grid(6);
    let mask = BoxMask::from_indices(&g, [0; 3], [5; 3]).unwrap();
    let s = Sphere::new([0.0; 3], 0.5);
    let e = Protrusion::dirichlet_only()
        .apply(&s, &g, &mask)
        .unwrap_err();
    assert!(matches!(e, RestoreError::MaskCoversGrid), "{e}");
    let e = Denoise::new([2, 2, 2]).apply(&s, &g, &mask).unwrap_err();
    assert!(matches!(e, RestoreError::MaskCoversGrid), "{e}");
}

#[test]
fn a_mask_made_for_another_grid_is_refused() {
    // Indices 2..=15 of a 40³ grid would be a different box on a 20³ one.
    let (big, small) = (grid(40), grid(20));
    let mask = BoxMask::from_corners(&big, [-0.9; 3], [-0.2; 3]).unwrap();
    assert_eq!(mask.grid_counts(), [40; 3]);
    let s = Sphere::new([0.0; 3], 0.5);
    let e = Protrusion::new(Face::new(2, Side::Lower))
        .apply(&s, &small, &mask)
        .unwrap_err();
    assert!(e.to_string().contains("another grid"), "{e}");
    let e = Denoise::new([2, 2, 2])
        .apply(&s, &small, &mask)
        .unwrap_err();
    assert!(e.to_string().contains("another grid"), "{e}");
    // A face of an axis the grid does not have touches nothing (it was an index panic).
    assert!(!mask.touches(Face::new(5, Side::Upper)));
}

#[test]
// Off Linux without ZEROSET_MEMORY_LIMIT there is no memory figure to refuse 8 PB by:
// the allocation itself would abort the test process.
#[cfg(target_os = "linux")]
fn a_grid_no_machine_holds_is_refused_before_it_is_sampled() {
    let g = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [100_000; 3]).unwrap();
    let mask = BoxMask::from_indices(&g, [10; 3], [20; 3]).unwrap();
    let s = Sphere::new([0.0; 3], 0.5);
    let e = Protrusion::new(Face::new(2, Side::Lower))
        .apply(&s, &g, &mask)
        .unwrap_err();
    assert!(e.to_string().contains("memory"), "{e}");
}

#[test]
fn grids_under_three_cells_are_refused() {
    let g = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [2, 8, 8]).unwrap();
    let mask = BoxMask::from_indices(&g, [0, 2, 2], [0, 4, 4]).unwrap();
    let s = Sphere::new([0.0; 3], 0.5);
    let e = Protrusion::dirichlet_only()
        .apply(&s, &g, &mask)
        .unwrap_err();
    assert!(
        matches!(
            e,
            RestoreError::Field(FieldError::GridTooSmall {
                axis: 0,
                needed: 3,
                got: 2
            })
        ),
        "{e}"
    );
}

#[test]
fn alpha_must_be_finite_and_the_face_must_have_cells_beyond_it() {
    let g = grid(10);
    let s = Sphere::new([0.0; 3], 0.5);
    let mask = BoxMask::from_indices(&g, [2; 3], [6; 3]).unwrap();
    for alpha in [f64::NAN, f64::INFINITY] {
        let e = Protrusion::new(Face::new(2, Side::Upper))
            .with_alpha(alpha)
            .apply(&s, &g, &mask)
            .unwrap_err();
        assert!(matches!(e, RestoreError::InvalidAlpha(_)), "{e}");
    }
    let top = BoxMask::from_indices(&g, [2, 2, 5], [6, 6, 9]).unwrap();
    let e = Protrusion::new(Face::new(2, Side::Upper))
        .apply(&s, &g, &top)
        .unwrap_err();
    assert!(e.to_string().contains("+z"), "{e}");
    let e = Protrusion::new(Face::new(3, Side::Upper))
        .apply(&s, &g, &mask)
        .unwrap_err();
    assert!(
        matches!(e, RestoreError::FaceAxisOutOfRange { axis: 3, dim: 3 }),
        "{e}"
    );
    // Two layers thick with both fixed: nothing left to solve for.
    let thin = BoxMask::from_indices(&g, [2, 2, 0], [6, 6, 1]).unwrap();
    let e = Protrusion::new(Face::new(2, Side::Upper))
        .apply(&s, &g, &thin)
        .unwrap_err();
    assert!(
        matches!(
            e,
            RestoreError::NoUnknowns {
                axis: 2,
                extent: 2,
                needed: 3
            }
        ),
        "{e}"
    );
    // One layer on the border with the Neumann face above it: two fixed layers, so three
    // cells are needed (the hint said two, then, given two, three).
    for (top, extent) in [(0, 1), (1, 2)] {
        let thin = BoxMask::from_indices(&g, [2, 2, 0], [6, 6, top]).unwrap();
        let e = Protrusion::new(Face::new(2, Side::Upper))
            .apply(&s, &g, &thin)
            .unwrap_err();
        assert!(
            matches!(e, RestoreError::NoUnknowns { axis: 2, needed: 3, extent: x } if x == extent),
            "{e}"
        );
    }
}

#[test]
fn coarse_sizes_must_fit_the_mask() {
    let g = grid(10);
    let s = Sphere::new([0.0; 3], 0.5);
    let mask = BoxMask::from_indices(&g, [2; 3], [5; 3]).unwrap();
    let e = Denoise::new([5, 2, 2]).apply(&s, &g, &mask).unwrap_err();
    assert!(
        matches!(
            e,
            RestoreError::InvalidCoarse {
                axis: 0,
                coarse: 5,
                extent: 4
            }
        ),
        "{e}"
    );
    let e = Denoise::new([2, 0, 2]).apply(&s, &g, &mask).unwrap_err();
    assert!(
        matches!(e, RestoreError::InvalidCoarse { axis: 1, .. }),
        "{e}"
    );
}

#[test]
fn non_finite_samples_and_wrong_lengths_are_refused() {
    let g = grid(6);
    let mask = BoxMask::from_indices(&g, [1; 3], [3; 3]).unwrap();
    let mut f = vec![0.5; g.len()];
    f[7] = f64::NAN;
    let e = Protrusion::dirichlet_only()
        .restore_samples(&g, &f, &mask)
        .unwrap_err();
    assert!(
        matches!(e, RestoreError::NonFiniteSample { index: 7, .. }),
        "{e}"
    );
    let e = Protrusion::dirichlet_only()
        .restore_samples(&g, &f[..10], &mask)
        .unwrap_err();
    assert!(
        matches!(e, RestoreError::Field(FieldError::ShapeMismatch { .. })),
        "{e}"
    );
    // A mask made for a bigger grid: refused for its grid before its indices are read.
    let big = grid(12);
    let far = BoxMask::from_indices(&big, [8; 3], [10; 3]).unwrap();
    let f = vec![0.5; g.len()];
    let e = Protrusion::dirichlet_only()
        .restore_samples(&g, &f, &far)
        .unwrap_err();
    assert!(
        matches!(
            e,
            RestoreError::Field(FieldError::ShapeMismatch {
                expected: 6,
                got: 12,
                ..
            })
        ),
        "{e}"
    );
}
