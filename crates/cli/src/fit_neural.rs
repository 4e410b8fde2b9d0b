//! `zeroset fit INPUT --method neural`: train a small neural field (Jiang–Turk, paper 003 §3).
//!
//! Inputs: a value-constraint file (`.xyv`: `x y value` per line, a 2-D curve; `.xyzv`:
//! `x y z value`) or an oriented point cloud, whose constraints are Carr et al.'s off-surface
//! points as for `--method rbf`: value 0 on the surface and `±εᵢ` at `pᵢ ± εᵢ nᵢ` (the offset
//! starts at `ε₀` = 1% of the diagonal and shrinks per point where needed).
//!
//! The input is moved into `[−1, 1]ᴰ` (the centre `c` of its box, half its longest extent `s`)
//! before training, so that λ, the learning rate and the default domain mean the same for any
//! units. A cloud's values are also divided by `ε₀`, so that the off-surface targets are ±1 as
//! in Jiang–Turk's inside/outside constraints: with targets of ±0.03 (the offset in the scaled
//! units) Adam parks the net at `f ≈ 0` (on bunny_2k: data term 3.8 = that of `f = 0` after 1000
//! steps), with ±1 it learns the surface. The saved field is moved back,
//! `f(x) = v · g((x − c)/s)` with `v = ε₀` for clouds (so `f` approximates the distance in the
//! cloud's units) and `v = 1` for value files.
//!
//! Defaults: those of [`NeuralParams`], except λ = 0.005 for point clouds (the paper's 0.05 is
//! for its 2-D curves; on bunny_2k after 3000 steps the median distance of the input points
//! from the zero set is 6.4e-4 at λ = 0.005 against 1.7e-3 at 0.05, box diagonal 0.26).
//!
//! Training shows a progress bar with the loss (hidden with `--quiet` or when stderr is not a
//! terminal); `-o` writes the `neural` kind of `.zsf` field file, which `zeroset mesh`,
//! `restore`, `preview` and `info` read.

use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context as _, bail};
use clap::{Args, ValueEnum};

use zeroset_bases::field_file::write_neural_field;
use zeroset_bases::neural::{
    Activation, Architecture, NeuralField, NeuralFit, NeuralParams, RefitReport, Trained,
    to_unit_frame, unit_frame,
};
use zeroset_bases::rbf::{Constraints, Offset};
use zeroset_field_core::geometry::Point;
use zeroset_solvers::DenseQr;

use crate::fit::{
    AUTO_FRACTION, FitArgs, OffsetArg, line, load, load_values, more, print_check, print_input,
};
use crate::info::g;
use crate::progress::counter;

const HEADING: &str = "Neural (--method neural)";

/// The default λ for point clouds (see the module docs).
const CLOUD_LAMBDA: f64 = 0.005;

/// The `--activation` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ActivationArg {
    /// tanh (the default).
    Tanh,
    /// softplus, ln(1 + eˣ).
    Softplus,
}

/// `--widths 32,32`: the hidden layers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Widths(pub Vec<usize>);

fn parse_widths(text: &str) -> Result<Widths, String> {
    text.split(',')
        .map(|w| {
            w.trim().parse::<usize>().map_err(|_| {
                format!("expected comma-separated layer widths such as 32,32, got {text:?}")
            })
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Widths)
}

/// The options of `--method neural`.
#[derive(Debug, Args, Default)]
pub struct NeuralArgs {
    /// Adam steps, each over every constraint and auxiliary point [default: 3000].
    #[arg(long, value_name = "N", help_heading = HEADING)]
    pub steps: Option<usize>,
    /// With --method neural: the curvature weight λ ≥ 0 of the thin-plate term [default: 0.05
    /// for value files, 0.005 for point clouds]. With --method mras: the dimensionless weight
    /// λ ≥ 0 of the trace norm that lowers each cell's rank [default: 0.3].
    #[arg(
        long,
        value_name = "L",
        allow_hyphen_values = true,
        help_heading = "Neural and MRAS (--method neural, mras)"
    )]
    pub lambda: Option<f64>,
    /// Auxiliary points P drawn uniformly in the domain for the curvature term [default: 250].
    #[arg(long, value_name = "P", help_heading = HEADING)]
    pub aux: Option<usize>,
    /// Hidden layer widths [default: 32,32].
    #[arg(long, value_name = "W,W,...", value_parser = parse_widths, help_heading = HEADING)]
    pub widths: Option<Widths>,
    /// The activation of the hidden layers [default: tanh].
    #[arg(long, value_enum, help_heading = HEADING)]
    pub activation: Option<ActivationArg>,
    /// The seed of the initial weights and auxiliary points [default: 0].
    #[arg(long, value_name = "S", help_heading = HEADING)]
    pub seed: Option<u64>,
    /// Adam's learning rate [default: 0.01].
    #[arg(long, value_name = "LR", allow_hyphen_values = true, help_heading = HEADING)]
    pub learning_rate: Option<f64>,
    /// Dropout rate in [0, 1) on the hidden activations while training [default: 0].
    #[arg(long, value_name = "RATE", allow_hyphen_values = true, help_heading = HEADING)]
    pub dropout: Option<f64>,
    /// Draw new auxiliary points at every step instead of one fixed set.
    #[arg(long, help_heading = HEADING)]
    pub resample_aux: bool,
    /// After training, refit the output layer to the constraints by linear least squares
    /// (dense QR); never raises the data term.
    #[arg(long, help_heading = HEADING)]
    pub refit_last_layer: bool,
}

impl NeuralArgs {
    /// The first option given, as its flag, if any (for refusing them with --method rbf).
    pub fn given(&self) -> Option<&'static str> {
        if self.lambda.is_some() {
            return Some("--lambda");
        }
        self.given_besides_lambda()
    }

    /// The first option given other than `--lambda` (which `--method mras` shares).
    pub fn given_besides_lambda(&self) -> Option<&'static str> {
        [
            (self.steps.is_some(), "--steps"),
            (self.aux.is_some(), "--aux"),
            (self.widths.is_some(), "--widths"),
            (self.activation.is_some(), "--activation"),
            (self.seed.is_some(), "--seed"),
            (self.learning_rate.is_some(), "--learning-rate"),
            (self.dropout.is_some(), "--dropout"),
            (self.resample_aux, "--resample-aux"),
            (self.refit_last_layer, "--refit-last-layer"),
        ]
        .into_iter()
        .find_map(|(given, flag)| given.then_some(flag))
    }

    /// The training parameters, checked; `default_lambda` unless --lambda is given.
    fn params(&self, default_lambda: f64) -> anyhow::Result<NeuralParams> {
        let mut p = NeuralParams::default().with_lambda(default_lambda);
        let widths = self
            .widths
            .as_ref()
            .map_or_else(|| p.architecture.widths().to_vec(), |w| w.0.clone());
        let activation = match self.activation {
            None | Some(ActivationArg::Tanh) => Activation::Tanh,
            Some(ActivationArg::Softplus) => Activation::Softplus,
        };
        p.architecture = Architecture::new(widths, activation).context("--widths")?;
        if let Some(v) = self.steps {
            p.steps = v;
        }
        if let Some(v) = self.lambda {
            p.lambda = v;
        }
        if let Some(v) = self.aux {
            p.aux_points = v;
        }
        if let Some(v) = self.seed {
            p.seed = v;
        }
        if let Some(v) = self.learning_rate {
            p.learning_rate = v;
        }
        if let Some(v) = self.dropout {
            p.dropout = v;
        }
        p.resample_aux = self.resample_aux;
        p.validate().context("checking the training options")?;
        Ok(p)
    }
}

/// Refuses the options of --method rbf; checks -o.
fn check_request(args: &FitArgs) -> anyhow::Result<()> {
    if let Some(flag) = args.rbf_flag_given() {
        bail!("{flag} is an option of --method rbf, not of --method neural");
    }
    if let Some(OffsetArg::Fixed(eps)) = args.offset
        && !(eps.is_finite() && eps > 0.0)
    {
        bail!("--offset must be auto or a finite distance > 0 in the cloud's units, got {eps}");
    }
    if let Some(output) = &args.output {
        crate::output::check_output(output, &[&args.points], args.force, &["zsf"])?;
    }
    Ok(())
}

/// Runs `zeroset fit --method neural`.
pub fn run(args: &FitArgs) -> anyhow::Result<()> {
    if let Some(flag) = args.mras.given() {
        bail!("{flag} is an option of --method mras, not of --method neural");
    }
    if let Some(flag) = args.outliers.given() {
        bail!("{flag} applies to --method rbf and mras, not to --method neural");
    }
    check_request(args)?;
    let start = Instant::now();
    match crate::normals::value_dimension(&args.points, args.format.as_deref()) {
        Some(dim) => {
            let params = args.neural.params(NeuralParams::default().lambda)?;
            if args.offset.is_some()
                || crate::normals::cloud_format_given(args.format.as_deref())
                || args.formation.is_some()
            {
                bail!(
                    "--offset, --format and --formation apply to point clouds; {} is a \
                     value-constraint file",
                    args.points.display()
                );
            }
            if dim == 2 {
                fit_values::<2>(args, params)?;
            } else {
                fit_values::<3>(args, params)?;
            }
        }
        None => fit_cloud(args, args.neural.params(CLOUD_LAMBDA)?)?,
    }
    if let Some(output) = &args.output {
        outln!(
            "wrote {} (the neural field) in {:.2} s",
            output.display(),
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

fn fit_values<const D: usize>(args: &FitArgs, params: NeuralParams) -> anyhow::Result<()> {
    let c = load_values::<D>(args)?;
    let (centre, scale) = unit_frame(&c.points);
    let u = to_unit_frame(&c.points, centre, scale);
    let field = train(&u, &c.values, params, args, (scale, 1.0), true)?;
    let field = field
        .transformed(centre, scale, 1.0)
        .context("moving the field back to the input's coordinates")?;
    if let Some(output) = &args.output {
        save(&field, output)?;
    }
    Ok(())
}

fn fit_cloud(args: &FitArgs, params: NeuralParams) -> anyhow::Result<()> {
    let cloud = load(args)?;
    print_input(args, &cloud);
    crate::fit::inward_normals(&cloud);
    let offset = match args.offset.unwrap_or(OffsetArg::Auto) {
        OffsetArg::Auto => Offset::Auto {
            fraction: AUTO_FRACTION,
        },
        OffsetArg::Fixed(eps) => Offset::Fixed(eps),
    };
    let (constraints, report) =
        Constraints::off_surface(&cloud, offset).context("building the off-surface constraints")?;
    let (points, targets) = constraints.values();
    line(
        "constraints",
        &format!(
            "{} off-surface (Carr et al.): {} values 0 on the surface, {} at ±offset (smallest \
             offset {}, {} shrunk, {} dropped)",
            points.len(),
            cloud.len() - report.merged,
            points.len() - (cloud.len() - report.merged),
            g(report.smallest),
            report.shrunk,
            report.dropped
        ),
    );
    crate::fit::print_merged(report.merged);
    let (centre, scale) = unit_frame(&points);
    let u = to_unit_frame(&points, centre, scale);
    let unit = report.initial;
    let z: Vec<f64> = targets.iter().map(|t| t / unit).collect();
    let field = train(&u, &z, params, args, (scale, unit), false)?;
    let field = field
        .transformed(centre, scale, unit)
        .context("moving the field back to the cloud's coordinates")?;
    print_check(&field, &cloud, &[]);
    if let Some(output) = &args.output {
        save(&field, output)?;
    }
    Ok(())
}

/// Trains on the scaled constraints with a progress bar, reports, and refits if asked.
///
/// `scale` is the coordinate scale `s` and `unit` the value scale `v` (both for the report);
/// `value_file`: the targets are a value file's (the gap rule of [`training_warnings`] reads them).
fn train<const D: usize>(
    u: &[Point<D>],
    z: &[f64],
    params: NeuralParams,
    args: &FitArgs,
    (scale, unit): (f64, f64),
    value_file: bool,
) -> anyhow::Result<NeuralField<D>> {
    let arch = params.architecture.clone();
    line(
        "network",
        &format!(
            "MLP {D} → {} → 1, {}, {} parameters",
            arch.widths()
                .iter()
                .map(|w| w.to_string())
                .collect::<Vec<_>>()
                .join(" → "),
            arch.activation().name(),
            arch.num_parameters(D)
        ),
    );
    line(
        "training",
        &format!(
            "Adam, {} steps, learning rate {}, λ = {}, {} auxiliary points ({}), seed {}{}",
            params.steps,
            g(params.learning_rate),
            g(params.lambda),
            params.aux_points,
            if params.resample_aux {
                "redrawn every step"
            } else {
                "one fixed set"
            },
            params.seed,
            if params.dropout > 0.0 {
                format!(", dropout {}", g(params.dropout))
            } else {
                String::new()
            }
        ),
    );
    more(&format!(
        "coordinates scaled by 1/{} into [-1, 1]^{D}{}; loss Σ(f - z)² + λ|Ω|/P Σ‖∇²f‖²",
        g(scale),
        if unit == 1.0 {
            String::new()
        } else {
            format!(", values by 1/{}", g(unit))
        }
    ));
    let fit = NeuralFit::new(params.clone());
    let bar = counter(args.quiet, params.steps, "training");
    let started = Instant::now();
    let trained = fit.fit_with(u, z, None, &mut |p| {
        if p.step % 10 == 0 || p.step == p.steps {
            bar.set_position(p.step as u64);
            bar.set_message(format!(
                "training: loss {:.4e} (data {:.3e}, curvature {:.3e})",
                p.loss, p.data_term, p.curvature_term
            ));
        }
        ControlFlow::Continue(())
    });
    bar.finish_and_clear();
    let Trained { field, report } = trained.context("training the neural field")?;
    line(
        "fit time",
        &format!(
            "{:.3} s ({:.3} ms per step)",
            started.elapsed().as_secs_f64(),
            1e3 * started.elapsed().as_secs_f64() / params.steps.max(1) as f64
        ),
    );
    line(
        "loss",
        &format!(
            "{:.4e} = data {:.4e} + curvature {:.4e} (first step: {})",
            report.loss,
            report.data_term,
            report.curvature_term,
            report
                .history
                .first()
                .map_or("-".to_owned(), |l| format!("{l:.4e}"))
        ),
    );
    line(
        "max residual",
        &format!(
            "{:.3e} (the largest |target − field| over the constraints)",
            report.max_residual * unit
        ),
    );
    let (field, max_residual) = if args.neural.refit_last_layer {
        let (refit, r) = field
            .refit_last_layer(u, z, &DenseQr::default())
            .context("refitting the last layer (dense QR)")?;
        print_refit(&r, unit);
        (refit, r.max_residual_after)
    } else {
        (field, report.max_residual)
    };
    // Off-surface targets are ±offsets that shrink near thin parts: their gaps say nothing of
    // the surface, so the gap rule reads value files only.
    let gaps = value_file.then_some(z);
    let warnings = training_warnings(&report.history, max_residual, gaps, args, unit);
    line(
        "warnings",
        &if warnings.is_empty() {
            "none".to_owned()
        } else {
            warnings.join("; ")
        },
    );
    Ok(field)
}

/// What a training run's report shows to be wrong: no step taken, a loss that rose, or (for a
/// value file's targets `z`) a constraint missed by more than half the gap between the
/// distinct target values. `max_residual` is the final field's, after any refit, in the
/// targets' unit; `unit` turns it back into the file's.
fn training_warnings(
    history: &[f64],
    max_residual: f64,
    z: Option<&[f64]>,
    args: &FitArgs,
    unit: f64,
) -> Vec<String> {
    let mut warnings = Vec::new();
    match (history.first(), history.last()) {
        (None, _) | (_, None) => {
            warnings.push("no training step (--steps 0): the net is its random start".to_owned());
        }
        (Some(&first), Some(&last)) if last > first || last.is_nan() => warnings.push(format!(
            "the loss rose from {first:.4e} to {last:.4e}: training diverged (a smaller \
             --learning-rate)"
        )),
        _ => {}
    }
    let Some(z) = z else {
        return warnings;
    };
    let mut values = z.to_vec();
    values.sort_by(f64::total_cmp);
    values.dedup();
    let gap = values
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    if gap.is_finite() && max_residual > 0.5 * gap {
        warnings.push(format!(
            "a constraint is missed by {}, more than half the gap {} between distinct values: \
             a level between them may pass on the wrong side of it (more --steps, a smaller \
             --lambda{})",
            g(max_residual * unit),
            g(gap * unit),
            if args.neural.refit_last_layer {
                ""
            } else {
                ", or --refit-last-layer"
            }
        ));
    }
    warnings
}

fn print_refit(r: &RefitReport, unit: f64) {
    line(
        "refit",
        &format!(
            "output layer by least squares ({}): data term {:.4e} → {:.4e}, max residual {:.3e}, \
             {:.3} s",
            r.info.solver,
            r.data_before,
            r.data_after,
            r.max_residual_after * unit,
            r.elapsed.as_secs_f64()
        ),
    );
}

fn save<const D: usize>(field: &NeuralField<D>, output: &Path) -> anyhow::Result<()> {
    line(
        "output",
        &format!(
            "{}: the neural field ({} parameters; exact)",
            output.display(),
            field.parameters().len()
        ),
    );
    write_neural_field(output, field).with_context(|| format!("writing {}", output.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_widths() {
        assert_eq!(parse_widths("32,32").unwrap(), Widths(vec![32, 32]));
        assert_eq!(parse_widths(" 8 ").unwrap(), Widths(vec![8]));
        assert_eq!(parse_widths("0,4").unwrap(), Widths(vec![0, 4]));
        assert!(parse_widths("32,x").is_err());
        assert!(parse_widths("").is_err());
    }
}
