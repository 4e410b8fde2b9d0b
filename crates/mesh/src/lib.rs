//! # zeroset-mesh
//!
//! Nothing here yet. This crate will hold isosurface extraction: marching squares and cubes on
//! any [`ScalarField`](zeroset_field_core::field::ScalarField), and the two-step signed marching
//! cubes of Zhang–Zhong–Wang driven by a black-box fast multipole method; mesh output (PLY, OBJ)
//! and previews.
