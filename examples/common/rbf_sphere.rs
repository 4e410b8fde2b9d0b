//! The RBF sphere set-up of `PEERS.md`, shared by `examples/rbf_timing.rs` and `benches/rbf.rs`.

use zeroset::bases::rbf::Constraints;

/// The sphere's centre (each coordinate), radius and off-surface offset.
pub const CENTRE: f64 = 0.5;
pub const RADIUS: f64 = 0.35;
pub const OFFSET: f64 = 0.05;

/// `N − 2⌊N/3⌋` Fibonacci points on the sphere (value 0) and, for the first `⌊N/3⌋` of them,
/// points at `±OFFSET` along the outward normal (values `±OFFSET`).
pub fn sphere_setup(n: usize) -> Constraints<3> {
    let third = n / 3;
    let on = n - 2 * third;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let unit: Vec<[f64; 3]> = (0..on)
        .map(|k| {
            let z = 1.0 - (2 * k + 1) as f64 / on as f64;
            let (s, t) = ((1.0 - z * z).sqrt(), k as f64 * golden);
            [s * t.cos(), s * t.sin(), z]
        })
        .collect();
    let at = |u: &[f64; 3], r: f64| u.map(|v| CENTRE + r * v);
    let mut c = Constraints::new();
    for u in &unit {
        c.push_value(at(u, RADIUS), 0.0);
    }
    for u in &unit[..third] {
        c.push_value(at(u, RADIUS + OFFSET), OFFSET);
        c.push_value(at(u, RADIUS - OFFSET), -OFFSET);
    }
    c
}
