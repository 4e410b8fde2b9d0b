//! The black-box fast multipole method (Fong & Darve 2009) for RBF fields, as paper 002 §2.2
//! uses it to evaluate `s(x) = Σⱼ wⱼ φ(|x − yⱼ|) + p(x)` at many points.
//!
//! ## The expansion
//!
//! For any smooth kernel, interpolating `φ(x, y)` in both variables at the `p³` Chebyshev nodes
//! of a target cell (`x̄_A`) and a source cell (`ȳ_B`) gives the low-rank form
//!
//! ```text
//!     φ(x, y) ≈ Σ_A Σ_B  S(x̄_A, x) · φ(x̄_A, ȳ_B) · S(ȳ_B, y),     S = Sₚ ⊗ Sₚ ⊗ Sₚ,
//! ```
//!
//! accurate when the cells are well separated, with an error falling geometrically in `p`. It
//! needs no analytic expansion of the kernel ("black box"): `r` and `r³` work alike. The
//! method's steps, over an adaptive octree (a cell with too many sources is split into all eight
//! children; an empty leaf next to much finer cells is split too, so that no point sums more
//! than a few leaves directly):
//!
//! - **P2M**: a leaf's multipole expansion `M_B = Σⱼ wⱼ S(ȳ_B, yⱼ) + vⱼ · ∇S(ȳ_B, yⱼ)` (the
//!   second term for the gradient constraints of Hermite fits: a centre `j` with derivative
//!   weights `vⱼ` contributes `−vⱼ · ∇φ(x − yⱼ)`).
//! - **M2M**, **L2L**: between a cell and its children, exactly (the interpolant of a
//!   polynomial of degree `p − 1` is itself), as three `p × p` products.
//! - **M2L**: `L_A += Σ_B φ(x̄_A, ȳ_B) M_B` between well-separated cells of one level, with
//!   the 316 operators reduced to 16 by symmetry and compressed by SVD, each on its own or in
//!   one basis shared by all offsets, even or odd along each axis so that an offset's 8
//!   reflections share one operator ([`M2lCompression`]; see [`FmmOperators`]).
//! - **P2L**, **M2P**, **P2P**: the adaptive tree's X, W and U lists (a small cell next to a
//!   large leaf), the last a direct sum over the near field.
//! - **L2P**: `s(x) ≈ Σ_A L_A S(x̄_A, x)` plus the near field, and the polynomial part added
//!   exactly. Gradients differentiate `S` and the kernel.
//!
//! The expansions are computed once, at construction, for every cell; evaluating a point then
//! costs one L2P (`p³`), its leaf's near field and its M2P list, **independent of the other
//! points** it is evaluated with. So a point's value never depends on the batch or on the number
//! of threads (the upward and downward passes run in a fixed order too), which the two-step
//! marching cubes relies on: a vertex evaluated twice gets the same bits.
//!
//! Told about how many points it will be evaluated at ([`FmmOptions::expected_points`]), the
//! field moves far sources that a small cell would take into its expansion (P2L, `|S| p³`
//! kernel evaluations) to the direct sums of that cell's points where they are fewer than `p³`
//! (`|S|` per point): the cost changes, the accuracy does not.
//!
//! Points outside the root cube (which covers the centres and the field's bounds) are still
//! exact to the same accuracy: they walk the tree from the root, using a cell's multipole
//! expansion when they are at least its width away from it and its sources otherwise.
//!
//! ## Enclosures
//!
//! [`ScalarField::value_range`] bounds the field over a box with about four evaluations' work:
//! in each leaf the box meets, the local expansion, every near and M2P kernel term and the
//! polynomial are linearised at the box's centre, with remainders from the expansion's Chebyshev
//! coefficients (Markov's inequality) and the kernel's [slope](Kernel::slope_bound) and
//! [curvature](Kernel::curvature_bound) bounds. The signed marching cubes settle whole blocks of
//! grid vertices this way. `None` for boxes not wholly inside the root or over more than eight
//! leaves, for fields with gradient constraints, and for kernels without the bounds.
//!
//! ## Accuracy
//!
//! The error falls steadily with `p` (paper 002, Tables 1–2; zeroset's own table:
//! `cargo run --release --example fmm_error`). The compression keeps singular values above
//! `tolerance · σ₁` (default `10^−(p+1)`, below the interpolation error of order `p`) at the
//! coarsest level, and the same absolute cut-off at the finer levels of a homogeneous kernel
//! ([`FmmOptions::tolerance`](FmmOptions#structfield.tolerance)). A kernel whose weights cancel
//! needs a small one: `r³` on 10,000 bunny centres reaches a maximum error of 1e-5 relative to
//! the field's largest value at `p = 10` with at most `3·10⁻¹¹` (7.8e-6; `5·10⁻¹¹` gives
//! 1.3e-5, the compression then being the larger part of the error; the default `10⁻¹¹`
//! gives 3.7e-6 and costs more).
//! [`FmmField::sampled_error`] measures the error of a built field against the exact sum.

pub mod cache;
mod chebyshev;
mod enclosure;
mod m2l;
mod operators;
pub mod product;
mod tree;

use std::sync::{Arc, OnceLock};
use std::time::Instant;

use rayon::prelude::*;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::rng::SplitMix64;
use zeroset_field_core::{Aabb, Point};

use super::field::RbfField;
use super::kernel::{self, Kernel};
use super::system::{self, Functional, Polynomial};
use chebyshev::MAX_ORDER;
use m2l::{CodedPair, Shared};
use operators::LevelOperators;
pub use operators::{FmmOperators, M2lCompression};
use tree::{Cell, ExpectedPoints, Tree, TreeShape};

/// The smallest expansion order (nodes per axis).
pub const MIN_ORDER: usize = 2;
/// The largest expansion order.
pub const LARGEST_ORDER: usize = MAX_ORDER;

/// What can go wrong building a multipole field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FmmError {
    /// The order is outside [`MIN_ORDER`]`..=`[`LARGEST_ORDER`].
    #[error(
        "the expansion order must be between {MIN_ORDER} and {LARGEST_ORDER} Chebyshev nodes per \
         axis, not {order}"
    )]
    Order {
        /// The order asked for.
        order: usize,
    },
    /// A leaf must hold at least one source.
    #[error("the leaf size must be at least 1")]
    LeafSize,
    /// The compression tolerance is not in `(0, 1)`.
    #[error("the compression tolerance must be in (0, 1), not {tolerance}")]
    Tolerance {
        /// The tolerance asked for.
        tolerance: f64,
    },
    /// The field has no centres.
    #[error("the field has no centres to expand")]
    NoSources,
    /// New weights that do not match the field's sources one to one.
    #[error(
        "{given} weights for a field of {sources} value sources (set_weights takes one weight per value centre, none with gradients)"
    )]
    Sources {
        /// Weights given.
        given: usize,
        /// The field's sources.
        sources: usize,
    },
    /// A centre, weight or domain corner is NaN or infinite.
    #[error("{what} {index} is not finite")]
    NonFinite {
        /// What is not finite.
        what: &'static str,
        /// Its index.
        index: usize,
    },
    /// The high order of a two-order pair is below the low one.
    #[error("the high order ({high}) must be at least the low order ({low})")]
    Orders {
        /// The low order.
        low: usize,
        /// The high order.
        high: usize,
    },
    /// The safety factor of a two-order pair is not finite and at least 1, or no error samples.
    #[error(
        "the safety factor must be finite and at least 1 and the error samples at least 1 (got {safety} and {samples})"
    )]
    Safety {
        /// The factor given.
        safety: f64,
        /// The sample count given.
        samples: usize,
    },
    /// The operators given were built for another kernel or order.
    #[error(
        "the operators were built for kernel `{built}` at order {built_order}, not for kernel \
         `{kernel}` at order {order}, or compressed {built_compression:?} rather than \
         {compression:?}"
    )]
    Operators {
        /// The operators' kernel.
        built: String,
        /// The operators' order.
        built_order: usize,
        /// The field's kernel.
        kernel: String,
        /// The order asked for.
        order: usize,
        /// The operators' compression.
        built_compression: M2lCompression,
        /// The compression asked for.
        compression: M2lCompression,
    },
}

/// Parameters of the multipole method.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct FmmOptions {
    /// Chebyshev nodes per axis, `p` (paper 002: 5…8 for the first step of the signed marching
    /// cubes, 9…12 for the second).
    pub order: usize,
    /// The most sources a leaf holds. Default: by order, `max(64, p³/2)` (a leaf's direct sums
    /// then cost about as much as its expansions); with [`expected_points`](Self::expected_points)
    /// `E` set, at most `max(8, √(28 N p⁵ / E))` for `N` sources, which minimises the cost model
    /// `E · 27 s` (each point's near field, 27 leaves of `s` sources) `+ (N / s) · 189 · 4 p³ r`
    /// (each leaf's M2L, rank `r ≈ p²`): many points per source want small leaves (at 10⁴
    /// centres and a 256³ grid, 12 at `p = 6`; 10⁵ points keep the default).
    pub leaf_size: Option<usize>,
    /// The deepest level (default 16).
    pub max_depth: u32,
    /// Relative singular-value cut-off of the M2L compression (default `10^−(p+1)`), at the
    /// coarsest level with M2L pairs. For a kernel of homogeneity `k` (`r`, `r³`) a level of
    /// width `w` has its operators scaled by `wᵏ`, so it keeps the singular values down to
    /// `tolerance · (w_top / w)ᵏ` of its largest: the same absolute error as the coarsest
    /// level's pairs, with fewer flops (`r³` at `p = 10`: ranks 20–35% lower one level down).
    pub tolerance: Option<f64>,
    /// A box the root cell must cover besides the centres (default: the field's bounds);
    /// points outside the root are exact but slower.
    pub domain: Option<Aabb<3>>,
    /// About how many points the field will be evaluated at, spread over the domain (default:
    /// unknown, many). A small cell next to a large leaf takes that leaf's sources into its
    /// local expansion (P2L: `|S| p³` kernel evaluations, once); where fewer than `p³` points
    /// are expected in the cell, they sum those sources directly instead (`|S|` per point).
    /// Many points per source also make the default leaves smaller ([`FmmOptions::leaf_size`]).
    /// Only the cost changes: every point is evaluated to the same accuracy either way.
    pub expected_points: Option<usize>,
    /// How the M2L operators are compressed (default: [`M2lCompression::for_order`]).
    pub compression: Option<M2lCompression>,
}

impl FmmOptions {
    /// Order `p`, the other parameters at their defaults.
    pub fn new(order: usize) -> Self {
        Self {
            order,
            leaf_size: None,
            max_depth: 16,
            tolerance: None,
            domain: None,
            expected_points: None,
            compression: None,
        }
    }

    /// These options with at most `leaf_size` sources per leaf.
    pub fn with_leaf_size(mut self, leaf_size: usize) -> Self {
        self.leaf_size = Some(leaf_size);
        self
    }

    /// These options with the tree at most `depth` levels deep.
    pub fn with_max_depth(mut self, depth: u32) -> Self {
        self.max_depth = depth;
        self
    }

    /// These options with compression cut-off `tolerance`.
    pub fn with_tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = Some(tolerance);
        self
    }

    /// These options with the root covering `domain`.
    pub fn with_domain(mut self, domain: Aabb<3>) -> Self {
        self.domain = Some(domain);
        self
    }

    /// These options with the M2L operators compressed as `compression` says.
    pub fn with_compression(mut self, compression: M2lCompression) -> Self {
        self.compression = Some(compression);
        self
    }

    /// The M2L compression these options ask for.
    pub fn compression(&self) -> M2lCompression {
        self.compression
            .unwrap_or_else(|| M2lCompression::for_order(self.order))
    }

    /// These options for about `count` evaluation points spread over the domain.
    pub fn with_expected_points(mut self, count: usize) -> Self {
        self.expected_points = Some(count);
        self
    }

    fn check(&self) -> Result<(), FmmError> {
        if !(MIN_ORDER..=LARGEST_ORDER).contains(&self.order) {
            return Err(FmmError::Order { order: self.order });
        }
        if self.leaf_size == Some(0) {
            return Err(FmmError::LeafSize);
        }
        if let Some(t) = self.tolerance
            && !(t > 0.0 && t < 1.0)
        {
            return Err(FmmError::Tolerance { tolerance: t });
        }
        Ok(())
    }

    /// The leaf size for `sources` centres (see [`FmmOptions::leaf_size`]).
    fn leaf_size_for(&self, sources: usize) -> usize {
        if let Some(size) = self.leaf_size {
            return size;
        }
        let by_order = (self.order.pow(3) / 2).max(64);
        match self.expected_points {
            Some(e) if e > 0 => {
                let p5 = (self.order as f64).powi(5);
                let balanced = (28.0 * sources as f64 * p5 / e as f64).sqrt().round();
                by_order.min((balanced as usize).max(8))
            }
            _ => by_order,
        }
    }

    fn tolerance(&self) -> f64 {
        self.tolerance
            .unwrap_or_else(|| 10f64.powi(-(self.order as i32 + 1)))
    }
}

/// What building a multipole field did, and how long it took.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct FmmReport {
    /// Chebyshev nodes per axis.
    pub order: usize,
    /// Sources (centres, a gradient constraint's derivatives merged with its point).
    pub sources: usize,
    /// Cells of the tree, and how many are leaves.
    pub cells: usize,
    /// Leaves of the tree.
    pub leaves: usize,
    /// Levels below the root.
    pub depth: usize,
    /// M2L pairs over all levels.
    pub m2l_pairs: usize,
    /// The largest rank kept by the compression: over the 16 canonical operators (per
    /// operator), or the dimension of the shared basis.
    pub max_rank: usize,
    /// Seconds spent computing (or fetching) the M2L operators.
    pub operator_seconds: f64,
    /// Seconds for the tree and its lists, the upward pass (P2M, M2M), the M2L and P2L step,
    /// and the downward pass (L2L).
    pub tree_seconds: f64,
    /// Seconds of the upward pass.
    pub upward_seconds: f64,
    /// Seconds of the M2L and P2L step.
    pub m2l_seconds: f64,
    /// Seconds of the downward pass.
    pub downward_seconds: f64,
}

/// An RBF field evaluated by the black-box fast multipole method; see the [module docs](self).
///
/// ```
/// use zeroset_bases::rbf::{Biharmonic, Constraints, RbfFit};
/// use zeroset_bases::rbf::fmm::{FmmField, FmmOptions};
/// use zeroset_field_core::ScalarField;
///
/// // Points on the unit sphere, with values 0 on it and ±0.1 just off it.
/// let mut c = Constraints::<3>::new();
/// for i in 0..300 {
///     let z = 1.0 - 2.0 * (i as f64 + 0.5) / 300.0;
///     let t = i as f64 * 2.399963;
///     let r = (1.0 - z * z).sqrt();
///     let p = [r * t.cos(), r * t.sin(), z];
///     c.push_value(p, 0.0);
///     c.push_value(p.map(|v| 1.1 * v), 0.1);
/// }
/// let exact = RbfFit::new(Biharmonic).fit(&c)?.field;
/// let fast = FmmField::new(&exact, &FmmOptions::new(8))?;
/// let x = [0.3, -0.2, 0.5];
/// assert!((fast.value(&x) - exact.value(&x)).abs() < 1e-5);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone)]
pub struct FmmField<K> {
    kernel: K,
    ops: Arc<FmmOperators>,
    tree: Tree,
    /// Source coordinates in tree order.
    pos: [Vec<f64>; 3],
    weights: Vec<f64>,
    /// Derivative weights in tree order, where the field has gradient constraints.
    dipoles: Option<[Vec<f64>; 3]>,
    multipoles: Vec<f64>,
    locals: Vec<f64>,
    poly: Polynomial<3>,
    poly_coefficients: Vec<f64>,
    bounds: Aabb<3>,
    report: FmmReport,
    /// Per leaf, bounds on the local expansion's second derivatives (computed on the first
    /// enclosure asked for).
    leaf_curvature: OnceLock<Vec<enclosure::LeafCurvature>>,
}

impl<K: Kernel + Clone> FmmField<K> {
    /// The multipole form of `field` at `options.order`, with the operators of the process-wide
    /// [`cache`] (built on first use, then shared by every field of the same kernel, order,
    /// tolerance and compression).
    ///
    /// # Errors
    /// [`FmmError`] for an order, leaf size or tolerance out of range, a field without
    /// centres, or a non-finite centre, weight or domain.
    pub fn new(field: &RbfField<K, 3>, options: &FmmOptions) -> Result<Self, FmmError> {
        let ops = Self::operators(field.kernel(), options)?;
        Self::with_operators(field, options, ops)
    }

    /// The M2L operators for `kernel` at `options.order`, to share between fields of one kernel
    /// ([`FmmField::with_operators`]), from the process-wide [`cache`]: building them is the one
    /// step whose cost does not grow with the data (for `r` and `r³` on two cores, about 0.1 s
    /// at `p = 8` and 0.25–0.3 s at `p = 10`), so it is paid once per process (or once per
    /// machine with [`cache::set_disk_dir`]). They are computed when a field first needs them.
    ///
    /// # Errors
    /// [`FmmError`] for an order or tolerance out of range.
    pub fn operators(kernel: &K, options: &FmmOptions) -> Result<Arc<FmmOperators>, FmmError> {
        options.check()?;
        Ok(cache::operators(
            kernel,
            options.order,
            options.tolerance(),
            options.compression(),
        ))
    }

    /// [`FmmField::new`] with operators built before (for the same kernel and order).
    ///
    /// # Errors
    /// As [`FmmField::new`], and [`FmmError::Operators`] if `ops` were built for another
    /// kernel or order.
    pub fn with_operators(
        field: &RbfField<K, 3>,
        options: &FmmOptions,
        ops: Arc<FmmOperators>,
    ) -> Result<Self, FmmError> {
        options.check()?;
        let kernel = field.kernel().clone();
        if !ops.fits(&kernel)
            || ops.order() != options.order
            || ops.compression() != options.compression()
        {
            return Err(FmmError::Operators {
                built: ops.kernel_name().to_owned(),
                built_order: ops.order(),
                kernel: kernel.name().to_owned(),
                order: options.order,
                built_compression: ops.compression(),
                compression: options.compression(),
            });
        }
        let (points, weights, dipoles) = sources(field)?;
        let bounds = field
            .bounds()
            .or_else(|| Aabb::from_points(&points))
            .ok_or(FmmError::NoSources)?;
        let domain = options.domain.unwrap_or(bounds);
        for (index, v) in domain.min().iter().chain(&domain.max()).enumerate() {
            if !v.is_finite() {
                return Err(FmmError::NonFinite {
                    what: "domain corner coordinate",
                    index,
                });
            }
        }
        let start = Instant::now();
        let (centre, half) = root_cube(&points, &domain);
        let p = options.order;
        let tree = Tree::build(
            &points,
            TreeShape {
                centre,
                half,
                leaf_size: options.leaf_size_for(points.len()),
                max_depth: options.max_depth,
                nodes: p * p * p,
                expected: options.expected_points.map(|count| ExpectedPoints {
                    count: count as f64,
                    lo: domain.min(),
                    hi: domain.max(),
                }),
            },
        );
        let reorder = |v: &dyn Fn(usize) -> f64| -> Vec<f64> {
            tree.order.iter().map(|&i| v(i as usize)).collect()
        };
        let pos = std::array::from_fn(|a| reorder(&|i| points[i][a]));
        let weights = reorder(&|i| weights[i]);
        let dipoles = dipoles.map(|d| std::array::from_fn(|a| reorder(&|i| d[i][a])));
        let n = p * p * p;
        let cells = tree.cells.len();
        let mut this = Self {
            kernel,
            ops,
            pos,
            weights,
            dipoles,
            multipoles: vec![0.0; cells * n],
            locals: vec![0.0; cells * n],
            poly: *field.polynomial(),
            poly_coefficients: field.polynomial_coefficients().to_vec(),
            bounds,
            report: FmmReport {
                order: p,
                sources: points.len(),
                cells,
                leaves: tree.cells.iter().filter(|c| c.is_leaf()).count(),
                depth: tree.levels.len() - 1,
                m2l_pairs: tree.m2l.iter().flatten().map(Vec::len).sum(),
                max_rank: 0,
                operator_seconds: 0.0,
                tree_seconds: start.elapsed().as_secs_f64(),
                upward_seconds: 0.0,
                m2l_seconds: 0.0,
                downward_seconds: 0.0,
            },
            tree,
            leaf_curvature: OnceLock::new(),
        };
        this.upward();
        this.m2l();
        this.downward();
        Ok(this)
    }
}

impl<K: Kernel> FmmField<K> {
    /// Replaces the weights of a field of value centres at distinct points (one weight per
    /// centre, in the field's order) and recomputes the expansions over the same tree: the
    /// products of an iterative fit, without rebuilding the tree or reallocating.
    ///
    /// # Errors
    /// [`FmmError::Sources`] if the count differs from the field's sources or the field has
    /// derivative (gradient) sources; [`FmmError::NonFinite`] for a non-finite weight.
    pub fn set_weights(&mut self, weights: &[f64]) -> Result<(), FmmError> {
        if weights.len() != self.weights.len() || self.dipoles.is_some() {
            return Err(FmmError::Sources {
                given: weights.len(),
                sources: self.weights.len(),
            });
        }
        if let Some(index) = weights.iter().position(|w| !w.is_finite()) {
            return Err(FmmError::NonFinite {
                what: "weight",
                index,
            });
        }
        for (dst, &i) in self.weights.iter_mut().zip(&self.tree.order) {
            *dst = weights[i as usize];
        }
        self.locals.fill(0.0);
        self.leaf_curvature = OnceLock::new();
        self.upward();
        self.m2l();
        self.downward();
        Ok(())
    }

    /// What building the field did.
    pub fn report(&self) -> &FmmReport {
        &self.report
    }

    /// The expansion order `p`.
    pub fn order(&self) -> usize {
        self.ops.order()
    }

    /// The operators, to build another field of the same kernel and order with.
    pub fn shared_operators(&self) -> Arc<FmmOperators> {
        self.ops.clone()
    }

    /// The largest and the root-mean-square difference `|s_fmm − s|` over `count` points
    /// against `exact` (the direct sum): half drawn uniformly in the field's bounds, half at
    /// the centres moved by up to a leaf's width, where the sign of the field matters most.
    /// Deterministic for a given `seed`.
    pub fn sampled_error<F: ScalarField<3> + ?Sized>(
        &self,
        exact: &F,
        count: usize,
        seed: u64,
    ) -> (f64, f64) {
        let points = self.error_samples(count, seed);
        let mut slow = vec![0.0; points.len()];
        exact.values(&points, &mut slow);
        self.error_at(&points, &slow)
    }

    /// The points [`FmmField::sampled_error`] measures at: `count` of them, half uniform in the
    /// field's bounds, half at the centres moved by up to a leaf's width (seeded).
    fn error_samples(&self, count: usize, seed: u64) -> Vec<Point<3>> {
        let mut rng = SplitMix64::new(seed ^ 0x9E37_79B9_7F4A_7C15);
        let mut uniform = move || rng.unit();
        let b = self.bounds;
        let leaf = self
            .tree
            .cells
            .iter()
            .filter(|c| c.is_leaf() && c.count() > 0)
            .map(|c| c.half)
            .fold(0.0, f64::max);
        let n = self.weights.len();
        (0..count)
            .map(|i| {
                if i % 2 == 0 {
                    std::array::from_fn(|a| b.min()[a] + uniform() * (b.max()[a] - b.min()[a]))
                } else {
                    let j = ((uniform() * n as f64) as usize).min(n - 1);
                    std::array::from_fn(|a| self.pos[a][j] + (2.0 * uniform() - 1.0) * leaf)
                }
            })
            .collect()
    }

    /// The largest and the root-mean-square difference from `exact` (the exact values at
    /// `points`).
    fn error_at(&self, points: &[Point<3>], exact: &[f64]) -> (f64, f64) {
        let mut fast = vec![0.0; points.len()];
        self.values(points, &mut fast);
        let (max, sum) = fast
            .iter()
            .zip(exact)
            .map(|(a, b)| (a - b).abs())
            .fold((0.0, 0.0), |(m, s), e| (f64::max(m, e), s + e * e));
        (max, (sum / points.len().max(1) as f64).sqrt())
    }

    fn n(&self) -> usize {
        self.ops.order().pow(3)
    }

    fn cell(&self, c: u32) -> &Cell {
        &self.tree.cells[c as usize]
    }

    /// P2M at the leaves, M2M above, level by level from the deepest.
    fn upward(&mut self) {
        let start = Instant::now();
        let n = self.n();
        for level in (0..self.tree.levels.len()).rev() {
            let done: Vec<(u32, Vec<f64>)> = self.tree.levels[level]
                .par_iter()
                .filter(|&&c| self.cell(c).count() > 0)
                .map(|&c| {
                    let mut m = vec![0.0; n];
                    let cell = self.cell(c);
                    if cell.is_leaf() {
                        self.p2m(cell, &mut m);
                    } else {
                        for (k, child) in cell.children().enumerate() {
                            if self.cell(child).count() > 0 {
                                let src = &self.multipoles[child as usize * n..][..n];
                                self.transfer(k, src, &mut m, false);
                            }
                        }
                    }
                    (c, m)
                })
                .collect();
            for (c, m) in done {
                self.multipoles[c as usize * n..][..n].copy_from_slice(&m);
            }
        }
        self.report.upward_seconds = start.elapsed().as_secs_f64();
    }

    /// The M2L pairs, then P2L. The pairs of all levels that one set of operators serves (every
    /// level, for a homogeneous kernel) go together: per operator, level by level and canonical
    /// operator by canonical operator (pairs sorted by target and offset, in blocks that keep a
    /// target's pairs together, so the order of additions into a local expansion is fixed);
    /// in the shared basis, all at once ([`m2l::shared`]).
    fn m2l(&mut self) {
        let start = Instant::now();
        let n = self.n();
        let root_width = 2.0 * self.tree.cells[0].half;
        let mut op_seconds = 0.0;
        let mut max_rank = 0;
        // Operator sets, with the pairs each serves, and every level's scale.
        let mut sets: Vec<(Arc<LevelOperators>, Vec<CodedPair>)> = Vec::new();
        let mut level_scale = vec![1.0; self.tree.m2l.len()];
        for (level, codes) in self.tree.m2l.iter().enumerate() {
            if codes.iter().all(Vec::is_empty) {
                continue;
            }
            let width = root_width / (1u64 << level) as f64;
            let t = Instant::now();
            let (ops, scale) = self.ops.level(&self.kernel, width);
            op_seconds += t.elapsed().as_secs_f64();
            level_scale[level] = scale;
            max_rank = max_rank.max(ops.rank());
            let set = match sets.iter().position(|(o, _)| Arc::ptr_eq(o, &ops)) {
                Some(i) => i,
                None => {
                    sets.push((ops, Vec::new()));
                    sets.len() - 1
                }
            };
            for (code, pairs) in codes.iter().enumerate() {
                sets[set].1.extend(pairs.iter().map(|q| CodedPair {
                    target: q.target,
                    code: code as u16,
                    source: q.source,
                }));
            }
        }
        // The operators' errors are relative to their own norm, which scales with the level
        // (`wᵏ` for a kernel of homogeneity `k`): a finer level may keep fewer singular values
        // for the same absolute error as the coarsest level's pairs.
        let top = level_scale
            .iter()
            .zip(&self.tree.m2l)
            .filter(|(_, codes)| codes.iter().any(|c| !c.is_empty()))
            .map(|(&s, _)| s)
            .fold(0.0, f64::max);
        let level_cut: Vec<f64> = level_scale
            .iter()
            .map(|&s| if s > 0.0 { (top / s).max(1.0) } else { 1.0 })
            .collect();
        let locals = Shared::new(&mut self.locals);
        let cells = &self.tree.cells;
        let scale = |c: u32| level_scale[cells[c as usize].level as usize];
        let cut = |c: u32| level_cut[cells[c as usize].level as usize];
        let tolerance = self.ops.tolerance();
        for (ops, pairs) in sets {
            match &*ops {
                LevelOperators::PerOperator(canonical) => {
                    // Level by level (a level's pairs share one scale), class by class.
                    let symmetry = &self.ops.symmetry;
                    let mut groups: Vec<Vec<CodedPair>> =
                        vec![Vec::new(); self.tree.m2l.len() * canonical.len()];
                    for q in pairs {
                        let level = cells[q.target as usize].level as usize;
                        let class = symmetry.canonical_of[q.code as usize];
                        groups[level * canonical.len() + class].push(q);
                    }
                    for (g, mut group) in groups.into_iter().enumerate() {
                        if group.is_empty() {
                            continue;
                        }
                        group.sort_unstable();
                        let (level, class) = (g / canonical.len(), g % canonical.len());
                        m2l::per_operator(
                            canonical,
                            symmetry,
                            class,
                            &group,
                            level_scale[level],
                            tolerance * level_cut[level],
                            &self.multipoles,
                            locals,
                            n,
                        );
                    }
                }
                LevelOperators::Shared {
                    basis,
                    basis_sigma,
                    signs,
                    offsets,
                } => m2l::shared(
                    basis,
                    basis_sigma,
                    signs,
                    offsets,
                    &self.ops.symmetry.mirror,
                    pairs,
                    &scale,
                    &|c| tolerance * cut(c),
                    &|c| cells[c as usize].level,
                    &self.multipoles,
                    locals,
                    n,
                    cells.len(),
                ),
            }
        }
        let this = &*self;
        let tree = &this.tree;
        // P2L: each cell adds its own list into its own expansion.
        let arch = pulp::Arch::new();
        (0..tree.cells.len())
            .into_par_iter()
            .filter(|&c| !tree.p2l[c].is_empty())
            .for_each(|c| {
                // SAFETY: each task writes only cell `c`'s range.
                let local = unsafe { locals.range(c * n, n) };
                arch.dispatch(P2lTask {
                    field: this,
                    target: c as u32,
                    local,
                });
            });
        self.report.max_rank = max_rank;
        self.report.operator_seconds = op_seconds;
        self.report.m2l_seconds = start.elapsed().as_secs_f64() - op_seconds;
    }

    /// L2L from every split cell into its children, level by level from the root.
    fn downward(&mut self) {
        let start = Instant::now();
        let n = self.n();
        let locals = Shared::new(&mut self.locals);
        let this = &*self;
        for level in &this.tree.levels {
            level
                .par_iter()
                .filter(|&&c| !this.cell(c).is_leaf())
                .for_each(|&c| {
                    // SAFETY: the parent's range is only read and each child's range only
                    // written, by this task alone, during this level.
                    let parent: Vec<f64> = unsafe { locals.range(c as usize * n, n) }.to_vec();
                    for (k, child) in this.cell(c).children().enumerate() {
                        let out = unsafe { locals.range(child as usize * n, n) };
                        this.transfer(k, &parent, out, true);
                    }
                });
        }
        self.report.downward_seconds = start.elapsed().as_secs_f64();
    }

    /// M2M (`out += E ⊗ E ⊗ E · src`) or, `transpose`, L2L (`out += Eᵀ ⊗ Eᵀ ⊗ Eᵀ · src`) for
    /// child octant `k`: one `p × p` map per axis, each pass a sum of scaled contiguous rows.
    fn transfer(&self, k: usize, src: &[f64], out: &mut [f64], transpose: bool) {
        let p = self.ops.order();
        let cheb = &self.ops.cheb;
        // maps[a][o * p + i]: the weight of input index i in output index o along axis a.
        let maps: [[f64; MAX_ORDER * MAX_ORDER]; 3] = std::array::from_fn(|a| {
            let e = cheb.transfer((k >> (2 - a)) & 1);
            let mut m = [0.0; MAX_ORDER * MAX_ORDER];
            for o in 0..p {
                for i in 0..p {
                    m[o * p + i] = if transpose {
                        e[i * p + o]
                    } else {
                        e[o * p + i]
                    };
                }
            }
            m
        });
        let n = p * p * p;
        let mut t1 = vec![0.0; n];
        let mut t2 = vec![0.0; n];
        // Along z: t1[ab, o] = Σᵢ m₂[o, i] src[ab, i], as rows m₂[·, i] scaled and added.
        let mut z_cols = [0.0; MAX_ORDER * MAX_ORDER];
        for o in 0..p {
            for i in 0..p {
                z_cols[i * p + o] = maps[2][o * p + i];
            }
        }
        for (row, dst) in src[..n].chunks_exact(p).zip(t1.chunks_exact_mut(p)) {
            for (i, &v) in row.iter().enumerate() {
                for (d, &m) in dst.iter_mut().zip(&z_cols[i * p..][..p]) {
                    *d += m * v;
                }
            }
        }
        // Along y: t2[a, o, :] = Σᵢ m₁[o, i] t1[a, i, :].
        for a in 0..p {
            for o in 0..p {
                let dst = &mut t2[(a * p + o) * p..][..p];
                for i in 0..p {
                    let w = maps[1][o * p + i];
                    for (d, &v) in dst.iter_mut().zip(&t1[(a * p + i) * p..][..p]) {
                        *d += w * v;
                    }
                }
            }
        }
        // Along x: out[o, :] += Σᵢ m₀[o, i] t2[i, :].
        for o in 0..p {
            let dst = &mut out[o * p * p..][..p * p];
            for i in 0..p {
                let w = maps[0][o * p + i];
                for (d, &v) in dst.iter_mut().zip(&t2[i * p * p..][..p * p]) {
                    *d += w * v;
                }
            }
        }
    }

    /// The 1-D Chebyshev weights of `x` in `cell` along each axis (and their derivatives in
    /// `x`'s units when `ds` is given).
    #[inline(always)]
    fn axis_weights(
        &self,
        cell: &Cell,
        x: &Point<3>,
        s: &mut [[f64; MAX_ORDER]; 3],
        ds: Option<&mut [[f64; MAX_ORDER]; 3]>,
    ) {
        let p = self.ops.order();
        let cheb = &self.ops.cheb;
        let u: [f64; 3] = std::array::from_fn(|a| (x[a] - cell.centre[a]) / cell.half);
        match ds {
            None => {
                for a in 0..3 {
                    cheb.weights(u[a], &mut s[a][..p]);
                }
            }
            Some(ds) => {
                for a in 0..3 {
                    cheb.weights_with_derivative(u[a], &mut s[a][..p], &mut ds[a][..p]);
                    for v in &mut ds[a][..p] {
                        *v /= cell.half;
                    }
                }
            }
        }
    }

    /// P2M of a leaf's sources.
    fn p2m(&self, cell: &Cell, m: &mut [f64]) {
        let p = self.ops.order();
        let mut s = [[0.0; MAX_ORDER]; 3];
        let mut ds = [[0.0; MAX_ORDER]; 3];
        for j in cell.begin as usize..cell.end as usize {
            let y = [self.pos[0][j], self.pos[1][j], self.pos[2][j]];
            let w = self.weights[j];
            match &self.dipoles {
                None => {
                    self.axis_weights(cell, &y, &mut s, None);
                    for a in 0..p {
                        for b in 0..p {
                            let wab = w * s[0][a] * s[1][b];
                            let row = &mut m[(a * p + b) * p..][..p];
                            for (c, v) in row.iter_mut().enumerate() {
                                *v += wab * s[2][c];
                            }
                        }
                    }
                }
                Some(d) => {
                    self.axis_weights(cell, &y, &mut s, Some(&mut ds));
                    let v = [d[0][j], d[1][j], d[2][j]];
                    for a in 0..p {
                        for b in 0..p {
                            let row = &mut m[(a * p + b) * p..][..p];
                            for (c, out) in row.iter_mut().enumerate() {
                                *out += w * s[0][a] * s[1][b] * s[2][c]
                                    + v[0] * ds[0][a] * s[1][b] * s[2][c]
                                    + v[1] * s[0][a] * ds[1][b] * s[2][c]
                                    + v[2] * s[0][a] * s[1][b] * ds[2][c];
                            }
                        }
                    }
                }
            }
        }
    }

    /// The Chebyshev node coordinates of `cell`, per axis.
    fn node_coordinates(&self, cell: &Cell) -> [[f64; MAX_ORDER]; 3] {
        let nodes = self.ops.cheb.nodes();
        std::array::from_fn(|a| {
            let mut c = [0.0; MAX_ORDER];
            for (m, v) in nodes.iter().enumerate() {
                c[m] = cell.centre[a] + cell.half * v;
            }
            c
        })
    }

    /// P2L: the sources of `source` into the local expansion of `target`. Without dipoles the
    /// loop runs over sources outside and the nodes along z inside (vectorised, as a cell
    /// in a P2L list often has only a few sources).
    #[inline(always)]
    fn p2l(&self, target: &Cell, source: &Cell, local: &mut [f64]) {
        let p = self.ops.order();
        let xs = self.node_coordinates(target);
        if self.dipoles.is_some() {
            for a in 0..p {
                for b in 0..p {
                    for c in 0..p {
                        let x = [xs[0][a], xs[1][b], xs[2][c]];
                        local[(a * p + b) * p + c] += self.direct(source.range(), &x);
                    }
                }
            }
            return;
        }
        let zs = &xs[2][..p];
        for j in source.begin as usize..source.end as usize {
            let w = self.weights[j];
            let y = [self.pos[0][j], self.pos[1][j], self.pos[2][j]];
            for a in 0..p {
                let dx = xs[0][a] - y[0];
                for b in 0..p {
                    let dy = xs[1][b] - y[1];
                    let rxy = dx * dx + dy * dy;
                    let row = &mut local[(a * p + b) * p..][..p];
                    for (l, &z) in row.iter_mut().zip(zs) {
                        let dz = z - y[2];
                        *l += w * self.kernel.value_of_squared(rxy + dz * dz);
                    }
                }
            }
        }
    }

    /// The coordinates (per axis) and weights of the sources `begin..end` (tree order).
    #[inline(always)]
    fn run(&self, (begin, end): (u32, u32)) -> ([&[f64]; 3], &[f64]) {
        let r = begin as usize..end as usize;
        (
            std::array::from_fn(|a| &self.pos[a][r.clone()]),
            &self.weights[r],
        )
    }

    /// The direct sum over the sources `begin..end` (tree order) at `x`.
    #[inline(always)]
    fn direct(&self, run: (u32, u32), x: &Point<3>) -> f64 {
        match &self.dipoles {
            None => {
                let (coords, weights) = self.run(run);
                system::kernel_sum_slices(&self.kernel, coords, weights, x)
            }
            Some(dip) => (run.0 as usize..run.1 as usize)
                .map(|j| {
                    let d = [
                        x[0] - self.pos[0][j],
                        x[1] - self.pos[1][j],
                        x[2] - self.pos[2][j],
                    ];
                    let g = kernel::gradient(&self.kernel, &d);
                    self.weights[j] * kernel::value(&self.kernel, &d)
                        - (dip[0][j] * g[0] + dip[1][j] * g[1] + dip[2][j] * g[2])
                })
                .sum(),
        }
    }

    /// The gradient of the direct sum over the sources `begin..end` at `x`.
    #[inline(always)]
    fn direct_gradient(&self, run: (u32, u32), x: &Point<3>) -> [f64; 3] {
        let Some(dip) = &self.dipoles else {
            let (coords, weights) = self.run(run);
            return system::kernel_gradient_sum_slices(&self.kernel, coords, weights, x);
        };
        let mut g = [0.0; 3];
        // Seven arrays indexed by source.
        #[allow(clippy::needless_range_loop)]
        for j in run.0 as usize..run.1 as usize {
            let d = [
                x[0] - self.pos[0][j],
                x[1] - self.pos[1][j],
                x[2] - self.pos[2][j],
            ];
            let gk = kernel::gradient(&self.kernel, &d);
            for a in 0..3 {
                g[a] += self.weights[j] * gk[a];
            }
            let h = kernel::hessian(&self.kernel, &d);
            for a in 0..3 {
                g[a] -= h[a][0] * dip[0][j] + h[a][1] * dip[1][j] + h[a][2] * dip[2][j];
            }
        }
        g
    }

    /// M2P: `cell`'s multipole expansion at `x`, `Σ_B M_B φ(|x − ȳ_B|)`.
    #[inline(always)]
    fn m2p(&self, c: u32, x: &Point<3>) -> f64 {
        let p = self.ops.order();
        let cell = self.cell(c);
        let ys = self.node_coordinates(cell);
        let m = &self.multipoles[c as usize * p * p * p..][..p * p * p];
        let mut acc = 0.0;
        for a in 0..p {
            let dx = x[0] - ys[0][a];
            for b in 0..p {
                let dy = x[1] - ys[1][b];
                let row = &m[(a * p + b) * p..][..p];
                let mut part = 0.0;
                for (cc, &mv) in row.iter().enumerate() {
                    let dz = x[2] - ys[2][cc];
                    part += mv * self.kernel.value_of_squared(dx * dx + dy * dy + dz * dz);
                }
                acc += part;
            }
        }
        acc
    }

    /// The gradient of [`Self::m2p`].
    fn m2p_gradient(&self, c: u32, x: &Point<3>) -> [f64; 3] {
        let p = self.ops.order();
        let cell = self.cell(c);
        let ys = self.node_coordinates(cell);
        let m = &self.multipoles[c as usize * p * p * p..][..p * p * p];
        let mut g = [0.0; 3];
        for a in 0..p {
            for b in 0..p {
                for cc in 0..p {
                    let d = [x[0] - ys[0][a], x[1] - ys[1][b], x[2] - ys[2][cc]];
                    let gk = kernel::gradient(&self.kernel, &d);
                    let mv = m[(a * p + b) * p + cc];
                    for k in 0..3 {
                        g[k] += mv * gk[k];
                    }
                }
            }
        }
        g
    }

    /// L2P: the local expansion of leaf `c` at `x`.
    #[inline(always)]
    fn l2p(&self, c: u32, x: &Point<3>) -> f64 {
        let p = self.ops.order();
        let cell = self.cell(c);
        let mut s = [[0.0; MAX_ORDER]; 3];
        self.axis_weights(cell, x, &mut s, None);
        chebyshev::contract(p, &s, &self.locals[c as usize * p * p * p..][..p * p * p])
    }

    /// [`Self::l2p`] and its gradient in one pass: `[value, ∂x, ∂y, ∂z]`.
    #[inline(always)]
    fn l2p_with_gradient(&self, c: u32, x: &Point<3>) -> [f64; 4] {
        let p = self.ops.order();
        let cell = self.cell(c);
        let mut s = [[0.0; MAX_ORDER]; 3];
        let mut ds = [[0.0; MAX_ORDER]; 3];
        self.axis_weights(cell, x, &mut s, Some(&mut ds));
        let l = &self.locals[c as usize * p * p * p..][..p * p * p];
        chebyshev::contract_with_gradient(p, &s, &ds, l)
    }

    /// The kernel part of the field at `x`, which lies in `leaf` (`None`: outside the root).
    #[inline(always)]
    fn kernel_part(&self, leaf: Option<u32>, x: &Point<3>) -> f64 {
        match leaf {
            Some(leaf) => {
                let mut v = self.l2p(leaf, x);
                for &run in &self.tree.near_runs[leaf as usize] {
                    v += self.direct(run, x);
                }
                for &s in &self.tree.m2p[leaf as usize] {
                    v += self.m2p(s, x);
                }
                v
            }
            None => {
                let mut v = 0.0;
                self.walk(x, |c, far| {
                    v += if far {
                        self.m2p(c, x)
                    } else {
                        self.direct(self.cell(c).range(), x)
                    };
                });
                v
            }
        }
    }

    /// [`ScalarField::value`], inlined into [`Batch`]'s instruction set.
    #[inline(always)]
    fn value_inline(&self, leaf: Option<u32>, x: &Point<3>) -> f64 {
        self.kernel_part(leaf, x) + self.poly.value(&self.poly_coefficients, x)
    }

    /// [`ScalarField::gradient`], inlined into [`GradientTask`]'s instruction set.
    #[inline(always)]
    fn gradient_inline(&self, x: &Point<3>) -> Point<3> {
        let mut g = self.poly.gradient(&self.poly_coefficients);
        let mut add = |h: [f64; 3]| {
            for a in 0..3 {
                g[a] += h[a];
            }
        };
        match self.tree.leaf_of(x) {
            Some(leaf) => {
                let [_, gx, gy, gz] = self.l2p_with_gradient(leaf, x);
                add([gx, gy, gz]);
                for &run in &self.tree.near_runs[leaf as usize] {
                    add(self.direct_gradient(run, x));
                }
                for &s in &self.tree.m2p[leaf as usize] {
                    add(self.m2p_gradient(s, x));
                }
            }
            None => self.walk(x, |c, far| {
                add(if far {
                    self.m2p_gradient(c, x)
                } else {
                    self.direct_gradient(self.cell(c).range(), x)
                })
            }),
        }
        g
    }

    /// Visits, for a point outside the root, the cells it is far from (`true`: use the
    /// multipole expansion) and the leaves it is near (`false`: sum directly), in a fixed order.
    fn walk(&self, x: &Point<3>, mut visit: impl FnMut(u32, bool)) {
        let mut stack = vec![0u32];
        while let Some(c) = stack.pop() {
            let cell = self.cell(c);
            if cell.count() == 0 {
                continue;
            }
            if tree::point_separated(x, cell) {
                visit(c, true);
            } else if cell.is_leaf() {
                visit(c, false);
            } else {
                stack.extend(cell.children().rev());
            }
        }
    }
}

impl<K: Kernel> ScalarField<3> for FmmField<K> {
    fn value(&self, x: &Point<3>) -> f64 {
        self.value_inline(self.tree.leaf_of(x), x)
    }

    fn gradient(&self, x: &Point<3>) -> Point<3> {
        pulp::Arch::new().dispatch(GradientTask { field: self, x })
    }

    fn values(&self, points: &[Point<3>], out: &mut [f64]) {
        assert_eq!(
            points.len(),
            out.len(),
            "values: points and out differ in length"
        );
        let arch = pulp::Arch::new();
        out.par_chunks_mut(EVAL_CHUNK)
            .zip(points.par_chunks(EVAL_CHUNK))
            .for_each(|(o, p)| {
                arch.dispatch(Batch {
                    field: self,
                    points: p,
                    out: o,
                })
            });
    }

    fn bounds(&self) -> Option<Aabb<3>> {
        Some(self.bounds)
    }

    /// An enclosure of the field over `region` from the local expansion's curvature and the
    /// kernel terms' Taylor remainders (see the module docs, "Enclosures").
    fn value_range(&self, region: &Aabb<3>) -> Option<[f64; 2]> {
        self.enclosure(region)
    }
}

/// Points per evaluation task.
const EVAL_CHUNK: usize = 2048;

/// A batch of evaluations, compiled per instruction set.
struct Batch<'a, K> {
    field: &'a FmmField<K>,
    points: &'a [Point<3>],
    out: &'a mut [f64],
}

impl<K: Kernel> pulp::WithSimd for Batch<'_, K> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        // Points are visited leaf by leaf, so that a leaf's local expansion and near sources
        // stay in cache; each value is computed exactly as alone.
        let mut order: Vec<(u32, u32)> = self
            .points
            .iter()
            .enumerate()
            .map(|(i, x)| (self.field.tree.leaf_of(x).unwrap_or(u32::MAX), i as u32))
            .collect();
        order.sort_unstable();
        for (leaf, i) in order {
            let x = &self.points[i as usize];
            self.out[i as usize] = self
                .field
                .value_inline((leaf != u32::MAX).then_some(leaf), x);
        }
    }
}

/// One gradient, compiled per instruction set.
struct GradientTask<'a, K> {
    field: &'a FmmField<K>,
    x: &'a Point<3>,
}

impl<K: Kernel> pulp::WithSimd for GradientTask<'_, K> {
    type Output = Point<3>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> Point<3> {
        self.field.gradient_inline(self.x)
    }
}

/// The P2L list of one cell into its local expansion, compiled per instruction set.
struct P2lTask<'a, K> {
    field: &'a FmmField<K>,
    target: u32,
    local: &'a mut [f64],
}

impl<K: Kernel> pulp::WithSimd for P2lTask<'_, K> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let f = self.field;
        let target = f.cell(self.target);
        for &s in &f.tree.p2l[self.target as usize] {
            f.p2l(target, f.cell(s), self.local);
        }
    }
}

/// The two fields of the two-step signed marching cubes (paper 002 §2.3) and the margin that
/// makes a low-order sign certain.
///
/// The paper takes the error `ε_p` of order `p` as known from its Tables 1–2, measured against
/// direct sums. Here it is measured the same way when the pair is built:
/// [`FmmField::sampled_error`] at `samples` points (half uniform in the field's box, half next
/// to the centres, where the sign changes), the same points for both orders (the direct sum is
/// evaluated there once). The margin is
/// `safety · (ε_p + ε_P)`: a vertex whose low-order value is farther than that from the level
/// has the same sign at order `P` (`|s_p − s_P| ≤ ε_p + ε_P`), so only the other vertices need
/// order `P`. The sampled maximum is an estimate, not a bound; the safety factor (default 10)
/// covers points worse than the samples.
#[derive(Debug, Clone)]
pub struct OrderPair<K> {
    /// The low-order field (step 1).
    pub low: FmmField<K>,
    /// The high-order field (step 2).
    pub high: FmmField<K>,
    /// The largest sampled error of the low order.
    pub low_error: f64,
    /// The largest sampled error of the high order.
    pub high_error: f64,
    /// `safety · (low_error + high_error)`.
    pub margin: f64,
    /// The safety factor.
    pub safety: f64,
    /// The error samples (the same points for both orders).
    pub samples: usize,
    /// The sample points and the exact values there.
    sample_points: Vec<Point<3>>,
    sample_values: Vec<f64>,
}

/// The default safety factor of [`OrderPair::new`].
pub const DEFAULT_SAFETY: f64 = 10.0;
/// The default number of error samples of [`OrderPair::new`].
pub const DEFAULT_ERROR_SAMPLES: usize = 4096;

impl<K: Kernel + Clone> OrderPair<K> {
    /// Checks the options of [`OrderPair::new`] without building anything.
    ///
    /// # Errors
    /// As [`OrderPair::new`] for the options: an order, leaf size or tolerance out of range,
    /// `high.order < low.order`, a safety factor below 1 or not finite, or no samples.
    pub fn check(
        low: &FmmOptions,
        high: &FmmOptions,
        samples: usize,
        safety: f64,
    ) -> Result<(), FmmError> {
        low.check()?;
        high.check()?;
        if high.order < low.order {
            return Err(FmmError::Orders {
                low: low.order,
                high: high.order,
            });
        }
        if !(safety.is_finite() && safety >= 1.0) || samples == 0 {
            return Err(FmmError::Safety { safety, samples });
        }
        Ok(())
    }

    /// Builds both orders of `field` and measures their errors (see the type's docs).
    ///
    /// # Errors
    /// [`FmmError::Orders`] if `high.order < low.order`, [`FmmError::Safety`] for a safety
    /// factor below 1 or not finite or no samples, and the errors of [`FmmField::new`].
    pub fn new(
        field: &RbfField<K, 3>,
        low: &FmmOptions,
        high: &FmmOptions,
        samples: usize,
        safety: f64,
    ) -> Result<Self, FmmError> {
        Self::check(low, high, samples, safety)?;
        let low_field = FmmField::new(field, low)?;
        let high_field = FmmField::new(field, high)?;
        // Both orders at the same points, so that the direct sum is evaluated once.
        let sample_points = low_field.error_samples(samples, 1);
        let mut sample_values = vec![0.0; samples];
        field.values(&sample_points, &mut sample_values);
        let (low_error, _) = low_field.error_at(&sample_points, &sample_values);
        let (high_error, _) = high_field.error_at(&sample_points, &sample_values);
        Ok(Self {
            low: low_field,
            high: high_field,
            low_error,
            high_error,
            margin: safety * (low_error + high_error),
            safety,
            samples,
            sample_points,
            sample_values,
        })
    }

    /// The pair with its low-order field rebuilt for `low` (same order and operators, e.g.
    /// shaped for another number of evaluations), its error measured again and the margin
    /// updated.
    ///
    /// # Errors
    /// The errors of [`FmmField::with_operators`]; [`FmmError::Operators`] if `low` asks for
    /// another order or compression than the pair's low field has.
    pub fn with_low(mut self, field: &RbfField<K, 3>, low: &FmmOptions) -> Result<Self, FmmError> {
        self.low = FmmField::with_operators(field, low, self.low.shared_operators())?;
        self.low_error = self
            .low
            .error_at(&self.sample_points, &self.sample_values)
            .0;
        self.margin = self.safety * (self.low_error + self.high_error);
        Ok(self)
    }
}

/// The field's centres merged by point: positions, value weights and (where the field has
/// gradient constraints) derivative weights.
#[allow(clippy::type_complexity, clippy::needless_range_loop)]
fn sources<K: Kernel>(
    field: &RbfField<K, 3>,
) -> Result<(Vec<[f64; 3]>, Vec<f64>, Option<Vec<[f64; 3]>>), FmmError> {
    let f = field.functionals();
    let w = field.weights();
    if f.len() == 0 {
        return Err(FmmError::NoSources);
    }
    let mut points: Vec<[f64; 3]> = Vec::new();
    let mut weights: Vec<f64> = Vec::new();
    let mut dipoles: Vec<[f64; 3]> = Vec::new();
    for j in 0..f.len() {
        let y = f.points[j];
        if y.iter().any(|v| !v.is_finite()) {
            return Err(FmmError::NonFinite {
                what: "centre",
                index: j,
            });
        }
        if !w[j].is_finite() {
            return Err(FmmError::NonFinite {
                what: "weight",
                index: j,
            });
        }
        if points.last() != Some(&y) {
            points.push(y);
            weights.push(0.0);
            dipoles.push([0.0; 3]);
        }
        let k = points.len() - 1;
        match f.kinds[j] {
            Functional::Value => weights[k] += w[j],
            Functional::Derivative(a) => dipoles[k][a] += w[j],
        }
    }
    let dipoles = (!f.values_only()).then_some(dipoles);
    Ok((points, weights, dipoles))
}

/// The cube around the centres and `domain`, enlarged a little so that points on the domain's
/// faces are inside.
fn root_cube(points: &[[f64; 3]], domain: &Aabb<3>) -> ([f64; 3], f64) {
    let mut lo = domain.min();
    let mut hi = domain.max();
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let centre = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
    let half = (0..3).map(|a| 0.5 * (hi[a] - lo[a])).fold(0.0, f64::max);
    let half = if half > 0.0 { half * (1.0 + 1e-9) } else { 1.0 };
    (centre, half)
}

#[cfg(test)]
mod tests;
