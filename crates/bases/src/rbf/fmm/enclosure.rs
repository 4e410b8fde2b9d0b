//! Enclosures of a multipole field over boxes ([`ScalarField::value_range`]), which let the
//! signed marching cubes settle whole blocks of grid vertices with one computation.
//!
//! ## The bound
//!
//! At a point `x` of leaf `ℓ` the field is evaluated as
//!
//! ```text
//!     s(x) = L_ℓ(x) + Σ_{j ∈ near(ℓ)} wⱼ φ(|x − yⱼ|) + Σ_{B ∈ M2P(ℓ)} Σₙ M_{B,n} φ(|x − ȳ_{B,n}|) + p(x):
//! ```
//!
//! the local expansion (a polynomial of degree `p − 1` per axis), a few hundred kernel terms
//! (the near sources, and the Chebyshev nodes of the M2P cells with their multipole weights),
//! and the linear polynomial. Over a box `B ⊂ ℓ` with centre `c` and half-sides `h`
//! (`ρ = ‖h‖`), every part is its first-order Taylor polynomial at `c` plus a bounded
//! remainder:
//!
//! - **Local expansion.** With its Chebyshev coefficients `c_ijk` on the leaf (half-width `a`)
//!   and Markov's inequalities on `[−1, 1]` (`|T_i′| ≤ i²`, `|T_i″| ≤ i²(i² − 1)/3`), every
//!   second derivative is bounded over the whole leaf:
//!   `|∂xx L| ≤ Σ |c_ijk| i²(i² − 1)/3 / a²`, `|∂xy L| ≤ Σ |c_ijk| i² j² / a²`, … (once per
//!   leaf), so the remainder is at most `½ Σ_ab H_ab h_a h_b`.
//! - **A kernel term** `w φ(|x − y|)` at distance `r = |c − y|`: linearised when `r > ρ`, with
//!   remainder `½ |w| κ(r − ρ, r + ρ) ρ²` (`κ` the kernel's
//!   [curvature bound](crate::rbf::Kernel::curvature_bound)); otherwise, or when smaller, kept
//!   constant with remainder `|w| σ(r + ρ) ρ` (`σ` its
//!   [slope bound](crate::rbf::Kernel::slope_bound)).
//! - **The polynomial** is linear: exact.
//!
//! The linear part ranges over exactly `±Σ_a |g_a| h_a`. Rounding (of the field's own
//! evaluation at the box's points and of the enclosure) is covered by `4 (n + 2p³ + 8) ε` times
//! the sum of the magnitudes of the `n` terms, of the expansion's node values and of the
//! polynomial's terms, plus `Σ |w| σ` times the coordinates' size (a distance computed from
//! rounded coordinates). A box meeting several leaves is the union of its pieces, one per leaf
//! (each cube grown by `10⁻¹²` of the coordinates' size, so that no leaf a point of the box may
//! be assigned to is missed). No enclosure (`None`) for a box not wholly inside the root cube
//! or meeting more than [`MAX_LEAVES`] leaves, for a field with gradient (Hermite) constraints,
//! or for a kernel without slope and curvature bounds.
//!
//! The bound is cheap (about four evaluations' work) and tight where the field is smooth at the
//! box's scale: far from the centres a box of many grid cells clears the level, and only the
//! blocks near the surface need their vertices evaluated.

use zeroset_field_core::Aabb;

use super::FmmField;
use super::chebyshev::MAX_ORDER;
use crate::rbf::Kernel;
use crate::rbf::system::Functional;

/// A box meeting more leaves than this gets no enclosure (the caller splits it).
pub(crate) const MAX_LEAVES: usize = 8;

/// Growth of a leaf's cube in the overlap test, relative to the coordinates' size (the root's
/// half-width plus its centre's largest coordinate), so that a point that rounding places in a
/// leaf is never missed by it: far above the `depth · ε` of the cells' computed faces.
const CUBE_SLACK: f64 = 1e-12;

/// A leaf's bounds on the second derivatives of its local expansion, in the field's units:
/// `[xx, yy, zz, xy, xz, yz]`, and the sum of the magnitudes of its node values.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct LeafCurvature {
    hessian: [f64; 6],
    magnitude: f64,
}

/// The running parts of an enclosure: value and gradient at the centre, the remainder bound,
/// and the magnitude and count of the terms (for the rounding slack).
#[derive(Default)]
struct Parts {
    value: f64,
    gradient: [f64; 3],
    remainder: f64,
    magnitude: f64,
    /// `Σ |w| σ(r + ρ)` over the kernel terms (the sensitivity to rounded coordinates).
    slope: f64,
    terms: usize,
}

/// [`Parts`] of the kernel terms, per lane.
struct Lanes<const L: usize> {
    value: [f64; L],
    gradient: [[f64; L]; 3],
    remainder: [f64; L],
    magnitude: [f64; L],
    slope: [f64; L],
    terms: usize,
}

impl<const L: usize> Default for Lanes<L> {
    fn default() -> Self {
        Self {
            value: [0.0; L],
            gradient: [[0.0; L]; 3],
            remainder: [0.0; L],
            magnitude: [0.0; L],
            slope: [0.0; L],
            terms: 0,
        }
    }
}

impl<const L: usize> Lanes<L> {
    /// Adds the lanes' sums (in lane order) to `parts`.
    fn add_to(&self, parts: &mut Parts) {
        let sum = |a: &[f64; L]| a.iter().sum::<f64>();
        parts.value += sum(&self.value);
        parts.magnitude += sum(&self.magnitude);
        parts.remainder += sum(&self.remainder);
        parts.slope += sum(&self.slope);
        for (g, lanes) in parts.gradient.iter_mut().zip(&self.gradient) {
            *g += sum(lanes);
        }
        parts.terms += self.terms;
    }
}

/// [`FmmField::enclosure`] compiled per instruction set (its kernel loops vectorise).
struct EnclosureTask<'a, K> {
    field: &'a FmmField<K>,
    region: &'a Aabb<3>,
}

impl<K: Kernel> pulp::WithSimd for EnclosureTask<'_, K> {
    type Output = Option<[f64; 2]>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> Self::Output {
        self.field.enclosure_inline(self.region)
    }
}

impl<K: Kernel> FmmField<K> {
    /// See the [module docs](self).
    pub(super) fn enclosure(&self, region: &Aabb<3>) -> Option<[f64; 2]> {
        pulp::Arch::new().dispatch(EnclosureTask {
            field: self,
            region,
        })
    }

    #[inline(always)]
    fn enclosure_inline(&self, region: &Aabb<3>) -> Option<[f64; 2]> {
        if self.dipoles.is_some()
            || self.kernel.slope_bound(1.0).is_none()
            || self.kernel.curvature_bound(1.0, 2.0).is_none()
        {
            return None;
        }
        let (lo, hi) = (region.min(), region.max());
        let root = &self.tree.cells[0];
        // Cell faces are computed one rounding per level from the root's centre: grow each
        // cube by a margin that covers that, relative to the coordinates' size, so that the
        // leaf `leaf_of` picks for a point of the box is always among those found; and keep
        // the box that far inside the root, whose points all take the leaf path.
        let scale = self.coordinate_scale();
        let slack = CUBE_SLACK * scale;
        let inside_root = (0..3).all(|a| {
            lo[a] >= root.centre[a] - root.half + slack
                && hi[a] <= root.centre[a] + root.half - slack
        });
        if !inside_root {
            return None;
        }
        let mut leaves = [0u32; MAX_LEAVES];
        let mut found = 0;
        // Depth-first, eight children at a time: at most 7 per level wait on the stack.
        let mut stack = [0u32; 8 * 20];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let c = stack[top];
            let cell = self.cell(c);
            let meets = (0..3).all(|a| {
                cell.centre[a] - cell.half - slack <= hi[a]
                    && lo[a] <= cell.centre[a] + cell.half + slack
            });
            if !meets {
                continue;
            }
            if cell.is_leaf() {
                if found == MAX_LEAVES {
                    return None;
                }
                leaves[found] = c;
                found += 1;
            } else if top + 8 > stack.len() {
                return None;
            } else {
                for child in cell.children() {
                    stack[top] = child;
                    top += 1;
                }
            }
        }
        let curvature = self.leaf_curvature.get_or_init(|| self.leaf_curvatures());
        let mut out = [f64::INFINITY, f64::NEG_INFINITY];
        for &leaf in &leaves[..found] {
            let cell = self.cell(leaf);
            let piece_lo: [f64; 3] =
                std::array::from_fn(|a| lo[a].max(cell.centre[a] - cell.half - slack));
            let piece_hi: [f64; 3] =
                std::array::from_fn(|a| hi[a].min(cell.centre[a] + cell.half + slack));
            let curvature = &curvature[leaf as usize];
            let [l, h] = self.enclosure_in_leaf(leaf, &piece_lo, &piece_hi, scale, curvature)?;
            out = [out[0].min(l), out[1].max(h)];
        }
        (found > 0).then_some(out)
    }

    /// The enclosure over the box `lo..hi` inside `leaf`.
    #[inline(always)]
    fn enclosure_in_leaf(
        &self,
        leaf: u32,
        lo: &[f64; 3],
        hi: &[f64; 3],
        coordinate_scale: f64,
        curvature: &LeafCurvature,
    ) -> Option<[f64; 2]> {
        let centre: [f64; 3] = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
        let h: [f64; 3] = std::array::from_fn(|a| 0.5 * (hi[a] - lo[a]));
        let rho = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
        let p = self.ops.order();
        let [value, gx, gy, gz] = self.l2p_with_gradient(leaf, &centre);
        let mut parts = Parts {
            value,
            gradient: [gx, gy, gz],
            magnitude: curvature.magnitude,
            terms: p * p * p,
            ..Parts::default()
        };
        let hs = &curvature.hessian;
        parts.remainder = 0.5 * (hs[0] * h[0] * h[0] + hs[1] * h[1] * h[1] + hs[2] * h[2] * h[2])
            + hs[3] * h[0] * h[1]
            + hs[4] * h[0] * h[2]
            + hs[5] * h[1] * h[2];
        for &run in &self.tree.near_runs[leaf as usize] {
            let (coords, weights) = self.run(run);
            self.add_terms(coords, weights, &centre, rho, &mut parts);
        }
        for &s in &self.tree.m2p[leaf as usize] {
            let ys = self.node_coordinates(self.cell(s));
            let m = &self.multipoles[s as usize * p * p * p..][..p * p * p];
            for a in 0..p {
                for b in 0..p {
                    for c in 0..p {
                        let y = [ys[0][a], ys[1][b], ys[2][c]];
                        self.add_term(m[(a * p + b) * p + c], &y, &centre, rho, &mut parts);
                    }
                }
            }
        }
        let poly = self.poly.value(&self.poly_coefficients, &centre);
        let poly_gradient = self.poly.gradient(&self.poly_coefficients);
        parts.value += poly;
        let row = self.poly.row(&centre, Functional::Value);
        parts.magnitude += (0..4)
            .map(|k| (self.poly_coefficients[k] * row[k]).abs())
            .sum::<f64>();
        // A distance computed from coordinates of size `scale` is off by about `ε scale`, which
        // moves a term by its slope times that: `Σ |w| σ` of the terms, times `scale`.
        parts.magnitude += parts.slope * coordinate_scale;
        let mut linear = 0.0;
        for a in 0..3 {
            linear += (parts.gradient[a] + poly_gradient[a]).abs() * h[a];
        }
        let spread = linear + parts.remainder;
        let rounding = 4.0
            * (parts.terms + p * p * p + 8) as f64
            * f64::EPSILON
            * (parts.magnitude + spread + parts.value.abs());
        let spread = spread + rounding;
        let out = [parts.value - spread, parts.value + spread];
        out.iter().all(|v| v.is_finite()).then_some(out)
    }

    /// The terms of the sources `coords`, `weights`: four lanes at a time, then the rest one
    /// by one (a fixed order, so the same bits on every call).
    #[inline(always)]
    fn add_terms(
        &self,
        coords: [&[f64]; 3],
        weights: &[f64],
        centre: &[f64; 3],
        rho: f64,
        parts: &mut Parts,
    ) {
        let n = weights.len();
        let (w_chunks, tail) = weights.as_chunks::<4>();
        let chunks: [&[[f64; 4]]; 3] = std::array::from_fn(|a| coords[a][..n].as_chunks().0);
        let mut lanes = Lanes::<4>::default();
        for (k, w) in w_chunks.iter().enumerate() {
            let y = [&chunks[0][k], &chunks[1][k], &chunks[2][k]];
            self.accumulate(w, y, centre, rho, &mut lanes);
        }
        lanes.add_to(parts);
        let full = n - tail.len();
        for (j, &w) in (full..n).zip(tail) {
            let y = [coords[0][j], coords[1][j], coords[2][j]];
            self.add_term(w, &y, centre, rho, parts);
        }
    }

    /// One kernel term `w φ(|x − y|)`.
    #[inline(always)]
    fn add_term(&self, w: f64, y: &[f64; 3], centre: &[f64; 3], rho: f64, parts: &mut Parts) {
        let mut lane = Lanes::<1>::default();
        self.accumulate(&[w], [&[y[0]], &[y[1]], &[y[2]]], centre, rho, &mut lane);
        lane.add_to(parts);
    }

    /// `L` kernel terms `w φ(|x − y|)` over the ball of radius `rho` about `centre`, lane by
    /// lane and branch-free (each step a simple loop over the lanes, so that it vectorises):
    /// linearised (a gradient) where that remainder is the smaller, constant otherwise.
    #[inline(always)]
    fn accumulate<const L: usize>(
        &self,
        w: &[f64; L],
        y: [&[f64; L]; 3],
        centre: &[f64; 3],
        rho: f64,
        acc: &mut Lanes<L>,
    ) {
        let mut d = [[0.0; L]; 3];
        let mut r2 = [0.0; L];
        for a in 0..3 {
            for l in 0..L {
                d[a][l] = centre[a] - y[a][l];
                r2[l] += d[a][l] * d[a][l];
            }
        }
        let mut r = [0.0; L];
        for l in 0..L {
            r[l] = r2[l].sqrt();
            let v = w[l] * self.kernel.value_of_squared(r2[l]);
            acc.value[l] += v;
            acc.magnitude[l] += v.abs();
        }
        let half_rho2 = 0.5 * rho * rho;
        let mut d1 = [0.0; L];
        for l in 0..L {
            let w_abs = w[l].abs();
            let far = r[l] + rho;
            let slope = w_abs * self.kernel.slope_bound(far).unwrap_or(f64::INFINITY);
            acc.slope[l] += slope;
            let constant = slope * rho;
            let curvature = self
                .kernel
                .curvature_bound((r[l] - rho).max(0.0), far)
                .unwrap_or(f64::INFINITY);
            let linearised = w_abs * curvature * half_rho2;
            // False where the linearised bound is infinite or NaN (a centre in the ball).
            let linear = linearised < constant;
            let radial = w[l] * self.kernel.radial(r[l])[1];
            d1[l] = if linear { radial } else { 0.0 };
            acc.remainder[l] += if linear { linearised } else { constant };
        }
        for (g, da) in acc.gradient.iter_mut().zip(&d) {
            for l in 0..L {
                g[l] += d1[l] * da[l];
            }
        }
        acc.terms += L;
    }

    /// The size of the coordinates: the root's half-width plus its centre's largest coordinate.
    fn coordinate_scale(&self) -> f64 {
        let root = &self.tree.cells[0];
        root.half + root.centre.iter().fold(0.0f64, |m, c| m.max(c.abs()))
    }

    /// [`LeafCurvature`] of every leaf (zeros for the other cells).
    ///
    /// Sequential: it runs inside a `OnceLock` initialiser reached from rayon tasks, where a
    /// parallel loop could let the initialising thread steal another enclosure task and
    /// re-enter the lock. A few `p⁴` products per leaf, milliseconds in all.
    fn leaf_curvatures(&self) -> Vec<LeafCurvature> {
        let p = self.ops.order();
        let n = p * p * p;
        let map = self.ops.cheb.coefficient_map();
        // Markov's bounds on [−1, 1]: max |T_i′| = i², max |T_i″| = i²(i² − 1)/3.
        let first: Vec<f64> = (0..p).map(|i| (i * i) as f64).collect();
        let second: Vec<f64> = (0..p)
            .map(|i| (i * i) as f64 * ((i * i) as f64 - 1.0).max(0.0) / 3.0)
            .collect();
        (0..self.tree.cells.len())
            .map(|c| {
                let cell = &self.tree.cells[c];
                if !cell.is_leaf() {
                    return LeafCurvature::default();
                }
                let values = &self.locals[c * n..][..n];
                let coeffs = chebyshev_coefficients(p, &map, values);
                let mut hs = [0.0; 6];
                for i in 0..p {
                    for j in 0..p {
                        for k in 0..p {
                            let m = coeffs[(i * p + j) * p + k].abs();
                            hs[0] += m * second[i];
                            hs[1] += m * second[j];
                            hs[2] += m * second[k];
                            hs[3] += m * first[i] * first[j];
                            hs[4] += m * first[i] * first[k];
                            hs[5] += m * first[j] * first[k];
                        }
                    }
                }
                let scale = 1.0 / (cell.half * cell.half);
                LeafCurvature {
                    hessian: hs.map(|v| v * scale),
                    magnitude: values.iter().map(|v| v.abs()).sum(),
                }
            })
            .collect()
    }
}

/// The Chebyshev coefficients `c[(i p + j) p + k]` of the interpolant with node values
/// `values[(a p + b) p + m]`: the 1-D map `map` (`p × p`) along each axis.
fn chebyshev_coefficients(p: usize, map: &[f64], values: &[f64]) -> Vec<f64> {
    debug_assert!(p <= MAX_ORDER);
    let n = p * p * p;
    let mut t1 = vec![0.0; n];
    // Along z: t1[a, b, k] = Σ_m map[k, m] values[a, b, m].
    for ab in 0..p * p {
        let line = &values[ab * p..][..p];
        for k in 0..p {
            t1[ab * p + k] = (0..p).map(|m| map[k * p + m] * line[m]).sum();
        }
    }
    // Along y: t2[a, j, k] = Σ_b map[j, b] t1[a, b, k].
    let mut t2 = vec![0.0; n];
    for a in 0..p {
        for j in 0..p {
            for b in 0..p {
                let w = map[j * p + b];
                for k in 0..p {
                    t2[(a * p + j) * p + k] += w * t1[(a * p + b) * p + k];
                }
            }
        }
    }
    // Along x: c[i, j, k] = Σ_a map[i, a] t2[a, j, k].
    let mut c = vec![0.0; n];
    for i in 0..p {
        for a in 0..p {
            let w = map[i * p + a];
            for jk in 0..p * p {
                c[i * p * p + jk] += w * t2[a * p * p + jk];
            }
        }
    }
    c
}
