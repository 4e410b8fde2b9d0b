//! The M2L step: the pairs of the interaction lists applied through the compressed operators
//! of [`super::operators`], per operator or in the shared basis.

use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Mat, MatMut, MatRef};
use rayon::prelude::*;

use super::operators::{Compressed, OffsetOperator, Symmetry, product};

/// Pairs per dense product (per operator; about): fixed, so that results never depend on the
/// thread count.
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

/// How many of `columns` leading singular vectors with singular values `sigma` (decreasing)
/// have `σ ≥ cut · σ₁` (at least one); all of them for an uncompressed operator (no `sigma`).
pub(crate) fn rank_for(sigma: &[f64], columns: usize, cut: f64) -> usize {
    match sigma.first() {
        None => columns,
        Some(&first) => sigma
            .iter()
            .take(columns)
            .take_while(|&&s| s >= cut * first)
            .count()
            .max(1),
    }
}

/// Per operator: `L_T += scale · K_t M_S` for every pair of one level whose offset maps to the
/// canonical operator `class`, keeping the singular values of at least `cut` relative to the
/// largest ([`rank_for`]). `pairs` must be sorted (by target, then offset code).
///
/// The pairs are cut into blocks of about [`BLOCK`] that never split one target's pairs; a
/// block gathers its permuted expansions into one matrix, applies `U_cΣ_c (V_cᵀ X)` as two
/// dense products, and adds the permuted results into its own targets, in order. The blocks
/// depend on the pairs alone, so the sums do not depend on the thread count.
#[allow(clippy::too_many_arguments)]
pub(crate) fn per_operator(
    canonical: &[Compressed],
    symmetry: &Symmetry,
    class: usize,
    pairs: &[CodedPair],
    scale: f64,
    cut: f64,
    multipoles: &[f64],
    locals: Shared,
    n: usize,
) {
    debug_assert!(pairs.is_sorted());
    let op = &canonical[class];
    let rank = rank_for(&op.sigma, op.us.ncols(), cut);
    let (us, v) = (op.us.subcols(0, rank), op.v.subcols(0, rank));
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
            product(y.rb_mut(), v.transpose(), x, 1.0);
            let mut z = MatMut::from_column_major_slice_mut(zs, n, m);
            product(z.rb_mut(), us, y.rb(), scale);
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

/// Shared basis: `L_T += K_t (s_S M_S)` for every pair of `pairs` (all served by `basis`,
/// whose columns have the singular values `basis_sigma` and take the reflection signs
/// `signs[σ]`, and by `offsets`, the operators of the offsets `t ≥ 0`; `mirror` maps an offset
/// code to that of `|t|` and its reflection; `scale(S)` the factor of the source's level,
/// `cut(S)` the singular value its level keeps, relative to the largest of each operator
/// ([`rank_for`]) and absolute for the basis, `level(S)` its level; cells numbered below
/// `cells`), in three steps, each level using the leading `r_ℓ` columns of the basis that its
/// cut keeps:
///
/// 1. every source's expansion is compressed, `M̃_S = s_S U_ℓᵀ M_S`, in blocks of at most
///    [`CELLS`] of one level;
/// 2. the pairs, sorted by `|t|` and level, are cut into blocks of at most [`SHARED_BLOCK`]
///    that share them; a block gathers its sources' `D_σ M̃` into one matrix, applies
///    `A_{|t|} (B_{|t|}ᵀ X)` (their first `r_ℓ` rows) as two dense products, and signs each
///    column by its `D_σ` (`C_{σt} = D_σ C_t D_σ`: the 8 reflections of an offset share one
///    pair of factors and one product). Blocks run in groups of about [`GROUP`] pairs (a work
///    array that stays in cache); after each group, every target adds its pairs' columns, in
///    the group's order, to its compressed local expansion `L̃_T`;
/// 3. every target adds `U_ℓ L̃_T` to its local expansion, in blocks as in step 1.
///
/// Every block, group and order of summation depends on the pairs alone, so the sums do not
/// depend on the thread count.
#[allow(clippy::too_many_arguments)]
pub(crate) fn shared(
    basis: &Mat<f64>,
    basis_sigma: &[f64],
    signs: &[Vec<f64>],
    offsets: &[Option<OffsetOperator>],
    mirror: &[(u16, u8)],
    mut pairs: Vec<CodedPair>,
    scale: &(dyn Fn(u32) -> f64 + Sync),
    cut: &(dyn Fn(u32) -> f64 + Sync),
    level: &(dyn Fn(u32) -> u32 + Sync),
    multipoles: &[f64],
    locals: Shared,
    n: usize,
    cells: usize,
) {
    if pairs.is_empty() {
        return;
    }
    let r = basis.ncols();
    // The basis columns a cell's level keeps (columns kept uncompressed have σ = ∞).
    let basis_rank = |c: u32| {
        basis_sigma
            .iter()
            .take_while(|&&s| s > cut(c))
            .count()
            .clamp(1, r)
    };
    let key = |q: &CodedPair| (mirror[q.code as usize].0, level(q.source));
    pairs.sort_unstable_by_key(|q| (key(q), q.target, q.source));
    // Dense numbering of the sources and targets, level by level, and blocks of at most
    // `CELLS` of one level.
    let number = |of: &dyn Fn(&CodedPair) -> u32| {
        let mut list: Vec<u32> = pairs.iter().map(of).collect();
        list.sort_unstable_by_key(|&c| (level(c), c));
        list.dedup();
        let mut index = vec![u32::MAX; cells];
        for (i, &c) in list.iter().enumerate() {
            index[c as usize] = i as u32;
        }
        let mut blocks = vec![0];
        for i in 1..=list.len() {
            let start = *blocks.last().unwrap_or(&0);
            if i == list.len() || i - start == CELLS || level(list[i]) != level(list[start]) {
                blocks.push(i);
            }
        }
        (list, index, blocks)
    };
    let (sources, source_index, source_blocks) = number(&|q| q.source);
    let (targets, target_index, target_blocks) = number(&|q| q.target);
    let target_rank: Vec<usize> = targets.iter().map(|&c| basis_rank(c)).collect();
    // 1. Compressed expansions of the sources.
    let mut compressed = vec![0.0; r * sources.len()];
    split_blocks(&mut compressed, r, &source_blocks)
        .into_par_iter()
        .zip(source_blocks.par_windows(2))
        .for_each(|(out, w)| {
            let chunk = &sources[w[0]..w[1]];
            let (m, rl) = (chunk.len(), basis_rank(chunk[0]));
            with_scratch(n * m, |x| {
                for (col, &c) in x.chunks_exact_mut(n).zip(chunk) {
                    let s = scale(c);
                    for (d, &v) in col.iter_mut().zip(&multipoles[c as usize * n..][..n]) {
                        *d = s * v;
                    }
                }
                let x = MatRef::from_column_major_slice(x, n, m);
                let y = MatMut::from_column_major_slice_mut(out, r, m);
                product(
                    y.subrows_mut(0, rl),
                    basis.subcols(0, rl).transpose(),
                    x,
                    1.0,
                );
            });
        });
    // 2. Blocks of one offset |t| (all its reflections) and level each, in groups.
    let mut bounds = vec![0];
    let mut end = 0;
    while end < pairs.len() {
        let first = key(&pairs[end]);
        let limit = (end + SHARED_BLOCK).min(pairs.len());
        while end < limit && key(&pairs[end]) == first {
            end += 1;
        }
        bounds.push(end);
    }
    let mut compressed_locals = vec![0.0; r * targets.len()];
    let mut results = vec![0.0; r * GROUP.max(SHARED_BLOCK).min(pairs.len())];
    let mut first = 0;
    while first + 1 < bounds.len() {
        let mut last = first + 1;
        while last + 1 < bounds.len() && bounds[last + 1] - bounds[first] <= GROUP {
            last += 1;
        }
        let group = &pairs[bounds[first]..bounds[last]];
        split_blocks(&mut results[..r * group.len()], r, &bounds[first..=last])
            .into_par_iter()
            .zip(bounds[first..=last].par_windows(2))
            .for_each(|(out, w)| {
                let block = &pairs[w[0]..w[1]];
                let Some(op) = &offsets[mirror[block[0].code as usize].0 as usize] else {
                    // Not reached (every M2L offset has factors); if it were, the slot must
                    // not carry an earlier group's columns into the targets.
                    out.fill(0.0);
                    return;
                };
                let sign = |q: &CodedPair| &signs[mirror[q.code as usize].1 as usize][..];
                let rl = basis_rank(block[0].source);
                let rc = rank_for(&op.sigma, op.a.ncols(), cut(block[0].source));
                let (a, b) = (op.a.submatrix(0, 0, rl, rc), op.b.submatrix(0, 0, rl, rc));
                let m = block.len();
                with_scratch((rl + rc) * m, |buf| {
                    let (x, y) = buf.split_at_mut(rl * m);
                    for (col, q) in x.chunks_exact_mut(rl).zip(block) {
                        let i = source_index[q.source as usize] as usize;
                        let src = &compressed[i * r..][..rl];
                        for ((d, &v), &s) in col.iter_mut().zip(src).zip(sign(q)) {
                            *d = s * v;
                        }
                    }
                    let x = MatRef::from_column_major_slice(x, rl, m);
                    let mut y = MatMut::from_column_major_slice_mut(y, rc, m);
                    product(y.rb_mut(), b.transpose(), x, 1.0);
                    let z = MatMut::from_column_major_slice_mut(out, r, m);
                    product(z.subrows_mut(0, rl), a, y.rb(), 1.0);
                });
                for (col, q) in out.chunks_exact_mut(r).zip(block) {
                    for (d, &s) in col[..rl].iter_mut().zip(sign(q)) {
                        *d *= s;
                    }
                }
            });
        // Each target's columns of this group, in offset order (the group's order); a
        // column's rows past its level's basis rank are not written and not read.
        let mut entries: Vec<(u32, u32)> = group
            .iter()
            .enumerate()
            .map(|(i, q)| (target_index[q.target as usize], i as u32))
            .collect();
        entries.sort_unstable();
        let results = &results;
        compressed_locals
            .par_chunks_mut(r * CELLS)
            .enumerate()
            .for_each(|(k, out)| {
                let (lo, hi) = ((k * CELLS) as u32, ((k + 1) * CELLS) as u32);
                let from = entries.partition_point(|e| e.0 < lo);
                let to = entries.partition_point(|e| e.0 < hi);
                for &(t, i) in &entries[from..to] {
                    let rl = target_rank[t as usize];
                    let dst = &mut out[(t - lo) as usize * r..][..rl];
                    for (d, &v) in dst.iter_mut().zip(&results[i as usize * r..][..rl]) {
                        *d += v;
                    }
                }
            });
        first = last;
    }
    // 3. Expanded into the local expansions.
    split_blocks(&mut compressed_locals, r, &target_blocks)
        .into_par_iter()
        .zip(target_blocks.par_windows(2))
        .for_each(|(lt, w)| {
            let chunk = &targets[w[0]..w[1]];
            let (m, rl) = (chunk.len(), basis_rank(chunk[0]));
            with_scratch(n * m, |full| {
                let lt = MatRef::from_column_major_slice(lt, r, m);
                let z = MatMut::from_column_major_slice_mut(full, n, m);
                product(z, basis.subcols(0, rl), lt.subrows(0, rl), 1.0);
                for (col, &t) in full.chunks_exact(n).zip(chunk) {
                    // SAFETY: every target appears once in `targets`, so only this task
                    // writes this target's range now.
                    let local = unsafe { locals.range(t as usize * n, n) };
                    for (l, &v) in local.iter_mut().zip(col) {
                        *l += v;
                    }
                }
            });
        });
}

/// `data` (columns of `rows` numbers) cut into one slice per block of columns, block `k`
/// holding `bounds[k + 1] − bounds[k]` columns (`bounds` increasing; only the differences
/// count).
fn split_blocks<'a>(mut data: &'a mut [f64], rows: usize, bounds: &[usize]) -> Vec<&'a mut [f64]> {
    let mut out = Vec::with_capacity(bounds.len().saturating_sub(1));
    for w in bounds.windows(2) {
        let (head, tail) = std::mem::take(&mut data).split_at_mut(rows * (w[1] - w[0]));
        out.push(head);
        data = tail;
    }
    out
}

/// Expansions compressed or expanded per dense product (shared basis): fixed, as [`BLOCK`].
const CELLS: usize = 64;

/// Pairs per block of one offset `|t|` and level in the shared basis (its 8 reflections
/// together): fixed, as [`BLOCK`].
const SHARED_BLOCK: usize = 512;

/// Pairs per group of blocks (their results: about 6 MB at a basis of rank 370).
const GROUP: usize = 2048;

thread_local! {
    /// Work space of [`apply`], kept per thread between blocks.
    static SCRATCH: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Runs `f` on this thread's work space of at least `len` numbers (contents unspecified:
/// every entry is written before it is read).
fn with_scratch(len: usize, f: impl FnOnce(&mut [f64])) {
    SCRATCH.with_borrow_mut(|buf| {
        if buf.len() < len {
            buf.resize(len, 0.0);
        }
        f(&mut buf[..len]);
    });
}
