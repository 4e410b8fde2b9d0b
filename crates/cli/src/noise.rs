//! The noise check ([`zeroset_bases::noise`]) as the commands report it: `zeroset info` on a
//! cloud, the warning of `zeroset fit --method rbf` on a noisy one, and the reason
//! `zeroset reconstruct --method auto` gives for not interpolating it.

use zeroset_bases::noise::{NOISY_SCATTER, Noise, estimate_noise};
use zeroset_bases::normals::estimate_noise_unoriented;
use zeroset_field_core::PointCloud3;

use crate::info::g;

/// The estimate for `cloud` (its normals used where it has them; otherwise, or where they are
/// all `0 0 0` placeholders, [`estimate_noise_unoriented`]), with its bounding-box diagonal.
pub fn measure(cloud: &PointCloud3) -> Option<Measured> {
    let diagonal = cloud.bounds().map_or(0.0, |b| b.diagonal());
    let given = cloud
        .normals()
        .filter(|normals| normals.iter().flatten().any(|&x| x != 0.0));
    match given {
        Some(normals) => estimate_noise(cloud.positions(), Some(normals)),
        None => estimate_noise_unoriented(cloud.positions()),
    }
    .map(|noise| Measured { noise, diagonal })
}

/// An estimate and the diagonal it is reported against.
#[derive(Debug, Clone, Copy)]
pub struct Measured {
    /// The estimate.
    pub noise: Noise,
    /// The cloud's bounding-box diagonal.
    pub diagonal: f64,
}

impl Measured {
    /// `scatter σ ≈ …` (of the diagonal) and its ratio to the spacing.
    pub fn describe(&self) -> String {
        let of_diagonal = if self.diagonal > 0.0 {
            format!(" ({} of the diagonal)", g(self.noise.sigma / self.diagonal))
        } else {
            String::new()
        };
        format!(
            "scatter about the local surface σ ≈ {}{of_diagonal}, {:.3} of the point spacing",
            g(self.noise.sigma),
            self.noise.relative()
        )
    }

    /// `zeroset info`'s line: the figures and what they mean for a fit.
    pub fn verdict(&self) -> String {
        if let Some(sheets) = self.two_sheets() {
            format!(
                "{}: noisy (above {NOISY_SCATTER}) on its face, but {sheets}; zeroset reconstruct \
                 still approximates it as a noisy scan (RBF with --smoothing auto up to {} \
                 points, MRAS beyond)",
                self.describe(),
                crate::reconstruct::AUTO_SMOOTHED_POINTS
            )
        } else if self.noise.is_noisy() {
            format!(
                "{}: noisy (above {NOISY_SCATTER}); RBF interpolation would fold between the \
                 points into bubbles, so zeroset reconstruct approximates them: RBF with \
                 --smoothing auto up to {} points, MRAS (least squares) beyond",
                self.describe(),
                crate::reconstruct::AUTO_SMOOTHED_POINTS
            )
        } else {
            format!(
                "{}: clean enough to interpolate (noisy above {NOISY_SCATTER})",
                self.describe()
            )
        }
    }

    /// Where two sheets explain the noisy reading ([`Noise::two_sheets_explain`]): what they
    /// are and what follows, as a clause.
    pub fn two_sheets(&self) -> Option<String> {
        let noise = &self.noise;
        noise.two_sheets_explain().then(|| {
            format!(
                "{:.0}% of the patches lie on two parallel sheets, about which the points \
                 scatter by σ ≈ {} ({} of the spacing): a wall thinner than about two point \
                 spacings, or two scans of one surface out of register, not noise. A wall: \
                 normals estimated from positions cannot tell its two faces apart, and a fit \
                 fuses, thickens or perforates it (give the scan its normals, or sample the wall \
                 more densely); scans out of register: a fit averages them as noise (register \
                 them first)",
                100.0 * noise.two_sheet_share(),
                g(noise.sigma_within_sheets),
                g(noise.sigma_within_sheets / noise.spacing)
            )
        })
    }

    /// The warning of an RBF fit, on a noisy cloud only.
    pub fn rbf_warning(&self) -> Option<String> {
        self.noise.is_noisy().then(|| {
            format!(
                "warning: {} (noisy above {NOISY_SCATTER}): RBF interpolates every point and \
                 folds between noisy ones, so the surface grows bubbles; --smoothing auto \
                 approximates them instead, or --method mras fits them by least squares",
                self.describe()
            )
        })
    }
}
