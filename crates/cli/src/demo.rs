//! `zeroset demo`: the main job on built-in sample data. It describes the bundled point cloud,
//! solves a restoration-shaped least-squares problem with every solver (how long each took,
//! iterations, residuals, and how far each answer is from the sparse-QR reference — the
//! solvers must agree: the demo fails, with exit status 1, if any answer is farther from the
//! reference than `κ² (τ + u) max|x_qr|`, `κ` the condition number of the mask's Laplacian,
//! `τ = 1e-12` the iterative solvers' tolerance and `u = 2⁻⁵³`; see [`agreement_tolerance`]),
//! removes the bunny's ears by protrusion removal, and finally runs the
//! whole pipeline on the sample: an RBF fit, sampled on a grid, its ears removed, the restored
//! zero set meshed by marching cubes, written as a binary PLY with a shaded PNG preview (and
//! the unrestored fit's for comparison) and a text report (in `./zeroset-demo/` or `--out`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::Args;
use zeroset_bases::bspline::{BSplineField, Degree};
use zeroset_bases::rbf::{Biharmonic, Constraints, Offset, RbfFit, Solver};
use zeroset_bases::tangent_plane::TangentPlaneField;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::grid::Grid;
use zeroset_field_core::lsq::{LeastSquaresSolver, LsqMatrix};
use zeroset_field_core::mask::{BoxMask, Face, Side};
use zeroset_mesh::preview::{Axis, RenderOptions, View, render_mesh};
use zeroset_mesh::voxel::{self, Detail};
use zeroset_mesh::{McOptions, PlyFormat, TriMesh, check, mesh_field, write_ply};
use zeroset_restore::protrusion::Protrusion;
use zeroset_solvers::kernels::max_abs_diff;
use zeroset_solvers::problems::protrusion_problem;
use zeroset_solvers::{
    Cgls, DenseQr, DirichletLaplacian, IterativeParams, Lsqr, NormalLu, Pcg, PcgParams,
    SparseCholesky, SparseQr,
};

/// The azimuth of the demo's bunny render, in degrees about +y from +z towards +x.
const BUNNY_AZIMUTH: f64 = -45.0;

/// The bundled sample (Stanford bunny, 2,000 oriented points; see `samples/README.md`).
const SAMPLE: &str = include_str!("../samples/bunny_2k.xyzn");

/// Shown after `zeroset demo --help`.
pub const EXAMPLES: &str = "\
Examples:
  zeroset demo                 the bundled bunny sample, then all solvers at k = 16
  zeroset demo --k 24          a bigger restoration problem (13,824 unknowns)
  zeroset demo --k 8 --quiet   small enough for the dense solvers too; no progress spinner
  zeroset demo --out /tmp/zd   the pipeline's bunny{,_fitted}.{ply,png} and report.txt go to /tmp/zd";

/// The default output directory of the pipeline step.
const DEFAULT_OUT: &str = "zeroset-demo";

/// Dense solvers are run only up to this many unknowns (they densify `A`).
const DENSE_LIMIT: usize = 1500;

/// Arguments of `zeroset demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Mask size of the restoration problem: k³ unknowns, k³ + k² equations.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(2..=64))]
    pub k: u32,

    /// No progress spinner.
    #[arg(long)]
    pub quiet: bool,

    /// Directory for the pipeline's bunny.ply, bunny.png (restored), bunny_fitted.ply,
    /// bunny_fitted.png and report.txt (created if missing).
    #[arg(long, value_name = "DIR", default_value = DEFAULT_OUT)]
    pub out: PathBuf,
}

/// Runs the demo.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    let sample = SampleFile::new()?;
    outln!("== the bundled sample (samples/bunny_2k.xyzn) ==");
    crate::info::run(&crate::info::InfoArgs {
        file: sample.path.clone(),
        format: None,
        quiet: args.quiet,
    })?;
    solve_all(args.k as usize, args.quiet)?;
    remove_ears(&sample.path)?;
    pipeline(&sample.path, &args.out)
}

/// The bundled sample written to a temporary file (the readers take paths), removed on drop.
struct SampleFile {
    dir: std::path::PathBuf,
    path: std::path::PathBuf,
}

impl SampleFile {
    fn new() -> anyhow::Result<Self> {
        let dir = std::env::temp_dir().join(format!("zeroset-demo-{}", std::process::id()));
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        let path = dir.join("bunny_2k.xyzn");
        // Owned before writing, so that a failed write still removes the directory.
        let sample = Self { dir, path };
        zeroset_field_core::io::write_atomic(&sample.path, |w| w.write_all(SAMPLE.as_bytes()))
            .with_context(|| format!("writing {}", sample.path.display()))?;
        Ok(sample)
    }
}

impl Drop for SampleFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The bunny's ears, as the mask of the restoration step: the box above the head, its
/// bottom face (−y) where the ears join it.
const EAR_MASK: ([f64; 3], [f64; 3]) = ([-0.1, 0.145, -0.07], [0.005, 0.2, 0.05]);

/// A restoration step on the bundled bunny: its tangent-plane field on a grid, the ears
/// removed by protrusion removal for a few α, and how high the surface still reaches.
fn remove_ears(sample: &std::path::Path) -> anyhow::Result<()> {
    let cloud = zeroset_field_core::io::read_point_cloud(sample)?;
    let field = TangentPlaneField::new(&cloud, 8)?;
    let bounds = field.bounds().context("the sample has no extent")?;
    let grid = zeroset_restore::sampling_grid(bounds)?;
    let mask = BoxMask::from_corners(&grid, EAR_MASK.0, EAR_MASK.1)?;
    let h = grid.spacing()[1];
    let base = EAR_MASK.0[1];
    outln!();
    outln!("== restoration: removing the bunny's ears (Ren–Fujita–Nakata protrusion removal) ==");
    let c = grid.counts();
    outln!(
        "   tangent-plane field of the sample on {}×{}×{} cells; mask {:?} .. {:?}, face -y",
        c[0],
        c[1],
        c[2],
        EAR_MASK.0,
        EAR_MASK.1
    );
    let top = highest_inside(&field, &grid, &mask);
    outln!(
        "   before: the surface reaches {:.1} cells above the mask's bottom face",
        (top - base) / h
    );
    outln!(
        "{:<22} {:>9} {:>9} {:>10} {:>14}",
        "alpha",
        "unknowns",
        "solve_ms",
        "rel_res",
        "top (cells)"
    );
    for alpha in [None, Some(1.0), Some(3.0)] {
        let mut p = Protrusion::new(Face::new(1, Side::Lower));
        p.alpha = alpha;
        let out = p.apply(&field, &grid, &mask)?;
        let r = &out.report;
        let label = match alpha {
            None => format!("{:.3} (field's slope)", r.alpha.unwrap_or(f64::NAN)),
            Some(a) => format!("{a}"),
        };
        let top = highest_inside(&out.field, &grid, &mask);
        outln!(
            "{label:<22} {:>9} {:>9.1} {:>10.2e} {:>14.1}",
            r.unknowns,
            r.solve.elapsed.as_secs_f64() * 1e3,
            r.solve.rel_residual,
            (top - base) / h
        );
    }
    outln!("   (a larger alpha makes the field leave the head faster: a flatter top)");
    Ok(())
}

/// The highest y inside the mask where `field ≤ 0`, scanning each (x, z) column in steps of a
/// quarter cell; the mask's bottom if none.
fn highest_inside<F: ScalarField<3> + ?Sized>(field: &F, grid: &Grid<3>, mask: &BoxMask<3>) -> f64 {
    let (lo, hi) = (mask.lo(), mask.hi());
    let h = grid.spacing()[1];
    let (y0, y1) = (grid.coordinate(1, lo[1]), grid.coordinate(1, hi[1]));
    let steps = ((y1 - y0) / (h / 4.0)).round() as usize;
    let mut best = EAR_MASK.0[1];
    for i in lo[0]..=hi[0] {
        for k in lo[2]..=hi[2] {
            let (x, z) = (grid.coordinate(0, i), grid.coordinate(2, k));
            if let Some(y) = (0..=steps)
                .rev()
                .map(|s| y0 + s as f64 * h / 4.0)
                .find(|&y| field.value(&[x, y, z]) <= 0.0)
            {
                best = best.max(y);
            }
        }
    }
    best
}

fn solve_all(k: usize, quiet: bool) -> anyhow::Result<()> {
    let p = protrusion_problem(k, 1.0);
    let (m, n) = (p.a.nrows(), p.a.ncols());
    outln!();
    outln!("== restoration least squares: {} ==", p.name);
    outln!(
        "   grid {}³ cells on [-1,1]³, f = sphere SDF r=0.6, mask = central {k}³ box,",
        2 * k
    );
    outln!(
        "   {m} equations (Laplace + Neumann rows), {n} unknowns, {} non-zeros",
        p.a.val().len()
    );
    let tight = IterativeParams::default().with_tolerance(ITERATIVE_TOLERANCE);
    let poisson = Arc::new(DirichletLaplacian::new([k, k, k], 1.0 / 6.0)?);
    let mut solvers: Vec<(&str, Box<dyn LeastSquaresSolver>)> = vec![
        ("sparse-qr", Box::new(SparseQr::default())),
        ("sparse-cholesky", Box::new(SparseCholesky::default())),
        ("lsqr", Box::new(Lsqr::new(tight.clone()))),
        (
            "lsqr + poisson",
            Box::new(Lsqr::new(tight.clone().with_preconditioner(poisson))),
        ),
        ("cgls", Box::new(Cgls::new(tight))),
        (
            "pcg-normal",
            Box::new(Pcg::new(PcgParams {
                tol: ITERATIVE_TOLERANCE,
                ..Default::default()
            })),
        ),
    ];
    if n <= DENSE_LIMIT {
        solvers.push(("dense-qr", Box::new(DenseQr::default())));
        solvers.push(("normal-lu", Box::new(NormalLu::default())));
    }
    outln!();
    outln!(
        "{:<16} {:>10} {:>7} {:>11} {:>11} {:>13}",
        "solver",
        "time_ms",
        "iters",
        "rel_res",
        "rel_normal",
        "max|x - x_qr|"
    );
    let spinner = crate::progress::spinner(quiet);
    let mut reference: Option<Vec<f64>> = None;
    let mut worst: Option<(f64, String)> = None;
    for (label, solver) in &solvers {
        spinner.set_message(format!("solving with {label}"));
        let start = Instant::now();
        let s = solver
            .solve(LsqMatrix::SparseRow(p.a.as_ref()), &p.b)
            .with_context(|| format!("{label} failed"))?;
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let diff = match &reference {
            None => {
                reference = Some(s.x.clone());
                0.0
            }
            Some(r) => {
                // A non-finite answer is the worst of all (max_abs_diff would skip a NaN).
                let diff = if s.x.iter().all(|v| v.is_finite()) {
                    max_abs_diff(r, &s.x)
                } else {
                    f64::NAN
                };
                if worst
                    .as_ref()
                    .is_none_or(|(w, _)| diff.is_nan() || diff > *w)
                {
                    worst = Some((diff, (*label).to_owned()));
                }
                diff
            }
        };
        spinner.suspend(|| {
            outln!(
                "{:<16} {:>10.1} {:>7} {:>11.2e} {:>11.2e} {:>13.2e}",
                label,
                ms,
                s.info.iterations,
                s.info.rel_residual,
                s.info.rel_normal_residual,
                diff
            )
        });
    }
    spinner.finish_and_clear();
    if n > DENSE_LIMIT {
        outln!("(dense-qr and normal-lu skipped above {DENSE_LIMIT} unknowns; try --k 11)");
    }
    let scale = reference
        .as_deref()
        .map_or(0.0, |x| x.iter().fold(0.0f64, |m, v| m.max(v.abs())));
    check_agreement(k, scale, &worst)
}

/// The relative normal-equation residual the iterative solvers are asked to reach.
const ITERATIVE_TOLERANCE: f64 = 1e-12;

/// The tolerance on `max|x − x_qr|` of the demo's restoration problem at mask size `k`, for a
/// solution of magnitude `scale = max|x_qr|`: `κ² (τ + u) · scale`, with `τ` =
/// [`ITERATIVE_TOLERANCE`] and `u = 2⁻⁵³`; returns `(κ, tolerance)`.
///
/// `κ = cot²(π / (2(k + 1)))` is the condition number of the `k³` Dirichlet Laplacian (its
/// eigenvalues `Σₐ 4 sin²(jₐπ / (2(k + 1)))`, `1 ≤ jₐ ≤ k`, range from `12 sin²(π/(2(k+1)))`
/// to `12 cos²(π/(2(k+1)))`), the square block of the least-squares matrix `A` (the Neumann
/// rows only add to `AᵀA`). An answer whose normal equations `AᵀA x = Aᵀb` hold to a relative
/// residual `ε` is off by up to `κ(AᵀA) ε = κ² ε` relative to `x*`: the normal equations square
/// the condition number. The direct solvers are exact to rounding (`ε ≈ u`: sparse QR better,
/// sparse Cholesky and LU on `AᵀA` at that bound), the iterative ones stop at `ε ≈ τ`, which
/// dominates. At the default `k = 16`: `κ = 117`, tolerance `1.4e-8 · scale`; the farthest
/// answer (CGLS, `3.6e-11 · scale`) is 380 times closer than that, and from `k = 11` to `32`
/// 150 to 1700 times; a wrong answer is off by orders of magnitude more.
fn agreement_tolerance(k: usize, scale: f64) -> (f64, f64) {
    let kappa = (std::f64::consts::PI / (2.0 * (k as f64 + 1.0)))
        .tan()
        .powi(-2);
    let u = f64::EPSILON / 2.0;
    (
        kappa,
        kappa * kappa * (ITERATIVE_TOLERANCE + u) * scale.max(f64::MIN_POSITIVE),
    )
}

/// Prints the tolerance and fails unless every solver's answer is within it of the
/// reference; `worst` is the largest `max|x − x_qr|` and the solver that had it.
fn check_agreement(k: usize, scale: f64, worst: &Option<(f64, String)>) -> anyhow::Result<()> {
    let (kappa, tolerance) = agreement_tolerance(k, scale);
    let Some((diff, label)) = worst else {
        return Ok(());
    };
    outln!(
        "agreement: largest max|x - x_qr| {diff:.2e} ({label}); tolerance {tolerance:.2e} = \
         κ² (τ + u) max|x_qr|, κ = {kappa:.1} (the Laplacian's condition number; the normal \
         equations square it), τ = {ITERATIVE_TOLERANCE:.0e} (the iterative solvers' \
         tolerance), u = 2^-53, max|x_qr| = {scale:.3}"
    );
    // A NaN difference fails too.
    if diff.is_nan() || *diff > tolerance {
        anyhow::bail!(
            "the solvers disagree: {label} is {diff:.2e} from the sparse-QR solution, more than \
             the tolerance {tolerance:.2e} (κ = {kappa:.1}); a solver is wrong on this problem"
        );
    }
    Ok(())
}

/// Seconds, two decimals.
fn secs(d: Duration) -> String {
    format!("{:.2} s", d.as_secs_f64())
}

/// Cells along the longest axis of the grid the fitted field is sampled on for restoration.
const PIPELINE_CELLS: usize = 96;

/// One mesh's figures for the pipeline's report.
fn mesh_figures(mesh: &TriMesh) -> (String, f64) {
    let m = check(mesh);
    let max_y = mesh
        .vertices()
        .iter()
        .map(|p| p[1])
        .fold(f64::NEG_INFINITY, f64::max);
    (
        format!(
            "{} vertices, {} triangles, {}, Euler characteristic {}, volume {:.6}, max y {max_y:.4}",
            mesh.num_vertices(),
            mesh.num_triangles(),
            if m.closed { "closed" } else { "open" },
            m.euler_characteristic,
            m.signed_volume,
        ),
        max_y,
    )
}

/// Meshes `field`'s zero set on the general l0 grid over its box, the boundary closed.
fn mesh_zero_set<F: ScalarField<3> + ?Sized>(field: &F) -> anyhow::Result<(TriMesh, String)> {
    let bounds = field.bounds().context("the field has no bounds")?;
    let h = voxel::voxel_size(&bounds, Detail::General);
    let grid = voxel::grid_for(&bounds, h, 0.0).context("building the meshing grid")?;
    let mesh = mesh_field(
        field,
        &grid,
        0.0,
        &McOptions::default().with_close_boundary(true),
    )
    .context("extracting the zero set")?;
    let c = grid.counts();
    Ok((
        mesh,
        format!("grid {}×{}×{} (voxel {h:.4}, general l0)", c[0], c[1], c[2]),
    ))
}

/// The whole pipeline on the bundled sample: RBF fit (kernel r, off-surface constraints, auto
/// solver), the fit sampled on a grid and its ears removed by protrusion removal (a quadratic
/// B-spline field), both the restored and the fitted field meshed by marching cubes on the
/// general l0 grid with the boundary closed, binary PLYs, shaded PNGs and a text report in
/// `out` (each written atomically).
fn pipeline(sample: &Path, out: &Path) -> anyhow::Result<()> {
    let total = Instant::now();
    outln!();
    outln!(
        "== pipeline: fit → restore → mesh → preview, into {} ==",
        out.display()
    );
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut report = String::new();
    let step = |report: &mut String, text: String| {
        outln!("   {text}");
        report.push_str(&text);
        report.push('\n');
    };

    let start = Instant::now();
    let cloud = zeroset_field_core::io::read_point_cloud(sample)?;
    let (constraints, _) = Constraints::off_surface(&cloud, Offset::Auto { fraction: 0.01 })
        .context("building the off-surface constraints")?;
    let fitted = RbfFit::new(Biharmonic)
        .with_solver(Solver::Auto)
        .fit(&constraints)
        .context("fitting the RBF field")?;
    let fit_time = start.elapsed();
    let r = &fitted.report;
    step(
        &mut report,
        format!(
            "fit: {} points, {} off-surface constraints, kernel r, solver {}, {} steps, max \
             residual {:.2e}, fit {}, step {}",
            cloud.len(),
            constraints.len(),
            r.solver,
            r.iterations,
            r.max_residual,
            secs(r.elapsed),
            secs(fit_time)
        ),
    );
    let field = &fitted.field;

    let start = Instant::now();
    let bounds = field.bounds().context("the fitted field has no bounds")?;
    let grid = Grid::cell_centered(
        bounds,
        crate::restore::cubic_counts(&bounds, PIPELINE_CELLS),
    )?;
    let samples = grid.sample(field);
    let c = grid.counts();
    step(
        &mut report,
        format!(
            "sample: the fit on {}×{}×{} cells ({} values), {}",
            c[0],
            c[1],
            c[2],
            samples.len(),
            secs(start.elapsed())
        ),
    );

    let start = Instant::now();
    let mask = BoxMask::from_corners(&grid, EAR_MASK.0, EAR_MASK.1)?;
    let p = Protrusion::new(Face::new(1, Side::Lower)).with_alpha(1.0);
    let (g, r) = p
        .restore_samples(&grid, &samples, &mask)
        .context("removing the ears")?;
    let restored = BSplineField::interpolate(grid, g, Degree::Quadratic)
        .context("interpolating the restored samples")?;
    let restore_time = start.elapsed();
    let start = Instant::now();
    let (h, base) = (grid.spacing()[1], EAR_MASK.0[1]);
    // Before: the unrestored samples' spline (the RBF evaluated point by point is much slower).
    let unrestored = BSplineField::interpolate(grid, samples, Degree::Quadratic)
        .context("interpolating the fitted samples")?;
    let top_before = (highest_inside(&unrestored, &grid, &mask) - base) / h;
    let top_after = (highest_inside(&restored, &grid, &mask) - base) / h;
    step(
        &mut report,
        format!(
            "restore: ears removed (protrusion, mask {:?} .. {:?}, face -y, alpha 1), {} \
             unknowns, solver {}, rel residual {:.2e}, ears' top {top_before:.1} → \
             {top_after:.1} cells above the mask's bottom, {} (measuring the ears {})",
            EAR_MASK.0,
            EAR_MASK.1,
            r.unknowns,
            r.solve.solver,
            r.solve.rel_residual,
            secs(restore_time),
            secs(start.elapsed())
        ),
    );

    let start = Instant::now();
    let (mesh, grid_text) = mesh_zero_set(&restored)?;
    let (figures, restored_y) = mesh_figures(&mesh);
    step(
        &mut report,
        format!(
            "mesh (restored): {grid_text}, {figures}, {}",
            secs(start.elapsed())
        ),
    );

    let start = Instant::now();
    let (fitted_mesh, grid_text) = mesh_zero_set(field)?;
    let (figures, fitted_y) = mesh_figures(&fitted_mesh);
    step(
        &mut report,
        format!(
            "mesh (fitted): {grid_text}, {figures}, {}",
            secs(start.elapsed())
        ),
    );
    step(
        &mut report,
        format!(
            "max y: fitted {fitted_y:.4}, restored {restored_y:.4} (ears {:.4} lower)",
            fitted_y - restored_y
        ),
    );

    // The bunny's up is +y (samples/README.md): a front three-quarter view, upright.
    let opts = RenderOptions {
        view: View {
            azimuth: BUNNY_AZIMUTH,
            elevation: 20.0,
        },
        up: Axis::Y,
        ..RenderOptions::default()
    };
    for (name, mesh) in [("bunny", &mesh), ("bunny_fitted", &fitted_mesh)] {
        let start = Instant::now();
        let ply = out.join(format!("{name}.ply"));
        write_ply(&ply, mesh, PlyFormat::BinaryLittleEndian)
            .with_context(|| format!("writing {}", ply.display()))?;
        step(
            &mut report,
            format!(
                "wrote {} (binary PLY), {}",
                ply.display(),
                secs(start.elapsed())
            ),
        );

        let start = Instant::now();
        let png = out.join(format!("{name}.png"));
        let image = render_mesh(mesh, &opts).context("rendering the mesh")?;
        image
            .write_png(&png)
            .with_context(|| format!("writing {}", png.display()))?;
        step(
            &mut report,
            format!(
                "wrote {} ({}×{} PNG), {}",
                png.display(),
                image.width(),
                image.height(),
                secs(start.elapsed())
            ),
        );
    }

    let txt = out.join("report.txt");
    let _ = writeln!(report, "pipeline total {}", secs(total.elapsed()));
    zeroset_field_core::io::write_atomic(&txt, |w| w.write_all(report.as_bytes()))
        .with_context(|| format!("writing {}", txt.display()))?;
    outln!("   wrote {}", txt.display());
    outln!("   pipeline total {}", secs(total.elapsed()));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tolerance_follows_the_laplacians_condition_number() {
        // κ(k) = cot²(π/(2(k+1))) is λ_max/λ_min of the k³ Dirichlet Laplacian.
        for k in [2usize, 16, 64] {
            let t = std::f64::consts::PI / (2.0 * (k as f64 + 1.0));
            let (lo, hi) = (12.0 * t.sin().powi(2), 12.0 * t.cos().powi(2));
            let (kappa, tolerance) = agreement_tolerance(k, 2.0);
            assert!((kappa - hi / lo).abs() < 1e-9 * kappa, "k = {k}: {kappa}");
            let want = kappa * kappa * (ITERATIVE_TOLERANCE + f64::EPSILON / 2.0) * 2.0;
            assert!((tolerance - want).abs() <= 1e-12 * want, "k = {k}");
        }
        let (kappa, tolerance) = agreement_tolerance(16, 1.0);
        assert!((kappa - 116.5).abs() < 0.1, "{kappa}");
        assert!((1.3e-8..1.4e-8).contains(&tolerance), "{tolerance}");
    }

    #[test]
    fn disagreement_fails_the_demo() {
        assert!(check_agreement(16, 0.3, &None).is_ok());
        assert!(check_agreement(16, 0.3, &Some((1e-11, "cgls".into()))).is_ok());
        let e = check_agreement(16, 0.3, &Some((1e-3, "lsqr".into()))).unwrap_err();
        assert!(
            e.to_string()
                .contains("the solvers disagree: lsqr is 1.00e-3"),
            "{e}"
        );
        // A non-finite answer is a disagreement.
        assert!(check_agreement(16, 0.3, &Some((f64::NAN, "pcg".into()))).is_err());
    }
}
