//! A fitted RBF field: `s(x) = Σⱼ wⱼ Lⱼʸ φ(|x − y|) + c · p(x)`, and the RBF space as a
//! [`Basis`].

use rayon::prelude::*;
use zeroset_field_core::basis::{Basis, BasisRow};
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::{Aabb, Point};

use super::kernel::{self, Kernel};
use super::system::{self, Functional, Functionals, Polynomial};

/// A fitted RBF field. Evaluation is a direct sum over the centres (`O(n)` per point),
/// parallel over points; where every constraint is a value the sum runs vectorised (AVX2
/// where the CPU has it) with eight fixed-order partial sums, so results do not depend on the
/// thread count.
#[derive(Debug, Clone)]
pub struct RbfField<K, const D: usize> {
    pub(crate) kernel: K,
    pub(crate) functionals: Functionals<D>,
    pub(crate) weights: Vec<f64>,
    pub(crate) poly: Polynomial<D>,
    pub(crate) poly_coefficients: Vec<f64>,
    pub(crate) bounds: Aabb<D>,
}

impl<K: Kernel, const D: usize> RbfField<K, D> {
    /// A field from its stored parts (the field file's reader): `points`, `kinds` and
    /// `targets` are the functionals, one each per weight. The caller checks the lengths.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn from_parts(
        kernel: K,
        points: Vec<Point<D>>,
        kinds: Vec<Functional>,
        targets: Vec<f64>,
        weights: Vec<f64>,
        poly: Polynomial<D>,
        poly_coefficients: Vec<f64>,
        bounds: Aabb<D>,
    ) -> Self {
        let soa = std::array::from_fn(|a| points.iter().map(|p| p[a]).collect());
        Self {
            kernel,
            functionals: Functionals {
                points,
                kinds,
                targets,
                soa,
                diagonal: 0.0,
            },
            weights,
            poly,
            poly_coefficients,
            bounds,
        }
    }

    /// The functionals' points, kinds and targets (the field file's writer).
    pub(crate) fn functionals(&self) -> &Functionals<D> {
        &self.functionals
    }

    /// The polynomial's centre and scale (the field file's writer).
    pub(crate) fn polynomial(&self) -> &Polynomial<D> {
        &self.poly
    }

    /// The kernel.
    pub fn kernel(&self) -> &K {
        &self.kernel
    }

    /// The number of centres (functionals: a gradient constraint counts `D`).
    pub fn num_centres(&self) -> usize {
        self.functionals.len()
    }

    /// The kernel weights `w`, one per functional.
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// The coefficients `c` of the linear polynomial `1, (x − m)/h`.
    pub fn polynomial_coefficients(&self) -> &[f64] {
        &self.poly_coefficients
    }

    /// The polynomial part in absolute coordinates: `(a, b)` with `p(x) = a + b · x`.
    pub fn linear_part(&self) -> (f64, Point<D>) {
        let c = &self.poly_coefficients;
        let b: Point<D> = std::array::from_fn(|k| c[1 + k] / self.poly.scale);
        let a = c[0] - (0..D).map(|k| b[k] * self.poly.centre[k]).sum::<f64>();
        (a, b)
    }

    /// The centres (one per functional: a gradient constraint repeats its point `D` times).
    pub fn centres(&self) -> &[Point<D>] {
        &self.functionals.points
    }

    /// The Hessian `∇²s(x)` (analytic; a gradient constraint's centre needs the kernel's third
    /// derivatives, which are undefined exactly at the centre and taken as 0 there).
    pub fn hessian(&self, x: &Point<D>) -> [[f64; D]; D] {
        let mut h = [[0.0; D]; D];
        let f = &self.functionals;
        for j in 0..f.len() {
            let d = sub(x, &f.points[j]);
            let w = self.weights[j];
            match f.kinds[j] {
                Functional::Value => {
                    let hj = kernel::hessian(&self.kernel, &d);
                    for a in 0..D {
                        for b in 0..D {
                            h[a][b] += w * hj[a][b];
                        }
                    }
                }
                Functional::Derivative(c) => {
                    let t = kernel::third(&self.kernel, &d);
                    for a in 0..D {
                        for b in 0..D {
                            h[a][b] -= w * t[a][b][c];
                        }
                    }
                }
            }
        }
        h
    }

    /// The basis function of functional `j` at `x`, and its gradient.
    fn basis_function(&self, j: usize, x: &Point<D>) -> (f64, Point<D>) {
        let d = sub(x, &self.functionals.points[j]);
        match self.functionals.kinds[j] {
            Functional::Value => (
                kernel::value(&self.kernel, &d),
                kernel::gradient(&self.kernel, &d),
            ),
            Functional::Derivative(b) => {
                let h = kernel::hessian(&self.kernel, &d);
                (
                    -kernel::gradient(&self.kernel, &d)[b],
                    std::array::from_fn(|a| -h[a][b]),
                )
            }
        }
    }

    /// The vectorised value-only sum at `x` (see [`system::kernel_sum`]).
    #[inline(always)]
    fn value_sum(&self, x: &Point<D>) -> f64 {
        system::kernel_sum(&self.kernel, &self.functionals, &self.weights, x)
    }
}

impl<K: Kernel, const D: usize> ScalarField<D> for RbfField<K, D> {
    fn value(&self, x: &Point<D>) -> f64 {
        let poly = self.poly.value(&self.poly_coefficients, x);
        if self.functionals.values_only() {
            return self.value_sum(x) + poly;
        }
        let s: f64 = (0..self.functionals.len())
            .map(|j| self.weights[j] * self.basis_function(j, x).0)
            .sum();
        s + poly
    }

    fn gradient(&self, x: &Point<D>) -> Point<D> {
        let mut g = self.poly.gradient(&self.poly_coefficients);
        if self.functionals.values_only() {
            let k = system::kernel_gradient_sum(&self.kernel, &self.functionals, &self.weights, x);
            for a in 0..D {
                g[a] += k[a];
            }
            return g;
        }
        for j in 0..self.functionals.len() {
            let (_, gj) = self.basis_function(j, x);
            for a in 0..D {
                g[a] += self.weights[j] * gj[a];
            }
        }
        g
    }

    fn values(&self, points: &[Point<D>], out: &mut [f64]) {
        assert_eq!(
            points.len(),
            out.len(),
            "values: points and out differ in length"
        );
        let arch = pulp::Arch::new();
        out.par_chunks_mut(64)
            .zip(points.par_chunks(64))
            .for_each(|(o, p)| {
                arch.dispatch(Batch {
                    field: self,
                    points: p,
                    out: o,
                })
            });
    }

    fn bounds(&self) -> Option<Aabb<D>> {
        Some(self.bounds)
    }
}

/// A batch of evaluations, compiled per instruction set (see [`RbfField::values`]).
struct Batch<'a, K, const D: usize> {
    field: &'a RbfField<K, D>,
    points: &'a [Point<D>],
    out: &'a mut [f64],
}

impl<K: Kernel, const D: usize> pulp::WithSimd for Batch<'_, K, D> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let field = self.field;
        for (o, x) in self.out.iter_mut().zip(self.points) {
            *o = if field.functionals.values_only() {
                field.value_sum(x) + field.poly.value(&field.poly_coefficients, x)
            } else {
                field.value(x)
            };
        }
    }
}

/// The RBF space of a fit's centres: one basis function per functional, then the `D + 1`
/// polynomial terms. Dense rows.
#[derive(Debug, Clone)]
pub struct RbfSpace<K, const D: usize> {
    field: RbfField<K, D>,
}

impl<K: Kernel, const D: usize> RbfSpace<K, D> {
    /// The space spanned by `field`'s centres and polynomial.
    pub fn of(field: &RbfField<K, D>) -> Self
    where
        K: Clone,
    {
        Self {
            field: field.clone(),
        }
    }
}

impl<K: Kernel, const D: usize> Basis<D> for RbfSpace<K, D> {
    fn num_coefficients(&self) -> usize {
        self.field.functionals.len() + Polynomial::<D>::len()
    }

    fn bounds(&self) -> Aabb<D> {
        self.field.bounds
    }

    fn max_row_nnz(&self) -> usize {
        self.num_coefficients()
    }

    fn eval_row(&self, p: &Point<D>, with_gradients: bool, row: &mut BasisRow<D>) {
        row.clear();
        let n = self.field.functionals.len();
        for j in 0..n {
            let (v, g) = self.field.basis_function(j, p);
            row.indices.push(j);
            row.values.push(v);
            if with_gradients {
                row.gradients.push(g);
            }
        }
        let poly = &self.field.poly;
        let values = poly.row(p, Functional::Value);
        for k in 0..Polynomial::<D>::len() {
            row.indices.push(n + k);
            row.values.push(values[k]);
            if with_gradients {
                let mut g = [0.0; D];
                if k > 0 {
                    g[k - 1] = 1.0 / poly.scale;
                }
                row.gradients.push(g);
            }
        }
    }
}

fn sub<const D: usize>(a: &Point<D>, b: &Point<D>) -> Point<D> {
    std::array::from_fn(|i| a[i] - b[i])
}
