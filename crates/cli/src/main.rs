//! `zeroset`: inspect point clouds; fit, restore and mesh fields.
//!
//! Each subcommand lives in its own module with an `Args` struct (clap derive) and a
//! `run(&Args) -> anyhow::Result<()>`; `main` only parses, dispatches and reports errors.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// `println!` for the commands' reports, except that a closed stdout (`zeroset fit … | head`)
/// stops the printing, not the command: see [`output::say_line`].
macro_rules! outln {
    () => {
        $crate::output::say_line(format_args!(""))
    };
    ($($arg:tt)*) => {
        $crate::output::say_line(format_args!($($arg)*))
    };
}

mod demo;
mod fit;
mod fit_mras;
mod fit_neural;
mod info;
mod interrupt;
mod machine;
mod mesh;
mod mesh_points;
mod noise;
mod normals;
mod outliers;
mod output;
mod preview;
mod progress;
mod reconstruct;
mod restore;
mod studio;
mod thickness;

const EXAMPLES: &str = "\
Examples:
  zeroset demo                                 the main job on built-in sample data
  zeroset info samples/bunny_2k.xyzn           describe the sample point cloud
  zeroset info scan.ply                        PLY, ascii or binary
  zeroset info points.dat --format csv         read a file whose extension says nothing
  zeroset info SandStone_Foliations.csv        a GemPy table: formations and counts
  zeroset fit samples/bunny_2k.xyzn --method rbf
                                               fit an RBF field to the sample and report it
  zeroset fit samples/bunny_2k.xyzn --method rbf --hermite -o bunny.zsf
                                               Hermite fit (r3), saved as a field file
  zeroset fit samples/curve.xyv --method rbf -o curve.zsf
                                               the thin-plate spline through 2-D value
                                               constraints (zeroset mesh curve.zsf -o curve.svg)
  zeroset fit samples/curve.xyv --method neural -o curve_nn.zsf
                                               a neural field through the same constraints
  zeroset restore samples/bunny_2k.xyzn --mode protrusion \
      --mask -0.1,0.145,-0.07:0.005,0.2,0.05 --face -y -o no_ears.zsf
                                               remove the bunny's ears
  zeroset mesh bunny.zsf -o bunny.ply          mesh the field's zero set (binary PLY)
  zeroset preview bunny.zsf -o bunny.png       a shaded PNG of the field's zero set
  zeroset studio samples/bunny_2k.xyzn -o no_ears.zsf
                                               restore in the browser: place the mask, move
                                               alpha, see the surface live, save
  zeroset reconstruct scan.ply -o scan_mesh.ply
                                               scan → field → mesh + PNG in one command
  zeroset normals scan.xyz -o scan_oriented.ply
                                               outward normals for a scan without them
  zeroset info --help                          more on one subcommand";

/// Implicit surfaces: fit scalar fields to oriented point clouds, restore them, and mesh their
/// zero set.
#[derive(Debug, Parser)]
#[command(name = "zeroset", version, after_help = EXAMPLES)]
struct Cli {
    /// Worker threads for the parallel parts (rayon's global pool); at least 1; by default one
    /// per CPU. Results are identical for any N: the computations are deterministic.
    #[arg(
        long,
        global = true,
        value_name = "N",
        value_parser = parse_threads,
        allow_hyphen_values = true
    )]
    threads: Option<usize>,

    #[command(subcommand)]
    command: Command,
}

/// `--threads N`: a whole number, at least 1.
fn parse_threads(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(0) => Err("the thread count must be at least 1".to_owned()),
        Ok(n) => Ok(n),
        Err(_) => Err(format!(
            "expected a whole number of threads (at least 1), got {text:?}"
        )),
    }
}

/// The subcommands. To add one (e.g. `demo`): add a variant holding its `Args`, a module with
/// `Args` and `run`, and an arm in [`run`].
#[derive(Debug, Subcommand)]
enum Command {
    /// Describe a point-cloud file: format, point count, bounding box, normals, duplicates,
    /// non-finite values, stray points, noise, thickness (a surface's points or a volume's),
    /// and GemPy formations.
    #[command(after_help = info::EXAMPLES)]
    Info(info::InfoArgs),
    /// Run the main job on built-in sample data: describe the bundled point cloud, solve a
    /// restoration least-squares problem with every solver and check that they agree (to the
    /// tolerance it prints), remove the bunny's ears, and run fit → restore → mesh → preview.
    #[command(after_help = demo::EXAMPLES)]
    Demo(demo::DemoArgs),
    /// Fit an implicit field to an oriented point cloud with radial basis functions (off-surface
    /// or Hermite constraints), multilevel low-rank splines (MRAS) or a small neural net, or to
    /// value constraints (x y [z] value files), and report the fit; -o saves the field as a
    /// .zsf field file.
    #[command(after_help = fit::EXAMPLES)]
    Fit(fit::FitArgs),
    /// Restore a field inside a box mask: remove a protrusion (least-squares Laplace with a
    /// slope across the face it grows from) or de-noise (coarse resampling); writes a .zsf
    /// field file.
    #[command(after_help = restore::EXAMPLES)]
    Restore(restore::RestoreArgs),
    /// Mesh the level set of a .zsf field file by marching cubes on cubic voxels (size by the
    /// l0 rule of the field's box, --resolution or --voxel); writes PLY, OBJ, STL or OFF (a
    /// 2-D field's curves as SVG) and reports whether the mesh is closed, its Euler
    /// characteristic, components and volume.
    #[command(after_help = mesh::EXAMPLES)]
    Mesh(mesh::MeshArgs),
    /// Render a PNG preview: a mesh (.ply) shaded, a field file's (.zsf) zero set meshed and
    /// shaded, or with --slice the field on an axis-aligned plane with its zero contour.
    #[command(after_help = preview::EXAMPLES)]
    Preview(preview::PreviewArgs),
    /// From a scan to a mesh in one command: fit a field (RBF for small clouds, smoothed where
    /// noisy; MRAS for large ones; or --method), mesh its zero set (signed marching cubes for RBF),
    /// write the mesh and a PNG preview beside it, and summarise the stages' times.
    #[command(after_help = reconstruct::EXAMPLES)]
    Reconstruct(reconstruct::ReconstructArgs),
    /// Estimate outward normals for a point cloud that has none (planes of each point's
    /// nearest neighbours, signs propagated along a minimum spanning forest, each piece turned
    /// outward) and write the oriented cloud (.ply or .xyzn).
    #[command(after_help = normals::EXAMPLES)]
    Normals(normals::NormalsArgs),
    /// The interactive restoration studio: a local web page (served by this binary on
    /// 127.0.0.1, with an access token) to place a box mask on the surface, move α or the
    /// de-noising resolution and see the restored surface live; undo/redo, the equivalent
    /// `zeroset restore` commands, and Save (atomic .zsf, and the mesh as .ply).
    #[command(after_help = studio::EXAMPLES)]
    Studio(studio::StudioArgs),
}

fn run(cli: Cli) -> anyhow::Result<()> {
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| anyhow::anyhow!("cannot start {n} worker threads: {e}"))?;
    }
    if !matches!(cli.command, Command::Studio(_)) {
        interrupt::install();
    }
    match cli.command {
        Command::Info(args) => info::run(&args),
        Command::Demo(args) => demo::run(&args),
        Command::Fit(args) => fit::run(&args),
        Command::Restore(args) => restore::run(&args),
        Command::Mesh(args) => mesh::run(&args),
        Command::Preview(args) => preview::run(&args),
        Command::Reconstruct(args) => reconstruct::run(&args),
        Command::Normals(args) => normals::run(&args),
        Command::Studio(args) => studio::run(&args),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {}", message(&err));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes, `: `-separated, leaving out a cause whose text the message
/// already holds (field-core's errors quote their I/O error).
fn message(err: &anyhow::Error) -> String {
    let mut text = err.to_string();
    for cause in err.chain().skip(1) {
        let cause = cause.to_string();
        if !text.contains(&cause) {
            text.push_str(": ");
            text.push_str(&cause);
        }
    }
    text
}
