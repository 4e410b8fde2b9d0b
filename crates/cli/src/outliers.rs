//! `--outlier-ratio` and `--outliers-out` of `zeroset fit` (RBF and MRAS fits of oriented
//! clouds): the stray points [`zeroset_bases::outliers`] sets aside, reported and written.
//! The RBF path removes them here ([`set_aside`]); MRAS removes them itself
//! (`MrasOptions::outlier_ratio`) and the CLI reports what it did with [`OutlierArgs::report`].

use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};
use clap::Args;
use zeroset_bases::outliers::{DEFAULT_OUTLIER_RATIO, remove_outliers, valid_ratio};
use zeroset_field_core::PointCloud3;

use crate::fit::{line, more};
use crate::info::g;

const HEADING: &str = "Stray points (--method rbf and mras)";

/// The stray-point options of `zeroset fit`.
#[derive(Debug, Args, Default)]
pub struct OutlierArgs {
    /// Set aside stray points before fitting (oriented clouds): those whose spacing (mean
    /// distance to their 8 nearest) exceeds R times the median and that do not lie on a surface
    /// with their neighbours, and those off a clean patch of surface with a normal of their
    /// own; 0 fits every point [default: 3].
    #[arg(long, value_name = "R", help_heading = HEADING)]
    pub outlier_ratio: Option<f64>,
    /// Write the stray points set aside to this .xyzn file (x y z nx ny nz per line, in input
    /// order; empty if there are none), written atomically. (`zeroset reconstruct` of a scan
    /// without normals reports the isolated points it sets aside before estimating them; this
    /// file lists the fit's.)
    #[arg(long, value_name = "FILE.xyzn", help_heading = HEADING)]
    pub outliers_out: Option<PathBuf>,
}

impl OutlierArgs {
    /// The first option given, as its flag, if any (for refusing them where they do not apply).
    pub fn given(&self) -> Option<&'static str> {
        [
            (self.outlier_ratio.is_some(), "--outlier-ratio"),
            (self.outliers_out.is_some(), "--outliers-out"),
        ]
        .into_iter()
        .find_map(|(given, flag)| given.then_some(flag))
    }

    /// `--outlier-ratio` or the default, checked.
    ///
    /// # Errors
    /// A ratio other than 0 below 1.5, or not finite.
    pub fn ratio(&self) -> anyhow::Result<f64> {
        let ratio = self.outlier_ratio.unwrap_or(DEFAULT_OUTLIER_RATIO);
        if !valid_ratio(ratio) {
            bail!(
                "--outlier-ratio {ratio}: give 0 (off) or a ratio ≥ 1.5 (below, most of a \
                 surface's points would be isolated)"
            );
        }
        Ok(ratio)
    }

    /// Checks `--outliers-out` before any work: an .xyzn file that is not `points` or
    /// `output`, and exists only with `force`.
    ///
    /// # Errors
    /// As [`crate::output::check_output`].
    pub fn check(&self, points: &Path, output: Option<&Path>, force: bool) -> anyhow::Result<()> {
        let Some(path) = &self.outliers_out else {
            return Ok(());
        };
        let mut inputs = vec![points];
        inputs.extend(output);
        crate::output::check_output(path, &inputs, force, &["xyzn"])
    }

    /// Reports the points of `cloud` at `indices` (increasing) set aside at `ratio`, and the
    /// `kept_sparse` isolated points kept; writes them to `--outliers-out` if given.
    ///
    /// # Errors
    /// Writing `--outliers-out`.
    pub fn report(
        &self,
        cloud: &PointCloud3,
        indices: &[usize],
        kept_sparse: usize,
        ratio: f64,
    ) -> anyhow::Result<()> {
        print(cloud, indices, kept_sparse, ratio);
        let Some(path) = &self.outliers_out else {
            return Ok(());
        };
        let normals = cloud.normals().unwrap_or_default();
        zeroset_field_core::io::write_atomic(path, |w| {
            for &i in indices {
                let p = cloud.positions()[i];
                let n = normals.get(i).copied().unwrap_or([0.0; 3]);
                writeln!(w, "{} {} {} {} {} {}", p[0], p[1], p[2], n[0], n[1], n[2])?;
            }
            Ok(())
        })
        .with_context(|| format!("writing {}", path.display()))?;
        outln!(
            "wrote {} ({} stray point{} set aside)",
            path.display(),
            indices.len(),
            if indices.len() == 1 { "" } else { "s" }
        );
        Ok(())
    }
}

/// The cloud without the stray points found at the `--outlier-ratio` of `args`, and their
/// indices, reported (the RBF path: an interpolant would make each of them surface).
///
/// # Errors
/// A bad `--outlier-ratio`; writing `--outliers-out`.
pub fn set_aside(
    args: &OutlierArgs,
    cloud: &PointCloud3,
) -> anyhow::Result<(PointCloud3, Vec<usize>)> {
    let ratio = args.ratio()?;
    let (kept, found) = remove_outliers(cloud, ratio).context("the cloud without its outliers")?;
    args.report(cloud, &found.indices, found.kept_sparse, ratio)?;
    Ok((kept, found.indices))
}

/// The `outliers` line of a fit's report.
fn print(cloud: &PointCloud3, indices: &[usize], kept_sparse: usize, ratio: f64) {
    if ratio == 0.0 {
        line(
            "outliers",
            "not looked for (--outlier-ratio 0): every point fitted",
        );
        return;
    }
    let sparse = match kept_sparse {
        0 => String::new(),
        k => format!("; {k} isolated but kept: on a surface with their neighbours"),
    };
    if indices.is_empty() {
        line("outliers", &format!("none{sparse}"));
        return;
    }
    const SHOWN: usize = 3;
    let examples: Vec<String> = indices
        .iter()
        .take(SHOWN)
        .map(|&i| format!("#{i} {}", crate::info::point(cloud.positions()[i])))
        .collect();
    line(
        "outliers",
        &format!(
            "{} stray point{} set aside, not fitted (isolated: spacing > {}× the median; or \
             off a clean patch of surface with a normal of their own){sparse}; --outlier-ratio 0 \
             fits every point",
            indices.len(),
            if indices.len() == 1 { "" } else { "s" },
            g(ratio),
        ),
    );
    more(&format!(
        "{}{}",
        examples.join(", "),
        if indices.len() > SHOWN { ", …" } else { "" }
    ));
}
