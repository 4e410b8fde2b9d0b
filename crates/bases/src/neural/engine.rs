//! The batched forward pass with input jets, and its reverse pass.
//!
//! A chunk of `n` points is pushed through the net as a block of columns. Without jets there is
//! one column per point (the value). With jets every point has `C = 1 + D + D(D+1)/2` columns:
//! its value, its `D` first derivatives `∂ₖ` and its packed second derivatives `∂ₖ∂ₗ`, `k ≤ l`
//! (see `net::pairs`). The columns are grouped into `C` blocks of `n` (block `b` holds component
//! `b` of every point), so every layer's activations are a `width × (C·n)` column-major matrix
//! whose blocks are contiguous:
//!
//! ```text
//! column b·n + p  =  component b of point p;     entry (j, c) at  j + width · c.
//! ```
//!
//! A hidden layer maps the jets of its input `h` to those of `a = W h + b` — one matrix product
//! (`W` against all `C·n` columns; the bias only enters the value block) — and then through the
//! activation with the chain rule,
//!
//! ```text
//! σ(a),   ∂ₖσ(a) = σ'(a) aₖ,   ∂ₖ∂ₗσ(a) = σ''(a) aₖ aₗ + σ'(a) aₖₗ.
//! ```
//!
//! The first layer's jets are known in closed form (`aₖ = W₁[:, k]/h`, `aₖₗ = 0`, `h` the input
//! scale), so its product is skipped. The reverse pass takes the adjoints of the output's
//! columns and runs the same steps backwards: per layer the adjoint of the activation's chain
//! rule (below), then two products, `W̄ += Ā Hᵀ` and `H̄ = Wᵀ Ā`. For `ā` (value), `āₖ`, `āₖₗ`:
//!
//! ```text
//! āₖₗ = H̄ₖₗ σ',
//! āₖ  = ḡₖ σ' + σ'' Σₗ H̄ₖₗ aₗ · (2 if k = l),
//! ā   = h̄ σ' + σ'' Σₖ ḡₖ aₖ + Σₖₗ H̄ₖₗ (σ''' aₖ aₗ + σ'' aₖₗ).
//! ```
//!
//! All products are faer's, sequential (`Par::Seq`): the parallelism is across chunks, whose
//! partial gradients the caller adds in chunk order, so the bits do not depend on the thread
//! count. The element-wise loops run under `pulp`'s dispatch so that they vectorise for the
//! machine; they use plain `*` and `+`, which every instruction set rounds the same way.

use faer::linalg::matmul::matmul;
use faer::{Accum, MatMut, MatRef, Par};
use zeroset_field_core::geometry::Point;

use super::Activation;
use super::field::NeuralField;
use super::net::Layout;

/// The buffers of one chunk, kept between steps.
#[derive(Debug, Clone, Default)]
pub(crate) struct Work {
    /// Points in the chunk.
    n: usize,
    /// Whether the chunk carries jets.
    jets: bool,
    /// `D × n` scaled inputs `u = (x − c)/h`.
    u: Vec<f64>,
    /// Per hidden layer, `w × cols`: pre-activations (the first layer: the value block only).
    a: Vec<Vec<f64>>,
    /// Per hidden layer, `w × cols`: activations (after dropout).
    h: Vec<Vec<f64>>,
    /// Per hidden layer, `w × n`: `σ'`, and with jets `σ''`, `σ'''` at the values.
    d1: Vec<Vec<f64>>,
    d2: Vec<Vec<f64>>,
    d3: Vec<Vec<f64>>,
    /// Per hidden layer, `w × n`: the dropout factors (0 or `1/(1 − rate)`), when dropout is on.
    pub mask: Vec<Vec<f64>>,
    /// The output's columns (`f` and its jets).
    pub f: Vec<f64>,
    /// The adjoints of the output's columns, set by the caller before [`backward`].
    pub fbar: Vec<f64>,
    /// Scratch for the reverse pass (`width_max × cols` each).
    hbar: Vec<f64>,
    abar: Vec<f64>,
    /// The first layer's constant jets: `W₁[:, k]/h` per `k`, then their products per pair.
    g1: Vec<f64>,
    /// This chunk's gradient (the caller zeroes it).
    pub grad: Vec<f64>,
    /// Whether the last hidden layer skips its second derivatives (see [`lean`]).
    lean: bool,
    /// The lean last layer's `U = w_out ⊙ mask ⊙ σ'` (`w × n`), `V = Wᵀ U` (`w' × n`) and
    /// their adjoints.
    lu: Vec<f64>,
    lv: Vec<f64>,
    lubar: Vec<f64>,
    lvbar: Vec<f64>,
}

/// `1 + D + D(D+1)/2`: the columns of one point with jets.
pub(crate) fn jet_columns(d: usize) -> usize {
    1 + d + d * (d + 1) / 2
}

fn resize(v: &mut Vec<f64>, len: usize) {
    v.resize(len, 0.0);
}

/// Bytes [`Work::prepare`] allocates for `n` points of `layout`'s net, at most (the lean
/// variant of the last layer counted as the full one), in saturating arithmetic: checked
/// before training starts.
pub(crate) fn work_bytes(layout: &Layout, n: usize, jets: bool, dropout: bool) -> u64 {
    let (d, n) = (layout.dims[0] as u64, n as u64);
    let cols = if jets {
        n.saturating_mul(jet_columns(layout.dims[0]) as u64)
    } else {
        n
    };
    let hidden = layout.hidden();
    let mut values = d.saturating_mul(n);
    for l in 0..hidden {
        let w = layout.dims[l + 1] as u64;
        let per_point = 2 * cols + n + if jets { 2 * n } else { 0 } + if dropout { n } else { 0 };
        values = values.saturating_add(w.saturating_mul(per_point));
    }
    let wmax = layout.max_width() as u64;
    // f, fbar; hbar, abar; g1; grad; lu, lubar, lv, lvbar.
    values = values
        .saturating_add(2 * cols)
        .saturating_add(wmax.saturating_mul(2 * cols))
        .saturating_add(wmax.saturating_mul(d + d * (d + 1) / 2))
        .saturating_add(layout.total as u64)
        .saturating_add(wmax.saturating_mul(4 * n));
    values.saturating_mul(8)
}

impl Work {
    /// Sizes the buffers for `n` points (with or without jets) of `layout`'s net.
    pub fn prepare(&mut self, layout: &Layout, n: usize, jets: bool, dropout: bool) {
        let d = layout.dims[0];
        let cols = if jets { n * jet_columns(d) } else { n };
        let hidden = layout.hidden();
        self.n = n;
        self.jets = jets;
        self.lean = jets && hidden >= 2;
        resize(&mut self.u, d * n);
        for v in [
            &mut self.a,
            &mut self.h,
            &mut self.d1,
            &mut self.d2,
            &mut self.d3,
            &mut self.mask,
        ] {
            v.resize_with(hidden, Vec::new);
        }
        for l in 0..hidden {
            let w = layout.dims[l + 1];
            let layer_cols = if self.lean && l + 1 == hidden {
                n * (1 + d)
            } else {
                cols
            };
            resize(&mut self.a[l], w * layer_cols);
            resize(&mut self.h[l], w * layer_cols);
            resize(&mut self.d1[l], w * n);
            let jet_len = if jets { w * n } else { 0 };
            resize(&mut self.d2[l], jet_len);
            resize(&mut self.d3[l], jet_len);
            resize(&mut self.mask[l], if dropout { w * n } else { 0 });
        }
        resize(&mut self.f, cols);
        resize(&mut self.fbar, cols);
        let wmax = layout.max_width();
        resize(&mut self.hbar, wmax * cols);
        resize(&mut self.abar, wmax * cols);
        let w1 = layout.dims[1];
        resize(&mut self.g1, w1 * (d + d * (d + 1) / 2));
        resize(&mut self.grad, layout.total);
        let (w, wp) = if self.lean {
            (layout.dims[hidden], layout.dims[hidden - 1])
        } else {
            (0, 0)
        };
        resize(&mut self.lu, w * n);
        resize(&mut self.lubar, w * n);
        resize(&mut self.lv, wp * n);
        resize(&mut self.lvbar, wp * n);
    }
}

fn mat(data: &[f64], nrows: usize, ncols: usize) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(data, nrows, ncols)
}

fn mat_mut(data: &mut [f64], nrows: usize, ncols: usize) -> MatMut<'_, f64> {
    MatMut::from_column_major_slice_mut(data, nrows, ncols)
}

/// Fills `h`, `d1` (and with jets `d2`, `d3`) from the pre-activations `a` (all `len` long).
/// One loop per activation, so that the loop body has no branch and vectorises.
#[inline(always)]
fn activate(
    act: Activation,
    a: &[f64],
    h: &mut [f64],
    d1: &mut [f64],
    jets: Option<(&mut [f64], &mut [f64])>,
) {
    #[inline(always)]
    fn run<F: Fn(f64) -> [f64; 4]>(
        all: F,
        a: &[f64],
        h: &mut [f64],
        d1: &mut [f64],
        jets: Option<(&mut [f64], &mut [f64])>,
    ) {
        match jets {
            None => {
                for ((a, h), d1) in a.iter().zip(h.iter_mut()).zip(d1.iter_mut()) {
                    let [v, s, _, _] = all(*a);
                    (*h, *d1) = (v, s);
                }
            }
            Some((d2, d3)) => {
                for ((((a, h), d1), d2), d3) in a
                    .iter()
                    .zip(h.iter_mut())
                    .zip(d1.iter_mut())
                    .zip(d2.iter_mut())
                    .zip(d3.iter_mut())
                {
                    [*h, *d1, *d2, *d3] = all(*a);
                }
            }
        }
    }
    match act {
        Activation::Tanh => run(|a| Activation::Tanh.all(a), a, h, d1, jets),
        Activation::Softplus => run(|a| Activation::Softplus.all(a), a, h, d1, jets),
    }
}

/// The forward pass of `points` through `net` into `work` (prepared for them). Dropout
/// factors, if `work.mask` holds them, multiply every hidden activation and its jets.
pub(crate) fn forward<const D: usize>(net: &NeuralField<D>, points: &[Point<D>], work: &mut Work) {
    pulp::Arch::new().dispatch(Forward { net, points, work });
}

/// [`forward`], compiled for the instruction set `pulp` picks (the body is inlined into
/// `with_simd`, so the element-wise loops vectorise for it).
struct Forward<'a, const D: usize> {
    net: &'a NeuralField<D>,
    points: &'a [Point<D>],
    work: &'a mut Work,
}

impl<const D: usize> pulp::WithSimd for Forward<'_, D> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        forward_imp(self.net, self.points, self.work);
    }
}

#[inline(always)]
fn forward_imp<const D: usize>(net: &NeuralField<D>, points: &[Point<D>], work: &mut Work) {
    let layout = net.layout();
    let params = net.parameters();
    let act = net.architecture().activation();
    let n = work.n;
    debug_assert_eq!(points.len(), n);
    let jets = work.jets;
    let np = D * (D + 1) / 2;
    let hidden = layout.hidden();
    let (centre, scale) = (net.centre(), net.input_scale());
    for (p, x) in points.iter().enumerate() {
        for k in 0..D {
            work.u[k + D * p] = (x[k] - centre[k]) / scale;
        }
    }
    let lean = work.lean;
    let Work {
        u,
        a,
        h,
        d1,
        d2,
        d3,
        mask,
        f,
        g1,
        lu,
        lv,
        ..
    } = work;
    for l in 0..hidden {
        let skip_hessian = lean && l + 1 == hidden;
        let w = layout.dims[l + 1];
        let wn = w * n;
        let weights = layout.weight(params, l);
        let bias = layout.bias(params, l);
        let (h_done, h_rest) = h.split_at_mut(l);
        let h_l = &mut h_rest[0];
        let a_l = &mut a[l];
        if l == 0 {
            // a = W₁ u + b₁, value block only.
            for p in 0..n {
                let col = &mut a_l[w * p..w * (p + 1)];
                col.copy_from_slice(bias);
                for k in 0..D {
                    let uk = u[k + D * p];
                    let wk = &weights[w * k..w * (k + 1)];
                    for (c, wjk) in col.iter_mut().zip(wk) {
                        *c += wjk * uk;
                    }
                }
            }
        } else {
            let prev = layout.dims[l];
            let cols = h_l.len() / w;
            matmul(
                mat_mut(a_l, w, cols),
                Accum::Replace,
                mat(weights, w, prev),
                mat(&h_done[l - 1][..prev * cols], prev, cols),
                1.0,
                Par::Seq,
            );
            for p in 0..n {
                for (c, b) in a_l[w * p..w * (p + 1)].iter_mut().zip(bias) {
                    *c += b;
                }
            }
        }
        let a_l = &a[l];
        if jets {
            activate(
                act,
                &a_l[..wn],
                &mut h_l[..wn],
                &mut d1[l],
                Some((&mut d2[l], &mut d3[l])),
            );
        } else {
            activate(act, &a_l[..wn], &mut h_l[..wn], &mut d1[l], None);
        }
        if jets {
            let (d1, d2) = (&d1[l], &d2[l]);
            if l == 0 {
                let inv = 1.0 / scale;
                for k in 0..D {
                    for j in 0..w {
                        g1[j + w * k] = weights[j + w * k] * inv;
                    }
                }
                let mut q = 0;
                for k in 0..D {
                    for m in k..D {
                        for j in 0..w {
                            g1[j + w * (D + q)] = g1[j + w * k] * g1[j + w * m];
                        }
                        q += 1;
                    }
                }
                for k in 0..D {
                    let gk = &g1[w * k..w * (k + 1)];
                    let out = &mut h_l[(1 + k) * wn..(2 + k) * wn];
                    for p in 0..n {
                        let o = &mut out[w * p..w * (p + 1)];
                        let s = &d1[w * p..w * (p + 1)];
                        for ((o, s), g) in o.iter_mut().zip(s).zip(gk) {
                            *o = s * g;
                        }
                    }
                }
                for q in 0..np {
                    let gq = &g1[w * (D + q)..w * (D + q + 1)];
                    let out = &mut h_l[(1 + D + q) * wn..(2 + D + q) * wn];
                    for p in 0..n {
                        let o = &mut out[w * p..w * (p + 1)];
                        let s = &d2[w * p..w * (p + 1)];
                        for ((o, s), g) in o.iter_mut().zip(s).zip(gq) {
                            *o = s * g;
                        }
                    }
                }
            } else {
                for k in 0..D {
                    let ak = &a_l[(1 + k) * wn..(2 + k) * wn];
                    let out = &mut h_l[(1 + k) * wn..(2 + k) * wn];
                    for ((o, s), ak) in out.iter_mut().zip(d1.iter()).zip(ak) {
                        *o = s * ak;
                    }
                }
                let mut q = 0;
                for k in 0..D {
                    for m in k..D {
                        if skip_hessian {
                            break;
                        }
                        let ak = &a_l[(1 + k) * wn..(2 + k) * wn];
                        let am = &a_l[(1 + m) * wn..(2 + m) * wn];
                        let aq = &a_l[(1 + D + q) * wn..(2 + D + q) * wn];
                        let out = &mut h_l[(1 + D + q) * wn..(2 + D + q) * wn];
                        for ((((o, s2), s1), (ak, am)), aq) in out
                            .iter_mut()
                            .zip(d2.iter())
                            .zip(d1.iter())
                            .zip(ak.iter().zip(am))
                            .zip(aq)
                        {
                            *o = s2 * ak * am + s1 * aq;
                        }
                        q += 1;
                    }
                }
            }
        }
        let m = &mask[l];
        if !m.is_empty() {
            for block in h_l.chunks_exact_mut(wn) {
                for (o, m) in block.iter_mut().zip(m.iter()) {
                    *o *= m;
                }
            }
        }
    }
    // Output: f = o · (w · h_L + b) on the value block, o · (w · jets) elsewhere.
    let last = hidden;
    let w = layout.dims[last];
    let cols = if lean { (1 + D) * n } else { f.len() };
    matmul(
        mat_mut(&mut f[..cols], 1, cols),
        Accum::Replace,
        mat(layout.weight(params, last), 1, w),
        mat(&h[last - 1][..w * cols], w, cols),
        1.0,
        Par::Seq,
    );
    let b = layout.bias(params, last)[0];
    let o = net.output_scale();
    for (c, v) in f[..cols].iter_mut().enumerate() {
        *v = if c < n { o * (*v + b) } else { o * *v };
    }
    if lean {
        let state = Layers {
            a: &a[..],
            h: &h[..],
            d1: &d1[..],
            d2: &d2[..],
            d3: &d3[..],
            mask: &mask[..],
        };
        lean_forward::<D>(net, n, state, f, lu, lv);
    }
}

/// The output's second derivatives when the last hidden layer carries no second derivatives
/// of its own ("lean"): with `a = W h' + b` that layer's pre-activation, `h'` the layer below
/// (with its packed Hessian blocks `Q_q`), `M` the dropout factors and `w` the output weights,
///
/// ```text
/// ∂ₖ∂ₗ f = o · [ Σⱼ wⱼ Mⱼ σ''(aⱼ) ∂ₖaⱼ ∂ₗaⱼ  +  Σᵢ Vᵢ Q_{kl,i} ],    V = Wᵀ (w ⊙ M ⊙ σ'(a)),
/// ```
///
/// which is `Σⱼ wⱼ Mⱼ (σ'' aₖ aₗ + σ' aₖₗ)` without forming `aₖₗ = W Q_{kl}`: one product of
/// `Wᵀ` per point instead of `D(D+1)/2` of `W` — and the reverse pass saves as many.
#[inline(always)]
fn lean_forward<const D: usize>(
    net: &NeuralField<D>,
    n: usize,
    state: Layers<'_>,
    f: &mut [f64],
    lu: &mut [f64],
    lv: &mut [f64],
) {
    let Layers {
        a, h, d1, d2, mask, ..
    } = state;
    let layout = net.layout();
    let params = net.parameters();
    let hidden = layout.hidden();
    let last = hidden - 1;
    let (w, wp) = (layout.dims[hidden], layout.dims[hidden - 1]);
    let (wn, wpn) = (w * n, wp * n);
    let w_out = layout.weight(params, hidden);
    let m = &mask[last];
    let (s1, s2) = (&d1[last], &d2[last]);
    let a_l = &a[last];
    // U = w ⊙ M ⊙ σ', then V = Wᵀ U.
    for p in 0..n {
        let r = w * p..w * (p + 1);
        for ((o, s), wj) in lu[r.clone()].iter_mut().zip(&s1[r.clone()]).zip(w_out) {
            *o = wj * s;
        }
        if !m.is_empty() {
            for (o, mj) in lu[r.clone()].iter_mut().zip(&m[r]) {
                *o *= mj;
            }
        }
    }
    matmul(
        mat_mut(lv, wp, n),
        Accum::Replace,
        mat(layout.weight(params, hidden - 1), w, wp).transpose(),
        mat(lu, w, n),
        1.0,
        Par::Seq,
    );
    let h_prev = &h[last - 1];
    let o = net.output_scale();
    let ones = vec![1.0; w];
    let mut terms = vec![0.0; w];
    let mut q = 0;
    for k in 0..D {
        for l in k..D {
            let (ak, al) = (
                &a_l[(1 + k) * wn..(2 + k) * wn],
                &a_l[(1 + l) * wn..(2 + l) * wn],
            );
            let hq = &h_prev[(1 + D + q) * wpn..(2 + D + q) * wpn];
            for p in 0..n {
                let r = w * p..w * (p + 1);
                let mrow = if m.is_empty() {
                    &ones[..]
                } else {
                    &m[r.clone()]
                };
                // The products vectorise; the sum is in `dot`'s fixed order.
                for ((((t, wo), mj), s), (x, y)) in terms
                    .iter_mut()
                    .zip(w_out)
                    .zip(mrow)
                    .zip(&s2[r.clone()])
                    .zip(ak[r.clone()].iter().zip(&al[r.clone()]))
                {
                    *t = (wo * mj) * s * x * y;
                }
                let first = dot(&terms, &ones[..w]);
                let rp = wp * p..wp * (p + 1);
                let second = dot(&lv[rp.clone()], &hq[rp]);
                f[(1 + D + q) * n + p] = o * (first + second);
            }
            q += 1;
        }
    }
}

/// `Σ xᵢ yᵢ` in a fixed order (four interleaved partial sums, then `(s₀ + s₁) + (s₂ + s₃)`).
#[inline(always)]
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let mut s = [0.0; 4];
    let (xc, xr) = x.as_chunks::<4>();
    let (yc, yr) = y.as_chunks::<4>();
    for (a, b) in xc.iter().zip(yc) {
        for i in 0..4 {
            s[i] += a[i] * b[i];
        }
    }
    let mut tail = 0.0;
    for (a, b) in xr.iter().zip(yr) {
        tail += a * b;
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// The reverse pass: adds to `work.grad` the gradient, with respect to the parameters, of
/// `Σ_c work.fbar[c] · work.f[c]` (the adjoints set by the caller), for the state left by
/// [`forward`] on the same points.
pub(crate) fn backward<const D: usize>(net: &NeuralField<D>, work: &mut Work) {
    pulp::Arch::new().dispatch(Backward { net, work });
}

/// [`backward`], compiled for the instruction set `pulp` picks.
struct Backward<'a, const D: usize> {
    net: &'a NeuralField<D>,
    work: &'a mut Work,
}

impl<const D: usize> pulp::WithSimd for Backward<'_, D> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        backward_imp(self.net, self.work);
    }
}

#[inline(always)]
fn backward_imp<const D: usize>(net: &NeuralField<D>, work: &mut Work) {
    let layout = net.layout();
    let params = net.parameters();
    let n = work.n;
    let jets = work.jets;
    let hidden = layout.hidden();
    let scale = net.input_scale();
    let lean = work.lean;
    let Work {
        u,
        a,
        h,
        d1,
        d2,
        d3,
        mask,
        fbar,
        hbar,
        abar,
        g1,
        grad,
        lu,
        lv,
        lubar,
        lvbar,
        ..
    } = work;
    let cols = fbar.len();
    let o = net.output_scale();
    for v in fbar.iter_mut() {
        *v *= o;
    }
    // Output layer (the lean last hidden layer with it).
    let last = hidden;
    let w = layout.dims[last];
    let top = if lean {
        let lean_work = LeanBack {
            u: lu,
            v: lv,
            ubar: lubar,
            vbar: lvbar,
        };
        let state = Layers {
            a: &a[..],
            h: &h[..],
            d1: &d1[..],
            d2: &d2[..],
            d3: &d3[..],
            mask: &mask[..],
        };
        lean_backward::<D>(net, n, state, fbar, hbar, abar, grad, lean_work);
        hidden - 1
    } else {
        {
            let (gw, gb) = grad[layout.weight[last]..layout.bias[last] + 1].split_at_mut(w);
            matmul(
                mat_mut(gw, w, 1),
                Accum::Add,
                mat(&h[last - 1], w, cols),
                mat(fbar, cols, 1),
                1.0,
                Par::Seq,
            );
            gb[0] += fbar[..n].iter().sum::<f64>();
        }
        let w_out = layout.weight(params, last);
        for (c, y) in fbar.iter().enumerate() {
            for (o, wj) in hbar[w * c..w * (c + 1)].iter_mut().zip(w_out) {
                *o = wj * y;
            }
        }
        hidden
    };
    for l in (0..top).rev() {
        let w = layout.dims[l + 1];
        let wn = w * n;
        let hb = &mut hbar[..w * cols];
        let ab = &mut abar[..w * cols];
        let m = &mask[l];
        if !m.is_empty() {
            for block in hb.chunks_exact_mut(wn) {
                for (o, m) in block.iter_mut().zip(m.iter()) {
                    *o *= m;
                }
            }
        }
        let (d1, d2, d3) = (&d1[l], &d2[l], &d3[l]);
        // ā for the value block (and the jet blocks), in passes over whole blocks.
        let (ab_v, ab_jets) = ab.split_at_mut(wn);
        for ((o, hb), s) in ab_v.iter_mut().zip(hb[..wn].iter()).zip(d1.iter()) {
            *o = hb * s;
        }
        if jets {
            adjoint_jets::<D>(l == 0, w, n, hb, &a[l], g1, d1, d2, d3, ab_v, ab_jets);
        } else {
            for (o, hb) in ab_jets.iter_mut().zip(&hb[wn..]) {
                *o = *hb;
            }
        }
        let ab = &abar[..w * cols];
        let (gw, gb) = grad[layout.weight[l]..layout.bias[l] + w]
            .split_at_mut(layout.bias[l] - layout.weight[l]);
        for p in 0..n {
            for (g, v) in gb.iter_mut().zip(&ab[w * p..w * (p + 1)]) {
                *g += v;
            }
        }
        if l > 0 {
            let prev = layout.dims[l];
            matmul(
                mat_mut(gw, w, prev),
                Accum::Add,
                mat(ab, w, cols),
                mat(&h[l - 1], prev, cols).transpose(),
                1.0,
                Par::Seq,
            );
            matmul(
                mat_mut(&mut hbar[..prev * cols], prev, cols),
                Accum::Replace,
                mat(layout.weight(params, l), w, prev).transpose(),
                mat(ab, w, cols),
                1.0,
                Par::Seq,
            );
        } else {
            let inv = 1.0 / scale;
            for k in 0..D {
                let gk = &mut gw[w * k..w * (k + 1)];
                for p in 0..n {
                    let uk = u[k + D * p];
                    for (g, v) in gk.iter_mut().zip(&ab[w * p..w * (p + 1)]) {
                        *g += v * uk;
                    }
                }
                if jets {
                    let block = &ab[(1 + k) * wn..(2 + k) * wn];
                    for p in 0..n {
                        for (g, v) in gk.iter_mut().zip(&block[w * p..w * (p + 1)]) {
                            *g += v * inv;
                        }
                    }
                }
            }
        }
    }
}

/// The adjoint of the activation's chain rule on the jet blocks (see the module docs):
/// adds to `ab_v` (which holds `h̄ σ'`) and fills the derivative blocks `ab_jets` (`āₖ`, then
/// `āₖₗ`) from the adjoints `hb` of all blocks. At the first layer (`first`) the jets of `a`
/// are the per-row constants of `g1` and `āₖₗ` is left alone (nothing needs it).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn adjoint_jets<const D: usize>(
    first: bool,
    w: usize,
    n: usize,
    hb: &[f64],
    a_l: &[f64],
    g1: &[f64],
    d1: &[f64],
    d2: &[f64],
    d3: &[f64],
    ab_v: &mut [f64],
    ab_jets: &mut [f64],
) {
    let wn = w * n;
    let block = |b: usize| b * wn..(b + 1) * wn;
    // āₖ = ḡₖ σ' first; ā += σ'' ḡₖ aₖ.
    for k in 0..D {
        let gk = &hb[block(1 + k)];
        let out = &mut ab_jets[block(k)];
        for ((o, g), s) in out.iter_mut().zip(gk).zip(d1) {
            *o = g * s;
        }
        if first {
            let c = &g1[w * k..w * (k + 1)];
            for p in 0..n {
                let r = w * p..w * (p + 1);
                for (((o, g), s), c) in ab_v[r.clone()]
                    .iter_mut()
                    .zip(&gk[r.clone()])
                    .zip(&d2[r])
                    .zip(c)
                {
                    *o += s * (g * c);
                }
            }
        } else {
            let ak = &a_l[block(1 + k)];
            for (((o, g), s), ak) in ab_v.iter_mut().zip(gk).zip(d2).zip(ak) {
                *o += s * (g * ak);
            }
        }
    }
    let mut q = 0;
    for k in 0..D {
        for m in k..D {
            let hq = &hb[block(1 + D + q)];
            let twice = if k == m { 2.0 } else { 1.0 };
            if first {
                let (ck, cm, cq) = (
                    &g1[w * k..w * (k + 1)],
                    &g1[w * m..w * (m + 1)],
                    &g1[w * (D + q)..w * (D + q + 1)],
                );
                for p in 0..n {
                    let r = w * p..w * (p + 1);
                    for (((o, t), s3), cq) in ab_v[r.clone()]
                        .iter_mut()
                        .zip(&hq[r.clone()])
                        .zip(&d3[r.clone()])
                        .zip(cq)
                    {
                        *o += t * (s3 * cq);
                    }
                    let (lo, hi) = ab_jets.split_at_mut(wn * (k + 1));
                    let ab_k = &mut lo[wn * k + r.start..wn * k + r.end];
                    for (((o, t), s2), cm) in ab_k
                        .iter_mut()
                        .zip(&hq[r.clone()])
                        .zip(&d2[r.clone()])
                        .zip(cm)
                    {
                        *o += s2 * (twice * t * cm);
                    }
                    if k != m {
                        let at = wn * (m - k - 1);
                        let ab_m = &mut hi[at + r.start..at + r.end];
                        for (((o, t), s2), ck) in ab_m
                            .iter_mut()
                            .zip(&hq[r.clone()])
                            .zip(&d2[r.clone()])
                            .zip(ck)
                        {
                            *o += s2 * (t * ck);
                        }
                    }
                }
            } else {
                let (ak, am, aq) = (
                    &a_l[block(1 + k)],
                    &a_l[block(1 + m)],
                    &a_l[block(1 + D + q)],
                );
                for (((((o, t), s3), s2), (ak, am)), aq) in ab_v
                    .iter_mut()
                    .zip(hq)
                    .zip(d3)
                    .zip(d2)
                    .zip(ak.iter().zip(am))
                    .zip(aq)
                {
                    *o += t * (s3 * ak * am + s2 * aq);
                }
                let (lo, hi) = ab_jets.split_at_mut(wn * (k + 1));
                let ab_k = &mut lo[block(k)];
                for (((o, t), s2), am) in ab_k.iter_mut().zip(hq).zip(d2).zip(am) {
                    *o += s2 * (twice * t * am);
                }
                if k != m {
                    let ab_m = &mut hi[wn * (m - k - 1)..wn * (m - k)];
                    for (((o, t), s2), ak) in ab_m.iter_mut().zip(hq).zip(d2).zip(ak) {
                        *o += s2 * (t * ak);
                    }
                }
                let out = &mut ab_jets[block(D + q)];
                for ((o, t), s1) in out.iter_mut().zip(hq).zip(d1) {
                    *o = t * s1;
                }
            }
            q += 1;
        }
    }
}

/// The per-layer state the forward pass leaves: pre-activations, activations, `σ'`, `σ''`,
/// `σ'''` and dropout factors (see [`Work`]).
#[derive(Clone, Copy)]
struct Layers<'a> {
    a: &'a [Vec<f64>],
    h: &'a [Vec<f64>],
    d1: &'a [Vec<f64>],
    d2: &'a [Vec<f64>],
    d3: &'a [Vec<f64>],
    mask: &'a [Vec<f64>],
}

/// The lean last layer's buffers in the reverse pass.
struct LeanBack<'a> {
    u: &'a [f64],
    v: &'a [f64],
    ubar: &'a mut [f64],
    vbar: &'a mut [f64],
}

/// The reverse pass through the output layer and a lean last hidden layer (see
/// [`lean_forward`]): adds their parameters' gradients to `grad` and leaves in `hbar` the
/// adjoints of every block of the layer below.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn lean_backward<const D: usize>(
    net: &NeuralField<D>,
    n: usize,
    state: Layers<'_>,
    ybar: &[f64],
    hbar: &mut [f64],
    abar: &mut [f64],
    grad: &mut [f64],
    lw: LeanBack<'_>,
) {
    let Layers {
        a,
        h,
        d1,
        d2,
        d3,
        mask,
    } = state;
    let layout = net.layout();
    let params = net.parameters();
    let hidden = layout.hidden();
    let last = hidden - 1;
    let (w, wp) = (layout.dims[hidden], layout.dims[hidden - 1]);
    let (wn, wpn) = (w * n, wp * n);
    let nl = (1 + D) * n;
    let w_out = layout.weight(params, hidden);
    let w_last = layout.weight(params, last);
    let m = &mask[last];
    let (s1, s2, s3) = (&d1[last], &d2[last], &d3[last]);
    let (a_l, h_l, h_prev) = (&a[last], &h[last], &h[last - 1]);
    let np = D * (D + 1) / 2;
    // Output weights and bias through the value and gradient outputs.
    {
        let (gw, gb) = grad[layout.weight[hidden]..layout.bias[hidden] + 1].split_at_mut(w);
        matmul(
            mat_mut(gw, w, 1),
            Accum::Add,
            mat(&h_l[..w * nl], w, nl),
            mat(&ybar[..nl], nl, 1),
            1.0,
            Par::Seq,
        );
        gb[0] += ybar[..n].iter().sum::<f64>();
    }
    // V̄ = Σ_q ȳ_q Q_q and the adjoints of the Hessian blocks below, Q̄_q = ȳ_q V.
    lw.vbar.fill(0.0);
    for q in 0..np {
        let hq = &h_prev[(1 + D + q) * wpn..(2 + D + q) * wpn];
        let out = &mut hbar[(1 + D + q) * wpn..(2 + D + q) * wpn];
        for p in 0..n {
            let y = ybar[(1 + D + q) * n + p];
            let r = wp * p..wp * (p + 1);
            for ((vb, qv), (ob, v)) in lw.vbar[r.clone()]
                .iter_mut()
                .zip(&hq[r.clone()])
                .zip(out[r.clone()].iter_mut().zip(&lw.v[r]))
            {
                *vb += y * qv;
                *ob = y * v;
            }
        }
    }
    // W̄ += U V̄ᵀ, Ū = W V̄.
    matmul(
        mat_mut(&mut grad[layout.weight[last]..layout.bias[last]], w, wp),
        Accum::Add,
        mat(lw.u, w, n),
        mat(lw.vbar, wp, n).transpose(),
        1.0,
        Par::Seq,
    );
    matmul(
        mat_mut(lw.ubar, w, n),
        Accum::Replace,
        mat(w_last, w, wp),
        mat(lw.vbar, wp, n),
        1.0,
        Par::Seq,
    );
    // Ā of the last hidden layer (value and gradient blocks), and the rest of w̄_out: per
    // point, loops over the neurons with the point's adjoints hoisted (they vectorise).
    let gw_out = &mut grad[layout.weight[hidden]..layout.weight[hidden] + w];
    let ones = vec![1.0; w];
    let (ab_v, ab_rest) = abar[..w * nl].split_at_mut(wn);
    let mut ab_k: Vec<&mut [f64]> = ab_rest.chunks_exact_mut(wn).collect();
    let mut yq = vec![0.0; np];
    for p in 0..n {
        let r = w * p..w * (p + 1);
        let mrow = if m.is_empty() {
            &ones[..]
        } else {
            &m[r.clone()]
        };
        let yv = ybar[p];
        let yk: [f64; D] = std::array::from_fn(|k| ybar[(1 + k) * n + p]);
        for (q, y) in yq.iter_mut().enumerate() {
            *y = ybar[(1 + D + q) * n + p];
        }
        let ak: [&[f64]; D] =
            std::array::from_fn(|k| &a_l[(1 + k) * wn + r.start..(1 + k) * wn + r.end]);
        let (t1, t2, t3) = (&s1[r.clone()], &s2[r.clone()], &s3[r.clone()]);
        let ub = &lw.ubar[r.clone()];
        for j in 0..w {
            let mj = mrow[j];
            let wj = w_out[j] * mj;
            let mut gout = ub[j] * mj * t1[j];
            let mut s2bar = 0.0;
            let mut av = (w_out[j] * yv) * mj * t1[j] + (ub[j] * wj) * t2[j];
            let mut akbar = [0.0; D];
            let mut q = 0;
            for k in 0..D {
                let a = ak[k][j];
                let gk = (w_out[j] * yk[k]) * mj;
                av += gk * t2[j] * a;
                akbar[k] += gk * t1[j];
                for l in k..D {
                    let b = ak[l][j];
                    let y = yq[q];
                    s2bar += y * wj * a * b;
                    gout += y * mj * t2[j] * a * b;
                    let yw = y * wj * t2[j];
                    if k == l {
                        akbar[k] += 2.0 * yw * a;
                    } else {
                        akbar[k] += yw * b;
                        akbar[l] += yw * a;
                    }
                    q += 1;
                }
            }
            av += s2bar * t3[j];
            ab_v[r.start + j] = av;
            for (block, v) in ab_k.iter_mut().zip(akbar) {
                block[r.start + j] = v;
            }
            gw_out[j] += gout;
        }
    }
    // Through a = W h' + b on the value and gradient blocks.
    let gb_last = &mut grad[layout.bias[last]..layout.bias[last] + w];
    for p in 0..n {
        for (g, v) in gb_last.iter_mut().zip(&abar[w * p..w * (p + 1)]) {
            *g += v;
        }
    }
    let gw_last = &mut grad[layout.weight[last]..layout.bias[last]];
    matmul(
        mat_mut(gw_last, w, wp),
        Accum::Add,
        mat(&abar[..w * nl], w, nl),
        mat(&h_prev[..wp * nl], wp, nl).transpose(),
        1.0,
        Par::Seq,
    );
    matmul(
        mat_mut(&mut hbar[..wp * nl], wp, nl),
        Accum::Replace,
        mat(w_last, w, wp).transpose(),
        mat(&abar[..w * nl], w, nl),
        1.0,
        Par::Seq,
    );
}
