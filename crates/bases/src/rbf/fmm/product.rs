//! The product `w ↦ Φ w = (Σⱼ wⱼ φ(|xᵢ − xⱼ|))ᵢ` at the centres themselves by the FMM: the
//! kernel part of one GMRES step of the iterative fit ([`super::super::iterative`]) in
//! `O(N)` time and memory instead of the direct sum's `O(N²)` time.
//!
//! Each product builds the expansions for its weights over the same centres (the M2L operators
//! come once from the process-wide [`cache`](super::cache)). The products are inexact: GMRES on
//! them reaches a relative residual near the FMM's own relative error and no lower, so the
//! iterative fit asks for no less ([`FMM_PRODUCT_TOLERANCE`]); the fit's report measures the
//! constraint residual by the exact direct sum.

use std::sync::Mutex;

use zeroset_field_core::field::ScalarField;
use zeroset_field_core::{Aabb, Point};

use super::super::field::RbfField;
use super::super::kernel::Kernel;
use super::super::system::{Functional, Polynomial};
use super::{FmmError, FmmField, FmmOptions};

/// The expansion order of the products: for `r`, a relative error near 1e-9 of the field's
/// scale on the bunny (README, FMM accuracy table).
pub const FMM_PRODUCT_ORDER: usize = 8;

/// The expansion order of the residual check above
/// [`EXACT_RESIDUAL_MAX`](super::super::EXACT_RESIDUAL_MAX) functionals: its error must be
/// well below the products' (whose own error the solve absorbs and an FMM of the same order
/// would not see: 3.6e-10 measured against 1.3e-8 exact on the sphere set-up).
pub const FMM_RESIDUAL_ORDER: usize = 12;

/// The fewest sources per leaf of a product's tree (or `p³/2` if that is more). The products'
/// sources and targets are the fit's centres, which lie on or next to a surface, so a leaf's
/// near field holds far fewer than the 27 full leaves [`FmmOptions::leaf_size`]'s cost model
/// assumes for points spread through a volume, and larger leaves trade cheap direct sums for
/// fewer M2L translations. Measured at order 8 on 2 threads (one product, `zeroset fit --method
/// rbf`, whole fit in brackets): the full bunny's 104,502 centres 0.65–0.9 s at leaves of 256
/// (the default), 0.33 s at 600 and 1000, 2.1 s at 128 (fit 26 → 17 s); 300,000 centres around
/// a sphere 2.2 s → 0.85 s at 600, 0.88 s at 1000 (fit 73 → 48 s); the kitten's 15,630 centres
/// 74 → 50 ms.
pub const FMM_PRODUCT_LEAF: usize = 600;

/// The relative residual GMRES stops at on FMM products: residuals below the products' own
/// error are noise (an inexact Krylov method stagnates there).
pub const FMM_PRODUCT_TOLERANCE: f64 = 1e-8;

/// `Φ w` at the centres by the FMM: one field over the centres whose weights each product
/// replaces ([`FmmField::set_weights`]: the same tree, the expansions recomputed in place).
pub(crate) struct FmmProduct<K> {
    points: Vec<Point<3>>,
    field: Mutex<FmmField<K>>,
}

impl<K: Kernel + Clone> FmmProduct<K> {
    /// The product over `points` (the centres, `D = 3`, distinct) at [`FMM_PRODUCT_ORDER`].
    pub(crate) fn new<const D: usize>(kernel: &K, points: &[Point<D>]) -> Result<Self, FmmError> {
        Self::with_order(kernel, points, FMM_PRODUCT_ORDER)
    }

    /// The product at expansion order `order`.
    pub(crate) fn with_order<const D: usize>(
        kernel: &K,
        points: &[Point<D>],
        order: usize,
    ) -> Result<Self, FmmError> {
        assert_eq!(D, 3, "the FMM product is three-dimensional");
        let points: Vec<Point<3>> = points
            .iter()
            .map(|p| std::array::from_fn(|a| p[a]))
            .collect();
        let n = points.len();
        let bounds = Aabb::from_points(&points).ok_or(FmmError::NoSources)?;
        let options = FmmOptions::new(order)
            .with_expected_points(n)
            .with_leaf_size(FMM_PRODUCT_LEAF.max(order.pow(3) / 2));
        let zero = RbfField::from_parts(
            kernel.clone(),
            points.clone(),
            vec![Functional::Value; n],
            vec![0.0; n],
            vec![0.0; n],
            Polynomial::fit(&points),
            vec![0.0; Polynomial::<3>::len()],
            bounds,
        );
        let field = FmmField::new(&zero, &options)?;
        Ok(Self {
            points,
            field: Mutex::new(field),
        })
    }

    /// `out = Φ w`; NaN everywhere if the FMM refuses the weights (a non-finite weight), so
    /// that the Krylov method stops on it.
    pub(crate) fn apply(&self, w: &[f64], out: &mut [f64]) {
        let mut field = self.field.lock().unwrap_or_else(|e| e.into_inner());
        match field.set_weights(w) {
            Ok(()) => field.values(&self.points, out),
            Err(_) => out.fill(f64::NAN),
        }
    }
}
