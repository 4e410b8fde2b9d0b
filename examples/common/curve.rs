//! The 2-D curve set-up of `PEERS.md` (Jiang–Turk, paper 003 §4), shared by
//! `examples/rbf_curve_2d.rs`, `examples/neural_curve.rs` and `benches/neural.rs`.
//!
//! The curve is `r(t) = 0.6 + 0.15 cos 3t` in polar coordinates (a rounded trefoil, diameter
//! about 1.3). Constraints: 30 on-curve points at `t = 2πk/30` (value 0), 15 inside points at
//! `0.5 r(t)` and 15 outside points at `1.4 r(t)`, both at `t = 2πj/15`. zeroset's fields are
//! negative inside: the inside points take −1 and the outside points +1 (the paper's signs
//! flipped).

#![allow(dead_code)] // each example uses what it needs

use std::f64::consts::{PI, TAU};

use zeroset::core::geometry::Point2;

/// Points of each kind.
pub const ON_CURVE: usize = 30;
pub const INSIDE: usize = 15;
pub const OUTSIDE: usize = 15;
/// Radial scales of the inside and outside points.
pub const INSIDE_SCALE: f64 = 0.5;
pub const OUTSIDE_SCALE: f64 = 1.4;

/// `r(t) = 0.6 + 0.15 cos 3t`.
pub fn radius(t: f64) -> f64 {
    0.6 + 0.15 * (3.0 * t).cos()
}

/// The point at angle `t` and `scale · r(t)` from the origin.
pub fn curve_point(t: f64, scale: f64) -> Point2 {
    let r = scale * radius(t);
    [r * t.cos(), r * t.sin()]
}

/// The area enclosed by the curve, `½ ∫ r² dt = π (0.6² + 0.15²/2)`.
pub fn true_area() -> f64 {
    PI * (0.6 * 0.6 + 0.15 * 0.15 / 2.0)
}

/// What a constraint point prescribes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    OnCurve,
    Inside,
    Outside,
}

impl Kind {
    /// The prescribed value, in zeroset's negative-inside convention (the paper's signs
    /// flipped).
    pub fn value(self) -> f64 {
        match self {
            Kind::OnCurve => 0.0,
            Kind::Inside => -1.0,
            Kind::Outside => 1.0,
        }
    }
}

/// A constraint point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Site {
    pub point: Point2,
    pub kind: Kind,
    /// Its angle `t`.
    pub t: f64,
}

/// The 60 constraint points: on-curve, then inside, then outside.
pub fn sites() -> Vec<Site> {
    let mut out = Vec::with_capacity(ON_CURVE + INSIDE + OUTSIDE);
    for (kind, count, scale) in [
        (Kind::OnCurve, ON_CURVE, 1.0),
        (Kind::Inside, INSIDE, INSIDE_SCALE),
        (Kind::Outside, OUTSIDE, OUTSIDE_SCALE),
    ] {
        for k in 0..count {
            let t = TAU * k as f64 / count as f64;
            out.push(Site {
                point: curve_point(t, scale),
                kind,
                t,
            });
        }
    }
    out
}

/// The points and targets of the sites.
pub fn points_and_targets(sites: &[Site]) -> (Vec<Point2>, Vec<f64>) {
    sites.iter().map(|s| (s.point, s.kind.value())).unzip()
}
