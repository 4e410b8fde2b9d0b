//! `zeroset restore`: mask-based restoration of a field (Ren–Fujita–Nakata) — protrusion
//! removal or de-noising inside a box — written as a `.zsf` field file.
//!
//! The input is a field file (a previous `zeroset restore`, or any `.zsf`) or an oriented point
//! cloud (PLY, xyzn, CSV…), which is turned into a field by Hoppe's tangent-plane distance
//! averaged over nearby samples. The field is sampled on a grid, restored in the mask and
//! interpolated by a quadratic B-spline; the result can be restored again.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, bail};
use clap::{Args, ValueEnum};

use zeroset_bases::bspline::BSplineField;
use zeroset_bases::field_file::{AnyField, is_field_file, read_any_field, write_field};
use zeroset_bases::tangent_plane::TangentPlaneField;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::Point;
use zeroset_field_core::grid::Grid;
use zeroset_field_core::io::{ReadOptions, read_point_cloud_with};
use zeroset_field_core::mask::{BoxMask, Face};
use zeroset_restore::RestoreError;
use zeroset_restore::denoise::{Denoise, Resampling};
use zeroset_restore::protrusion::{Convention, Protrusion};

use crate::info::g;
use crate::machine::{counts_text, ensure_memory, sample_count};

/// Shown after `zeroset restore --help`.
pub const EXAMPLES: &str = "\
Examples:
  # remove the bunny's ears: the mask's bottom face (-y) is where they join the head
  zeroset restore samples/bunny_2k.xyzn --mode protrusion \\
      --mask -0.095,0.145,-0.065:0.0,0.2,0.04 --face -y -o no_ears.zsf
  # flatter: a steeper slope across the face
  zeroset restore samples/bunny_2k.xyzn --mode protrusion \\
      --mask -0.095,0.145,-0.065:0.0,0.2,0.04 --face -y --alpha 3 -o flat.zsf
  # then smooth a region of the result (restorations compose)
  zeroset restore no_ears.zsf --mode denoise --mask -0.05,0.05,-0.03:0.05,0.12,0.06 \\
      --coarse 6,6,4 -o smooth.zsf";

/// Which restoration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Mode {
    /// Replace a protrusion by a least-squares harmonic fill with a slope α across --face.
    Protrusion,
    /// Resample the mask coarsely (--coarse) and interpolate: removes jaggy noise.
    Denoise,
}

/// Arguments of `zeroset restore`.
#[derive(Debug, Args)]
pub struct RestoreArgs {
    /// A field file (.zsf: a B-spline field, or an RBF field sampled onto the grid) or an
    /// oriented point cloud (PLY, xyz/xyzn/pts, CSV).
    pub input: PathBuf,

    /// The box to restore, two opposite corners in world coordinates: x0,y0,z0:x1,y1,z1.
    #[arg(long, value_parser = parse_mask, allow_hyphen_values = true)]
    pub mask: [[f64; 3]; 2],

    /// protrusion or denoise.
    #[arg(long, value_enum)]
    pub mode: Mode,

    /// Protrusion: the mask face the protrusion's base crosses (+x, -x, +y, -y, +z, -z).
    /// Without it the mask is filled harmonically from its boundary (no slope condition).
    #[arg(long, value_parser = parse_face, allow_hyphen_values = true)]
    pub face: Option<Face>,

    /// Protrusion: the field's slope entering the mask across --face, in field units per unit
    /// length (default: the field's own mean slope there). Larger = flatter.
    #[arg(long, allow_hyphen_values = true)]
    pub alpha: Option<f64>,

    /// The data are positive inside (zeroset's convention is negative inside).
    #[arg(long)]
    pub positive_inside: bool,

    /// Denoise: coarse cells per axis inside the mask, m,n,l (fewer = smoother).
    #[arg(long, value_parser = parse_counts)]
    pub coarse: Option<[usize; 3]>,

    /// Denoise: sample the field at the coarse points (the paper's rule) instead of averaging
    /// the fine samples over each coarse cell.
    #[arg(long)]
    pub point_resampling: bool,

    /// Grid cells per axis, L,M,N (default: a B-spline field file's grid, or 64 along the
    /// longest axis of an RBF field's or a point cloud's box with near-cubic cells).
    #[arg(long, value_parser = parse_counts)]
    pub grid: Option<[usize; 3]>,

    /// Point clouds: the number of nearest samples averaged by the tangent-plane field.
    #[arg(long, default_value_t = 8)]
    pub neighbours: usize,

    /// Force the point-cloud format (ply, xyz, xyzn, pts, csv) when the extension says nothing.
    #[arg(long)]
    pub format: Option<String>,

    /// The output field file (.zsf), written atomically.
    #[arg(short, long)]
    pub output: PathBuf,

    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
}

/// Bytes per grid sample that a restoration holds at once: the field's samples, the restored
/// samples and the quadratic spline's coefficients, 8 bytes each.
const BYTES_PER_SAMPLE: u64 = 24;

/// Bytes per mask cell (and per coarse cell) for the least-squares system or the coarse fit:
/// an estimate of the local copy of the field, the right-hand side, the solution and the
/// solver's or spline's work vectors, 8 bytes each.
const BYTES_PER_MASK_CELL: u64 = 64;

/// Runs `zeroset restore`.
pub fn run(args: &RestoreArgs) -> anyhow::Result<()> {
    crate::output::check_output(&args.output, &[&args.input], args.force, &["zsf"])?;
    // Counts whose product overflows are refused before anything is read.
    if let Some(counts) = &args.grid {
        sample_count(counts, "--grid")?;
    }
    if let Some(coarse) = &args.coarse {
        sample_count(coarse, "--coarse")?;
    }
    let start = Instant::now();
    let (field, default_grid) = load(args)?;
    let grid = match args.grid {
        Some(counts) => {
            Grid::cell_centered(default_grid.bounds(), counts).context("building the --grid")?
        }
        None => default_grid,
    };
    let [a, b] = args.mask;
    let mask = BoxMask::from_corners(&grid, a, b).with_context(|| {
        let bb = grid.bounds();
        format!(
            "the mask must lie in the field's box {} .. {}",
            crate::info::point(bb.min()),
            crate::info::point(bb.max())
        )
    })?;
    check_size(args, &grid, &mask)?;
    let counts = grid.counts();
    println!(
        "grid {}×{}×{} cells over {:?} .. {:?}; mask cells {:?} ..= {:?} ({} cells)",
        counts[0],
        counts[1],
        counts[2],
        grid.bounds().min(),
        grid.bounds().max(),
        mask.lo(),
        mask.hi(),
        mask.len()
    );
    let restored: BSplineField<3> = match args.mode {
        Mode::Protrusion => {
            if args.coarse.is_some() {
                bail!("--coarse applies to --mode denoise");
            }
            let params = Protrusion {
                face: args.face,
                alpha: args.alpha,
                convention: if args.positive_inside {
                    Convention::PositiveInside
                } else {
                    Convention::NegativeInside
                },
                ..Protrusion::default()
            };
            if args.face.is_none() {
                println!("no --face: filling the mask harmonically from its boundary");
            }
            let out = params
                .apply(field.as_ref(), &grid, &mask)
                .context("protrusion removal")?;
            let r = &out.report;
            if let Some(alpha) = r.alpha {
                println!(
                    "alpha {alpha:.4}{}",
                    if args.alpha.is_none() {
                        " (the field's mean slope across the face)"
                    } else {
                        ""
                    }
                );
            }
            println!(
                "{} unknowns, {} equations, solver {}: assembly {:.1} ms, solve {:.1} ms, \
                 spline {:.1} ms; relative residual {:.3e}",
                r.unknowns,
                r.rows,
                r.solve.solver,
                r.assembly.as_secs_f64() * 1e3,
                r.solve.elapsed.as_secs_f64() * 1e3,
                r.interpolation.as_secs_f64() * 1e3,
                r.solve.rel_residual
            );
            out.field
        }
        Mode::Denoise => {
            if args.face.is_some() || args.alpha.is_some() {
                bail!("--face and --alpha apply to --mode protrusion");
            }
            let Some(coarse) = args.coarse else {
                bail!("--mode denoise needs --coarse m,n,l (coarse cells per axis in the mask)");
            };
            let resampling = if args.point_resampling {
                Resampling::Point
            } else {
                Resampling::Area
            };
            let out = Denoise::new(coarse)
                .with_resampling(resampling)
                .apply(field.as_ref(), &grid, &mask)
                .context("de-noising")?;
            println!(
                "coarse {:?} ({resampling:?} resampling): {:.1} ms, spline {:.1} ms",
                out.report.coarse,
                out.report.coarse_fit.as_secs_f64() * 1e3,
                out.report.interpolation.as_secs_f64() * 1e3
            );
            out.field
        }
    };
    write_field(&args.output, &restored)
        .with_context(|| format!("writing {}", args.output.display()))?;
    println!(
        "wrote {} in {:.2} s",
        args.output.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Refuses a grid (or a coarse grid) that cannot be restored here, before the field is
/// sampled: `--coarse` finer than the mask on some axis, or more memory than is available
/// ([`BYTES_PER_SAMPLE`] per grid sample plus [`BYTES_PER_MASK_CELL`] per mask and coarse
/// cell).
fn check_size(args: &RestoreArgs, grid: &Grid<3>, mask: &BoxMask<3>) -> anyhow::Result<()> {
    let counts = grid.counts();
    let coarse_cells = match (args.mode, args.coarse) {
        (Mode::Denoise, Some(coarse)) => {
            let extent = mask.extent();
            if let Some(axis) = (0..3).find(|&a| coarse[a] > extent[a]) {
                return Err(anyhow::Error::new(RestoreError::InvalidCoarse {
                    axis,
                    coarse: coarse[axis],
                    extent: extent[axis],
                })
                .context(format!("--coarse {}", counts_text(&coarse))));
            }
            sample_count(&coarse, "--coarse")?
        }
        _ => 0,
    };
    let samples = sample_count(&counts, "--grid")?;
    let need = (samples as u64)
        .saturating_mul(BYTES_PER_SAMPLE)
        .saturating_add(
            (mask.len() as u64)
                .saturating_add(coarse_cells as u64)
                .saturating_mul(BYTES_PER_MASK_CELL),
        );
    let what = match args.grid {
        Some(_) => format!(
            "--grid {} ({} cells)",
            counts_text(&counts),
            g(samples as f64)
        ),
        None => format!(
            "the field file's grid {} ({} cells)",
            counts_text(&counts).replace(',', "×"),
            g(samples as f64)
        ),
    };
    ensure_memory(need, &what, "choose fewer cells per axis with --grid L,M,N")
}

/// The input as a field, and the grid to restore it on by default.
fn load(args: &RestoreArgs) -> anyhow::Result<(Box<dyn ScalarField<3>>, Grid<3>)> {
    let zsf = args.input.extension().and_then(|e| e.to_str()) == Some("zsf");
    if zsf || is_field_file(&args.input) {
        let field = read_any_field::<3>(&args.input)
            .with_context(|| format!("reading {}", args.input.display()))?;
        let described = field.describe();
        return match field {
            AnyField::BSpline(field) => {
                let grid = *field.grid();
                println!("field file {}: {described}", args.input.display());
                Ok((Box::new(field), grid))
            }
            field @ (AnyField::Rbf(_) | AnyField::Neural(_) | AnyField::Mras(_)) => {
                // Sampled onto a grid over the field's box, like a point cloud's field.
                let bounds = field.bounds().context("the field has no bounds")?;
                let grid = zeroset_restore::sampling_grid(bounds)?;
                println!(
                    "field file {}: {described}, sampled on the grid",
                    args.input.display()
                );
                Ok((Box::new(field), grid))
            }
        };
    }
    let mut options = ReadOptions::default();
    if let Some(format) = &args.format {
        options = options.with_format(format.parse().context("--format")?);
    }
    let cloud = read_point_cloud_with(&args.input, &options).map_err(|e| {
        crate::fit::read_error(
            &args.input,
            e,
            "record",
            "zeroset restore needs finite coordinates and normals (`zeroset info` counts them all)",
        )
    })?;
    if cloud.normals().is_none() {
        bail!(
            "{} has no normals: a point cloud is restored through its tangent-plane field, \
             which needs an oriented cloud (x y z nx ny nz; PLY properties nx ny nz; CSV \
             columns nx,ny,nz)",
            args.input.display()
        );
    }
    crate::fit::check_extent(&args.input, &cloud)?;
    let field = TangentPlaneField::new(&cloud, args.neighbours)
        .context("building the tangent-plane field (the cloud needs normals)")?;
    let bounds = field.bounds().context("the point cloud has no extent")?;
    println!(
        "point cloud {}: {} points, tangent-plane field over {} neighbours",
        args.input.display(),
        cloud.len(),
        field.k()
    );
    let grid = zeroset_restore::sampling_grid(bounds)?;
    Ok((Box::new(field), grid))
}

pub use zeroset_field_core::grid::cubic_counts;

pub(crate) fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

fn parse_triple<T: std::str::FromStr>(s: &str, what: &str) -> Result<[T; 3], String>
where
    T::Err: std::fmt::Display,
{
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!(
            "{what} needs three comma-separated numbers, got {s:?}"
        ));
    }
    let mut out = Vec::with_capacity(3);
    for p in parts {
        out.push(p.parse::<T>().map_err(|e| format!("{what}: {p:?}: {e}"))?);
    }
    out.try_into().map_err(|_| "three values".to_string())
}

fn parse_mask(s: &str) -> Result<[[f64; 3]; 2], String> {
    let Some((a, b)) = s.split_once(':') else {
        return Err(format!(
            "the mask is two corners x0,y0,z0:x1,y1,z1, got {s:?}"
        ));
    };
    let a: Point<3> = parse_triple(a, "mask corner")?;
    let b: Point<3> = parse_triple(b, "mask corner")?;
    if a.iter().chain(&b).any(|v| !v.is_finite()) {
        return Err("mask corners must be finite".into());
    }
    Ok([a, b])
}

pub(crate) fn parse_counts(s: &str) -> Result<[usize; 3], String> {
    let c: [usize; 3] = parse_triple(s, "counts")?;
    if c.contains(&0) {
        return Err(format!("counts must be positive, got {s:?}"));
    }
    Ok(c)
}

fn parse_face(s: &str) -> Result<Face, String> {
    s.parse()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_masks_faces_and_counts() {
        assert_eq!(
            parse_mask("0,1,2:3,4.5,-6").unwrap(),
            [[0.0, 1.0, 2.0], [3.0, 4.5, -6.0]]
        );
        assert!(parse_mask("0,1:3,4,5").is_err());
        assert!(parse_mask("0,1,2").is_err());
        assert!(parse_mask("0,1,nan:1,2,3").is_err());
        assert_eq!(
            parse_face("-z").unwrap(),
            Face::new(2, zeroset_field_core::mask::Side::Lower)
        );
        assert_eq!(
            parse_face("+x").unwrap(),
            Face::new(0, zeroset_field_core::mask::Side::Upper)
        );
        assert!(parse_face("z").is_err());
        assert!(parse_face("+w").is_err());
        assert_eq!(parse_counts("4,5,6").unwrap(), [4, 5, 6]);
        assert!(parse_counts("4,0,6").is_err());
    }
}
