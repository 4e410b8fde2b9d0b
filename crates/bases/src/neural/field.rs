//! The trained net as a field: evaluation with exact derivatives, batched evaluation.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use zeroset_field_core::field::{ScalarField, VALUES_CHUNK};
use zeroset_field_core::geometry::{Aabb, Point};

use super::engine::{self, Work};
use super::net::{Architecture, Layout, pair_index, pairs};
use super::{NeuralError, STREAM_INIT};

/// A multilayer perceptron `f: Rᴰ → R` as a field:
///
/// ```text
/// f(x) = o · N((x − c) / h),   N(u) = w_out · σ(W_L … σ(W₁ u + b₁) … + b_L) + b_out,
/// ```
///
/// with the input map (centre `c`, scale `h > 0`) and the output scale `o` fixed (not trained):
/// [`NeuralField::initial`] maps the domain's centre to 0 and its longest half-extent to 1, so
/// that the default initialisation suits any box. [`ScalarField::gradient`] and
/// [`NeuralField::hessian`] are exact (forward-mode derivatives through every layer).
///
/// Evaluation: [`ScalarField::value`] runs one point through the layers with plain loops;
/// [`ScalarField::values`] pushes fixed chunks of
/// [`VALUES_CHUNK`](zeroset_field_core::field::VALUES_CHUNK) points through faer's matrix
/// products, in parallel. Both are deterministic and independent of the thread count; they
/// agree to rounding (a few units in the last place), not bit for bit, because the products
/// sum in another order.
#[derive(Debug, Clone, PartialEq)]
pub struct NeuralField<const D: usize> {
    arch: Architecture,
    layout: Layout,
    params: Vec<f64>,
    centre: Point<D>,
    input_scale: f64,
    output_scale: f64,
    bounds: Aabb<D>,
}

/// A point's value, gradient and packed Hessian (see [`NeuralField::jet`]).
type Jet<const D: usize> = (f64, Point<D>, Vec<f64>);

impl<const D: usize> NeuralField<D> {
    /// A net with the given parameters (layout in the [module docs](super)), input map and
    /// output scale, meaningful over `bounds`.
    ///
    /// # Errors
    /// [`NeuralError::ParameterCount`] if `params` does not fit `arch`;
    /// [`NeuralError::InvalidParameter`] for a non-finite parameter or centre, an input scale
    /// that is not finite and positive, or an output scale that is not finite and non-zero.
    pub fn new(
        arch: Architecture,
        params: Vec<f64>,
        centre: Point<D>,
        input_scale: f64,
        output_scale: f64,
        bounds: Aabb<D>,
    ) -> Result<Self, NeuralError> {
        let layout = Layout::new(D, arch.widths());
        if params.len() != layout.total {
            return Err(NeuralError::ParameterCount {
                expected: layout.total,
                got: params.len(),
            });
        }
        if let Some(v) = params.iter().chain(&centre).find(|v| !v.is_finite()) {
            return Err(NeuralError::InvalidParameter {
                name: "network parameter",
                value: *v,
                expected: "finite values",
            });
        }
        if !(input_scale.is_finite() && input_scale > 0.0) {
            return Err(NeuralError::InvalidParameter {
                name: "input scale",
                value: input_scale,
                expected: "a finite value > 0",
            });
        }
        if !(output_scale.is_finite() && output_scale != 0.0) {
            return Err(NeuralError::InvalidParameter {
                name: "output scale",
                value: output_scale,
                expected: "a finite value ≠ 0",
            });
        }
        Ok(Self {
            arch,
            layout,
            params,
            centre,
            input_scale,
            output_scale,
            bounds,
        })
    }

    /// The untrained net for `domain`: Glorot (Xavier) uniform weights,
    /// `W[j, k] ~ U(−a, a)` with `a = √(6 / (fan_in + fan_out))`, zero biases, drawn from
    /// ChaCha8 seeded with `seed` (stream 0) in parameter order; the input map sends the
    /// domain's centre to 0 and scales by its longest half-extent (1 for a point); output
    /// scale 1.
    pub fn initial(arch: Architecture, domain: Aabb<D>, seed: u64) -> Self {
        let layout = Layout::new(D, arch.widths());
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(STREAM_INIT);
        let mut params = vec![0.0; layout.total];
        for l in 0..layout.layers() {
            let (fan_in, fan_out) = (layout.dims[l], layout.dims[l + 1]);
            let a = (6.0 / (fan_in + fan_out) as f64).sqrt();
            for w in &mut params[layout.weight[l]..layout.bias[l]] {
                *w = (2.0 * rng.random::<f64>() - 1.0) * a;
            }
        }
        let half = domain.extent().into_iter().fold(0.0, f64::max) / 2.0;
        Self {
            arch,
            layout,
            params,
            centre: domain.center(),
            input_scale: if half > 0.0 { half } else { 1.0 },
            output_scale: 1.0,
            bounds: domain,
        }
    }

    /// The architecture.
    pub fn architecture(&self) -> &Architecture {
        &self.arch
    }

    /// The net in words: `MLP 3 → 32 → 32 → 1, tanh`.
    pub fn network(&self) -> String {
        let widths: Vec<String> = self.arch.widths().iter().map(|w| w.to_string()).collect();
        format!(
            "MLP {D} → {} → 1, {}",
            widths.join(" → "),
            self.arch.activation().name()
        )
    }

    /// All parameters, layer by layer: `W₁` (column-major, `w₁ × D`), `b₁`, `W₂`, `b₂`, …,
    /// `w_out` (`1 × w_L`), `b_out`.
    pub fn parameters(&self) -> &[f64] {
        &self.params
    }

    /// Layer `l`'s weight matrix (`dims[l+1] × dims[l]`, column-major; `l` = number of hidden
    /// layers is the output) and bias.
    ///
    /// # Panics
    /// If `l` is more than the number of hidden layers.
    pub fn layer(&self, l: usize) -> (&[f64], &[f64]) {
        (
            self.layout.weight(&self.params, l),
            self.layout.bias(&self.params, l),
        )
    }

    /// The box the field was fitted on (its [`ScalarField::bounds`]).
    pub fn domain(&self) -> Aabb<D> {
        self.bounds
    }

    /// The input map's centre `c`.
    pub fn centre(&self) -> Point<D> {
        self.centre
    }

    /// The input map's scale `h` (`u = (x − c)/h`).
    pub fn input_scale(&self) -> f64 {
        self.input_scale
    }

    /// The output scale `o`.
    pub fn output_scale(&self) -> f64 {
        self.output_scale
    }

    pub(crate) fn layout(&self) -> &Layout {
        &self.layout
    }

    pub(crate) fn parameters_mut(&mut self) -> &mut [f64] {
        &mut self.params
    }

    /// The field `x ↦ v · self((x − c)/s)`: this field, fitted in coordinates `u = (x − c)/s`
    /// with values in units of `1/v`, moved back to `x`. The CLI fits inputs scaled into
    /// `[−1, 1]ᴰ` (so that λ does not depend on their units) and saves them this way; with
    /// `v = s` a field that approximates a distance in `u` does so in `x`.
    ///
    /// # Errors
    /// [`NeuralError::InvalidParameter`] unless `s` is finite and positive, `v` finite and
    /// non-zero and `c` finite.
    pub fn transformed(&self, c: Point<D>, s: f64, v: f64) -> Result<Self, NeuralError> {
        if !(s.is_finite() && s > 0.0) || c.iter().any(|x| !x.is_finite()) {
            return Err(NeuralError::InvalidParameter {
                name: "coordinate scale",
                value: s,
                expected: "a finite value > 0 and a finite centre",
            });
        }
        if !(v.is_finite() && v != 0.0) {
            return Err(NeuralError::InvalidParameter {
                name: "value scale",
                value: v,
                expected: "a finite value ≠ 0",
            });
        }
        let map = |p: Point<D>| -> Point<D> { std::array::from_fn(|a| c[a] + s * p[a]) };
        let bounds = Aabb::new(map(self.bounds.min()), map(self.bounds.max())).map_err(|_| {
            NeuralError::InvalidParameter {
                name: "coordinate scale",
                value: s,
                expected: "a scale that keeps the box finite",
            }
        })?;
        Self::new(
            self.arch.clone(),
            self.params.clone(),
            map(self.centre),
            s * self.input_scale,
            v * self.output_scale,
            bounds,
        )
    }

    /// The same net with new last-layer weights `w_out` (length `w_L`) and bias.
    ///
    /// # Errors
    /// [`NeuralError::ParameterCount`] for a wrong length; [`NeuralError::InvalidParameter`]
    /// for a non-finite value.
    pub fn with_last_layer(&self, weights: &[f64], bias: f64) -> Result<Self, NeuralError> {
        let last = self.layout.hidden();
        let w = self.layout.dims[last];
        if weights.len() != w {
            return Err(NeuralError::ParameterCount {
                expected: w,
                got: weights.len(),
            });
        }
        if let Some(v) = weights.iter().chain([&bias]).find(|v| !v.is_finite()) {
            return Err(NeuralError::InvalidParameter {
                name: "last-layer weight",
                value: *v,
                expected: "finite values",
            });
        }
        let mut out = self.clone();
        let at = self.layout.weight[last];
        out.params[at..at + w].copy_from_slice(weights);
        out.params[self.layout.bias[last]] = bias;
        Ok(out)
    }

    /// Value, gradient and Hessian at `x` (the Hessian packed as `(k, l)`, `k ≤ l`:
    /// `f_xx, f_xy, f_yy` in 2-D, `f_xx, f_xy, f_xz, f_yy, f_yz, f_zz` in 3-D).
    pub fn jet(&self, x: &Point<D>) -> Jet<D> {
        let (f, g, h, _) = self.eval_point(x, 2);
        (f, g, h)
    }

    /// The Hessian `∇²f(x)`, exact.
    pub fn hessian(&self, x: &Point<D>) -> [[f64; D]; D] {
        let (_, _, h, _) = self.eval_point(x, 2);
        std::array::from_fn(|k| std::array::from_fn(|l| h[pair_index(D, k, l)]))
    }

    /// The last hidden layer's activations at `x` and, with `with_gradients`, their gradients
    /// (`w_L` values; gradients as `w_L` points): the learned basis (see
    /// [`HiddenBasis`](super::HiddenBasis)).
    pub fn features(&self, x: &Point<D>, with_gradients: bool) -> (Vec<f64>, Vec<Point<D>>) {
        let (_, _, _, features) = self.eval_point(x, if with_gradients { 1 } else { 0 });
        features
    }

    /// The thin-plate energy `∫_Ω f_xx² + 2 f_xy² + f_yy²` (3-D: `Σₖₗ (∂ₖ∂ₗf)²`) over the
    /// field's box, by the midpoint rule on `samples_per_axis`ᴰ cells (at least 1; capped so
    /// that there are at most 2²⁴ cells in all). Exact Hessians, batched; the same bits for any
    /// thread count.
    pub fn thin_plate_energy(&self, samples_per_axis: usize) -> f64 {
        let cap = (f64::from(1u32 << 24).powf(1.0 / D as f64)).floor() as usize;
        let n = samples_per_axis.clamp(1, cap.max(1));
        let (lo, ext) = (self.bounds.min(), self.bounds.extent());
        let total = n.pow(D as u32);
        let points: Vec<Point<D>> = (0..total)
            .map(|mut i| {
                let mut p = [0.0; D];
                for a in (0..D).rev() {
                    p[a] = lo[a] + ext[a] * ((i % n) as f64 + 0.5) / n as f64;
                    i /= n;
                }
                p
            })
            .collect();
        let measure: f64 = ext.iter().product();
        let weights: Vec<f64> = pairs(D)
            .iter()
            .map(|&(k, l)| if k == l { 1.0 } else { 2.0 })
            .collect();
        let partial: Vec<f64> = points
            .par_chunks(JET_CHUNK)
            .map_init(Work::default, |work, ps| {
                work.prepare(&self.layout, ps.len(), true, false);
                engine::forward(self, ps, work);
                let m = ps.len();
                let mut s = 0.0;
                for p in 0..m {
                    for (q, wq) in weights.iter().enumerate() {
                        let v = work.f[(1 + D + q) * m + p];
                        s += wq * v * v;
                    }
                }
                s
            })
            .collect();
        partial.iter().sum::<f64>() * measure / total as f64
    }

    /// One point through the net with jets up to `order` (0: value, 1: + gradient,
    /// 2: + Hessian); also returns the last hidden layer (and its gradients if `order ≥ 1`).
    fn eval_point(&self, x: &Point<D>, order: usize) -> (f64, Point<D>, Vec<f64>, Features<D>) {
        let layout = &self.layout;
        let act = self.arch.activation();
        let pr = pairs(D);
        let np = pr.len();
        let hidden = layout.hidden();
        let u: Point<D> = std::array::from_fn(|k| (x[k] - self.centre[k]) / self.input_scale);
        // h (value), hg[k] (gradient), hh[q] (Hessian) of the current layer, per neuron.
        let mut h: Vec<f64> = Vec::new();
        let mut hg: Vec<Vec<f64>> = Vec::new();
        let mut hh: Vec<Vec<f64>> = Vec::new();
        for l in 0..hidden {
            let w = layout.dims[l + 1];
            let weights = layout.weight(&self.params, l);
            let bias = layout.bias(&self.params, l);
            let mut a = bias.to_vec();
            let mut ag = vec![vec![0.0; w]; if order >= 1 { D } else { 0 }];
            let mut ah = vec![vec![0.0; w]; if order >= 2 { np } else { 0 }];
            if l == 0 {
                for k in 0..D {
                    for j in 0..w {
                        a[j] += weights[j + w * k] * u[k];
                    }
                }
                let inv = 1.0 / self.input_scale;
                for (k, agk) in ag.iter_mut().enumerate() {
                    for j in 0..w {
                        agk[j] = weights[j + w * k] * inv;
                    }
                }
            } else {
                let prev = layout.dims[l];
                for j in 0..w {
                    let mut s = 0.0;
                    for k in 0..prev {
                        s += weights[j + w * k] * h[k];
                    }
                    a[j] = s + bias[j];
                    for (agk, hgk) in ag.iter_mut().zip(&hg) {
                        let mut s = 0.0;
                        for k in 0..prev {
                            s += weights[j + w * k] * hgk[k];
                        }
                        agk[j] = s;
                    }
                    for (ahq, hhq) in ah.iter_mut().zip(&hh) {
                        let mut s = 0.0;
                        for k in 0..prev {
                            s += weights[j + w * k] * hhq[k];
                        }
                        ahq[j] = s;
                    }
                }
            }
            let mut nh = vec![0.0; w];
            let mut ng = vec![vec![0.0; w]; ag.len()];
            let mut nhh = vec![vec![0.0; w]; ah.len()];
            for j in 0..w {
                let [s0, s1, s2, _] = if order >= 2 {
                    act.all(a[j])
                } else {
                    let (v, d) = act.value_d1(a[j]);
                    [v, d, 0.0, 0.0]
                };
                nh[j] = s0;
                for (ngk, agk) in ng.iter_mut().zip(&ag) {
                    ngk[j] = s1 * agk[j];
                }
                for (q, &(k, m)) in pr.iter().enumerate().take(nhh.len()) {
                    nhh[q][j] = if l == 0 {
                        s2 * (ag[k][j] * ag[m][j])
                    } else {
                        s2 * ag[k][j] * ag[m][j] + s1 * ah[q][j]
                    };
                }
            }
            h = nh;
            hg = ng;
            hh = nhh;
        }
        let w = layout.dims[hidden];
        let w_out = layout.weight(&self.params, hidden);
        let b_out = layout.bias(&self.params, hidden)[0];
        let o = self.output_scale;
        let dot = |v: &[f64]| -> f64 {
            let mut s = 0.0;
            for j in 0..w {
                s += w_out[j] * v[j];
            }
            s
        };
        let f = o * (dot(&h) + b_out);
        let mut grad = [0.0; D];
        for (g, hgk) in grad.iter_mut().zip(&hg) {
            *g = o * dot(hgk);
        }
        let hess: Vec<f64> = hh.iter().map(|v| o * dot(v)).collect();
        let features_grad = if order >= 1 {
            (0..w).map(|j| std::array::from_fn(|k| hg[k][j])).collect()
        } else {
            Vec::new()
        };
        (f, grad, hess, (h, features_grad))
    }
}

/// The last hidden layer's values and gradients at a point.
type Features<const D: usize> = (Vec<f64>, Vec<Point<D>>);

/// Points per chunk of the batched evaluation with jets.
pub(crate) const JET_CHUNK: usize = 256;

impl<const D: usize> ScalarField<D> for NeuralField<D> {
    fn value(&self, p: &Point<D>) -> f64 {
        self.eval_point(p, 0).0
    }

    fn gradient(&self, p: &Point<D>) -> Point<D> {
        self.eval_point(p, 1).1
    }

    fn values(&self, points: &[Point<D>], out: &mut [f64]) {
        assert_eq!(
            points.len(),
            out.len(),
            "values: {} points but {} output slots",
            points.len(),
            out.len()
        );
        points
            .par_chunks(VALUES_CHUNK)
            .zip(out.par_chunks_mut(VALUES_CHUNK))
            .for_each_init(Work::default, |work, (ps, os)| {
                work.prepare(&self.layout, ps.len(), false, false);
                engine::forward(self, ps, work);
                os.copy_from_slice(&work.f[..ps.len()]);
            });
    }

    fn bounds(&self) -> Option<Aabb<D>> {
        Some(self.bounds)
    }
}
