//! The M2L operators, compressed, and their application in blocks.
//!
//! The M2L operator between two cells of one level whose integer offset is `t` (a vector in
//! `{−3, …, 3}³` with `‖t‖∞ ≥ 2`: 316 of them) is the `p³ × p³` matrix
//! `K_t[A, B] = φ(|w t + h (x̄_A − x̄_B)|)` over the cells' Chebyshev nodes (`w = 2h` the width).
//! The 48 symmetries of the cube (axis permutations and reflections) map every offset onto one
//! of **16 canonical offsets** `0 ≤ c₂ ≤ c₁ ≤ c₀`, and, because the Chebyshev nodes are
//! symmetric (`−x̄_a = x̄_{p−1−a}`), they act on the node indices as a permutation `P`:
//! `K_t[A, B] = K_c[P(A), P(B)]` (Messner, Schanz & Darve 2012, §3). Each `K_c` is compressed
//! once by a truncated SVD, `K_c ≈ U_c Σ_c V_cᵀ`, keeping the singular values above
//! `ε · σ₁` (computed by a seeded randomised range finder, exact to well below `ε` because the
//! singular values of a smooth kernel fall geometrically). All pairs of one level whose offsets
//! share a canonical operator are applied together, in blocks: two dense products per block,
//! `U_cΣ_c (V_cᵀ X)`, with `X` the permuted expansions.
//!
//! A kernel with [`homogeneity`](crate::rbf::Kernel::homogeneity) `k` (`r`, `r³`) has
//! `K_t(w) = wᵏ K_t(1)`: one set of operators at unit width serves every level. Any other
//! kernel gets its operators per level (per cell width), cached.

use std::sync::{Arc, Mutex};

use faer::linalg::matmul::matmul;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;

use super::chebyshev::Chebyshev;
use super::tree::offset_of;
use crate::rbf::kernel::{self, Kernel};

/// The compressed operator of one canonical offset.
#[derive(Debug, Clone)]
pub(crate) struct Compressed {
    /// `U Σ`, `p³ × r`.
    pub us: Mat<f64>,
    /// `V`, `p³ × r`.
    pub v: Mat<f64>,
}

/// The 16 compressed operators of one cell width.
#[derive(Debug, Clone)]
pub(crate) struct LevelOperators {
    pub canonical: Vec<Compressed>,
}

impl LevelOperators {
    /// The ranks kept, per canonical offset.
    pub fn ranks(&self) -> Vec<usize> {
        self.canonical.iter().map(|c| c.us.ncols()).collect()
    }
}

/// How the symmetries map offsets to canonical ones.
#[derive(Debug, Clone)]
pub(crate) struct Symmetry {
    /// The canonical offsets `[c₀, c₁, c₂]`.
    pub canonical: Vec<[i64; 3]>,
    /// Per offset code: its canonical index (`usize::MAX` for the 27 adjacent offsets).
    pub canonical_of: Vec<usize>,
    /// Per offset code: `perm[A]`, the canonical node index of node `A`.
    pub perm: Vec<Vec<u32>>,
}

impl Symmetry {
    pub fn new(p: usize) -> Self {
        let mut canonical: Vec<[i64; 3]> = Vec::new();
        let mut canonical_of = vec![usize::MAX; 343];
        let mut perm = vec![Vec::new(); 343];
        for code in 0..343 {
            let t = offset_of(code);
            if t.iter().all(|v| v.abs() <= 1) {
                continue;
            }
            // π sorts |t| decreasingly (stable); σ reflects the axes where t < 0.
            let mut pi = [0usize, 1, 2];
            pi.sort_by_key(|&a| std::cmp::Reverse(t[a].abs()));
            let c = [t[pi[0]].abs(), t[pi[1]].abs(), t[pi[2]].abs()];
            let index = match canonical.iter().position(|&x| x == c) {
                Some(i) => i,
                None => {
                    canonical.push(c);
                    canonical.len() - 1
                }
            };
            canonical_of[code] = index;
            let sigma = |axis: usize, a: usize| if t[axis] < 0 { p - 1 - a } else { a };
            let mut map = vec![0u32; p * p * p];
            for (lin, m) in map.iter_mut().enumerate() {
                let a = [lin / (p * p), (lin / p) % p, lin % p];
                let b: [usize; 3] = std::array::from_fn(|i| sigma(pi[i], a[pi[i]]));
                *m = (b[0] * p * p + b[1] * p + b[2]) as u32;
            }
            perm[code] = map;
        }
        Self {
            canonical,
            canonical_of,
            perm,
        }
    }
}

/// Everything the M2L step needs for one kernel and order: the symmetries and the compressed
/// operators, built on first use per cell width and shared (an `Arc`) between fields.
#[derive(Debug)]
pub struct FmmOperators {
    pub(crate) cheb: Chebyshev,
    pub(crate) symmetry: Symmetry,
    pub(crate) tolerance: f64,
    kernel_name: String,
    homogeneity: Option<i32>,
    /// `(width, operators)`; for homogeneous kernels only width 1.
    cache: Mutex<Vec<(f64, Arc<LevelOperators>)>>,
}

impl FmmOperators {
    /// The operators of `kernel` at order `p` (`p` Chebyshev nodes per axis), singular values
    /// kept down to `tolerance` relative to the largest. Nothing is computed until a field
    /// needs it.
    pub(crate) fn new<K: Kernel + ?Sized>(kernel: &K, p: usize, tolerance: f64) -> Self {
        Self {
            cheb: Chebyshev::new(p),
            symmetry: Symmetry::new(p),
            tolerance,
            kernel_name: kernel.name().to_owned(),
            homogeneity: kernel.homogeneity(),
            cache: Mutex::new(Vec::new()),
        }
    }

    /// The order `p`.
    pub fn order(&self) -> usize {
        self.cheb.order()
    }

    /// The kernel these operators were built for (its [`Kernel::name`]).
    pub fn kernel_name(&self) -> &str {
        &self.kernel_name
    }

    /// The relative singular-value cut-off of the compression.
    pub fn tolerance(&self) -> f64 {
        self.tolerance
    }

    /// Whether `kernel` is the one these operators were built for (same name and homogeneity).
    pub(crate) fn fits<K: Kernel + ?Sized>(&self, kernel: &K) -> bool {
        kernel.name() == self.kernel_name && kernel.homogeneity() == self.homogeneity
    }

    /// The operators for cells of width `width`, and the factor their products are scaled by.
    pub(crate) fn level<K: Kernel + ?Sized>(
        &self,
        kernel: &K,
        width: f64,
    ) -> (Arc<LevelOperators>, f64) {
        let (key, scale) = match self.homogeneity {
            Some(k) => (1.0, width.powi(k)),
            None => (width, 1.0),
        };
        // A poisoned lock only means another thread panicked while building; the cache is a
        // list of complete entries, so it is still valid.
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, ops)) = cache.iter().find(|(w, _)| *w == key) {
            return (ops.clone(), scale);
        }
        let ops = Arc::new(self.build(kernel, key));
        cache.push((key, ops.clone()));
        (ops, scale)
    }

    fn build<K: Kernel + ?Sized>(&self, kernel: &K, width: f64) -> LevelOperators {
        let p = self.cheb.order();
        let n = p * p * p;
        let h = 0.5 * width;
        let nodes = self.cheb.nodes();
        let canonical = self
            .symmetry
            .canonical
            .par_iter()
            .map(|c| {
                let k = Mat::from_fn(n, n, |i, j| {
                    let a = [i / (p * p), (i / p) % p, i % p];
                    let b = [j / (p * p), (j / p) % p, j % p];
                    let d: [f64; 3] = std::array::from_fn(|x| {
                        width * c[x] as f64 + h * (nodes[a[x]] - nodes[b[x]])
                    });
                    kernel::value(kernel, &d)
                });
                compress(k.as_ref(), self.tolerance)
            })
            .collect();
        LevelOperators { canonical }
    }
}

/// Truncated SVD `K ≈ (UΣ) Vᵀ`, keeping the singular values above `tolerance · σ₁`, by a
/// randomised range finder (Halko, Martinsson & Tropp 2011, Alg. 4.4 with one power step): the
/// singular values of a smooth kernel's operator fall geometrically, so a sample of `l`
/// columns `K Ω` (seeded, so the result is always the same) captures the leading `l − 16` to
/// full accuracy. `l` starts at 64 and doubles until the last kept singular value lies at
/// least 16 columns inside the sample, or `l = n` (then this is the plain SVD). All products
/// and SVDs are sequential, so the result does not depend on the thread count.
///
/// Cost `O(n² l)` instead of the plain SVD's `O(n³)`: at `p = 8` (`n = 512`, kept ranks
/// 20–70) about 15× less.
fn compress(k: MatRef<'_, f64>, tolerance: f64) -> Compressed {
    const OVERSAMPLE: usize = 16;
    let n = k.nrows();
    let mut l = 64.min(n);
    loop {
        if let Some(c) = sampled_svd(k, l, tolerance) {
            if c.us.ncols() + OVERSAMPLE <= l || l == n {
                return c;
            }
        } else if l == n {
            // The SVD of a smooth kernel's matrix does not fail to converge; if it ever did,
            // the uncompressed operator (rank n via the identity factorisation) is still exact.
            return Compressed {
                us: k.to_owned(),
                v: Mat::identity(n, n),
            };
        }
        l = (2 * l).min(n);
    }
}

/// The truncated SVD of `K` restricted to the range of `K Ω` (`Ω`: `n × l`, seeded), after one
/// power step; `None` if an SVD did not converge.
fn sampled_svd(k: MatRef<'_, f64>, l: usize, tolerance: f64) -> Option<Compressed> {
    let n = k.nrows();
    let mut state = 0x5EED_u64;
    let omega = Mat::from_fn(n, l, |_, _| {
        // SplitMix64, uniform in [−1, 1).
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        2.0 * (((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64) - 1.0
    });
    let mut y = Mat::<f64>::zeros(n, l);
    product(y.as_mut(), k, omega.as_ref(), 1.0);
    let q = zeroset_tensor::thin_svd(y.as_ref()).ok()?.u;
    let mut z = Mat::<f64>::zeros(n, l);
    product(z.as_mut(), k.transpose(), q.as_ref(), 1.0);
    let q = zeroset_tensor::thin_svd(z.as_ref()).ok()?.u;
    product(y.as_mut(), k, q.as_ref(), 1.0);
    let q = zeroset_tensor::thin_svd(y.as_ref()).ok()?.u;
    // B = Qᵀ K (l × n) = Ũ Σ Vᵀ, so K ≈ (Q Ũ) Σ Vᵀ.
    let mut b = Mat::<f64>::zeros(l, n);
    product(b.as_mut(), q.transpose(), k, 1.0);
    let zeroset_tensor::ThinSvd { u: ub, s: sv, v } = zeroset_tensor::thin_svd(b.as_ref()).ok()?;
    let rank = sv
        .iter()
        .take_while(|&&x| x > tolerance * sv[0])
        .count()
        .max(1);
    let mut us = Mat::<f64>::zeros(n, rank);
    product(us.as_mut(), q.as_ref(), ub.subcols(0, rank), 1.0);
    for j in 0..rank {
        for i in 0..n {
            us[(i, j)] *= sv[j];
        }
    }
    Some(Compressed {
        us,
        v: v.subcols(0, rank).to_owned(),
    })
}

/// Pairs per dense product (about): fixed, so that results never depend on the thread count.
const BLOCK: usize = 96;

/// A slice written from several threads at disjoint ranges.
#[derive(Clone, Copy)]
pub(crate) struct Shared(*mut f64);
// SAFETY: `Shared` is only used to write disjoint ranges from different threads (see uses).
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}

impl Shared {
    pub fn new(s: &mut [f64]) -> Self {
        Self(s.as_mut_ptr())
    }

    /// # Safety
    /// `start..start + len` lies inside the slice `self` was made from, and no other
    /// reference to that range is alive while the returned one is.
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn range(&self, start: usize, len: usize) -> &mut [f64] {
        // SAFETY: guaranteed by the caller.
        unsafe { std::slice::from_raw_parts_mut(self.0.add(start), len) }
    }
}

/// An M2L pair with the offset code of its target relative to its source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct CodedPair {
    pub target: u32,
    pub code: u16,
    pub source: u32,
}

/// `L_T += scale · K_t M_S` for every pair of one level whose offset maps to the canonical
/// operator `canonical`. `pairs` must be sorted (by target, then offset code).
///
/// The pairs are cut into blocks of about [`BLOCK`] that never split one target's pairs; a
/// block gathers its permuted expansions into one matrix, applies `U_cΣ_c (V_cᵀ X)` as two
/// dense products, and adds the permuted results into its own targets, in order. The blocks
/// depend on the pairs alone, so the sums do not depend on the thread count.
#[allow(clippy::too_many_arguments)]
pub(crate) fn apply(
    ops: &LevelOperators,
    symmetry: &Symmetry,
    canonical: usize,
    pairs: &[CodedPair],
    scale: f64,
    multipoles: &[f64],
    locals: Shared,
    n: usize,
) {
    debug_assert!(pairs.is_sorted());
    let op = &ops.canonical[canonical];
    let rank = op.us.ncols();
    let mut bounds = vec![0];
    let mut end = 0;
    while end < pairs.len() {
        end = (end + BLOCK).min(pairs.len());
        while end < pairs.len() && pairs[end].target == pairs[end - 1].target {
            end += 1;
        }
        bounds.push(end);
    }
    bounds.par_windows(2).for_each(|w| {
        let block = &pairs[w[0]..w[1]];
        let m = block.len();
        SCRATCH.with_borrow_mut(|buf| {
            // x (n × m), y (rank × m), z (n × m): every entry is written before it is read.
            if buf.len() < (2 * n + rank) * m {
                buf.resize((2 * n + rank) * m, 0.0);
            }
            let (xs, rest) = buf.split_at_mut(n * m);
            let (ys, rest) = rest.split_at_mut(rank * m);
            let zs = &mut rest[..n * m];
            for (pair, col) in block.iter().zip(xs.chunks_exact_mut(n)) {
                let src = &multipoles[pair.source as usize * n..][..n];
                let perm = &symmetry.perm[pair.code as usize][..n];
                for (&v, &to) in src.iter().zip(perm) {
                    // SAFETY: `perm` is a permutation of `0..n` (`Symmetry::new`).
                    unsafe { *col.get_unchecked_mut(to as usize) = v };
                }
            }
            let x = MatRef::from_column_major_slice(xs, n, m);
            let mut y = MatMut::from_column_major_slice_mut(ys, rank, m);
            product(y.rb_mut(), op.v.transpose(), x, 1.0);
            let mut z = MatMut::from_column_major_slice_mut(zs, n, m);
            product(z.rb_mut(), op.us.as_ref(), y.rb(), scale);
            for (pair, col) in block.iter().zip(zs.chunks_exact(n)) {
                let perm = &symmetry.perm[pair.code as usize][..n];
                // SAFETY: all pairs of a target are in one block, and the blocks of one call
                // run over distinct targets, so only this task writes this target's range now.
                let local = unsafe { locals.range(pair.target as usize * n, n) };
                for (l, &from) in local.iter_mut().zip(perm) {
                    // SAFETY: `perm` is a permutation of `0..n`.
                    *l += unsafe { *col.get_unchecked(from as usize) };
                }
            }
        });
    });
}

thread_local! {
    /// Work space of [`apply`], kept per thread between blocks.
    static SCRATCH: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

fn product(out: MatMut<'_, f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>, alpha: f64) {
    matmul(out, Accum::Replace, a, b, alpha, Par::Seq);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rbf::fmm::tree::offset_code;
    use crate::rbf::kernel::Biharmonic;

    /// The permuted canonical operator equals the operator built for the offset itself.
    #[test]
    fn symmetries_map_every_offset_to_its_canonical_operator() {
        let p = 3;
        let sym = Symmetry::new(p);
        assert_eq!(sym.canonical.len(), 16);
        assert_eq!(
            sym.canonical_of
                .iter()
                .filter(|&&c| c != usize::MAX)
                .count(),
            316
        );
        let cheb = Chebyshev::new(p);
        let nodes = cheb.nodes();
        let h = 0.5;
        let k = |t: [f64; 3], a: usize, b: usize| {
            let ia = [a / (p * p), (a / p) % p, a % p];
            let ib = [b / (p * p), (b / p) % p, b % p];
            let d: [f64; 3] = std::array::from_fn(|x| t[x] + h * (nodes[ia[x]] - nodes[ib[x]]));
            kernel::value(&Biharmonic, &d)
        };
        for t in [[2, -3, 1], [-3, -3, 0], [0, 2, -2], [-1, 0, 3]] {
            let code = offset_code(t);
            let c = sym.canonical[sym.canonical_of[code]];
            let perm = &sym.perm[code];
            for a in 0..p * p * p {
                for b in 0..p * p * p {
                    let direct = k(t.map(|v| v as f64), a, b);
                    let canon = k(c.map(|v| v as f64), perm[a] as usize, perm[b] as usize);
                    assert!((direct - canon).abs() < 1e-13, "{t:?} {a} {b}");
                }
            }
        }
    }
}
