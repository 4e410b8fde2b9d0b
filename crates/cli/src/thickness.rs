//! The thickness check ([`zeroset_bases::thickness`]) as the commands report it: `zeroset
//! info`'s line on a cloud, and the warning of `zeroset fit`, `normals` and `reconstruct` on
//! points that fill a volume rather than sample a surface.

use std::path::Path;

use zeroset_bases::thickness::{
    POINTS_PER_SCALE, THICKNESS_SCALES, Thickness, VOLUME_THICKNESS, measure_thickness,
};
use zeroset_field_core::geometry::Point;

/// `zeroset info`'s line: what the thickness says of the points.
pub fn info_line(positions: &[Point<3>]) -> String {
    match measure_thickness(positions) {
        None => format!(
            "not measured (fewer than {} points, or all at a few positions)",
            POINTS_PER_SCALE * THICKNESS_SCALES[0]
        ),
        Some(t) if t.fills_volume() => format!("a volume's, not a surface's: {}", volume(&t)),
        Some(t) => {
            let thinnest = t.thinnest();
            format!(
                "a surface's: at {} neighbours a point's neighbourhood is {:.3} as thick as it \
                 is wide (the median; a volume's is {VOLUME_THICKNESS} or more at every scale \
                 from {} neighbours up)",
                thinnest.neighbours, thinnest.thickness, THICKNESS_SCALES[0]
            )
        }
    }
}

/// The warning for points that fill a volume (`path` names them); `None` for a surface's, or
/// a cloud too small to tell.
pub fn warning(path: &Path, positions: &[Point<3>]) -> Option<String> {
    let t = measure_thickness(positions).filter(Thickness::fills_volume)?;
    Some(format!(
        "warning: {}: the points fill a volume rather than sample a surface: {}",
        path.display(),
        volume(&t)
    ))
}

/// What a volume's reading is, and what follows.
fn volume(t: &Thickness) -> String {
    let (first, last) = (
        t.scales[0].neighbours,
        t.scales[t.scales.len() - 1].neighbours,
    );
    let reading = if first == last {
        format!("at {first} neighbours a point's neighbourhood is")
    } else {
        format!(
            "at every scale from {first} to {last} neighbours a point's neighbourhood is at least"
        )
    };
    format!(
        "{reading} {:.2} as thick as it is wide (the median; a surface's is under \
         {VOLUME_THICKNESS} at some scale). zeroset fits a surface through points that lie on \
         one: fitted as a very noisy scan, these give a crumpled sheet through the volume, not \
         its boundary; give points sampled on the boundary",
        t.thinnest().thickness
    )
}
