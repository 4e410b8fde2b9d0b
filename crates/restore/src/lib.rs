//! # zeroset-restore
//!
//! Nothing here yet. This crate will hold mask-based restoration of a scalar field
//! (Ren–Fujita–Nakata): protrusion removal by a Laplace least-squares problem inside a box mask
//! with Dirichlet and Neumann rows, and de-noising by coarse resampling and quadratic B-spline
//! interpolation. The least-squares problems are solved by `zeroset-solvers`.
