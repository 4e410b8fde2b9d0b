//! # zeroset-bases
//!
//! The fitted field representations, each a [`Basis`](zeroset_field_core::basis::Basis) and a
//! [`ScalarField`](zeroset_field_core::field::ScalarField):
//!
//! - [`bspline`] — uniform tensor-product B-splines (quadratic and cubic) on a grid, with exact
//!   interpolation of grid samples (a parallel tridiagonal prefilter, mirror boundaries), analytic
//!   gradients and Hessians, and the B-splines as a sparse [`Basis`](zeroset_field_core::basis::Basis).
//! - [`tangent_plane`] — Hoppe et al.'s signed distance to the nearest sample's tangent plane
//!   (optionally a weighted mean over `k` neighbours): no fit, a baseline (a field, not a basis).
//! - [`field_file`] — the versioned, checksummed `.zsf` file of B-spline, RBF, neural and MRAS fields.
//! - [`rbf`] — radial basis functions (`r`, `r³`, thin plate, Wendland, user kernels) through value and
//!   gradient (Hermite) constraints, with Carr's off-surface points, dense, mixed-precision and
//!   iterative fits, and incremental constraints by the Schur complement (Jiang–Turk).
//!
//! - [`neural`] — a small multilayer perceptron trained with Jiang–Turk's thin-plate curvature
//!   loss (input Hessians and their parameter gradients written out over faer products), its
//!   hidden layers as a learned [`Basis`](zeroset_field_core::basis::Basis).
//! - [`mras`] — multilevel rational algebraic splines (Pan–Tong–Chen): an octree of quadratic
//!   B-spline offsets blended by a partition of unity, fitted by ADMM with a trace-norm term and
//!   stored as CP factors of adaptive rank.
//! - [`noise`] — how noisy a scan is: its points' scatter about a local quadric, against their
//!   spacing (noisy scans are approximated, not interpolated).
//! - [`normals`] — outward normals for a scan without them: local planes by PCA, signs
//!   propagated along a minimum spanning forest (Hoppe et al. 1992), each piece turned outward.
//! - [`thickness`] — whether a cloud samples a surface or fills a volume: its neighbourhoods'
//!   thinnest spread against their widest, from 32 neighbours to 2048.
//! - [`outliers`] — the stray samples of an oriented scan (isolated from the surface the rest
//!   samples), set aside before a fit so that they do not become surface.

#![warn(missing_docs)]

pub mod bspline;
pub mod field_file;
mod meeting;
pub mod mras;
pub mod neural;
pub mod noise;
pub mod normals;
pub mod outliers;
pub mod rbf;
pub mod tangent_plane;
pub mod thickness;
