//! # zeroset
//!
//! Implicit surfaces in Rust: fit a scalar field to an oriented point cloud, restore it where it
//! went wrong, and mesh its zero set. This crate is the facade a geometry crate depends on; it
//! re-exports the workspace crates under short names:
//!
//! | module | crate | what it holds |
//! |---|---|---|
//! | [`core`] | `zeroset-field-core` | geometry, grids, masks, point clouds and file formats, the `ScalarField` / `Basis` / `LeastSquaresSolver` traits |
//! | [`solvers`] | `zeroset-solvers` | CGLS, LSQR, dense QR, LU on normal equations, sparse QR, sparse Cholesky, PCG, ADMM |
//! | [`bases`] | `zeroset-bases` | RBF fields (with a fast multipole evaluator), B-spline fields, neural fields and MRAS fields (multilevel rational algebraic splines) |
//! | [`restore`] | `zeroset-restore` | protrusion removal and de-noising by least squares |
//! | [`tensor`] | `zeroset-tensor` | 3-way tensors, unfoldings, trace norm, singular-value thresholding, CP-ALS with the adaptive rank of MRAS |
//! | [`mesh`] | `zeroset-mesh` | marching cubes and the two-step signed marching cubes |
//!
//! ```
//! use zeroset::core::analytic::Sphere;
//! use zeroset::core::field::ScalarField;
//!
//! let sphere = Sphere::new([0.0, 0.0, 0.0], 1.0);
//! assert!(sphere.value(&[0.0, 0.0, 0.0]) < 0.0); // negative inside
//! ```

pub use zeroset_bases as bases;
pub use zeroset_field_core as core;
pub use zeroset_mesh as mesh;
pub use zeroset_restore as restore;
pub use zeroset_solvers as solvers;
pub use zeroset_tensor as tensor;
