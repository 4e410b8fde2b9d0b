//! The M2L operators, compressed two ways (applied in [`super::m2l`]).
//!
//! The M2L operator between two cells of one level whose integer offset is `t` (a vector in
//! `{−3, …, 3}³` with `‖t‖∞ ≥ 2`: 316 of them) is the `p³ × p³` matrix
//! `K_t[A, B] = φ(|w t + h (x̄_A − x̄_B)|)` over the cells' Chebyshev nodes (`w = 2h` the width).
//!
//! **Symmetries.** The 48 symmetries of the cube (axis permutations and reflections) map every
//! offset onto one of **16 canonical offsets** `0 ≤ c₂ ≤ c₁ ≤ c₀`, and, because the Chebyshev
//! nodes are symmetric (`−x̄_a = x̄_{p−1−a}`), they act on the node indices as a permutation
//! `Π_t`: `K_t[A, B] = K_c[Π_t(A), Π_t(B)]` (Messner, Schanz & Darve 2012, §3). Only the 16
//! canonical operators are built, each compressed by a truncated SVD `K_c ≈ (U_cΣ_c) V_cᵀ`
//! (singular values above `ε σ₁`, by adaptive cross approximation recompressed and checked
//! against `K_c`, a seeded randomised range finder as the fallback; exact to well below `ε`
//! because the singular values of a smooth kernel fall geometrically).
//!
//! **Per operator** ([`M2lCompression::PerOperator`]): a pair applies `U_cΣ_c (V_cᵀ Π_t M)` in
//! the `p³`-dimensional node space, `4 p³ r_c` flops (`r_c` = 20–90, the canonical rank).
//!
//! **Shared basis** ([`M2lCompression::SharedBasis`], Fong & Darve 2009, §3.3): the columns of
//! all 316 operators span, to `ε`, a space of dimension `r` well below `p³` (`r = 212` for `r`
//! at `p = 8`, `ε = 10⁻⁸`, against `p³ = 512`; 370 for `r³` at `p = 10`, `ε = 3·10⁻¹¹`,
//! against 1000). `U` (`p³ × r`, orthonormal) is the left singular basis of
//! `[Π_t U_cΣ_c / σ₁(K_c)]` over all offsets (each scaled to norm 1, so that every operator
//! keeps `ε` relative to its own norm; the Gram matrix is that of the fat matrix `[K_t]`), cut
//! at `ε`. The row space is the same `U`: `K_{−t} = K_tᵀ` for a radial kernel and the offsets
//! come in pairs `±t`. Each offset keeps `C_t = Uᵀ K_t U ≈ A_t B_tᵀ` with
//! `A_t = Uᵀ Π_t U_cΣ_c` and `B_t = Uᵀ Π_t V_c` (`r × r_c`): expansions are compressed
//! (`M̃ = Uᵀ M`) and expanded (`L += U L̃`) once per cell, and a pair costs `4 r r_c` flops.
//!
//! **Reflections.** The 8 reflections `σ` of the node grid (`x̄ₘ ↦ x̄_{p−1−m}` along some axes)
//! map the offset `t` to `σt` with `K_{σt} = Π_σ K_t Π_σ`, so the span of all the columns is
//! closed under them and `U` can be taken even or odd along each axis: `Π_σ U = U D_σ` with
//! `D_σ` a diagonal of signs. Then `C_{σt} = D_σ C_t D_σ`: only the 56 offsets with no
//! negative component keep factors, and the pairs of all 8 reflections of one offset go
//! through one pair of dense products, their columns signed. `U` is found sector by sector
//! (8 SVDs of about `p³/8` rows, each from the 56 offsets' columns weighted by the square root
//! of their number of reflections: the same singular values as the 316 offsets' matrix, to
//! the accuracy of the canonical factors — at `p = 10`, `ε = 3·10⁻¹¹` the latter has 404 above
//! the cut against 370, the difference being the factors' own asymmetry at the cut, which the
//! sectors drop: the bunny `r³` field's error is 7.8e-6 against 7.6e-6). Each sector's
//! coordinates have at most 8 non-zeros a column, so its columns are gathered straight from the
//! canonical factors. At `p = 10`, `ε = 3·10⁻¹¹` the canonical operators and the shared basis
//! take about 0.3 s on 2 cores (0.7 s before cross approximation) and 20 MB; the M2L step runs 30–45%
//! faster than with 316 offsets' factors (bigger products, 5.6× fewer operands to stream).
//!
//! A kernel with [`homogeneity`](crate::rbf::Kernel::homogeneity) `k` (`r`, `r³`) has
//! `K_t(w) = wᵏ K_t(1)`: one set of operators at unit width serves every level. Any other
//! kernel gets its operators per level (per cell width), cached. The singular values are kept
//! with the factors and with the shared basis, in decreasing order, so a finer level of a
//! homogeneous kernel applies only the leading columns (of `U_cΣ_c`, `V_c`, and of `U`, `A_t`,
//! `B_t`) that its smaller scale needs for the coarsest level's absolute error
//! ([`super::m2l::rank_for`]; `FmmOptions::tolerance`): at `p = 10`, `ε = 3·10⁻¹¹`, the `r³`
//! basis keeps 370 columns at the coarsest level, 280 one level down and 214 two down.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;
use zeroset_field_core::rng::SplitMix64;

use super::cache::{self, OperatorKey};
use super::chebyshev::Chebyshev;
use super::tree::{offset_code, offset_of};
use crate::rbf::kernel::Kernel;

/// How the M2L operators are compressed and applied: each of the 16 canonical operators by its
/// own truncated SVD, or all 316 offsets in one shared basis of dimension `r < p³`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum M2lCompression {
    /// Each canonical operator compressed on its own, pairs applied in the `p³`-dimensional
    /// node space (Messner, Schanz & Darve 2012): cheapest to build.
    PerOperator,
    /// One basis for all offsets, pairs applied in its `r`-dimensional space (Fong & Darve
    /// 2009): fewer flops per pair where `r` is well below `p³`, one larger SVD to build.
    SharedBasis,
}

impl M2lCompression {
    /// The default of order `p`: the shared basis at `p = 7` and 8, where it is measured
    /// faster (at 10,000 bunny centres the M2L step takes 25–30% less time at `p = 8`); per
    /// operator below (`r` is close to `p³`) and above, where the shared basis still makes
    /// the field's build faster (`r³`, 10,000 bunny centres: 44 against 64 ms at `p = 10`) but
    /// costs more to build once (`r³` on 2 cores: 0.32 against 0.25 s at `p = 10`, 1.3 against
    /// 0.85 s and 260 against 200 MB at `p = 12`), which one-off fields such as the signed
    /// marching cubes' pay where no cache holds the operators ([`super::cache`]). Applications that build many fields of one kernel and order should choose the
    /// shared basis ([`FmmOptions::with_compression`](super::FmmOptions::with_compression)).
    pub fn for_order(p: usize) -> Self {
        if (7..=8).contains(&p) {
            Self::SharedBasis
        } else {
            Self::PerOperator
        }
    }
}

/// The compressed operator of one canonical offset, `K_c ≈ (U_cΣ_c) V_cᵀ`.
#[derive(Debug, Clone)]
pub(crate) struct Compressed {
    /// `U Σ`, `p³ × r`.
    pub us: Mat<f64>,
    /// `V`, `p³ × r`.
    pub v: Mat<f64>,
    /// The singular values `Σ`, decreasing (empty for an uncompressed operator).
    pub sigma: Vec<f64>,
}

/// The operator of one offset in the shared basis, `C_t = Uᵀ K_t U ≈ A Bᵀ`.
#[derive(Debug, Clone)]
pub(crate) struct OffsetOperator {
    /// `A_t`, `r × r_c`.
    pub a: Mat<f64>,
    /// `B_t`, `r × r_c`.
    pub b: Mat<f64>,
    /// The canonical operator's singular values (the columns' weights), decreasing.
    pub sigma: Vec<f64>,
}

/// The compressed M2L operators of one cell width.
#[derive(Debug, Clone)]
pub(crate) enum LevelOperators {
    /// The 16 canonical operators.
    PerOperator(Vec<Compressed>),
    /// The shared basis `U` (`p³ × r`, orthonormal columns, each even or odd along each axis),
    /// the singular values of the matrix it spans (decreasing; infinite for columns kept
    /// uncompressed), per reflection mask the signs `D_σ` it takes the columns to
    /// (`Π_σ U = U D_σ`), and `C_t` for the offsets with no negative component (`None` for
    /// the others and the 27 adjacent offsets: `C_{σt} = D_σ C_t D_σ`).
    Shared {
        basis: Mat<f64>,
        basis_sigma: Vec<f64>,
        signs: Vec<Vec<f64>>,
        offsets: Vec<Option<OffsetOperator>>,
    },
}

impl LevelOperators {
    /// The bytes of the matrices and singular values.
    pub fn bytes(&self) -> usize {
        let mat = |m: &Mat<f64>| m.nrows() * m.ncols();
        let words = match self {
            Self::PerOperator(c) => c
                .iter()
                .map(|c| mat(&c.us) + mat(&c.v) + c.sigma.len())
                .sum(),
            Self::Shared {
                basis,
                basis_sigma,
                signs,
                offsets,
            } => {
                mat(basis)
                    + basis_sigma.len()
                    + signs.iter().map(Vec::len).sum::<usize>()
                    + offsets
                        .iter()
                        .flatten()
                        .map(|o| mat(&o.a) + mat(&o.b) + o.sigma.len())
                        .sum::<usize>()
            }
        };
        8 * words
    }

    /// The largest rank kept: of the canonical operators, or of the shared basis.
    pub fn rank(&self) -> usize {
        match self {
            Self::PerOperator(c) => c.iter().map(|c| c.us.ncols()).max().unwrap_or(0),
            Self::Shared { basis, .. } => basis.ncols(),
        }
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
    /// Per offset code `t`: the code of `|t|` (componentwise) and the reflection that maps
    /// `|t|` to `t`, as a mask (bit `a` set where `t[a] < 0`).
    pub mirror: Vec<(u16, u8)>,
}

impl Symmetry {
    pub fn new(p: usize) -> Self {
        let mut canonical: Vec<[i64; 3]> = Vec::new();
        let mut canonical_of = vec![usize::MAX; 343];
        let mut perm = vec![Vec::new(); 343];
        let mirror = (0..343)
            .map(|code| {
                let t = offset_of(code);
                let mask = (0..3).filter(|&a| t[a] < 0).fold(0u8, |m, a| m | (1 << a));
                (offset_code(t.map(i64::abs)) as u16, mask)
            })
            .collect();
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
            mirror,
        }
    }
}

/// Everything the M2L step needs for one kernel and order: the symmetries and the compressed
/// operators, built on first use per cell width and shared (an `Arc`) between fields — and,
/// through [`super::cache`], between every field of the same kernel, order, tolerance and
/// compression in the process (and across processes on disk, where enabled).
#[derive(Debug)]
pub struct FmmOperators {
    pub(crate) cheb: Chebyshev,
    pub(crate) symmetry: Symmetry,
    pub(crate) tolerance: f64,
    pub(crate) compression: M2lCompression,
    kernel_name: String,
    homogeneity: Option<i32>,
    key: OperatorKey,
    /// `(width, operators)`; for homogeneous kernels only width 1.
    cache: Mutex<Vec<(f64, Arc<LevelOperators>)>>,
    /// Bytes of the built operators in `cache` (read without its lock).
    bytes: AtomicUsize,
}

impl FmmOperators {
    /// The operators of `kernel` at order `p` (`p` Chebyshev nodes per axis), singular values
    /// kept down to `tolerance` relative to the largest, compressed as `compression` says.
    /// Nothing is computed until a field needs it.
    pub(crate) fn new<K: Kernel + ?Sized>(
        kernel: &K,
        p: usize,
        tolerance: f64,
        compression: M2lCompression,
    ) -> Self {
        Self {
            cheb: Chebyshev::new(p),
            symmetry: Symmetry::new(p),
            tolerance,
            compression,
            kernel_name: kernel.name().to_owned(),
            homogeneity: kernel.homogeneity(),
            key: OperatorKey::new(kernel, p, tolerance, compression),
            cache: Mutex::new(Vec::new()),
            bytes: AtomicUsize::new(0),
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

    /// How the operators are compressed.
    pub fn compression(&self) -> M2lCompression {
        self.compression
    }

    /// The bytes the operators built so far take (their matrices and singular values).
    pub fn bytes(&self) -> usize {
        self.bytes.load(Ordering::Relaxed)
    }

    /// Whether the operators for cells of `width` (1 for any width of a homogeneous kernel) are
    /// built already.
    pub(crate) fn has_level(&self, width: f64) -> bool {
        let list = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        list.iter().any(|(w, _)| *w == width)
    }

    /// What identifies these operators in the caches.
    pub(crate) fn key(&self) -> &OperatorKey {
        &self.key
    }

    /// Whether `kernel` is the one these operators were built for (same key, so the same
    /// name, parameters and values).
    pub(crate) fn fits<K: Kernel + ?Sized>(&self, kernel: &K) -> bool {
        OperatorKey::new(kernel, self.order(), self.tolerance, self.compression) == self.key
    }

    /// The operators for cells of width `width`, and the factor their products are scaled by:
    /// from this set's own list, else from the disk cache, else computed (and then written to
    /// the disk cache, where there is one).
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
        let list = || self.cache.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, ops)) = list().iter().find(|(w, _)| *w == key) {
            return (ops.clone(), scale);
        }
        // Read or built without the lock: the build runs rayon jobs, and a worker waiting in one
        // may steal an outer job that asks for these same operators (fields built inside a
        // caller's `par_iter`), which then waited for the lock its own thread held — a
        // deadlock. Two threads may now build the same level at once; the first to finish is
        // kept (the builds are identical).
        let file = cache::disk_dir().map(|dir| cache::file_for(&dir, &self.key, key));
        let n = self.order().pow(3);
        let loaded = file
            .as_deref()
            .and_then(|f| cache::load(f, &self.key, key, n));
        let from_disk = loaded.is_some();
        let built = Arc::new(loaded.unwrap_or_else(|| self.build(kernel, key)));
        let mut list = list();
        if let Some((_, ops)) = list.iter().find(|(w, _)| *w == key) {
            return (ops.clone(), scale);
        }
        // A cache that cannot be written (a read-only folder, a full disk) only costs the next
        // process a rebuild.
        let written = !from_disk
            && file
                .as_deref()
                .is_some_and(|f| cache::save(f, &self.key, key, &built).is_ok());
        self.bytes.fetch_add(built.bytes(), Ordering::Relaxed);
        list.push((key, built.clone()));
        drop(list);
        cache::record(from_disk, written);
        (built, scale)
    }

    fn build<K: Kernel + ?Sized>(&self, kernel: &K, width: f64) -> LevelOperators {
        let canonical = self.canonical(kernel, width);
        match self.compression {
            M2lCompression::PerOperator => LevelOperators::PerOperator(canonical),
            M2lCompression::SharedBasis => self.shared(&canonical),
        }
    }

    /// The 16 canonical operators of cells of `width`, each compressed on its own.
    fn canonical<K: Kernel + ?Sized>(&self, kernel: &K, width: f64) -> Vec<Compressed> {
        let p = self.cheb.order();
        let n = p * p * p;
        let h = 0.5 * width;
        let nodes = self.cheb.nodes();
        self.symmetry
            .canonical
            .par_iter()
            .map(|c| {
                // K[A, B] = φ(|w c + h (x̄_A − x̄_B)|), the squared distance summed per axis
                // from tables of p × p squared components; A's last index runs fastest.
                let table: [Vec<f64>; 3] = std::array::from_fn(|x| {
                    (0..p * p)
                        .map(|ab| {
                            let (a, b) = (ab / p, ab % p);
                            let d = width * c[x] as f64 + h * (nodes[a] - nodes[b]);
                            d * d
                        })
                        .collect()
                });
                let mut k = vec![0.0; n * n];
                for (j, column) in k.chunks_exact_mut(n).enumerate() {
                    let b = [j / (p * p), (j / p) % p, j % p];
                    for a0 in 0..p {
                        let d0 = table[0][a0 * p + b[0]];
                        for a1 in 0..p {
                            let d01 = d0 + table[1][a1 * p + b[1]];
                            let out = &mut column[(a0 * p + a1) * p..][..p];
                            for (a2, v) in out.iter_mut().enumerate() {
                                *v = kernel.value_of_squared(d01 + table[2][a2 * p + b[2]]);
                            }
                        }
                    }
                }
                compress(MatRef::from_column_major_slice(&k, n, n), self.tolerance)
            })
            .collect()
    }

    /// The shared basis and the offsets' factors from the canonical compressions.
    ///
    /// The columns of all 316 operators, `Π_t U_cΣ_c / σ₁(K_c)`, span a space closed under the
    /// 8 reflections of the node grid (`K_{σt} = Π_σ K_t Π_σ`), so its singular basis splits
    /// into the 8 parity sectors (even or odd along each axis). Each sector's basis is the SVD
    /// of the projected columns of the 56 offsets with no negative component, each weighted by
    /// the square root of its number of reflections (the same Gram matrix as all 316): 8 SVDs
    /// of `p³/8` rows instead of one of `p³`. The sectors' columns are merged by singular value.
    fn shared(&self, canonical: &[Compressed]) -> LevelOperators {
        let sym = &self.symmetry;
        let p = self.cheb.order();
        let n = p * p * p;
        let codes: Vec<usize> = (0..sym.perm.len())
            .filter(|&code| sym.canonical_of[code] != usize::MAX && sym.mirror[code].1 == 0)
            .collect();
        // [√m_t Π_t U_cΣ_c / σ₁(K_c)] over the offsets t ≥ 0 (σ₁ = ‖first column of U_cΣ_c‖,
        // m_t = 2^(non-zero components of t) reflections).
        let total: usize = codes
            .iter()
            .map(|&code| canonical[sym.canonical_of[code]].us.ncols())
            .sum();
        let norms: Vec<f64> = canonical
            .iter()
            .map(|c| c.us.col(0).norm_l2().max(f64::MIN_POSITIVE))
            .collect();
        // Per sector: its orthonormal coordinates Q_e (at most 8 non-zeros a column), then the
        // SVD of Q_eᵀ F = W_e Σ_e Z_eᵀ, F = [√m_t Π_t U_cΣ_c / σ₁(K_c)] gathered straight from
        // the canonical factors; the sector's basis columns are Q_e W_e.
        let sectors: Vec<(ParitySector, Mat<f64>, Vec<f64>)> = (0u8..8)
            .into_par_iter()
            .map(|e| {
                let q = ParitySector::new(p, e);
                let mut projected = Mat::<f64>::zeros(q.len(), total);
                let mut col = 0;
                for &code in &codes {
                    let c = sym.canonical_of[code];
                    let us = &canonical[c].us;
                    let reflections = offset_of(code).iter().filter(|&&v| v != 0).count();
                    let weight = ((1u32 << reflections) as f64).sqrt() / norms[c];
                    q.gather_into(
                        us.as_ref(),
                        &sym.perm[code],
                        weight,
                        projected.subcols_mut(col, us.ncols()),
                    );
                    col += us.ncols();
                }
                let (w, sigma) = left_basis(projected.as_ref(), self.tolerance);
                let sigma = if sigma.is_empty() {
                    vec![f64::INFINITY; w.ncols()]
                } else {
                    sigma
                };
                (q, w, sigma)
            })
            .collect();
        let mut order: Vec<(f64, u8, usize)> = sectors
            .iter()
            .enumerate()
            .flat_map(|(e, (_, _, sigma))| {
                sigma.iter().enumerate().map(move |(j, &s)| (s, e as u8, j))
            })
            .collect();
        order.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        // Each sector's SVD keeps at least one column; the basis keeps those above the
        // tolerance (at least one).
        let keep = order.iter().filter(|o| o.0 > self.tolerance).count().max(1);
        order.truncate(keep);
        // Per sector, its kept columns of W_e and where they go in the basis.
        let kept: Vec<(Mat<f64>, Vec<usize>)> = sectors
            .iter()
            .enumerate()
            .map(|(e, (_, w, _))| {
                let (locals, globals): (Vec<usize>, Vec<usize>) = order
                    .iter()
                    .enumerate()
                    .filter(|(_, o)| o.1 as usize == e)
                    .map(|(k, o)| (o.2, k))
                    .unzip();
                (
                    Mat::from_fn(w.nrows(), locals.len(), |i, j| w[(i, locals[j])]),
                    globals,
                )
            })
            .collect();
        let mut basis = Mat::<f64>::zeros(n, order.len());
        for ((q, _, _), (w, globals)) in sectors.iter().zip(&kept) {
            let columns = q.scatter(w.as_ref(), n);
            for (j, &k) in globals.iter().enumerate() {
                basis.col_mut(k).copy_from(columns.col(j));
            }
        }
        let basis_sigma: Vec<f64> = order.iter().map(|o| o.0).collect();
        let signs: Vec<Vec<f64>> = (0u8..8)
            .map(|mask| {
                order
                    .iter()
                    .map(|&(_, e, _)| {
                        if (e & mask).count_ones() % 2 == 1 {
                            -1.0
                        } else {
                            1.0
                        }
                    })
                    .collect()
            })
            .collect();
        // Uᵀ Π_t M, sector by sector: W_eᵀ (Q_eᵀ Π_t M), rows scattered to the basis's order.
        let project = |m: &Mat<f64>, code: usize| {
            let mut out = Mat::<f64>::zeros(basis.ncols(), m.ncols());
            for ((q, _, _), (w, globals)) in sectors.iter().zip(&kept) {
                if globals.is_empty() {
                    continue;
                }
                let mut z = Mat::<f64>::zeros(q.len(), m.ncols());
                q.gather_into(m.as_ref(), &sym.perm[code], 1.0, z.as_mut());
                let mut y = Mat::<f64>::zeros(w.ncols(), m.ncols());
                product(y.as_mut(), w.transpose(), z.as_ref(), 1.0);
                for (j, &k) in globals.iter().enumerate() {
                    out.row_mut(k).copy_from(y.row(j));
                }
            }
            out
        };
        let built: Vec<(usize, OffsetOperator)> = codes
            .par_iter()
            .map(|&code| {
                let c = &canonical[sym.canonical_of[code]];
                let op = OffsetOperator {
                    a: project(&c.us, code),
                    b: project(&c.v, code),
                    sigma: c.sigma.clone(),
                };
                (code, op)
            })
            .collect();
        let mut offsets: Vec<Option<OffsetOperator>> = vec![None; sym.perm.len()];
        for (code, op) in built {
            offsets[code] = Some(op);
        }
        LevelOperators::Shared {
            basis,
            basis_sigma,
            signs,
            offsets,
        }
    }
}

/// The orthonormal coordinates `Q_e` of parity sector `e` of the `p³` node grid (bit `a` of
/// `e` set: odd along axis `a`, under the reflection `x̄ₘ ↦ x̄_{p−1−m}`): the products of the
/// 1-D even vectors `(δₘ + δ_{p−1−m})/√2` (and `δ` at the middle node of an odd order) or odd
/// vectors `(δₘ − δ_{p−1−m})/√2`, `m < p/2`. Each column has at most 8 non-zeros, kept as a
/// list, so that `Q_eᵀ X` and `Q_e W` cost `O(8 · size)` instead of a dense product.
#[derive(Debug, Clone)]
struct ParitySector {
    /// Per column: its non-zero entries `(row, value)`.
    columns: Vec<Vec<(usize, f64)>>,
}

impl ParitySector {
    fn new(p: usize, e: u8) -> Self {
        let axis = |odd: bool| -> Vec<Vec<(usize, f64)>> {
            let h = std::f64::consts::FRAC_1_SQRT_2;
            let mut out = Vec::new();
            for m in 0..p.div_ceil(2) {
                if 2 * m + 1 == p {
                    if !odd {
                        out.push(vec![(m, 1.0)]);
                    }
                } else {
                    out.push(vec![(m, h), (p - 1 - m, if odd { -h } else { h })]);
                }
            }
            out
        };
        let [x, y, z] = [0, 1, 2].map(|a| axis(e & (1 << a) != 0));
        let mut columns = Vec::with_capacity(x.len() * y.len() * z.len());
        for vx in &x {
            for vy in &y {
                for vz in &z {
                    let mut column = Vec::with_capacity(vx.len() * vy.len() * vz.len());
                    for &(a, u) in vx {
                        for &(b, v) in vy {
                            for &(c, w) in vz {
                                column.push(((a * p + b) * p + c, u * v * w));
                            }
                        }
                    }
                    columns.push(column);
                }
            }
        }
        Self { columns }
    }

    /// The number of columns.
    fn len(&self) -> usize {
        self.columns.len()
    }

    /// `out = weight · Q_eᵀ Π X` (`X`: `p³ × m`, `Π` the node permutation `perm`: row `i` of
    /// `Π X` is row `perm[i]` of `X`).
    fn gather_into(&self, x: MatRef<'_, f64>, perm: &[u32], weight: f64, mut out: MatMut<'_, f64>) {
        for j in 0..x.ncols() {
            let column = x.col(j);
            for (k, entries) in self.columns.iter().enumerate() {
                let sum: f64 = entries
                    .iter()
                    .map(|&(i, v)| v * column[perm[i] as usize])
                    .sum();
                out[(k, j)] = weight * sum;
            }
        }
    }

    /// `Q_e W` (`W`: columns of the sector × `m`), `n = p³` rows.
    fn scatter(&self, w: MatRef<'_, f64>, n: usize) -> Mat<f64> {
        let mut out = Mat::<f64>::zeros(n, w.ncols());
        for (k, column) in self.columns.iter().enumerate() {
            for &(i, v) in column {
                for j in 0..w.ncols() {
                    out[(i, j)] += v * w[(k, j)];
                }
            }
        }
        out
    }
}

/// The left singular vectors of `f` whose singular values exceed `tolerance` (at least one),
/// and those singular values, by a sequential SVD that leaves out the right vectors. If the
/// SVD does not converge (it does not on a smooth kernel's operators), the identity (exact,
/// uncompressed) and no singular values.
fn left_basis(f: MatRef<'_, f64>, tolerance: f64) -> (Mat<f64>, Vec<f64>) {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::svd::{self, ComputeSvdVectors};
    let (m, n) = (f.nrows(), f.ncols());
    let k = m.min(n);
    let mut u = Mat::<f64>::zeros(m, k);
    let mut s = faer::diag::Diag::<f64>::zeros(k);
    let mut mem = MemBuffer::new(svd::svd_scratch::<f64>(
        m,
        n,
        ComputeSvdVectors::Thin,
        ComputeSvdVectors::No,
        Par::Seq,
        Default::default(),
    ));
    let done = svd::svd(
        f,
        s.as_mut(),
        Some(u.as_mut()),
        None,
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    );
    if done.is_err() || k == 0 {
        return (Mat::identity(m, m), Vec::new());
    }
    let rank = (0..k).take_while(|&i| s[i] > tolerance).count().max(1);
    (
        u.subcols(0, rank).to_owned(),
        (0..rank).map(|i| s[i]).collect(),
    )
}

/// Truncated SVD `K ≈ (UΣ) Vᵀ`, keeping the singular values above `tolerance · σ₁`.
///
/// First by adaptive cross approximation ([`cross_approximation`], `O(n r²)` for rank `r`),
/// checked against `K` on a few seeded random vectors; where that check fails (it does not on
/// a smooth kernel's well-separated operators), by a randomised range finder (Halko, Martinsson
/// & Tropp 2011, Alg. 4.4 with one power step, `O(n² l)`): the singular values of a smooth
/// kernel's operator fall geometrically, so a sample of `l` columns `K Ω` (seeded, so the
/// result is always the same) captures the leading `l − 16` to full accuracy. `l` starts at 64
/// and doubles until the last kept singular value lies at least 16 columns inside the sample,
/// or `l = n` (then this is the plain SVD). All products and SVDs are sequential, so the result
/// does not depend on the thread count.
fn compress(k: MatRef<'_, f64>, tolerance: f64) -> Compressed {
    if let Some(c) = cross_approximation(k, tolerance) {
        return c;
    }
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
                sigma: Vec::new(),
            };
        }
        l = (2 * l).min(n);
    }
}

/// The truncated SVD of an M2L operator `K` (`n × n`, with `K[A, B] = K[σB, σA]` for the
/// reflection `σ` of the node grid) by adaptive cross approximation with partial pivoting
/// (Bebendorf 2000), recompressed; `None` where it does not reach the tolerance.
///
/// Step `k` takes the residual's row `i_k` (the largest entry of the previous column among
/// rows not used yet), its largest entry as the pivot `j_k`, and the residual's column `j_k`:
/// `R ← R − c rᵀ / R[i_k, j_k]`, reading only one row and one column of `K`. It stops once
/// three successive updates are below `tolerance / 4` of the running Frobenius norm of the
/// approximation. The factors `C Rᵀ` are then put in SVD form through the QR factorisations
/// of `C` and `R` and the SVD of `R_C R_Rᵀ` (`O(n r²)`), and cut at `tolerance · σ₁`. The result is accepted only if
/// `‖K Ω − U Σ Vᵀ Ω‖_F ≤ 10 · tolerance · ‖K Ω‖_F` for 8 seeded random vectors, and its rank
/// is at most `n / 2` (past that a low-rank form is not worth it).
fn cross_approximation(k: MatRef<'_, f64>, tolerance: f64) -> Option<Compressed> {
    let n = k.nrows();
    if n != k.ncols() || n < 8 {
        return None;
    }
    let max_rank = n / 2;
    let eps = tolerance / 4.0;
    let mut cols: Vec<Vec<f64>> = Vec::new(); // c_k, length n
    let mut rows: Vec<Vec<f64>> = Vec::new(); // r_k / pivot, length n
    let mut used = vec![false; n];
    let mut norm2 = 0.0f64;
    let mut quiet = 0;
    let mut row = 0;
    loop {
        used[row] = true;
        // K[A, B] = K[σB, σA] for the reflection σ of every axis (i ↦ n − 1 − i: the nodes
        // are symmetric, x̄_{p−1−a} = −x̄_a, and the kernel radial), so the row is a column read
        // backwards, contiguous in memory. The two agree to rounding; the final check is
        // against `K` itself.
        let mut r: Vec<f64> = k.col(n - 1 - row).iter().rev().copied().collect();
        for (c, v) in cols.iter().zip(&rows) {
            let a = c[row];
            r.iter_mut().zip(v).for_each(|(x, y)| *x -= a * y);
        }
        let (pivot_col, pivot) = r.iter().enumerate().fold((0, 0.0f64), |best, (j, &x)| {
            if x.abs() > best.1.abs() { (j, x) } else { best }
        });
        if pivot != 0.0 {
            r.iter_mut().for_each(|x| *x /= pivot);
            let mut c: Vec<f64> = k.col(pivot_col).iter().copied().collect();
            for (cc, v) in cols.iter().zip(&rows) {
                let a = v[pivot_col];
                c.iter_mut().zip(cc).for_each(|(x, y)| *x -= a * y);
            }
            // ‖S + c rᵀ‖²_F = ‖S‖² + 2 Σ (c_lᵀ c)(r_lᵀ r) + ‖c‖² ‖r‖².
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
            let (cn, rn) = (dot(&c, &c), dot(&r, &r));
            let cross: f64 = cols
                .iter()
                .zip(&rows)
                .map(|(cl, rl)| dot(cl, &c) * dot(rl, &r))
                .sum();
            norm2 = (norm2 + 2.0 * cross + cn * rn).max(0.0);
            let step = (cn * rn).sqrt();
            cols.push(c);
            rows.push(r);
            if step <= eps * norm2.sqrt() {
                quiet += 1;
            } else {
                quiet = 0;
            }
        } else {
            quiet += 1;
        }
        if quiet >= 3 {
            break;
        }
        if cols.len() > max_rank {
            return None;
        }
        // The next row: the largest entry of the last column among the unused rows.
        let last = cols.last();
        row = match (0..n).filter(|&i| !used[i]).max_by(|&a, &b| {
            let v = |i: usize| last.map_or(0.0, |c| c[i].abs());
            v(a).total_cmp(&v(b)).then(b.cmp(&a))
        }) {
            Some(i) => i,
            None => break,
        };
    }
    let rank = cols.len();
    if rank == 0 {
        return None;
    }
    let c = Mat::from_fn(n, rank, |i, j| cols[j][i]);
    let r = Mat::from_fn(n, rank, |i, j| rows[j][i]);
    // C Rᵀ = Qc (Rc Rrᵀ) Qrᵀ = Qc (X Σ Yᵀ) Qrᵀ.
    let (qc, rc) = thin_qr(c.as_ref());
    let (qr, rr) = thin_qr(r.as_ref());
    let mut core = Mat::<f64>::zeros(rank, rank);
    product(core.as_mut(), rc.as_ref(), rr.transpose(), 1.0);
    let zeroset_tensor::ThinSvd {
        u: x,
        s: sigma,
        v: y,
    } = zeroset_tensor::thin_svd(core.as_ref()).ok()?;
    let keep = sigma
        .iter()
        .take_while(|&&s| s > tolerance * sigma[0])
        .count()
        .max(1);
    let mut us = Mat::<f64>::zeros(n, keep);
    product(us.as_mut(), qc.as_ref(), x.subcols(0, keep), 1.0);
    for (j, &s) in sigma.iter().take(keep).enumerate() {
        us.col_mut(j).iter_mut().for_each(|v| *v *= s);
    }
    let mut v = Mat::<f64>::zeros(n, keep);
    product(v.as_mut(), qr.as_ref(), y.subcols(0, keep), 1.0);
    let out = Compressed {
        us,
        v,
        sigma: sigma[..keep].to_vec(),
    };
    // The check: K Ω against U Σ (Vᵀ Ω).
    let omega = seeded_uniform(n, 8);
    let mut exact = Mat::<f64>::zeros(n, 8);
    product(exact.as_mut(), k, omega.as_ref(), 1.0);
    let mut vo = Mat::<f64>::zeros(keep, 8);
    product(vo.as_mut(), out.v.transpose(), omega.as_ref(), 1.0);
    let mut approx = Mat::<f64>::zeros(n, 8);
    product(approx.as_mut(), out.us.as_ref(), vo.as_ref(), 1.0);
    let error = (&exact - &approx).norm_l2();
    (error <= 10.0 * tolerance * exact.norm_l2()).then_some(out)
}

/// The thin QR factorisation `A = Q R` of a tall matrix (`Q`: `m × n` orthonormal columns, `R`:
/// `n × n` upper triangular), by blocked Householder reflections, sequential (the same bits on
/// any thread count).
fn thin_qr(a: MatRef<'_, f64>) -> (Mat<f64>, Mat<f64>) {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::householder;
    use faer::linalg::qr::no_pivoting::factor;
    let (m, n) = (a.nrows(), a.ncols());
    let mut qr = a.to_owned();
    let block = factor::recommended_block_size::<f64>(m, n);
    let mut coeff = Mat::<f64>::zeros(block, n.min(m));
    factor::qr_in_place(
        qr.as_mut(),
        coeff.as_mut(),
        Par::Seq,
        MemStack::new(&mut MemBuffer::new(factor::qr_in_place_scratch::<f64>(
            m,
            n,
            block,
            Par::Seq,
            Default::default(),
        ))),
        Default::default(),
    );
    let size = m.min(n);
    let r = Mat::from_fn(size, n, |i, j| if i <= j { qr[(i, j)] } else { 0.0 });
    // The Householder vectors: below the diagonal, with a unit diagonal.
    let basis = Mat::from_fn(m, size, |i, j| match i.cmp(&j) {
        std::cmp::Ordering::Less => 0.0,
        std::cmp::Ordering::Equal => 1.0,
        std::cmp::Ordering::Greater => qr[(i, j)],
    });
    let mut q = Mat::<f64>::identity(m, size);
    householder::apply_block_householder_sequence_on_the_left_in_place_with_conj(
        basis.as_ref(),
        coeff.as_ref(),
        faer::Conj::No,
        q.as_mut(),
        Par::Seq,
        MemStack::new(&mut MemBuffer::new(
            householder::apply_block_householder_sequence_on_the_left_in_place_scratch::<f64>(
                m, block, size,
            ),
        )),
    );
    (q, r)
}

/// An `n × l` matrix of seeded uniform numbers in `[−1, 1)` ([`SplitMix64`]): always the same.
fn seeded_uniform(n: usize, l: usize) -> Mat<f64> {
    let mut rng = SplitMix64::new(0x5EED);
    Mat::from_fn(n, l, |_, _| rng.uniform(-1.0, 1.0))
}

/// The truncated SVD of `K` restricted to the range of `K Ω` (`Ω`: `n × l`, seeded), after one
/// power step; `None` if an SVD did not converge.
fn sampled_svd(k: MatRef<'_, f64>, l: usize, tolerance: f64) -> Option<Compressed> {
    let n = k.nrows();
    let omega = seeded_uniform(n, l);
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
        sigma: sv[..rank].to_vec(),
    })
}

/// `out = alpha a b`, sequential.
pub(crate) fn product(out: MatMut<'_, f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>, alpha: f64) {
    matmul(out, Accum::Replace, a, b, alpha, Par::Seq);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rbf::fmm::tree::offset_code;
    use crate::rbf::kernel;
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

    /// The cross approximation of a canonical operator is its truncated SVD: the same singular
    /// values as a full SVD down to the cut, and the operator to the tolerance; a matrix of full
    /// rank is refused by it and still compressed exactly.
    #[test]
    fn cross_approximation_matches_the_full_svd() {
        use crate::rbf::kernel::Triharmonic;
        for (p, tolerance) in [(6usize, 1e-7), (8, 1e-9)] {
            let ops = FmmOperators::new(&Triharmonic, p, tolerance, M2lCompression::PerOperator);
            let n = p * p * p;
            let nodes = ops.cheb.nodes();
            let index = |i: usize| [i / (p * p), (i / p) % p, i % p];
            for c in [[2i64, 0, 0], [3, 2, 1], [3, 3, 3]] {
                let k = Mat::from_fn(n, n, |i, j| {
                    let (a, b) = (index(i), index(j));
                    let d: [f64; 3] =
                        std::array::from_fn(|x| c[x] as f64 + 0.5 * (nodes[a[x]] - nodes[b[x]]));
                    kernel::value(&Triharmonic, &d)
                });
                let aca = cross_approximation(k.as_ref(), tolerance).expect("low rank");
                let full = zeroset_tensor::thin_svd(k.as_ref()).expect("svd").s;
                let kept = full
                    .iter()
                    .take_while(|&&s| s > tolerance * full[0])
                    .count();
                assert!(
                    aca.sigma.len().abs_diff(kept) <= 1,
                    "{c:?}: {} vs {kept}",
                    aca.sigma.len()
                );
                for (a, b) in aca.sigma.iter().zip(&full) {
                    // Weyl: a perturbation of norm ε moves every singular value by at most ε.
                    assert!((a - b).abs() <= 2.0 * tolerance * full[0], "{a} vs {b}");
                }
                let mut approx = Mat::<f64>::zeros(n, n);
                product(approx.as_mut(), aca.us.as_ref(), aca.v.transpose(), 1.0);
                let error = (&approx - &k).norm_l2() / k.norm_l2();
                assert!(error < 10.0 * tolerance, "p = {p}, {c:?}: {error:e}");
            }
        }
        // Full rank: refused, and `compress` falls back to the exact SVD.
        let n = 64;
        let random = seeded_uniform(n, n);
        assert!(cross_approximation(random.as_ref(), 1e-10).is_none());
        let c = compress(random.as_ref(), 1e-10);
        let mut approx = Mat::<f64>::zeros(n, n);
        product(approx.as_mut(), c.us.as_ref(), c.v.transpose(), 1.0);
        assert!((&approx - &random).norm_l2() < 1e-9 * random.norm_l2());
    }

    /// The shared basis keeps its singular values (decreasing, above the tolerance, one per
    /// column), which are those of the matrix of all 316 offsets' columns (the sectors'
    /// weighting keeps its Gram matrix), and its columns' reflection signs
    /// (`Π_σ U = U D_σ`); the operators of the offsets `t ≥ 0` give every offset's,
    /// `C_{σt} = D_σ C_t D_σ`; and the basis of a finer level, cut where its smaller scale
    /// allows, is a leading part that still spans every offset's operator to that cut. At an
    /// even and an odd order (a middle node).
    #[test]
    fn shared_basis_keeps_its_singular_values_for_finer_levels() {
        for p in [4, 5] {
            check_shared_basis(p);
        }
    }

    fn check_shared_basis(p: usize) {
        use crate::rbf::kernel::Triharmonic;
        let tolerance = 1e-7;
        let ops = FmmOperators::new(&Triharmonic, p, tolerance, M2lCompression::SharedBasis);
        let (level, _) = ops.level(&Triharmonic, 1.0);
        let LevelOperators::Shared {
            basis,
            basis_sigma,
            signs,
            offsets,
        } = &*level
        else {
            panic!("shared basis expected");
        };
        let sym = &ops.symmetry;
        assert_eq!(basis_sigma.len(), basis.ncols());
        assert!(basis_sigma.windows(2).all(|w| w[0] >= w[1]));
        assert!(basis_sigma.iter().all(|&s| s > tolerance));
        let n = p * p * p;
        // The singular values of [Π_t U_cΣ_c / σ₁(K_c)] over all 316 offsets.
        let canonical = ops.canonical(&Triharmonic, 1.0);
        let codes: Vec<usize> = (0..343)
            .filter(|&code| sym.canonical_of[code] != usize::MAX)
            .collect();
        let total: usize = codes
            .iter()
            .map(|&code| canonical[sym.canonical_of[code]].us.ncols())
            .sum();
        let mut fat = Mat::<f64>::zeros(n, total);
        let mut col = 0;
        for &code in &codes {
            let c = &canonical[sym.canonical_of[code]];
            let norm = c.us.col(0).norm_l2();
            for j in 0..c.us.ncols() {
                for (i, &from) in sym.perm[code].iter().enumerate() {
                    fat[(i, col + j)] = c.us[(from as usize, j)] / norm;
                }
            }
            col += c.us.ncols();
        }
        let (_, full) = left_basis(fat.as_ref(), tolerance);
        assert_eq!(full.len(), basis_sigma.len(), "p = {p}");
        for (a, b) in full.iter().zip(basis_sigma) {
            assert!((a - b).abs() <= 1e-9 * full[0], "p = {p}: {a} vs {b}");
        }
        let index = |i: usize| [i / (p * p), (i / p) % p, i % p];
        // Reflections: U[σA, k] = D_σ[k] U[A, k].
        for (mask, sign) in signs.iter().enumerate() {
            let reflect = |i: usize| {
                let a = index(i);
                let b: [usize; 3] = std::array::from_fn(|x| {
                    if mask & (1 << x) != 0 {
                        p - 1 - a[x]
                    } else {
                        a[x]
                    }
                });
                (b[0] * p + b[1]) * p + b[2]
            };
            for k in 0..basis.ncols() {
                for i in 0..n {
                    let d = basis[(reflect(i), k)] - sign[k] * basis[(i, k)];
                    assert!(d.abs() < 1e-12, "p = {p}: mask {mask} column {k}");
                }
            }
        }
        // One level down, r³ operators are 8× smaller: the cut is 8× looser.
        let cut = 8.0 * tolerance;
        let rl = basis_sigma.iter().take_while(|&&s| s > cut).count();
        assert!(rl < basis.ncols(), "{rl} of {}", basis.ncols());
        // Every offset's operator, from the factors of |t| and the signs of its reflection,
        // on the leading rl columns only, keeps the cut.
        let u = basis.subcols(0, rl);
        let nodes = ops.cheb.nodes();
        let mut worst = 0.0f64;
        for &code in &codes {
            let (positive, mask) = sym.mirror[code];
            let op = offsets[positive as usize]
                .as_ref()
                .expect("t ≥ 0 has factors");
            let t = offset_of(code);
            let k = Mat::from_fn(n, n, |i, j| {
                let (a, b) = (index(i), index(j));
                let d: [f64; 3] =
                    std::array::from_fn(|x| t[x] as f64 + 0.5 * (nodes[a[x]] - nodes[b[x]]));
                kernel::value(&Triharmonic, &d)
            });
            let rc = super::super::m2l::rank_for(&op.sigma, op.a.ncols(), cut);
            let sign = &signs[mask as usize];
            // U_l D (A Bᵀ)_l D U_lᵀ against K_t.
            let mut ab = Mat::<f64>::zeros(rl, rl);
            product(
                ab.as_mut(),
                op.a.submatrix(0, 0, rl, rc),
                op.b.submatrix(0, 0, rl, rc).transpose(),
                1.0,
            );
            let signed = Mat::from_fn(rl, rl, |i, j| sign[i] * ab[(i, j)] * sign[j]);
            let mut left = Mat::<f64>::zeros(n, rl);
            product(left.as_mut(), u, signed.as_ref(), 1.0);
            let mut approx = Mat::<f64>::zeros(n, n);
            product(approx.as_mut(), left.as_ref(), u.transpose(), 1.0);
            let error = (&approx - &k).norm_l2() / k.norm_l2();
            worst = worst.max(error / cut);
        }
        assert!(worst < 10.0, "p = {p}: {worst} cuts");
    }
}
