//! Sparse and dense least-squares solvers (being written).
