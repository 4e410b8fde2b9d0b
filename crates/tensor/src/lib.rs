//! # zeroset-tensor
//!
//! Nothing here yet. This crate will hold 3-way tensors, their unfoldings, singular-value
//! thresholding and the trace norm, and CP decomposition by alternating least squares with an
//! adaptive rank (the compression step of MRAS).
