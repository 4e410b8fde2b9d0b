#[path = "common/curve.rs"]
mod curve;
use std::time::Instant;
use zeroset::bases::neural::*;
use zeroset::core::Aabb;
fn main() {
    let (pts, z) = curve::points_and_targets(&curve::sites());
    let steps: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(3000);
    let lr: f64 = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1e-2);
    for v in Variant::ALL {
        let mut p = NeuralParams::variant(v)
            .with_steps(steps)
            .with_learning_rate(lr);
        p.resample_aux = std::env::var("RESAMPLE").is_ok();
        p.seed = std::env::var("SEED")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(0);
        let fit = NeuralFit::new(p).with_domain(Aabb::new([-1.0, -1.0], [1.0, 1.0]).unwrap());
        let t = Instant::now();
        let tr = fit.fit(&pts, &z).unwrap();
        let dt = t.elapsed().as_secs_f64();
        println!(
            "{:?}: {:.3} s ({:.3} ms/step) max res {:.4} data {:.3e} curv {:.3e} energy {:.3}",
            v,
            dt,
            dt * 1e3 / steps as f64,
            tr.report.max_residual,
            tr.report.data_term,
            tr.report.curvature_term,
            tr.field.thin_plate_energy(200)
        );
    }
}
