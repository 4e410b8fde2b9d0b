//! The thickness check ([`zeroset_bases::thickness`]) as the commands report it: `zeroset
//! info`'s line on a cloud, and the warning of `zeroset fit`, `normals` and `reconstruct` on
//! points that fill a volume rather than sample a surface.

use std::path::Path;

use zeroset_bases::noise::Noise;
use zeroset_bases::thickness::{
    POINTS_PER_SCALE, THICKNESS_SCALES, Thickness, VOLUME_THICKNESS, measure_thickness,
    thick_everywhere,
};
use zeroset_field_core::PointCloud3;
use zeroset_field_core::geometry::Point;

/// `zeroset info`'s line: what the thickness, with the `noise` measured on the same points,
/// says of them.
pub fn info_line(positions: &[Point<3>], noise: Option<&Noise>) -> String {
    let Some(t) = measure_thickness(positions) else {
        return format!(
            "not measured (fewer than {} distinct positions)",
            POINTS_PER_SCALE * THICKNESS_SCALES[0]
        );
    };
    if t.fills_volume(noise) {
        return format!("a volume's, not a surface's: {}", volume(&t));
    }
    let thinnest = t.thinnest();
    if t.thick_everywhere() {
        // Thick at every scale it has points for, but on smooth sheets: a small cloud of a
        // thin part, or scans out of register.
        return format!(
            "a surface's: {} {:.2} as thick as it is wide (the median), as a volume's is, but \
             the points lie on smooth sheets (the noise above), as a thin part sampled by a few \
             points across does",
            reading(&t),
            thinnest.thickness
        );
    }
    format!(
        "a surface's: at {} neighbours a point's neighbourhood is {:.3} as thick as it is wide \
         (the median; a volume's is {VOLUME_THICKNESS} or more at every scale from {} \
         neighbours up)",
        thinnest.neighbours, thinnest.thickness, THICKNESS_SCALES[0]
    )
}

/// The warning for the points of `cloud` (`path` names them) where they fill a volume; `None`
/// for a surface's, or a cloud too small to tell. The scales stop at the first thin one
/// ([`thick_everywhere`]), and the noise check runs only where the
/// thickness reads a volume.
pub fn warning(path: &Path, cloud: &PointCloud3) -> Option<String> {
    let t = thick_everywhere(cloud.positions())?;
    let noise = crate::noise::measure(cloud).map(|m| m.noise);
    t.fills_volume(noise.as_ref()).then(|| {
        format!(
            "warning: {}: the points fill a volume rather than sample a surface: {}",
            path.display(),
            volume(&t)
        )
    })
}

/// Where the thickness was read and how much of each neighbourhood it found, without the
/// figure: "at 32 neighbours a point's neighbourhood is" or "at every scale … at least".
fn reading(t: &Thickness) -> String {
    let scales = t.scales();
    let (first, last) = (scales[0].neighbours, scales[scales.len() - 1].neighbours);
    if first == last {
        format!("at {first} neighbours a point's neighbourhood is")
    } else {
        format!(
            "at every scale from {first} to {last} neighbours a point's neighbourhood is at least"
        )
    }
}

/// What a volume's reading is, and what follows.
fn volume(t: &Thickness) -> String {
    format!(
        "{} {:.2} as thick as it is wide (the median; a surface's is under {VOLUME_THICKNESS} at \
         some scale, or lies on smooth sheets), and the points scatter about every local \
         surface. zeroset fits a surface through points that lie on one: fitted as a very noisy \
         scan, these give a crumpled sheet through the volume, not its boundary; give points \
         sampled on the boundary",
        reading(t),
        t.thinnest().thickness
    )
}
