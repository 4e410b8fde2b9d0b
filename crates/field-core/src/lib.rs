//! # zeroset-field-core
//!
//! The ground every other zeroset crate stands on: points and boxes, uniform grids and box masks,
//! point clouds and their file formats, analytic test fields, and the three traits that decouple
//! representations from solvers:
//!
//! - [`ScalarField`] — a function `f: Rᴰ → R` (`D` = 2 or 3) with value,
//!   gradient, batched parallel evaluation and bounds. Every fitted representation implements it,
//!   so restoration and meshing accept any field.
//! - [`Basis`] — a linear function space `f(x) = Σⱼ cⱼ bⱼ(x)`: the row
//!   `[b₀(x), …, b_{n−1}(x)]` (sparse or dense) and its gradients, so that a fit assembles a
//!   design matrix `A` and solves `min ‖A c − y‖₂`.
//! - [`LeastSquaresSolver`] — `min ‖A x − b‖₂` for a dense matrix, a
//!   sparse matrix or a matrix-free operator, with a report (iterations, residuals, time).
//!   The implementations live in `zeroset-solvers`.
//!
//! ## The sign convention (stated once, used everywhere)
//!
//! A field is **negative inside** the solid, **positive outside**, and zero on the surface; the
//! outward normal is **`+∇f / ‖∇f‖`**. Point-cloud normals point out of the solid. A signed
//! distance function is the model: `f(x) = ‖x − c‖ − r` for a sphere. Papers that take
//! positive inside (the restoration paper, Jiang–Turk's inside/outside constraints) are flipped at
//! the boundary of zeroset, never inside it: see [`field::Negated`].
//!
//! ## Interoperability
//!
//! ndarray arrays, faer matrices and sprs sparse matrices are accepted without a copy where the
//! memory layout allows: see [`interop`] and [`lsq::LsqMatrix`].

#![warn(missing_docs)]

pub mod analytic;
pub mod basis;
pub mod cloud;
pub mod error;
pub mod field;
pub mod geometry;
pub mod grid;
pub mod interop;
pub mod io;
pub mod limits;
pub mod lsq;
pub mod mask;
pub mod memory;
pub mod rng;

pub use basis::{Basis, BasisField, BasisRow, PolynomialBasis};
pub use cloud::{CloudStats, PointCloud, PointCloud2, PointCloud3};
pub use error::{Error, Result};
pub use field::{ScalarField, ScalarField2, ScalarField3};
pub use geometry::{Aabb, Aabb2, Aabb3, Point, Point2, Point3};
pub use grid::{Centering, Grid, Grid2, Grid3};
pub use lsq::{
    LeastSquaresSolver, LeastSquaresSolverExt, LinearOperator, LsqMatrix, Monitor, Progress,
    Solution, SolveError, SolveInfo, Stage,
};
pub use mask::{BoxMask, Face, Side};
