//! The paper's uniqueness argument (Ren–Fujita–Nakata §2.2), tested: on random grids, masks
//! (inside and touching the border), faces, α and smooth fields, every solver returns the same
//! restoration; the matrix has full column rank; its rows at the unknown cells are the
//! Dirichlet Laplacian; and without a Neumann face the system is square and solved exactly.

use std::sync::Arc;

use faer::Mat;
use proptest::prelude::*;

use zeroset_field_core::geometry::Aabb;
use zeroset_field_core::grid::Grid;
use zeroset_field_core::lsq::{LeastSquaresSolver, LinearOperator};
use zeroset_field_core::mask::{BoxMask, Face, Side};
use zeroset_restore::laplace::BoxLaplace;
use zeroset_restore::protrusion::{Convention, Protrusion, Solver};
use zeroset_solvers::{Cgls, DenseQr, IterativeParams, Lsqr, NormalLu, SparseCholesky, SparseQr};

/// A random smooth field sampled on `grid`: a few random plane waves plus a quadratic.
fn smooth_samples<const D: usize>(grid: &Grid<D>, waves: &[(f64, [f64; 3], f64)]) -> Vec<f64> {
    grid.points()
        .iter()
        .map(|p| {
            let r2: f64 = p.iter().map(|x| x * x).sum();
            r2 - 0.3
                + waves
                    .iter()
                    .map(|(amp, k, phase)| {
                        let dot: f64 = (0..D).map(|a| k[a] * p[a]).sum();
                        amp * (dot + phase).sin()
                    })
                    .sum::<f64>()
        })
        .collect()
}

fn solvers(dim: usize) -> Vec<(String, Solver)> {
    let tight = || IterativeParams::default().with_tolerance(1e-14);
    let general: Vec<Arc<dyn LeastSquaresSolver>> = vec![
        Arc::new(Cgls::new(tight())),
        Arc::new(Lsqr::new(tight())),
        Arc::new(DenseQr::default()),
        Arc::new(NormalLu::default()),
        Arc::new(SparseQr::default()),
        Arc::new(SparseCholesky::default()),
    ];
    let mut all: Vec<(String, Solver)> = general
        .into_iter()
        .map(|s| (s.name().to_string(), Solver::General(s)))
        .collect();
    all.push(("separable (default)".into(), Solver::Separable));
    if dim == 3 {
        all.push((
            "preconditioned-lsqr".into(),
            Solver::PreconditionedLsqr { tolerance: 1e-14 },
        ));
    }
    all
}

fn max_rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let scale = a.iter().fold(1e-300f64, |m, v| m.max(v.abs()));
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
        / scale
}

/// Every solver on one case; returns the largest relative difference to the default.
fn agreement<const D: usize>(
    grid: &Grid<D>,
    f: &[f64],
    mask: &BoxMask<D>,
    params: &Protrusion,
) -> f64 {
    let reference = params.restore_samples(grid, f, mask).unwrap().0;
    let mut worst = 0.0f64;
    for (name, solver) in solvers(D) {
        let p = params.clone().with_solver(solver);
        let (g, report) = p.restore_samples(grid, f, mask).unwrap();
        let d = max_rel_diff(&reference, &g);
        assert!(
            d <= 1e-8,
            "{name} differs from the default by {d:e} ({report:?})"
        );
        worst = worst.max(d);
    }
    worst
}

/// Full column rank by SVD, and the Dirichlet-Laplacian structure of the first `n` rows.
fn check_rank<const D: usize>(system: &BoxLaplace<D>) {
    let a: Mat<f64> = system.to_sparse().to_dense();
    let n = a.ncols();
    let sv = a.singular_values().unwrap();
    let (max, min) = (sv[0], sv[n - 1]);
    assert!(
        min > 1e-10 * max,
        "rank-deficient: σ_min {min:e}, σ_max {max:e}"
    );
    // The first n rows alone: the square Dirichlet Laplacian, nonsingular.
    let square = a.subrows(0, n).to_owned();
    let sv = square.singular_values().unwrap();
    assert!(sv[n - 1] > 1e-10, "Laplace block singular: {:e}", sv[n - 1]);
    let w = BoxLaplace::<D>::weight();
    for i in 0..n {
        assert_eq!(square[(i, i)], -1.0);
        let off: f64 = (0..n).filter(|&j| j != i).map(|j| square[(i, j)]).sum();
        assert!(off <= 2.0 * D as f64 * w + 1e-15 && off >= 0.0);
    }
}

#[derive(Debug, Clone)]
struct Case3 {
    counts: [usize; 3],
    lo: [usize; 3],
    hi: [usize; 3],
    face: Option<Face>,
    alpha: Option<f64>,
    positive_inside: bool,
    waves: Vec<(f64, [f64; 3], f64)>,
}

fn case3() -> impl Strategy<Value = Case3> {
    (
        prop::array::uniform3(4usize..12),
        prop::array::uniform3((0.0f64..1.0, 0.0f64..1.0)),
        0usize..7,
        prop::option::of(-3.0f64..3.0),
        any::<bool>(),
        prop::collection::vec(
            (
                0.05f64..0.5,
                prop::array::uniform3(-4.0f64..4.0),
                0.0f64..6.3,
            ),
            1..4,
        ),
    )
        .prop_map(|(counts, spans, face, alpha, pos, waves)| {
            // Masks at least 3 cells thick, anywhere (touching the border included).
            let mut lo = [0; 3];
            let mut hi = [0; 3];
            for a in 0..3 {
                let (u, v) = spans[a];
                lo[a] = (u * u * (counts[a] - 2) as f64) as usize;
                let room = counts[a] - lo[a] - 3;
                hi[a] = (lo[a] + 2 + (v.sqrt() * (room + 1) as f64) as usize).min(counts[a] - 1);
            }
            // The Neumann face: one the mask does not share with the grid border, or none
            // (choice 6); a face on the border is tested among the errors.
            let free: Vec<Face> = Face::all::<3>()
                .filter(|f| match f.side {
                    Side::Lower => lo[f.axis] > 0,
                    Side::Upper => hi[f.axis] + 1 < counts[f.axis],
                })
                .collect();
            let face = (face < 6 && !free.is_empty()).then(|| free[face % free.len()]);
            Case3 {
                counts,
                lo,
                hi,
                face,
                alpha,
                positive_inside: pos,
                waves,
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Random 3-D cases: where the configuration is valid, all solvers agree to 1e-8 and the
    /// rank is full; where it is not, the error is a specific one, never a panic.
    #[test]
    fn all_solvers_agree_in_3d(case in case3()) {
        let grid = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), case.counts).unwrap();
        let f = smooth_samples(&grid, &case.waves);
        let mask = BoxMask::from_indices(&grid, case.lo, case.hi).unwrap();
        let params = Protrusion {
            face: case.face,
            alpha: case.alpha,
            convention: if case.positive_inside { Convention::PositiveInside } else { Convention::NegativeInside },
            solver: Solver::Separable,
        };
        match params.system(&grid, &f, &mask) {
            Ok(system) => {
                check_rank(system.operator());
                let worst = agreement(&grid, &f, &mask, &params);
                if std::env::var_os("ZEROSET_REPORT").is_some() {
                    eprintln!("3d {:?} unknowns {} worst {worst:.1e}", case.face, system.operator().ncols());
                }
            }
            Err(e) => {
                // Only the documented refusal: a mask as large as the grid.
                prop_assert!(e.to_string().contains("whole grid"), "unexpected error {e}");
            }
        }
    }

    /// 2-D (the paper's Fig. 7 setting): the same agreement.
    #[test]
    fn all_solvers_agree_in_2d(
        counts in prop::array::uniform2(3usize..12),
        spans in prop::array::uniform2((0.0f64..1.0, 0.0f64..1.0)),
        face in 0usize..5,
        alpha in -3.0f64..3.0,
        waves in prop::collection::vec((0.05f64..0.5, prop::array::uniform3(-4.0f64..4.0), 0.0f64..6.3), 1..4),
    ) {
        let grid = Grid::cell_centered(Aabb::new([-1.0; 2], [1.0; 2]).unwrap(), counts).unwrap();
        let f = smooth_samples(&grid, &waves);
        let mut lo = [0; 2];
        let mut hi = [0; 2];
        for a in 0..2 {
            let (u, v) = spans[a];
            let i = ((u * counts[a] as f64) as usize).min(counts[a] - 1);
            let j = ((v * counts[a] as f64) as usize).min(counts[a] - 1);
            lo[a] = i.min(j);
            hi[a] = i.max(j);
        }
        let mask = BoxMask::from_indices(&grid, lo, hi).unwrap();
        let face = (face < 4).then(|| Face::new(face / 2, if face % 2 == 0 { Side::Lower } else { Side::Upper }));
        let params = Protrusion { face, alpha: Some(alpha), ..Protrusion::default() };
        if let Ok(system) = params.system(&grid, &f, &mask) {
            check_rank(system.operator());
            agreement(&grid, &f, &mask, &params);
        }
    }
}

#[test]
fn a_border_touching_mask_agrees_and_has_full_rank() {
    // Touches −x and −z; Neumann on +z.
    let grid = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [7, 6, 8]).unwrap();
    let f = smooth_samples(&grid, &[(0.3, [1.0, 2.0, -1.5], 0.4)]);
    let mask = BoxMask::from_indices(&grid, [0, 1, 0], [4, 4, 5]).unwrap();
    let params = Protrusion::new(Face::new(2, Side::Upper)).with_alpha(0.7);
    let system = params.system(&grid, &f, &mask).unwrap();
    assert_eq!(system.unknown_box(), ([1, 1, 1], [4, 4, 4]));
    check_rank(system.operator());
    let worst = agreement(&grid, &f, &mask, &params);
    assert!(worst <= 1e-8);
}

#[test]
fn without_a_neumann_face_the_system_is_square_and_solved_exactly() {
    let grid = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [9, 9, 9]).unwrap();
    let f = smooth_samples(&grid, &[(0.4, [2.0, -1.0, 3.0], 1.0)]);
    let mask = BoxMask::from_indices(&grid, [2, 2, 2], [6, 6, 5]).unwrap();
    let params = Protrusion::dirichlet_only();
    let system = params.system(&grid, &f, &mask).unwrap();
    let op = system.operator();
    assert_eq!(op.nrows(), op.ncols());
    for (_, solver) in solvers(3) {
        let (_, info) = system.solve(&solver).unwrap();
        assert!(
            info.rel_residual < 1e-10,
            "{}: {:e}",
            info.solver,
            info.rel_residual
        );
    }
    // α changes nothing without the layer: the pure Dirichlet fill ignores it.
    let with_alpha = Protrusion {
        alpha: Some(5.0),
        ..Protrusion::dirichlet_only()
    };
    let a = params.restore_samples(&grid, &f, &mask).unwrap().0;
    let b = with_alpha.restore_samples(&grid, &f, &mask).unwrap().0;
    assert_eq!(a, b);
    // With the layer it does, and the system is overdetermined with a non-zero residual.
    let neumann = Protrusion::new(Face::new(2, Side::Upper)).with_alpha(5.0);
    let system = neumann.system(&grid, &f, &mask).unwrap();
    assert!(system.operator().nrows() > system.operator().ncols());
    let (c, report) = neumann.restore_samples(&grid, &f, &mask).unwrap();
    assert!(report.solve.rel_residual > 1e-6);
    assert!(max_rel_diff(&a, &c) > 1e-3);
}

#[test]
fn outside_the_mask_the_samples_are_untouched() {
    let grid = Grid::cell_centered(Aabb::centered_cube(1.0).unwrap(), [10, 9, 8]).unwrap();
    let f = smooth_samples(&grid, &[(0.2, [3.0, 1.0, -2.0], 0.1)]);
    let mask = BoxMask::from_indices(&grid, [2, 0, 3], [6, 5, 6]).unwrap();
    let (g, _) = Protrusion::new(Face::new(0, Side::Upper))
        .restore_samples(&grid, &f, &mask)
        .unwrap();
    for (l, index) in (0..grid.len()).map(|l| (l, grid.multi_index(l))) {
        if !mask.contains(index) {
            assert_eq!(g[l], f[l]);
        }
    }
}
