//! Training: the loss, its gradient over fixed chunks, and Adam.

use std::ops::ControlFlow;
use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::{Aabb, Point};
use zeroset_field_core::limits;

use super::engine::{self, Work};
use super::field::NeuralField;
use super::net::{Architecture, pairs};
use super::{NeuralError, STREAM_AUX, STREAM_DROPOUT};

/// Points with jets per chunk of the training pass (a chunk is one rayon task).
const TRAIN_JET_CHUNK: usize = 64;
/// Points without jets per chunk.
const TRAIN_VALUE_CHUNK: usize = 256;
/// The default domain is the constraints' box grown by this fraction of its diagonal.
pub const DOMAIN_MARGIN: f64 = 0.05;
/// The most auxiliary points a fit takes (memory grows with them; 10⁷ points with their
/// derivatives through a 32-wide net are several GB).
pub const MAX_AUX_POINTS: usize = 10_000_000;

/// Where the curvature term of the loss is evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum CurvatureSites {
    /// At `P` auxiliary points drawn uniformly in the domain (the paper's method): weight
    /// `λ|Ω|/P`.
    #[default]
    Auxiliary,
    /// At the constraint points themselves (the paper's baseline (b); no auxiliary points):
    /// weight `λ|Ω|/N`.
    Constraints,
}

/// The four set-ups of the paper's experiment (§4.2, Figs. 3–4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Variant {
    /// λ = 0.05, curvature at P = 250 uniform auxiliary points (Fig. 3).
    Paper,
    /// Baseline (a): λ = 0, a plain regression of the constraints.
    NoCurvature,
    /// Baseline (b): the curvature term at the constraint points instead.
    CurvatureAtConstraints,
    /// Baseline (c): no curvature term; dropout on the hidden activations while training
    /// (rate [`DROPOUT_BASELINE_RATE`]), off when evaluating.
    Dropout,
}

impl Variant {
    /// All four, in the paper's order.
    pub const ALL: [Variant; 4] = [
        Variant::Paper,
        Variant::NoCurvature,
        Variant::CurvatureAtConstraints,
        Variant::Dropout,
    ];

    /// A short label.
    pub fn label(self) -> &'static str {
        match self {
            Variant::Paper => "λ=0.05, aux curvature",
            Variant::NoCurvature => "λ=0",
            Variant::CurvatureAtConstraints => "curvature at constraints",
            Variant::Dropout => "dropout",
        }
    }
}

/// The dropout rate of [`Variant::Dropout`]: each hidden activation is zeroed with this
/// probability (and the survivors scaled by `1/(1 − rate)`) at every step.
pub const DROPOUT_BASELINE_RATE: f64 = 0.1;

/// How to train; [`Default`] is the paper's set-up (see the [module docs](super)).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct NeuralParams {
    /// Hidden widths and activation (default 32, 32, `tanh`).
    pub architecture: Architecture,
    /// The curvature weight λ ≥ 0 (default 0.05).
    pub lambda: f64,
    /// Where the curvature term is evaluated (default: auxiliary points).
    pub curvature_at: CurvatureSites,
    /// The number `P` of auxiliary points (default 250).
    pub aux_points: usize,
    /// Draw new auxiliary points at every step (default `false`: one set, drawn once).
    pub resample_aux: bool,
    /// The dropout rate in `[0, 1)` on every hidden activation while training (default 0).
    pub dropout: f64,
    /// Adam steps (default 3000), each on every constraint and auxiliary point.
    pub steps: usize,
    /// Adam's learning rate (default 1e-2).
    pub learning_rate: f64,
    /// Adam's `β₁` (default 0.9).
    pub beta1: f64,
    /// Adam's `β₂` (default 0.999).
    pub beta2: f64,
    /// Adam's `ε` (default 1e-8).
    pub epsilon: f64,
    /// The seed of the initial weights, the auxiliary points and the dropout masks.
    pub seed: u64,
}

impl Default for NeuralParams {
    fn default() -> Self {
        Self {
            architecture: Architecture::paper(),
            lambda: 0.05,
            curvature_at: CurvatureSites::Auxiliary,
            aux_points: 250,
            resample_aux: false,
            dropout: 0.0,
            steps: 3000,
            learning_rate: 1e-2,
            beta1: 0.9,
            beta2: 0.999,
            epsilon: 1e-8,
            seed: 0,
        }
    }
}

impl NeuralParams {
    /// The set-up of one of the paper's four variants (otherwise the defaults).
    pub fn variant(v: Variant) -> Self {
        let mut p = Self::default();
        match v {
            Variant::Paper => {}
            Variant::NoCurvature => p.lambda = 0.0,
            Variant::CurvatureAtConstraints => p.curvature_at = CurvatureSites::Constraints,
            Variant::Dropout => {
                p.lambda = 0.0;
                p.dropout = DROPOUT_BASELINE_RATE;
            }
        }
        p
    }

    /// With `steps` Adam steps.
    pub fn with_steps(mut self, steps: usize) -> Self {
        self.steps = steps;
        self
    }

    /// With curvature weight `lambda`.
    pub fn with_lambda(mut self, lambda: f64) -> Self {
        self.lambda = lambda;
        self
    }

    /// With `p` auxiliary points.
    pub fn with_aux_points(mut self, p: usize) -> Self {
        self.aux_points = p;
        self
    }

    /// With this architecture.
    pub fn with_architecture(mut self, architecture: Architecture) -> Self {
        self.architecture = architecture;
        self
    }

    /// With this learning rate.
    pub fn with_learning_rate(mut self, learning_rate: f64) -> Self {
        self.learning_rate = learning_rate;
        self
    }

    /// With this seed.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// With this dropout rate.
    pub fn with_dropout(mut self, rate: f64) -> Self {
        self.dropout = rate;
        self
    }

    /// Checks every parameter's range.
    ///
    /// # Errors
    /// [`NeuralError::InvalidParameter`] naming the first parameter out of range.
    pub fn validate(&self) -> Result<(), NeuralError> {
        let bad = |name, value, expected| {
            Err(NeuralError::InvalidParameter {
                name,
                value,
                expected,
            })
        };
        if !(self.lambda.is_finite() && self.lambda >= 0.0) {
            return bad("λ (curvature weight)", self.lambda, "a finite value ≥ 0");
        }
        if !(self.learning_rate.is_finite() && self.learning_rate > 0.0) {
            return bad("learning rate", self.learning_rate, "a finite value > 0");
        }
        if !(0.0..1.0).contains(&self.dropout) {
            return bad("dropout rate", self.dropout, "a rate in [0, 1)");
        }
        for (name, b) in [("Adam β₁", self.beta1), ("Adam β₂", self.beta2)] {
            if !(0.0..1.0).contains(&b) {
                return bad(name, b, "a value in [0, 1)");
            }
        }
        if !(self.epsilon.is_finite() && self.epsilon > 0.0) {
            return bad("Adam ε", self.epsilon, "a finite value > 0");
        }
        if self.aux_points > MAX_AUX_POINTS {
            return bad(
                "number of auxiliary points",
                self.aux_points as f64,
                "at most 10,000,000",
            );
        }
        Ok(())
    }
}

/// Where training stands, passed to the monitor after every step.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct TrainProgress {
    /// Steps completed (1-based).
    pub step: usize,
    /// Steps in all.
    pub steps: usize,
    /// The loss at this step's parameters (before its update).
    pub loss: f64,
    /// Its data term `Σ (f(xᵢ) − zᵢ)²`.
    pub data_term: f64,
    /// Its curvature term (weight included).
    pub curvature_term: f64,
}

/// What training did.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct TrainReport {
    /// Adam steps taken.
    pub steps: usize,
    /// The final data term `Σ (f(xᵢ) − zᵢ)²` (no dropout).
    pub data_term: f64,
    /// The final curvature term `w Σⱼ ‖∇²f(yⱼ)‖_F²` at the last step's curvature points.
    pub curvature_term: f64,
    /// `data_term + curvature_term`.
    pub loss: f64,
    /// `maxᵢ |f(xᵢ) − zᵢ|` over the constraints.
    pub max_residual: f64,
    /// The weight `w = λ|Ω|/P` (or `λ|Ω|/N` at the constraints) of the curvature sum.
    pub curvature_weight: f64,
    /// The loss before each step's update, one entry per step.
    pub history: Vec<f64>,
    /// Wall-clock time of the training (set-up and final evaluation included).
    pub elapsed: Duration,
}

/// A trained field and its report.
#[derive(Debug, Clone)]
pub struct Trained<const D: usize> {
    /// The field.
    pub field: NeuralField<D>,
    /// How training went.
    pub report: TrainReport,
}

/// Trains neural fields; see the [module docs](super).
#[derive(Debug, Clone, PartialEq)]
pub struct NeuralFit<const D: usize> {
    params: NeuralParams,
    domain: Option<Aabb<D>>,
}

/// The frame a fit in the constraints' own units trains in: the centre `c` of the points' box
/// and half its longest extent `s` (1 for a single point), so that `u = (x − c)/s` lies in
/// `[−1, 1]ᴰ` and λ, the learning rate and the initial weights mean the same whatever the
/// units of the data ([`NeuralFit::fit_scaled`]). `([0; D], 1)` without points.
pub fn unit_frame<const D: usize>(points: &[Point<D>]) -> (Point<D>, f64) {
    match Aabb::from_points(points) {
        Some(b) => {
            let half = b.extent().into_iter().fold(0.0, f64::max) / 2.0;
            (b.center(), if half > 0.0 { half } else { 1.0 })
        }
        None => ([0.0; D], 1.0),
    }
}

/// `points` in the frame `(c, s)` of [`unit_frame`]: `(x − c)/s`.
pub fn to_unit_frame<const D: usize>(points: &[Point<D>], c: Point<D>, s: f64) -> Vec<Point<D>> {
    points
        .iter()
        .map(|p| std::array::from_fn(|a| (p[a] - c[a]) / s))
        .collect()
}

/// `n` points drawn uniformly in `domain` from ChaCha8 seeded with `seed`, stream 1, one
/// coordinate after the other: the auxiliary points of a fit. With
/// [`NeuralParams::resample_aux`], step `t` (0-based) uses points `tP … (t+1)P − 1` of this
/// sequence; otherwise every step uses the first `P`.
pub fn auxiliary_points<const D: usize>(domain: &Aabb<D>, seed: u64, n: usize) -> Vec<Point<D>> {
    let mut rng = aux_rng(seed);
    let mut out = Vec::with_capacity(n);
    draw_points(&mut rng, domain, n, &mut out);
    out
}

fn aux_rng(seed: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(STREAM_AUX);
    rng
}

fn draw_points<const D: usize>(
    rng: &mut ChaCha8Rng,
    domain: &Aabb<D>,
    n: usize,
    out: &mut Vec<Point<D>>,
) {
    let (lo, ext) = (domain.min(), domain.extent());
    out.clear();
    for _ in 0..n {
        let mut p = [0.0; D];
        for a in 0..D {
            p[a] = lo[a] + ext[a] * rng.random::<f64>();
        }
        out.push(p);
    }
}

/// A chunk of the loss: points, their targets (if they are constraints) and the weight of
/// their curvature (0: no jets).
#[derive(Debug, Clone)]
struct Chunk<const D: usize> {
    points: Vec<Point<D>>,
    targets: Option<Vec<f64>>,
    curvature_weight: f64,
    /// Whether this chunk holds auxiliary points (redrawn when resampling).
    aux: bool,
}

/// One chunk's share of the loss.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Parts {
    pub data: f64,
    pub curvature: f64,
}

impl<const D: usize> Chunk<D> {
    fn jets(&self) -> bool {
        self.curvature_weight > 0.0
    }

    /// Forward, loss and (with `gradient`) backward into `work.grad`.
    fn run(&self, net: &NeuralField<D>, work: &mut Work, gradient: bool) -> Parts {
        let n = self.points.len();
        engine::forward(net, &self.points, work);
        let mut parts = Parts::default();
        work.fbar.fill(0.0);
        if let Some(z) = &self.targets {
            for ((f, fbar), z) in work.f[..n].iter().zip(&mut work.fbar[..n]).zip(z) {
                let r = f - z;
                parts.data += r * r;
                *fbar = 2.0 * r;
            }
        }
        if self.jets() {
            let c = self.curvature_weight;
            for (q, &(k, l)) in pairs(D).iter().enumerate() {
                let m = if k == l { 1.0 } else { 2.0 };
                let block = (1 + D + q) * n;
                for p in 0..n {
                    let v = work.f[block + p];
                    parts.curvature += c * m * v * v;
                    work.fbar[block + p] = 2.0 * c * m * v;
                }
            }
        }
        if gradient {
            work.grad.fill(0.0);
            engine::backward(net, work);
        }
        parts
    }
}

/// The training state: chunks, their buffers, the random streams.
pub(crate) struct Trainer<const D: usize> {
    chunks: Vec<Chunk<D>>,
    works: Vec<Work>,
    parts: Vec<Parts>,
    dropout: f64,
    aux_rng: ChaCha8Rng,
    dropout_rng: ChaCha8Rng,
    domain: Aabb<D>,
    scratch: Vec<Point<D>>,
}

/// The bytes a [`Trainer`] of `points` constraints allocates for `layout`'s net, at most:
/// each chunk's [`Work`] buffers and its copy of its points, cut as [`Trainer::new`] cuts them.
fn trainer_bytes(
    layout: &super::net::Layout,
    dim: usize,
    points: usize,
    params: &NeuralParams,
    curvature_weight: f64,
) -> u64 {
    let dropout = params.dropout > 0.0;
    let chunked = |total: usize, size: usize, jets: bool| -> u64 {
        let per_chunk = |n: usize| {
            engine::work_bytes(layout, n, jets, dropout)
                .saturating_add((n as u64).saturating_mul(8 * dim as u64 + 8))
        };
        ((total / size) as u64)
            .saturating_mul(per_chunk(size))
            .saturating_add(if total.is_multiple_of(size) {
                0
            } else {
                per_chunk(total % size)
            })
    };
    let at_constraints =
        curvature_weight > 0.0 && params.curvature_at == CurvatureSites::Constraints;
    let size = if at_constraints {
        TRAIN_JET_CHUNK
    } else {
        TRAIN_VALUE_CHUNK
    };
    let mut bytes = chunked(points, size, at_constraints);
    if curvature_weight > 0.0 && params.curvature_at == CurvatureSites::Auxiliary {
        bytes = bytes.saturating_add(chunked(params.aux_points, TRAIN_JET_CHUNK, true));
    }
    bytes
}

impl<const D: usize> Trainer<D> {
    pub(crate) fn new(
        net: &NeuralField<D>,
        points: &[Point<D>],
        targets: &[f64],
        params: &NeuralParams,
        domain: Aabb<D>,
        curvature_weight: f64,
    ) -> Self {
        let curvature_at_constraints =
            curvature_weight > 0.0 && params.curvature_at == CurvatureSites::Constraints;
        let (size, cw) = if curvature_at_constraints {
            (TRAIN_JET_CHUNK, curvature_weight)
        } else {
            (TRAIN_VALUE_CHUNK, 0.0)
        };
        let mut chunks: Vec<Chunk<D>> = points
            .chunks(size)
            .zip(targets.chunks(size))
            .map(|(p, z)| Chunk {
                points: p.to_vec(),
                targets: Some(z.to_vec()),
                curvature_weight: cw,
                aux: false,
            })
            .collect();
        let mut aux_rng = aux_rng(params.seed);
        if curvature_weight > 0.0 && params.curvature_at == CurvatureSites::Auxiliary {
            let mut aux = Vec::new();
            draw_points(&mut aux_rng, &domain, params.aux_points, &mut aux);
            chunks.extend(aux.chunks(TRAIN_JET_CHUNK).map(|p| Chunk {
                points: p.to_vec(),
                targets: None,
                curvature_weight,
                aux: true,
            }));
        }
        let mut dropout_rng = ChaCha8Rng::seed_from_u64(params.seed);
        dropout_rng.set_stream(STREAM_DROPOUT);
        let dropout = params.dropout;
        let works = chunks
            .iter()
            .map(|c| {
                let mut w = Work::default();
                w.prepare(net.layout(), c.points.len(), c.jets(), dropout > 0.0);
                w
            })
            .collect();
        Self {
            parts: vec![Parts::default(); chunks.len()],
            chunks,
            works,
            dropout,
            aux_rng,
            dropout_rng,
            domain,
            scratch: Vec::new(),
        }
    }

    /// Draws the next set of auxiliary points (in chunk order).
    fn resample(&mut self) {
        let n: usize = self
            .chunks
            .iter()
            .filter(|c| c.aux)
            .map(|c| c.points.len())
            .sum();
        draw_points(&mut self.aux_rng, &self.domain, n, &mut self.scratch);
        let mut at = 0;
        for c in self.chunks.iter_mut().filter(|c| c.aux) {
            let m = c.points.len();
            c.points.copy_from_slice(&self.scratch[at..at + m]);
            at += m;
        }
    }

    /// Fresh dropout factors for every chunk, drawn in chunk, layer, neuron order.
    pub(crate) fn draw_masks(&mut self) {
        let keep = 1.0 - self.dropout;
        let scale = 1.0 / keep;
        for w in &mut self.works {
            for m in &mut w.mask {
                for v in m.iter_mut() {
                    *v = if self.dropout_rng.random::<f64>() < keep {
                        scale
                    } else {
                        0.0
                    };
                }
            }
        }
    }

    /// The loss at `net` and (with `gradient`) its gradient into `grad`, summed over the
    /// chunks in order.
    pub(crate) fn evaluate(
        &mut self,
        net: &NeuralField<D>,
        gradient: bool,
        grad: &mut [f64],
    ) -> Parts {
        self.chunks
            .par_iter()
            .zip(self.works.par_iter_mut())
            .zip(self.parts.par_iter_mut())
            .for_each(|((c, w), parts)| *parts = c.run(net, w, gradient));
        let mut total = Parts::default();
        if gradient {
            grad.fill(0.0);
        }
        for (p, w) in self.parts.iter().zip(&self.works) {
            total.data += p.data;
            total.curvature += p.curvature;
            if gradient {
                for (g, v) in grad.iter_mut().zip(&w.grad) {
                    *g += v;
                }
            }
        }
        total
    }

    /// Turns dropout off (for the final evaluation).
    fn without_dropout(&mut self, net: &NeuralField<D>) {
        self.dropout = 0.0;
        for (c, w) in self.chunks.iter().zip(&mut self.works) {
            w.prepare(net.layout(), c.points.len(), c.jets(), false);
        }
    }
}

/// Adam (Kingma & Ba 2015) in PyTorch's arithmetic: `m ← β₁m + (1−β₁)g`,
/// `v ← β₂v + (1−β₂)g²`, `θ ← θ − (lr/(1−β₁ᵗ)) · m / (√v/√(1−β₂ᵗ) + ε)`.
#[derive(Debug, Clone)]
struct Adam {
    m: Vec<f64>,
    v: Vec<f64>,
    t: i32,
    lr: f64,
    beta1: f64,
    beta2: f64,
    eps: f64,
}

impl Adam {
    fn new(n: usize, p: &NeuralParams) -> Self {
        Self {
            m: vec![0.0; n],
            v: vec![0.0; n],
            t: 0,
            lr: p.learning_rate,
            beta1: p.beta1,
            beta2: p.beta2,
            eps: p.epsilon,
        }
    }

    fn step(&mut self, theta: &mut [f64], g: &[f64]) {
        self.t = self.t.saturating_add(1);
        let bc1 = 1.0 - self.beta1.powi(self.t);
        let bc2_sqrt = (1.0 - self.beta2.powi(self.t)).sqrt();
        let step = self.lr / bc1;
        let (b1, b2) = (self.beta1, self.beta2);
        for (((x, g), m), v) in theta.iter_mut().zip(g).zip(&mut self.m).zip(&mut self.v) {
            *m = b1 * *m + (1.0 - b1) * g;
            *v = b2 * *v + (1.0 - b2) * g * g;
            let denom = v.sqrt() / bc2_sqrt + self.eps;
            *x -= step * (*m / denom);
        }
    }
}

impl<const D: usize> NeuralFit<D> {
    /// A fit with `params` on the default domain (the constraints' box grown by
    /// [`DOMAIN_MARGIN`] of its diagonal on every side).
    pub fn new(params: NeuralParams) -> Self {
        Self {
            params,
            domain: None,
        }
    }

    /// Sets the domain `Ω`: where the auxiliary points are drawn, whose measure scales λ,
    /// and the field's bounds.
    pub fn with_domain(mut self, domain: Aabb<D>) -> Self {
        self.domain = Some(domain);
        self
    }

    /// The parameters.
    pub fn params(&self) -> &NeuralParams {
        &self.params
    }

    /// The domain a fit of `points` uses (see [`NeuralFit::new`]); `None` if there is no point.
    pub fn domain_for(&self, points: &[Point<D>]) -> Option<Aabb<D>> {
        self.domain.or_else(|| {
            let b = Aabb::from_points(points)?;
            Some(b.expanded(DOMAIN_MARGIN * b.diagonal()))
        })
    }

    /// The untrained net of a fit of `points`: [`NeuralField::initial`] on its domain with
    /// the seed.
    ///
    /// # Errors
    /// [`NeuralError::NoConstraints`] without a point (and no domain).
    pub fn initial_field(&self, points: &[Point<D>]) -> Result<NeuralField<D>, NeuralError> {
        let domain = self.domain_for(points).ok_or(NeuralError::NoConstraints)?;
        Ok(NeuralField::initial(
            self.params.architecture.clone(),
            domain,
            self.params.seed,
        ))
    }

    /// Trains a net from [`NeuralFit::initial_field`] so that `f(pointsᵢ) ≈ targetsᵢ`.
    ///
    /// # Errors
    /// As [`NeuralFit::fit_with`].
    pub fn fit(&self, points: &[Point<D>], targets: &[f64]) -> Result<Trained<D>, NeuralError> {
        self.fit_with(points, targets, None, &mut |_| ControlFlow::Continue(()))
    }

    /// Trains on constraints in their own units: the points moved into `[−1, 1]ᴰ` by
    /// [`unit_frame`] and the targets divided by `unit` (for off-surface constraints, their
    /// offset), trained by [`NeuralFit::fit_with`] from the initial net, and the field moved
    /// back by [`NeuralField::transformed`], so that it approximates the targets at the
    /// given points. The report's loss terms and residual are in the frame's units (divide
    /// by `unit` to compare with the targets); [`Trained::field`] is in the data's.
    ///
    /// # Errors
    /// As [`NeuralFit::fit_with`]; [`NeuralError::InvalidParameter`] for a `unit` that is
    /// not finite and non-zero.
    pub fn fit_scaled(
        &self,
        points: &[Point<D>],
        targets: &[f64],
        unit: f64,
        monitor: &mut (dyn FnMut(&TrainProgress) -> ControlFlow<()> + Send),
    ) -> Result<Trained<D>, NeuralError> {
        if !(unit.is_finite() && unit != 0.0) {
            return Err(NeuralError::InvalidParameter {
                name: "value unit",
                value: unit,
                expected: "a finite value ≠ 0",
            });
        }
        let (centre, scale) = unit_frame(points);
        let u = to_unit_frame(points, centre, scale);
        let z: Vec<f64> = targets.iter().map(|t| t / unit).collect();
        let Trained { field, report } = self.fit_with(&u, &z, None, monitor)?;
        Ok(Trained {
            field: field.transformed(centre, scale, unit)?,
            report,
        })
    }

    /// Trains from `initial` (a warm start; its architecture wins over the parameters') or
    /// from [`NeuralFit::initial_field`], calling `monitor` after every step; a
    /// `ControlFlow::Break` stops with [`NeuralError::Cancelled`].
    ///
    /// # Errors
    /// [`NeuralError::NoConstraints`], [`NeuralError::LengthMismatch`],
    /// [`NeuralError::NonFinite`] naming the constraint, [`NeuralError::InvalidParameter`]
    /// (λ < 0, …), [`NeuralError::NoAuxiliaryPoints`], [`NeuralError::FlatDomain`],
    /// [`NeuralError::Diverged`], [`NeuralError::Cancelled`].
    pub fn fit_with(
        &self,
        points: &[Point<D>],
        targets: &[f64],
        initial: Option<NeuralField<D>>,
        monitor: &mut (dyn FnMut(&TrainProgress) -> ControlFlow<()> + Send),
    ) -> Result<Trained<D>, NeuralError> {
        let start = Instant::now();
        let p = &self.params;
        p.validate()?;
        check_constraints(points, targets)?;
        let domain = self.domain_for(points).ok_or(NeuralError::NoConstraints)?;
        let measure: f64 = domain.extent().iter().product();
        let sites = match p.curvature_at {
            CurvatureSites::Auxiliary => p.aux_points,
            CurvatureSites::Constraints => points.len(),
        };
        let curvature_weight = if p.lambda > 0.0 {
            if sites == 0 {
                return Err(NeuralError::NoAuxiliaryPoints { lambda: p.lambda });
            }
            if !(measure > 0.0 && measure.is_finite()) {
                return Err(NeuralError::FlatDomain {
                    min: domain.min().to_vec(),
                    max: domain.max().to_vec(),
                });
            }
            p.lambda * measure / sites as f64
        } else {
            0.0
        };
        // The training buffers grow with the points times the widths: checked before the net
        // or any buffer is made (a warm start's architecture wins, as below).
        let arch = initial
            .as_ref()
            .map_or(&p.architecture, |f| f.architecture());
        let layout = super::net::Layout::new(D, arch.widths());
        let what = format!(
            "training the net {:?} on {} points{}",
            arch.widths(),
            points.len(),
            if curvature_weight > 0.0 && p.curvature_at == CurvatureSites::Auxiliary {
                format!(" and {} auxiliary points", p.aux_points)
            } else {
                String::new()
            }
        );
        let needed = trainer_bytes(&layout, D, points.len(), p, curvature_weight)
            .saturating_add((layout.total as u64).saturating_mul(8 * 5));
        let limit = limits::current_limit().unwrap_or_else(|_| {
            limits::machine_available().map_or(limits::Limit::Unknown, limits::Limit::Machine)
        });
        if let Some(e) = limits::memory_error(&what, needed, limit) {
            return Err(e.into());
        }
        let mut net = match initial {
            Some(f) => f,
            None => NeuralField::initial(p.architecture.clone(), domain, p.seed),
        };
        let mut trainer = Trainer::new(&net, points, targets, p, domain, curvature_weight);
        let mut adam = Adam::new(net.parameters().len(), p);
        let mut grad = vec![0.0; net.parameters().len()];
        // The history grows step by step: a huge --steps is not reserved up front.
        let mut history = Vec::with_capacity(p.steps.min(1 << 16));
        // The loop runs on a worker of the current rayon pool, so that each step's parallel
        // pass neither wakes the calling thread nor waits for it (a step is ~0.3 ms).
        rayon::scope(|_| -> Result<(), NeuralError> {
            for step in 0..p.steps {
                if p.resample_aux && step > 0 {
                    trainer.resample();
                }
                if trainer.dropout > 0.0 {
                    trainer.draw_masks();
                }
                let parts = trainer.evaluate(&net, true, &mut grad);
                let loss = parts.data + parts.curvature;
                if !loss.is_finite() || grad.iter().any(|g| !g.is_finite()) {
                    return Err(NeuralError::Diverged {
                        step: step + 1,
                        loss,
                    });
                }
                history.push(loss);
                adam.step(net.parameters_mut(), &grad);
                let progress = TrainProgress {
                    step: step + 1,
                    steps: p.steps,
                    loss,
                    data_term: parts.data,
                    curvature_term: parts.curvature,
                };
                if monitor(&progress).is_break() {
                    return Err(NeuralError::Cancelled { steps: step + 1 });
                }
            }
            Ok(())
        })?;
        trainer.without_dropout(&net);
        let parts = trainer.evaluate(&net, false, &mut grad);
        let mut values = vec![0.0; points.len()];
        net.values(points, &mut values);
        let max_residual = values
            .iter()
            .zip(targets)
            .map(|(f, z)| (f - z).abs())
            .fold(0.0, f64::max);
        if !(parts.data + parts.curvature).is_finite()
            || net.parameters().iter().any(|v| !v.is_finite())
        {
            return Err(NeuralError::Diverged {
                step: p.steps,
                loss: parts.data + parts.curvature,
            });
        }
        Ok(Trained {
            field: net,
            report: TrainReport {
                steps: p.steps,
                data_term: parts.data,
                curvature_term: parts.curvature,
                loss: parts.data + parts.curvature,
                max_residual,
                curvature_weight,
                history,
                elapsed: start.elapsed(),
            },
        })
    }
}

/// Lengths, emptiness and finiteness of the constraints.
pub(crate) fn check_constraints<const D: usize>(
    points: &[Point<D>],
    targets: &[f64],
) -> Result<(), NeuralError> {
    if points.len() != targets.len() {
        return Err(NeuralError::LengthMismatch {
            points: points.len(),
            targets: targets.len(),
        });
    }
    if points.is_empty() {
        return Err(NeuralError::NoConstraints);
    }
    for (index, (p, z)) in points.iter().zip(targets).enumerate() {
        if let Some(v) = p.iter().find(|v| !v.is_finite()) {
            return Err(NeuralError::NonFinite {
                index,
                what: "coordinate",
                value: *v,
            });
        }
        if !z.is_finite() {
            return Err(NeuralError::NonFinite {
                index,
                what: "target",
                value: *z,
            });
        }
    }
    Ok(())
}
