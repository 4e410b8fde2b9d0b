//! `zeroset preview INPUT -o IMAGE.png`: a PNG picture of a mesh or a field.
//!
//! A mesh (`.ply`, `.obj`, `.stl`) is drawn shaded (`zeroset_mesh::preview::render_mesh`: orthographic,
//! z-buffered, back faces darker and warmer). A field file (`.zsf`, recognised by its magic) is
//! meshed at its zero set by marching cubes on the `l0` voxel grid of its box at the detail
//! class `zeroset mesh` defaults to (general; fine for an MRAS field, not refined for a dense
//! scan), capped where it leaves the box, and drawn the same way; with `--slice AXIS[=POS]` the field is drawn
//! on the plane `AXIS = POS` instead (blue inside, red outside, the zero contour in black). A
//! 2-D field file (a curve) is drawn over its box the same way as a slice. The image is
//! written atomically.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, bail};
use clap::Args;

use crate::progress::seconds;
use zeroset_bases::field_file::{is_field_file, read_any_field, read_dimension};
use zeroset_field_core::field::ScalarField;
use zeroset_mesh::preview::{
    Axis, Image, MAX_IMAGE_SIZE, RenderOptions, View, render_field_2d, render_mesh, render_slice,
};
use zeroset_mesh::voxel::{self, Detail};
use zeroset_mesh::{McOptions, MeshFormat, TriMesh, mesh_field};

/// Shown after `zeroset preview --help`.
pub const EXAMPLES: &str = "\
Examples:
  # a field's zero set, meshed on the l0 grid (general; fine for MRAS) and shaded
  zeroset fit samples/bunny_2k.xyzn --method rbf -o bunny.zsf
  zeroset preview bunny.zsf -o bunny.png
  # a mesh file, seen from another side, wider
  zeroset mesh bunny.zsf -o bunny.ply
  zeroset preview bunny.ply -o side.png --azimuth 120 --elevation 10 --width 1200
  # the field on the plane through the box centre normal to z; or at x = 0.01
  zeroset preview bunny.zsf -o slice.png --slice z
  zeroset preview bunny.zsf -o slice_x.png --slice x=0.01 --force
  # a 2-D field (a curve): the field over its box with the zero contour
  zeroset fit samples/curve.xyv --method neural -o curve.zsf
  zeroset preview curve.zsf -o curve.png";

/// A slice plane: the axis (0, 1, 2) and the position on it (the box centre when `None`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slice {
    /// 0, 1 or 2 for x, y, z.
    pub axis: usize,
    /// Where the plane crosses the axis.
    pub position: Option<f64>,
}

/// Parses `x`, `y`, `z`, optionally followed by `=POS`.
fn parse_slice(s: &str) -> Result<Slice, String> {
    let (name, pos) = match s.split_once('=') {
        Some((n, p)) => (n.trim(), Some(p.trim())),
        None => (s.trim(), None),
    };
    let axis = match name.to_ascii_lowercase().as_str() {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        _ => {
            return Err(format!(
                "the axis must be x, y or z (as x, y=0.5, z=-1), got {s:?}"
            ));
        }
    };
    let position = match pos {
        None => None,
        Some(p) => {
            let v: f64 = p
                .parse()
                .map_err(|_| format!("the position {p:?} is not a number"))?;
            if !v.is_finite() {
                return Err(format!("the position must be finite, got {p:?}"));
            }
            Some(v)
        }
    };
    Ok(Slice { axis, position })
}

/// Arguments of `zeroset preview`.
#[derive(Debug, Args)]
pub struct PreviewArgs {
    /// A mesh (.ply, .obj, .stl, .off) or a field file (.zsf).
    pub input: PathBuf,

    /// The image, a .png file, written atomically.
    #[arg(short, long, value_name = "IMAGE.png")]
    pub output: PathBuf,

    /// Image width in pixels (for --slice, the longer side is the larger of width and height).
    #[arg(long, default_value_t = 800)]
    pub width: usize,

    /// Image height in pixels.
    #[arg(long, default_value_t = 800)]
    pub height: usize,

    /// Camera angle about the up axis (--up), in degrees from the next axis in x, y, z order
    /// (x for z up, z for y up, y for x up).
    #[arg(long, default_value_t = 35.0, allow_hyphen_values = true)]
    pub azimuth: f64,

    /// Camera angle above the plane across the up axis, in degrees (90 looks straight down).
    #[arg(long, default_value_t = 25.0, allow_hyphen_values = true)]
    pub elevation: f64,

    /// The axis drawn up: z (the default; terrain, geology, most scanners) or y (the Stanford
    /// bunny and most meshes from graphics tools) or x.
    #[arg(long, value_enum, default_value_t = Up::Z)]
    pub up: Up,

    /// A field file only: draw the field on the plane AXIS = POS (default: the box centre)
    /// with its zero contour, instead of its meshed zero set.
    #[arg(long, value_name = "x|y|z[=POS]", value_parser = parse_slice)]
    pub slice: Option<Slice>,

    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,

    /// Accepted for symmetry with the other subcommands (preview shows no progress spinner).
    #[arg(long)]
    pub quiet: bool,
}

/// The axis a preview draws up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Up {
    /// `+x` up.
    X,
    /// `+y` up.
    Y,
    /// `+z` up.
    Z,
}

/// Runs `zeroset preview`.
pub fn run(args: &PreviewArgs) -> anyhow::Result<()> {
    check_output(args)?;
    for (what, v) in [("--width", args.width), ("--height", args.height)] {
        if v == 0 || v > MAX_IMAGE_SIZE {
            bail!("{what} must be 1 to {MAX_IMAGE_SIZE} pixels, got {v}");
        }
    }
    for (what, v) in [("--azimuth", args.azimuth), ("--elevation", args.elevation)] {
        if !v.is_finite() {
            bail!("{what} must be finite, got {v}");
        }
    }
    if !args.input.exists() {
        bail!("the input {} does not exist", args.input.display());
    }
    let total = Instant::now();
    let field_input = is_field_file(&args.input);
    let flat = field_input && matches!(read_dimension(&args.input), Ok(2));
    // Defaults are not told from the same values given; either way nothing is lost.
    let camera = args.azimuth != 35.0 || args.elevation != 25.0 || args.up != Up::Z;
    if camera && (flat || args.slice.is_some()) {
        bail!(
            "--azimuth, --elevation and --up place the camera for a shaded surface; {} is drawn \
             flat, seen straight on",
            if flat { "a 2-D field" } else { "a --slice" }
        );
    }
    let image = if flat {
        if args.slice.is_some() {
            bail!(
                "--slice cuts a 3-D field; {} holds a 2-D field, drawn whole without it",
                args.input.display()
            );
        }
        let field = read_any_field::<2>(&args.input)
            .with_context(|| format!("reading {}", args.input.display()))?;
        let Some(bounds) = field.bounds() else {
            bail!("the field in {} has no bounding box", args.input.display());
        };
        let image = render_field_2d(&field, bounds, args.width.max(args.height))
            .context("rendering the field")?;
        outln!(
            "the 2-D {} field {} over its box, zero contour in black",
            field.kind(),
            args.input.display()
        );
        image
    } else if field_input {
        let field = read_any_field::<3>(&args.input)
            .with_context(|| format!("reading {}", args.input.display()))?;
        let Some(bounds) = field.bounds() else {
            bail!("the field in {} has no bounding box", args.input.display());
        };
        match args.slice {
            Some(slice) => {
                let c = bounds.center();
                let position = slice.position.unwrap_or(c[slice.axis]);
                let (lo, hi) = (bounds.min()[slice.axis], bounds.max()[slice.axis]);
                if !(lo..=hi).contains(&position) {
                    bail!(
                        "--slice {axis}={} lies outside the field's box, where {axis} runs from {} \
                         to {}: the field is only defined in its box",
                        crate::info::g(position),
                        crate::info::g(lo),
                        crate::info::g(hi),
                        axis = ["x", "y", "z"][slice.axis]
                    );
                }
                let pixels = args.width.max(args.height);
                let image = render_slice(&field, bounds, slice.axis, position, pixels)
                    .context("rendering the slice")?;
                outln!(
                    "slice {} = {} of the {} field {}, zero contour in black",
                    ["x", "y", "z"][slice.axis],
                    position,
                    field.kind(),
                    args.input.display()
                );
                image
            }
            None => {
                // The detail class `zeroset mesh` takes by default: fine for MRAS fields, whose
                // deep levels general voxels would not resolve (jagged ear rims on the bunny).
                // Not refined further for a dense scan as `zeroset mesh` is: an 800-pixel
                // picture shows no finer than this.
                let detail = if field.wants_fine_mesh() {
                    Detail::Fine
                } else {
                    Detail::General
                };
                let h = voxel::voxel_size(&bounds, detail);
                if !(h.is_finite() && h > 0.0) {
                    bail!("the field's box is a point: nothing to mesh; try --slice");
                }
                let grid =
                    voxel::grid_for(&bounds, h, 0.0).context("building the sampling grid")?;
                let options = McOptions::default().with_close_boundary(true);
                let mesh =
                    mesh_field(&field, &grid, 0.0, &options).context("extracting the zero set")?;
                if mesh.is_empty() {
                    bail!(
                        "the zero set of {} does not cross its box: nothing to render; try --slice",
                        args.input.display()
                    );
                }
                let c = grid.counts();
                outln!(
                    "zero set of the {} field {}: {} triangles (marching cubes, {}×{}×{} grid, \
                     voxel {h:.4e})",
                    field.kind(),
                    args.input.display(),
                    mesh.num_triangles(),
                    c[0],
                    c[1],
                    c[2]
                );
                render(args, &mesh)?
            }
        }
    } else {
        if args.slice.is_some() {
            bail!(
                "--slice needs a field file (.zsf); {} is not one",
                args.input.display()
            );
        }
        let mesh = read_mesh(&args.input)?;
        outln!(
            "mesh {}: {} vertices, {} triangles",
            args.input.display(),
            mesh.num_vertices(),
            mesh.num_triangles()
        );
        render(args, &mesh)?
    };
    image
        .write_png(&args.output)
        .with_context(|| format!("writing {}", args.output.display()))?;
    outln!(
        "wrote {} ({}×{} PNG) in {}",
        args.output.display(),
        image.width(),
        image.height(),
        seconds(total.elapsed())
    );
    Ok(())
}

/// Reads a mesh file (PLY, OBJ, STL or OFF) by its extension.
fn read_mesh(path: &Path) -> anyhow::Result<TriMesh> {
    if MeshFormat::from_path(path).is_none() {
        bail!(
            "{} is neither a field file (.zsf) nor a mesh (.ply, .obj, .stl, .off)",
            path.display()
        );
    }
    let mesh =
        zeroset_mesh::read_mesh(path).with_context(|| format!("reading {}", path.display()))?;
    if mesh.triangles().is_empty() {
        bail!(
            "{} holds no triangle (a point cloud?): there is nothing to render",
            path.display()
        );
    }
    Ok(mesh)
}

fn render(args: &PreviewArgs, mesh: &TriMesh) -> anyhow::Result<Image> {
    let opts = RenderOptions {
        width: args.width,
        height: args.height,
        view: View {
            azimuth: args.azimuth,
            elevation: args.elevation,
        },
        up: match args.up {
            Up::X => Axis::X,
            Up::Y => Axis::Y,
            Up::Z => Axis::Z,
        },
        ..RenderOptions::default()
    };
    render_mesh(mesh, &opts).context("rendering the mesh")
}

/// Refuses a non-.png output, the input, a missing directory, a directory and an existing file
/// without --force — all before any work.
fn check_output(args: &PreviewArgs) -> anyhow::Result<()> {
    crate::output::check_output(&args.output, &[&args.input], args.force, &["png"])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_slices() {
        assert_eq!(
            parse_slice("z"),
            Ok(Slice {
                axis: 2,
                position: None
            })
        );
        assert_eq!(
            parse_slice("X=-0.5"),
            Ok(Slice {
                axis: 0,
                position: Some(-0.5)
            })
        );
        assert!(parse_slice("w").is_err());
        assert!(parse_slice("y=abc").is_err());
        assert!(parse_slice("y=inf").is_err());
    }
}
