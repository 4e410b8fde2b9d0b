//! # zeroset-bases
//!
//! Nothing here yet. This crate will hold the fitted field representations, each a
//! [`Basis`](zeroset_field_core::basis::Basis) and a
//! [`ScalarField`](zeroset_field_core::field::ScalarField):
//! radial basis functions with incremental constraints (Jiang–Turk), uniform tensor-product
//! B-splines, multilevel low-rank splines (MRAS, Pan–Tong–Chen) and small neural fields.
