//! Uniform tensor-product B-splines of degree 2 (quadratic) and 3 (cubic) on a grid, and their
//! interpolation of grid samples.
//!
//! ## The spline
//!
//! On a [`Grid`] with `n_a` samples along axis `a`, let `x = grid.continuous_index(p)` be the
//! continuous index of a point (sample `i` sits at `x_a = i`). The spline is
//!
//! ```text
//! s(x) = Σ_{j ∈ Zᴰ} c_j Π_a β(x_a − j_a)
//! ```
//!
//! with one B-spline **centred on each sample** and `β` the centred B-spline of degree 2 or 3:
//!
//! ```text
//! β²(t) = ¾ − t²                  |t| ≤ ½          β³(t) = ⅔ − t² + |t|³/2     |t| ≤ 1
//!       = (3/2 − |t|)²/2           ½ ≤ |t| ≤ 3/2          = (2 − |t|)³/6        1 ≤ |t| ≤ 2
//! ```
//!
//! For cell-centred data the quadratic knots (the breakpoints `t = ±½, ±3/2`) fall on the **cell
//! faces**: `s` is C¹ everywhere, piecewise quadratic in each cell, with a piecewise-constant
//! Hessian that jumps on the faces. The cubic is C² with knots at the samples. (Knots at the
//! samples for the quadratic would give the sampled kernel `[½, ½]`, whose inverse is unstable.)
//! A point reads `3ᴰ` (quadratic) or `4ᴰ` (cubic) coefficients.
//!
//! ## Interpolation (the prefilter)
//!
//! At the samples the spline is the coefficients convolved with the **sampled kernel**, along
//! each axis
//!
//! ```text
//! s_i = a c_{i−1} + b c_i + a c_{i+1},    (a, b) = (⅛, ¾) quadratic,  (⅙, ⅔) cubic,
//! ```
//!
//! so interpolation is the inverse of that convolution, a tridiagonal solve per grid line
//! ([`prefilter`], separable: one axis after the other). The inverse is also a symmetric
//! recursive filter with gain 8 (6) and pole `z = −3 + 2√2 ≈ −0.1716` (cubic `−2 + √3 ≈ −0.268`),
//! as in Unser's and scipy's implementations; zeroset uses the exact LU (Thomas) factorisation of
//! the boundary-modified matrix instead, which needs no start-up approximation. A sample's
//! influence on coefficients decays like `|z|^distance`.
//!
//! ## Boundaries
//!
//! Coefficients outside `[0, n)` are defined by mirroring ([`Boundary`]):
//! - [`Boundary::HalfSample`] (the default): mirror about the half-sample point,
//!   `c₋₁ = c₀, c_n = c_{n−1}` — scipy's `mode='reflect'` (`'grid-mirror'`); natural for
//!   cell-centred data, where the mirror plane is the box face.
//! - [`Boundary::WholeSample`]: mirror about the end sample, `c₋₁ = c₁, c_n = c_{n−2}` — scipy's
//!   `mode='mirror'`; natural for vertex-centred data.
//!
//! The same rule is used by the prefilter (it modifies the first and last rows of the matrix)
//! and by evaluation (indices are folded back into the grid), so the spline interpolates the
//! samples exactly (to rounding, about `1e-13`). A polynomial of the spline's degree or less is
//! reproduced exactly away from the boundary; near it, the mirror perturbs the coefficients of
//! a polynomial that is not itself mirror-symmetric (constants are reproduced everywhere), by an
//! amount that decays like `0.17^distance` (quadratic) from the boundary.
//!
//! ## Points outside the grid
//!
//! Evaluation **clamps** the continuous index to the grid's box: `[−½, n−½]` per axis for a
//! cell-centred grid, `[0, n−1]` for a vertex-centred one. Outside the box the field is
//! therefore constant along the clamped directions, and derivatives are those of the spline at
//! the clamped point (not zero). Gradients and Hessians are in world units (the index-space
//! derivatives divided by the spacing, or by `h_a h_b`).
//!
//! ## The paper
//!
//! The restoration paper (Ren–Fujita–Nakata 2022, Eq. 6 and 9) interpolates the restored grid
//! values `g_ijk` with "the standard spline interpolation" of quadratic B-splines with uniform
//! intervals, without saying where the knots go or how the boundary is treated; the choices above
//! (samples at the B-spline centres, knots on cell faces, half-sample mirror) are zeroset's.
//!
//! ```
//! use zeroset_bases::bspline::{BSplineField, Degree};
//! use zeroset_field_core::analytic::Sphere;
//! use zeroset_field_core::field::ScalarField;
//! use zeroset_field_core::geometry::Aabb;
//! use zeroset_field_core::grid::Grid;
//!
//! let grid = Grid::cell_centered(Aabb::centered_cube(1.0)?, [16, 16, 16])?;
//! let sphere = Sphere::new([0.0; 3], 0.5);
//! let spline = BSplineField::sample(&sphere, grid, Degree::Quadratic)?;
//! // It interpolates the samples ...
//! let p = grid.point([3, 8, 11]);
//! assert!((spline.value(&p) - sphere.value(&p)).abs() < 1e-12);
//! // ... and is smooth in between, with an analytic gradient.
//! let q = [0.52, 0.01, -0.03];
//! assert!((spline.value(&q) - sphere.value(&q)).abs() < 1e-2);
//! assert!((spline.gradient(&q)[0] - 1.0).abs() < 0.05);
//! # Ok::<(), zeroset_field_core::Error>(())
//! ```

mod batch;
mod prefilter;
mod space;
pub(crate) mod stencil;

use zeroset_field_core::Error;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::{Aabb, Point};
use zeroset_field_core::grid::{Centering, Grid};

pub use prefilter::{prefilter, prefilter_means};
pub use space::BSplineSpace;

use stencil::{AxisWeights, fold, strides, weights};

/// The polynomial degree of the B-splines.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Degree {
    /// Degree 2: C¹, `3ᴰ` coefficients per point, sampled kernel `[⅛, ¾, ⅛]`.
    Quadratic,
    /// Degree 3: C², `4ᴰ` coefficients per point, sampled kernel `[⅙, ⅔, ⅙]`.
    Cubic,
}

impl Degree {
    /// The number of B-splines overlapping a point along one axis: 3 or 4.
    pub fn stencil_len(self) -> usize {
        match self {
            Degree::Quadratic => 3,
            Degree::Cubic => 4,
        }
    }
}

/// How coefficients outside the grid are defined (see the [module docs](self#boundaries)).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum Boundary {
    /// Mirror about the half-sample point: `c₋₁ = c₀`, `c_n = c_{n−1}` (scipy `mode='reflect'`
    /// or `'grid-mirror'`). The default; natural for cell-centred data.
    #[default]
    HalfSample,
    /// Mirror about the end sample: `c₋₁ = c₁`, `c_n = c_{n−2}` (scipy `mode='mirror'`).
    WholeSample,
}

/// How many derivatives [`BSplineField::evaluate`] computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Derivatives {
    /// The value only.
    Value,
    /// The value and the gradient.
    Gradient,
    /// The value, the gradient and the Hessian.
    Hessian,
}

/// The result of [`BSplineField::evaluate`]; parts that were not asked for are zero.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Evaluation<const D: usize> {
    /// `f(p)`.
    pub value: f64,
    /// `∇f(p)` in world units.
    pub gradient: Point<D>,
    /// `∇²f(p)` in world units (symmetric).
    pub hessian: [[f64; D]; D],
}

/// The clamp interval of continuous indices: the grid's box in index space.
pub(crate) fn clamp_range<const D: usize>(grid: &Grid<D>) -> (f64, [f64; D]) {
    let counts = grid.counts();
    match grid.centering() {
        Centering::Cell => (-0.5, counts.map(|n| n as f64 - 0.5)),
        Centering::Vertex => (0.0, counts.map(|n| n as f64 - 1.0)),
    }
}

/// A uniform tensor-product B-spline on a grid: `f(p) = Σⱼ cⱼ Π_a β(x_a − j_a)` with
/// `x = grid.continuous_index(p)` (see the [module docs](self)).
///
/// Coefficients are stored in the grid's C order (last axis fastest), one per sample.
#[derive(Debug, Clone)]
pub struct BSplineField<const D: usize> {
    grid: Grid<D>,
    coefficients: Vec<f64>,
    degree: Degree,
    boundary: Boundary,
    strides: [usize; D],
    lo: f64,
    hi: [f64; D],
    inv_spacing: [f64; D],
}

fn check_finite(values: &[f64], what: &str) -> Result<(), Error> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(record) => Err(Error::NonFinite {
            source_name: what.to_string(),
            record,
            line: None,
            field: "value",
            value: values[record],
        }),
    }
}

impl<const D: usize> BSplineField<D> {
    /// The spline of `degree` that interpolates `samples` (one per grid point, in the grid's
    /// C order), with the default [`Boundary::HalfSample`].
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if `samples.len() != grid.len()`; [`Error::NonFinite`] (naming
    /// the linear index as `record`) for a NaN or infinite sample.
    pub fn interpolate(grid: Grid<D>, samples: Vec<f64>, degree: Degree) -> Result<Self, Error> {
        Self::interpolate_with(grid, samples, degree, Boundary::HalfSample)
    }

    /// [`interpolate`](Self::interpolate) with a chosen boundary rule.
    ///
    /// # Errors
    /// As [`interpolate`](Self::interpolate).
    pub fn interpolate_with(
        grid: Grid<D>,
        mut samples: Vec<f64>,
        degree: Degree,
        boundary: Boundary,
    ) -> Result<Self, Error> {
        Self::check_len(&grid, &samples, "B-spline samples")?;
        check_finite(&samples, "B-spline samples")?;
        prefilter(&mut samples, grid.counts(), degree, boundary)?;
        Self::from_coefficients(grid, samples, degree, boundary)
    }

    /// Samples `field` at the grid points (with [`Grid::sample`]) and interpolates the samples
    /// ([`Boundary::HalfSample`]).
    ///
    /// # Errors
    /// [`Error::NonFinite`] if the field is NaN or infinite at a grid point.
    pub fn sample<F: ScalarField<D> + ?Sized>(
        field: &F,
        grid: Grid<D>,
        degree: Degree,
    ) -> Result<Self, Error> {
        Self::interpolate(grid, grid.try_sample(field)?, degree)
    }

    /// The spline with the given coefficients (no prefilter), in the grid's C order.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if `coefficients.len() != grid.len()`; [`Error::NonFinite`] for
    /// a NaN or infinite coefficient.
    pub fn from_coefficients(
        grid: Grid<D>,
        coefficients: Vec<f64>,
        degree: Degree,
        boundary: Boundary,
    ) -> Result<Self, Error> {
        Self::check_len(&grid, &coefficients, "B-spline coefficients")?;
        check_finite(&coefficients, "B-spline coefficients")?;
        let (lo, hi) = clamp_range(&grid);
        Ok(Self {
            strides: strides(grid.counts()),
            inv_spacing: grid.spacing().map(|h| 1.0 / h),
            grid,
            coefficients,
            degree,
            boundary,
            lo,
            hi,
        })
    }

    fn check_len(grid: &Grid<D>, values: &[f64], what: &'static str) -> Result<(), Error> {
        if values.len() == grid.len() {
            Ok(())
        } else {
            Err(Error::ShapeMismatch {
                what,
                expected: grid.len(),
                got: values.len(),
            })
        }
    }

    /// The grid.
    pub fn grid(&self) -> &Grid<D> {
        &self.grid
    }

    /// The coefficients, in the grid's C order.
    pub fn coefficients(&self) -> &[f64] {
        &self.coefficients
    }

    /// Consumes the field, returning its coefficients.
    pub fn into_coefficients(self) -> Vec<f64> {
        self.coefficients
    }

    /// The degree.
    pub fn degree(&self) -> Degree {
        self.degree
    }

    /// The boundary rule.
    pub fn boundary(&self) -> Boundary {
        self.boundary
    }

    /// The same B-splines as a [`Basis`](zeroset_field_core::basis::Basis).
    pub fn space(&self) -> BSplineSpace<D> {
        BSplineSpace::new(self.grid, self.degree, self.boundary)
    }

    /// `f(p)` (the point is clamped to the grid's box).
    pub fn value(&self, p: &Point<D>) -> f64 {
        self.value_at_index(self.grid.continuous_index(p))
    }

    /// `∇f(p)` in world units, analytic (at the clamped point outside the box).
    pub fn gradient(&self, p: &Point<D>) -> Point<D> {
        self.evaluate(p, Derivatives::Gradient).gradient
    }

    /// The Hessian `∇²f(p)` in world units. For the quadratic spline it is constant inside each
    /// cell and jumps on the cell faces (the knots), where the value on the upper side is
    /// returned.
    pub fn hessian(&self, p: &Point<D>) -> [[f64; D]; D] {
        self.evaluate(p, Derivatives::Hessian).hessian
    }

    /// The value and, as asked, the gradient and Hessian at `p`, in one pass over the
    /// coefficients.
    pub fn evaluate(&self, p: &Point<D>, derivatives: Derivatives) -> Evaluation<D> {
        let x = self.grid.continuous_index(p);
        let mut e = match (self.degree, derivatives) {
            // The same code path as `value`, so that the two agree bit for bit.
            (_, Derivatives::Value) => {
                return Evaluation {
                    value: self.value_at_index(x),
                    gradient: [0.0; D],
                    hessian: [[0.0; D]; D],
                };
            }
            (Degree::Quadratic, Derivatives::Gradient) => self.eval_index::<3, 1>(x),
            (Degree::Quadratic, Derivatives::Hessian) => self.eval_index::<3, 2>(x),
            (Degree::Cubic, Derivatives::Gradient) => self.eval_index::<4, 1>(x),
            (Degree::Cubic, Derivatives::Hessian) => self.eval_index::<4, 2>(x),
        };
        for a in 0..D {
            e.gradient[a] *= self.inv_spacing[a];
            for b in 0..D {
                e.hessian[a][b] *= self.inv_spacing[a] * self.inv_spacing[b];
            }
        }
        e
    }

    /// The value at a continuous index `x` (sample `i` at `x = i`; see
    /// [`Grid::continuous_index`]), clamped to the grid's box in index space like
    /// [`value`](Self::value). Skips the world-to-index transform.
    pub fn value_at_index(&self, x: [f64; D]) -> f64 {
        match self.degree {
            Degree::Quadratic => self.value_index::<3>(x),
            Degree::Cubic => self.value_index::<4>(x),
        }
    }

    /// The per-axis part of evaluation: the offsets (folded index × stride) of the `K`
    /// B-splines overlapping the clamped index `x` on axis `a`, and their weights.
    #[inline(always)]
    fn axis_taps<const K: usize>(&self, a: usize, x: f64) -> ([usize; K], AxisWeights<K>) {
        let aw = weights::<K>(x.clamp(self.lo, self.hi[a]));
        let n = self.grid.counts()[a];
        let mut offset = [0usize; K];
        if aw.first >= 0 && aw.first as usize + K <= n {
            let first = aw.first as usize;
            for (k, o) in offset.iter_mut().enumerate() {
                *o = (first + k) * self.strides[a];
            }
        } else {
            for (k, o) in offset.iter_mut().enumerate() {
                *o = fold(aw.first + k as isize, n, self.boundary) * self.strides[a];
            }
        }
        (offset, aw)
    }

    /// The taps of an outer axis of [`value_index`](Self::value_index), or a single tap of
    /// weight 1 for an axis that is not there.
    #[inline(always)]
    fn outer_taps<const K: usize>(
        &self,
        present: bool,
        a: usize,
        x: &[f64; D],
    ) -> (usize, [usize; K], [f64; K]) {
        if present {
            let (o, aw) = self.axis_taps::<K>(a, x[a]);
            (K, o, aw.w)
        } else {
            let mut w = [0.0; K];
            w[0] = 1.0;
            (1, [0; K], w)
        }
    }

    /// The value only, the hot path. Up to three axes are unrolled: the last (contiguous) axis
    /// is a dot product of `K` coefficients, the two before it loops of `K` (an axis missing in
    /// 1-D and 2-D counts as one tap of weight 1); `D > 3` takes the general path.
    #[inline(always)]
    fn value_index<const K: usize>(&self, x: [f64; D]) -> f64 {
        if D == 0 || D > 3 {
            return self.eval_index::<K, 0>(x).value;
        }
        let (n0, o0, w0) = self.outer_taps::<K>(D >= 3, D.saturating_sub(3), &x);
        let (n1, o1, w1) = self.outer_taps::<K>(D >= 2, D.saturating_sub(2), &x);
        let (o2, aw2) = self.axis_taps::<K>(D - 1, x[D - 1]);
        let w2 = aw2.w;
        let c = &self.coefficients;
        let mut sum = 0.0;
        if o2[K - 1] == o2[0] + K - 1 {
            // Unfolded: the K coefficients of each row are contiguous.
            for i in 0..n0 {
                let mut si = 0.0;
                for j in 0..n1 {
                    let start = o0[i] + o1[j] + o2[0];
                    let row = &c[start..start + K];
                    let mut dot = 0.0;
                    for k in 0..K {
                        dot += w2[k] * row[k];
                    }
                    si += w1[j] * dot;
                }
                sum += w0[i] * si;
            }
        } else {
            for i in 0..n0 {
                let mut si = 0.0;
                for j in 0..n1 {
                    let base = o0[i] + o1[j];
                    let mut dot = 0.0;
                    for k in 0..K {
                        dot += w2[k] * c[base + o2[k]];
                    }
                    si += w1[j] * dot;
                }
                sum += w0[i] * si;
            }
        }
        sum
    }

    /// [`value_at_index`](Self::value_at_index) at many indices, in parallel;
    /// bit-identical to the pointwise calls for any number of threads.
    ///
    /// Large batches (16,384 indices or more, and at least one per plane of axis 0 and block of
    /// 16 rows of axis 1) on grids larger than a cache (32,768 coefficients or more, `D ≥ 2`) are
    /// evaluated in a cache-friendly order: the indices are bucketed by the rows of the grid they
    /// read, each bucket is evaluated after its rows are streamed into the cache, and the
    /// results are put back in the caller's order — so that random points cost little more than
    /// points in a small grid. The same holds for [`ScalarField::values`]. The reordering
    /// allocates about 40–80 bytes per point, for at most 4,194,304 points at a time.
    ///
    /// # Panics
    /// If `indices.len() != out.len()`.
    pub fn values_at_indices(&self, indices: &[[f64; D]], out: &mut [f64]) {
        assert_eq!(
            indices.len(),
            out.len(),
            "BSplineField::values_at_indices: {} indices but {} output slots",
            indices.len(),
            out.len()
        );
        self.values_by(indices, out, |x| *x);
    }

    /// The core: value, gradient (`ORDER ≥ 1`) and Hessian (`ORDER ≥ 2`) at a continuous index,
    /// derivatives in index units, `K` = 3 (quadratic) or 4 (cubic) B-splines per axis.
    #[inline(always)]
    fn eval_index<const K: usize, const ORDER: usize>(&self, x: [f64; D]) -> Evaluation<D> {
        // Per axis: the offsets of the K B-splines and their weights w[a][order][k].
        let mut offset = [[0usize; K]; D];
        let mut w = [[[0.0; K]; 3]; D];
        for a in 0..D {
            let (o, aw) = self.axis_taps::<K>(a, x[a]);
            offset[a] = o;
            w[a] = [aw.w, aw.d1, aw.d2];
        }
        let mut e = Evaluation {
            value: 0.0,
            gradient: [0.0; D],
            hessian: [[0.0; D]; D],
        };
        let terms = K.pow(D as u32);
        for flat in 0..terms {
            let mut r = flat;
            let mut k = [0usize; D];
            let mut index = 0;
            for a in (0..D).rev() {
                k[a] = r % K;
                r /= K;
                index += offset[a][k[a]];
            }
            let c = self.coefficients[index];
            let mut v = c;
            for a in 0..D {
                v *= w[a][0][k[a]];
            }
            e.value += v;
            if ORDER >= 1 {
                for b in 0..D {
                    let mut g = c;
                    for a in 0..D {
                        g *= w[a][usize::from(a == b)][k[a]];
                    }
                    e.gradient[b] += g;
                }
            }
            if ORDER >= 2 {
                for b in 0..D {
                    for d in b..D {
                        let mut h = c;
                        for a in 0..D {
                            h *= w[a][usize::from(a == b) + usize::from(a == d)][k[a]];
                        }
                        e.hessian[b][d] += h;
                    }
                }
            }
        }
        if ORDER >= 2 {
            for b in 0..D {
                for d in 0..b {
                    e.hessian[b][d] = e.hessian[d][b];
                }
            }
        }
        e
    }
}

impl<const D: usize> ScalarField<D> for BSplineField<D> {
    fn value(&self, p: &Point<D>) -> f64 {
        BSplineField::value(self, p)
    }

    fn gradient(&self, p: &Point<D>) -> Point<D> {
        BSplineField::gradient(self, p)
    }

    fn values(&self, points: &[Point<D>], out: &mut [f64]) {
        assert_eq!(
            points.len(),
            out.len(),
            "ScalarField::values: {} points but {} output slots",
            points.len(),
            out.len()
        );
        self.values_by(points, out, |p| self.grid.continuous_index(p));
    }

    fn bounds(&self) -> Option<Aabb<D>> {
        Some(self.grid.bounds())
    }
}
