//! Smooth activations and their first three derivatives.
//!
//! The curvature loss differentiates the net twice in its input and once more in its
//! parameters, so an activation needs `σ`, `σ'`, `σ''` and `σ'''`; ReLU would make every
//! second derivative zero (the curvature term would vanish), so only smooth ones are offered.
//!
//! | activation | `σ(a)` | `σ'(a)` | `σ''(a)` | `σ'''(a)` |
//! |---|---|---|---|---|
//! | [`Activation::Tanh`] | `t = tanh a` | `s = 1 − t²` | `−2 t s` | `−2 s (1 − 3t²)` |
//! | [`Activation::Softplus`] | `ln(1 + eᵃ)` | `p = 1/(1 + e⁻ᵃ)` | `p (1 − p)` | `p (1 − p)(1 − 2p)` |
//!
//! `tanh` is computed here rather than by the C library so that it vectorises: with
//! `e = expm1(−2|a|)`, `tanh a = sign(a) · (−e)/(e + 2)` and `1 − t² = 4 e^{−2|a|}/(e + 2)²`
//! (both without cancellation). `expm1` reduces its argument by `k ln 2` (Cody–Waite, two
//! constants) to `|r| ≤ ln 2 / 2` and sums the Taylor series to `r¹³` (truncation below
//! `1e-17` relative). Measured against `f64::tanh` over `[−30, 30]` the error is within
//! 2 units in the last place; `tests` check 4. The same code runs in training and evaluation,
//! written as plain `*`/`+` (no fused multiply-add), so every instruction set gives the same
//! bits. Softplus uses the C library's `exp` and `ln_1p` (correct, not vectorised).

/// A smooth activation function.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Activation {
    /// `tanh a` — the default, and the activation of the paper-set-up benchmarks.
    #[default]
    Tanh,
    /// `ln(1 + eᵃ)`: a smooth ReLU.
    Softplus,
}

impl Activation {
    /// The name used by the CLI and the field file (`tanh`, `softplus`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Tanh => "tanh",
            Self::Softplus => "softplus",
        }
    }

    /// The activation called `name` (`tanh`, `softplus`), if any.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "tanh" => Some(Self::Tanh),
            "softplus" => Some(Self::Softplus),
            _ => None,
        }
    }

    /// The code stored in field files (0 = tanh, 1 = softplus).
    pub(crate) fn code(self) -> u32 {
        match self {
            Self::Tanh => 0,
            Self::Softplus => 1,
        }
    }

    /// The activation of a field-file code.
    pub(crate) fn from_code(code: u32) -> Option<Self> {
        match code {
            0 => Some(Self::Tanh),
            1 => Some(Self::Softplus),
            _ => None,
        }
    }

    /// `σ(a)`.
    #[inline(always)]
    pub fn value(self, a: f64) -> f64 {
        match self {
            Self::Tanh => tanh_parts(a).0,
            Self::Softplus => softplus_parts(a).0,
        }
    }

    /// `(σ(a), σ'(a))`.
    #[inline(always)]
    pub fn value_d1(self, a: f64) -> (f64, f64) {
        match self {
            Self::Tanh => tanh_parts(a),
            Self::Softplus => {
                let (v, p, _) = softplus_all(a);
                (v, p)
            }
        }
    }

    /// `[σ(a), σ'(a), σ''(a), σ'''(a)]`.
    #[inline(always)]
    pub fn all(self, a: f64) -> [f64; 4] {
        match self {
            Self::Tanh => {
                let (t, s) = tanh_parts(a);
                [t, s, -2.0 * t * s, -2.0 * s * (1.0 - 3.0 * t * t)]
            }
            Self::Softplus => {
                let (v, p, q) = softplus_all(a);
                // q = p (1 − p), computed without cancellation.
                [v, p, q, q * (1.0 - 2.0 * p)]
            }
        }
    }
}

/// `ln 2` split for Cody–Waite reduction: `LN2_HI` has its low 32 bits zero, so `k · LN2_HI`
/// is exact for `|k| < 2²⁰`.
const LN2_HI: f64 = 6.931_471_803_691_238e-1;
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
const LOG2_E: f64 = std::f64::consts::LOG2_E;
/// `1.5 · 2⁵²`: adding it rounds to an integer, held in the low mantissa bits.
const ROUND_SHIFT: f64 = 6_755_399_441_055_744.0;

/// `(eʸ − 1, eʸ)` for `y ∈ [−708, 0]` (the only range `tanh` needs), branch-free, both with a
/// small relative error.
#[inline(always)]
fn expm1_nonpositive(y: f64) -> (f64, f64) {
    let shifted = y * LOG2_E + ROUND_SHIFT;
    let kf = shifted - ROUND_SHIFT;
    let k = (shifted.to_bits() as i64).wrapping_sub(ROUND_SHIFT.to_bits() as i64);
    let two_k = f64::from_bits(((k + 1023) as u64) << 52);
    let r = (y - kf * LN2_HI) - kf * LN2_LO;
    // Taylor series of eʳ − 1 to r¹³ (Horner).
    const C: [f64; 12] = [
        1.0 / 2.0,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5_040.0,
        1.0 / 40_320.0,
        1.0 / 362_880.0,
        1.0 / 3_628_800.0,
        1.0 / 39_916_800.0,
        1.0 / 479_001_600.0,
        1.0 / 6_227_020_800.0,
    ];
    let mut p = C[11];
    for &c in C[..11].iter().rev() {
        p = p * r + c;
    }
    let em1 = r + r * r * p;
    (two_k * em1 + (two_k - 1.0), two_k * (1.0 + em1))
}

/// `(tanh a, 1 − tanh² a)`.
#[inline(always)]
fn tanh_parts(a: f64) -> (f64, f64) {
    // A comparison, not `f64::max`, so that a NaN stays NaN. Below −708, 2ᵏ would leave the
    // normal range; tanh is ±1 there and 1 − t² < 1e-307.
    let y = -2.0 * a.abs();
    let y = if y < -708.0 { -708.0 } else { y };
    let (e, ey) = expm1_nonpositive(y);
    // One division for both (the vector divider is the slow unit).
    let inv = 1.0 / (e + 2.0);
    let t = (-e * inv).copysign(a);
    let s = 4.0 * ey * (inv * inv);
    (t, s)
}

#[inline(always)]
fn softplus_parts(a: f64) -> (f64, f64) {
    let (v, p, _) = softplus_all(a);
    (v, p)
}

/// `(softplus a, σ'(a) = p, σ''(a) = p (1 − p))`.
#[inline(always)]
fn softplus_all(a: f64) -> (f64, f64, f64) {
    let e = (-a.abs()).exp();
    let v = a.max(0.0) + e.ln_1p();
    let big = 1.0 / (1.0 + e);
    let small = e / (1.0 + e);
    let p = if a >= 0.0 { big } else { small };
    (v, p, big * small)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ulps(a: f64, b: f64) -> f64 {
        if a == b {
            return 0.0;
        }
        (a - b).abs() / (f64::EPSILON * a.abs().max(b.abs()).max(f64::MIN_POSITIVE))
    }

    #[test]
    fn tanh_matches_the_c_library() {
        let mut worst: f64 = 0.0;
        for i in -300_000..=300_000 {
            let a = i as f64 * 1e-4 + 1.234_567e-7;
            let (t, s) = tanh_parts(a);
            worst = worst.max(ulps(t, a.tanh()));
            let exact_s = 1.0 / a.cosh().powi(2);
            assert!(
                ulps(s, exact_s) < 8.0 || (s - exact_s).abs() < 1e-300,
                "{a}: {s} vs {exact_s}"
            );
        }
        assert!(worst <= 4.0, "{worst} ulps");
        for a in [
            0.0,
            -0.0,
            1e-300,
            -1e-20,
            19.0,
            25.0,
            -700.0,
            1e308,
            f64::INFINITY,
        ] {
            let (t, _) = tanh_parts(a);
            assert!(ulps(t, a.tanh()) <= 4.0, "{a}: {t}");
        }
        assert!(tanh_parts(f64::NAN).0.is_nan());
    }

    #[test]
    fn derivatives_match_finite_differences() {
        for act in [Activation::Tanh, Activation::Softplus] {
            for a in [-3.1, -0.7, 0.0, 0.2, 1.3, 4.0] {
                let d = act.all(a);
                let h = 1e-5;
                for k in 0..3 {
                    let fd = (act.all(a + h)[k] - act.all(a - h)[k]) / (2.0 * h);
                    assert!(
                        (fd - d[k + 1]).abs() < 1e-8,
                        "{act:?} {a} {k}: {fd} vs {}",
                        d[k + 1]
                    );
                }
                assert_eq!(act.value(a), d[0]);
                assert_eq!(act.value_d1(a), (d[0], d[1]));
            }
        }
        assert!((Activation::Softplus.value(0.0) - 2f64.ln()).abs() < 1e-16);
        assert_eq!(Activation::Softplus.value(800.0), 800.0);
        assert_eq!(Activation::Softplus.value(-800.0), 0.0);
    }

    #[test]
    fn names_and_codes_round_trip() {
        for a in [Activation::Tanh, Activation::Softplus] {
            assert_eq!(Activation::from_name(a.name()), Some(a));
            assert_eq!(Activation::from_code(a.code()), Some(a));
        }
        assert_eq!(Activation::from_name("relu"), None);
        assert_eq!(Activation::from_code(7), None);
    }
}
