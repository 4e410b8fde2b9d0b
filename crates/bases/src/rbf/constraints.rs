//! What an RBF field must satisfy: values at points, and gradients at points (Hermite).
//!
//! - **On-surface** points: value 0.
//! - **Off-surface** points (Carr et al. 2001): `pᵢ ± εᵢ nᵢ` with values `±εᵢ`, zeroset's
//!   negative-inside convention. `εᵢ` is chosen per point so that the offset point's nearest
//!   input point is `pᵢ` itself (a k-d tree query); otherwise the offset has reached another
//!   sheet of the surface and its value would be a lie. [`Offset::Auto`] starts at 1% of the
//!   bounding-box diagonal and halves `εᵢ` until the test passes; [`Offset::Fixed`] refuses a
//!   crossing offset with [`RbfError::OffsetCrossesSurface`].
//! - **Inside/outside** points (Jiang–Turk): any value, e.g. −1 inside and +1 outside (003 takes
//!   +1 inside: flip its signs for zeroset).
//! - **Gradient** (Hermite) constraints: `∇f(p) = n`, the normal as the gradient, which geology
//!   orientations need and which removes the need for off-surface points. They need a kernel
//!   that is twice differentiable at 0 (`r³`).

use kiddo::SquaredEuclidean;
use kiddo::kd_tree::KdTree;
use kiddo::leaf_strategies::FlatVec;
use kiddo::stem_strategies::Eytzinger;
use zeroset_field_core::geometry::norm as point_norm;
use zeroset_field_core::{Point, PointCloud};

use super::RbfError;
use crate::meeting::{Meeting, meeting};

/// What a constraint prescribes at its point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Prescribed<const D: usize> {
    /// `f(p) = v`.
    Value(f64),
    /// `∇f(p) = g`.
    Gradient(Point<D>),
}

/// One constraint: a point and what `f` must do there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Constraint<const D: usize> {
    /// Where.
    pub point: Point<D>,
    /// What.
    pub prescribed: Prescribed<D>,
}

/// How far off-surface points sit from the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Offset {
    /// Start at `fraction` of the bounding-box diagonal and halve per point until the offset
    /// point's nearest input point is its own (at most 8 halvings; points that still fail get
    /// no off-surface constraint and are counted in [`OffsetReport::dropped`]).
    Auto {
        /// The starting offset as a fraction of the bounding-box diagonal.
        fraction: f64,
    },
    /// The same offset for every point; a crossing one is an error.
    Fixed(f64),
}

impl Default for Offset {
    fn default() -> Self {
        Self::Auto { fraction: 0.01 }
    }
}

/// What [`Constraints::off_surface`] did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct OffsetReport {
    /// The starting offset.
    pub initial: f64,
    /// The smallest offset used.
    pub smallest: f64,
    /// Offset points that had to be moved closer (one per side).
    pub shrunk: usize,
    /// Offset points dropped because even the smallest offset crossed the surface.
    pub dropped: usize,
    /// Input points merged into an earlier one within [`MERGE_DISTANCE`] (no constraints of
    /// their own: two centres at one place make the system singular).
    pub merged: usize,
    /// Points whose normal points against those of most of their [`NORMAL_NEIGHBOURS`]
    /// nearest neighbours near their tangent plane (negative dot product with more than half of
    /// those within [`TANGENT_SLOPE`] of it, or of all of them where fewer than 3 are): likely
    /// flipped normals, whose offsets would put a bump or a bubble into the surface there.
    /// They get value 0 only, no offsets (CGAL's `ball.ply`, 86 of 31,374: 39 components, 37
    /// of them blobs, and Euler characteristic −8 with offsets; 4, 3 and −4 without). Neighbours
    /// off the plane — the other face of a wall thinner than the sampling, whose normals
    /// rightly point the other way — do not count.
    pub opposed_normals: usize,
    /// Points with two of their [`NORMAL_NEIGHBOURS`] nearest neighbours behind them, off their
    /// tangent plane ([`TANGENT_SLOPE`]) and facing the other way ([`WALL_FACES`]): they lie on
    /// a wall (or another thin part) thinner than the points' spacing, which an interpolant
    /// between its two faces thickens, pits or breaks.
    pub thin_wall: usize,
    /// Places where points merged into one ([`MERGE_DISTANCE`]) have normals that point apart
    /// (negative dot product): two sheets meeting there — a closed mesh touching itself, two
    /// solids touching, a thin sheet's two faces, a sharp edge or a crease whose faces keep
    /// their own vertices. Each gets value 0 and offsets along both normals on one side,
    /// chosen by where the other sheet's points around it lie (those of its
    /// [`NORMAL_NEIGHBOURS`] nearest that face the other normal's way): ahead of the kept
    /// point's normal, two solids touching, inside (`−ε` against each normal); behind it, a
    /// wall pinched to nothing, outside (`+ε` along each); no offset where there is no
    /// telling. Where the neighbours all face one of the two ways, it is one sheet with a
    /// flipped normal at a repeated sample (not counted here): that way is its normal.
    pub touching: usize,
}

/// How many nearest neighbours [`OffsetReport::opposed_normals`] compares each normal with.
pub const NORMAL_NEIGHBOURS: usize = 8;

/// A neighbour `q` of `p` is compared with `p`'s normal only where it lies near `p`'s tangent
/// plane: `|(q − p)·n_p| ≤ TANGENT_SLOPE·‖q − p‖` (within 17°). On a smooth surface sampled at
/// spacing `s` the neighbours lie within about `κs/2` of it (0.05 at 10 points per radius); the
/// other face of a wall of thickness `t` lies `t/‖q − p‖` off it (a 1 mm tube wall sampled every
/// 1.1 mm: 0.5–0.9). Those normals point the other way by right: counted, 1,357 of a clean
/// tube's 20,000 exact normals were called flipped.
pub const TANGENT_SLOPE: f64 = 0.3;

/// [`OffsetReport::thin_wall`] takes a neighbour behind a point for the far face of a wall
/// where their normals' dot product is below this (more than 134° apart: a wall's faces are
/// opposite; across a sharp edge they are not — a tetrahedron's faces meet at 109.5°, whose
/// edges counted 17.6% of its points as a thin wall). Two such neighbours are needed.
pub const WALL_FACES: f64 = -0.7;

/// Input points closer than this fraction of the bounding-box diagonal are one point to
/// [`Constraints::off_surface`] (the first is kept, with its normal): about a float32
/// coordinate's resolution, where a scanner's or a merge's repeated samples are the same
/// measurement. Two of them whose normals point apart are a place where two sheets meet
/// ([`OffsetReport::touching`]; refused by [`Constraints::hermite`], whose gradient there
/// would be both normals: [`RbfError::ConflictingDuplicates`]).
pub const MERGE_DISTANCE: f64 = 1e-7;

/// An ordered list of constraints.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Constraints<const D: usize> {
    items: Vec<Constraint<D>>,
}

type Tree<const D: usize> = KdTree<f64, u32, Eytzinger, FlatVec<f64, u32, D, 32>, D, 32>;

impl<const D: usize> Constraints<D> {
    /// No constraints.
    pub fn new() -> Self {
        Self { items: Vec::new() }
    }

    /// The constraints, in order.
    pub fn as_slice(&self) -> &[Constraint<D>] {
        &self.items
    }

    /// The value constraints as points and targets, in order (gradient constraints left
    /// out): the data of a fit that takes values only, such as a neural field's.
    pub fn values(&self) -> (Vec<Point<D>>, Vec<f64>) {
        self.items
            .iter()
            .filter_map(|k| match k.prescribed {
                Prescribed::Value(v) => Some((k.point, v)),
                Prescribed::Gradient(_) => None,
            })
            .unzip()
    }

    /// The number of constraints.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Adds `f(point) = value` (an on-surface point with 0, inside/outside with any value).
    pub fn push_value(&mut self, point: Point<D>, value: f64) -> &mut Self {
        self.items.push(Constraint {
            point,
            prescribed: Prescribed::Value(value),
        });
        self
    }

    /// Adds `∇f(point) = gradient`.
    pub fn push_gradient(&mut self, point: Point<D>, gradient: Point<D>) -> &mut Self {
        self.items.push(Constraint {
            point,
            prescribed: Prescribed::Gradient(gradient),
        });
        self
    }

    /// Appends every constraint of `other`.
    pub fn extend(&mut self, other: &Self) -> &mut Self {
        self.items.extend_from_slice(&other.items);
        self
    }

    /// Value 0 at every point of `cloud`.
    pub fn on_surface(cloud: &PointCloud<D>) -> Self {
        let mut c = Self::new();
        for p in cloud.positions() {
            c.push_value(*p, 0.0);
        }
        c
    }

    /// Value 0 at every point and `±εᵢ` at `pᵢ ± εᵢ nᵢ` (Carr et al.), `εᵢ` as `offset` says;
    /// see the [module docs](self). Normals are normalised here; points within
    /// [`MERGE_DISTANCE`] of an earlier one are merged into it ([`OffsetReport::merged`]),
    /// and where their normals point apart the place gets value 0 and no offset
    /// ([`OffsetReport::touching`]). A point whose normal points against most of its
    /// neighbours' (flipped?) gets value 0 only ([`OffsetReport::opposed_normals`]).
    ///
    /// # Errors
    /// [`RbfError::Empty`], [`RbfError::NonFinite`], [`RbfError::ZeroNormal`], a cloud
    /// without normals or (with the automatic offset) without extent as
    /// [`RbfError::Degenerate`], [`RbfError::InvalidOffset`], and for a fixed offset
    /// [`RbfError::OffsetCrossesSurface`].
    pub fn off_surface(
        cloud: &PointCloud<D>,
        offset: Offset,
    ) -> Result<(Self, OffsetReport), RbfError> {
        let normals = unit_normals(cloud)?;
        let points = cloud.positions();
        let diagonal = cloud.bounds().map_or(0.0, |b| b.diagonal());
        let (initial, halvings) = match offset {
            Offset::Auto { fraction } => (fraction * diagonal, 8),
            Offset::Fixed(eps) => (eps, 0),
        };
        if diagonal == 0.0 && matches!(offset, Offset::Auto { .. }) {
            // The automatic offset is a fraction of the diagonal: say why it is 0.
            return Err(RbfError::Degenerate {
                detail: format!(
                    "all {} points lie at one position (the cloud has no extent)",
                    points.len()
                ),
            });
        }
        if !(initial.is_finite() && initial > 0.0) {
            return Err(RbfError::InvalidOffset(initial));
        }
        let all = index(points)?;
        // Of each kept point, the first merged into it whose normal points against its own.
        let mut touching: Vec<Option<usize>> = vec![None; points.len()];
        let kept = distinct(&all, points, MERGE_DISTANCE * diagonal, |i, j| {
            if touching[i].is_none() && dot(&normals[i], &normals[j]) < 0.0 {
                touching[i] = Some(j);
            }
            Ok(())
        })?;
        let positions: Vec<Point<D>> = kept.iter().map(|&i| points[i]).collect();
        // The offset test's tree: over the kept points (the same as `all` when none merged).
        let tree = if kept.len() == points.len() {
            all
        } else {
            index(&positions)?
        };
        let mut c = Self::new();
        for p in &positions {
            c.push_value(*p, 0.0);
        }
        let mut report = OffsetReport {
            initial,
            smallest: initial,
            merged: points.len() - kept.len(),
            ..OffsetReport::default()
        };
        let (opposed, thin_wall) = opposed_normals(&tree, &positions, &kept, &normals);
        report.opposed_normals = opposed.iter().filter(|&&o| o).count();
        report.thin_wall = thin_wall;
        for (k, (p, &i)) in positions.iter().zip(&kept).enumerate() {
            // A normal against its neighbours' (flipped?): its offsets would put the field's
            // other sign on this side of the surface; the point keeps its value 0 only.
            if opposed[k] && touching[i].is_none() {
                continue;
            }
            // Outside along the normal and inside against it; where two sheets meet, along
            // both normals on the side the sheets around say (none where they say nothing).
            let meets =
                touching[i].map(|j| (j, meeting_at(&tree, &positions, &kept, &normals, k, j)));
            let sides = match meets {
                None => vec![(normals[i], 1.0), (normals[i], -1.0)],
                // A flipped normal at a repeated sample: the sheet around has one side.
                Some((j, Meeting::OneSheet { first })) => {
                    let m = if first { i } else { j };
                    vec![(normals[m], 1.0), (normals[m], -1.0)]
                }
                Some((j, Meeting::Sheets { ahead })) => {
                    report.touching += 1;
                    if ahead == 0.0 {
                        Vec::new()
                    } else {
                        let side = -ahead.signum();
                        vec![(normals[i], side), (normals[j], side)]
                    }
                }
            };
            for (n, side) in sides {
                let mut eps = initial;
                let mut placed = false;
                for attempt in 0..=halvings {
                    let q: Point<D> = std::array::from_fn(|a| p[a] + side * eps * n[a]);
                    let nearest = tree
                        .query(&q)
                        .nearest_one::<SquaredEuclidean<f64>>()
                        .execute();
                    let own = squared(&q, p);
                    // Another point as near (within 0.1%: a near-duplicate sample) counts as
                    // the own point: the value ±ε is then still the distance to the surface
                    // within 0.1%.
                    if nearest.item as usize == k || nearest.distance >= own * (1.0 - 2e-3) {
                        if attempt > 0 {
                            report.shrunk += 1;
                        }
                        report.smallest = report.smallest.min(eps);
                        c.push_value(q, side * eps);
                        placed = true;
                        break;
                    }
                    if halvings == 0 {
                        return Err(RbfError::OffsetCrossesSurface {
                            index: i,
                            eps,
                            nearest: kept[nearest.item as usize],
                        });
                    }
                    eps *= 0.5;
                }
                if !placed {
                    report.dropped += 1;
                }
            }
        }
        Ok((c, report))
    }

    /// Value 0 and gradient `nᵢ` (unit) at every point: Hermite constraints. Points within
    /// [`MERGE_DISTANCE`] of an earlier one are merged into it, as in
    /// [`Constraints::off_surface`] (two constraints a point: `cloud.len() − len() / 2` were
    /// merged).
    ///
    /// # Errors
    /// As [`Constraints::off_surface`], without the offset ones.
    pub fn hermite(cloud: &PointCloud<D>) -> Result<Self, RbfError> {
        let normals = unit_normals(cloud)?;
        let points = cloud.positions();
        let diagonal = cloud.bounds().map_or(0.0, |b| b.diagonal());
        let kept = distinct(
            &index(points)?,
            points,
            MERGE_DISTANCE * diagonal,
            opposite_normals(points, &normals),
        )?;
        let mut c = Self::new();
        for i in kept {
            c.push_value(points[i], 0.0);
            c.push_gradient(points[i], normals[i]);
        }
        Ok(c)
    }

    /// Value constraints `f(pᵢ) = vᵢ` from a value file's rows, a point within
    /// [`MERGE_DISTANCE`] of the points' box diagonal of an earlier one merged into it when
    /// their values agree (to 1e-12 of the largest |v|, or exactly when all are 0): a curve's
    /// closing point repeated, a row written twice. Returns the constraints and the indices of
    /// the rows kept (in order; the others were merged).
    ///
    /// ```
    /// use zeroset_bases::rbf::Constraints;
    /// let points = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 0.0]];
    /// let (c, kept) = Constraints::from_values(&points, &[1.0, -1.0, 0.5, 1.0]).unwrap();
    /// assert_eq!((c.len(), kept), (3, vec![0, 1, 2]));
    /// assert!(Constraints::from_values(&points, &[1.0, -1.0, 0.5, 2.0]).is_err());
    /// ```
    ///
    /// # Errors
    /// [`RbfError::Empty`]; [`RbfError::NonFinite`] naming the row;
    /// [`RbfError::ConflictingValues`] for two rows at one place with different values.
    ///
    /// # Panics
    /// If `values` is not as long as `points`.
    pub fn from_values(
        points: &[Point<D>],
        values: &[f64],
    ) -> Result<(Self, Vec<usize>), RbfError> {
        assert_eq!(points.len(), values.len(), "one value a point");
        if points.is_empty() {
            return Err(RbfError::Empty);
        }
        for (index, (p, v)) in points.iter().zip(values).enumerate() {
            let bad = |value: f64, what| RbfError::NonFinite { index, what, value };
            if let Some(&x) = p.iter().find(|x| !x.is_finite()) {
                return Err(bad(x, "coordinate"));
            }
            if !v.is_finite() {
                return Err(bad(*v, "value"));
            }
        }
        let diagonal = zeroset_field_core::Aabb::from_points(points).map_or(0.0, |b| b.diagonal());
        let scale = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let kept = distinct(
            &index(points)?,
            points,
            MERGE_DISTANCE * diagonal,
            |i, j| {
                if (values[i] - values[j]).abs() > 1e-12 * scale {
                    return Err(RbfError::ConflictingValues {
                        first: i,
                        second: j,
                        point: points[i].to_vec(),
                        values: (values[i], values[j]),
                    });
                }
                Ok(())
            },
        )?;
        let mut c = Self::new();
        for &i in &kept {
            c.push_value(points[i], values[i]);
        }
        Ok((c, kept))
    }
}

/// A k-d tree over `points` (items: their indices).
fn index<const D: usize>(points: &[Point<D>]) -> Result<Tree<D>, RbfError> {
    Tree::<D>::new_from_slice(points).map_err(|e| RbfError::Degenerate {
        detail: format!("cannot index the points: {e}"),
    })
}

/// The indices of the points to keep, in order (`tree` indexes `points`): each point closer
/// than `radius` to an earlier kept one is merged into it (exact duplicates always), told to
/// `merge(kept, other)`, whose error says the two cannot be one ([`opposite_normals`],
/// different values).
fn distinct<const D: usize>(
    tree: &Tree<D>,
    points: &[Point<D>],
    radius: f64,
    mut merge: impl FnMut(usize, usize) -> Result<(), RbfError>,
) -> Result<Vec<usize>, RbfError> {
    // `within` keeps distances below the bound: the smallest positive one catches exact
    // duplicates when the radius is 0.
    let r2 = (radius * radius).max(f64::MIN_POSITIVE);
    let mut merged = vec![false; points.len()];
    let mut kept = Vec::with_capacity(points.len());
    for (i, p) in points.iter().enumerate() {
        if merged[i] {
            continue;
        }
        kept.push(i);
        for found in tree.query(p).within::<SquaredEuclidean<f64>>(r2).execute() {
            let j = found.item as usize;
            if j <= i || merged[j] {
                continue;
            }
            merge(i, j)?;
            merged[j] = true;
        }
    }
    Ok(kept)
}

/// How the sheets meet at kept point `k` (input point `kept[k]`), whose normal points against
/// that of input point `j`, merged into it: judged by its [`NORMAL_NEIGHBOURS`] nearest kept
/// points ([`crate::meeting`]).
fn meeting_at<const D: usize>(
    tree: &Tree<D>,
    positions: &[Point<D>],
    kept: &[usize],
    normals: &[Point<D>],
    k: usize,
    j: usize,
) -> Meeting {
    let p = &positions[k];
    let wanted = std::num::NonZero::new((NORMAL_NEIGHBOURS + 1).min(positions.len()))
        .expect("the point itself is kept");
    let around = tree
        .query(p)
        .nearest_n::<SquaredEuclidean<f64>>(wanted)
        .execute();
    let around = around
        .into_iter()
        .map(|found| found.item as usize)
        .filter(|&m| m != k)
        .map(|m| (positions[m], normals[kept[m]]));
    meeting(p, &normals[kept[k]], &normals[j], around)
}

/// Normals that point apart at one place, refused where the gradient is prescribed (it cannot
/// be both).
fn opposite_normals<const D: usize>(
    points: &[Point<D>],
    normals: &[Point<D>],
) -> impl Fn(usize, usize) -> Result<(), RbfError> {
    move |i, j| {
        let dot = dot(&normals[i], &normals[j]);
        if dot < 0.0 {
            return Err(RbfError::ConflictingDuplicates {
                first: i,
                second: j,
                point: points[i].to_vec(),
                dot,
            });
        }
        Ok(())
    }
}

/// `a · b`.
fn dot<const D: usize>(a: &Point<D>, b: &Point<D>) -> f64 {
    (0..D).map(|x| a[x] * b[x]).sum()
}

/// Which of the kept points have a normal with a negative dot product with more than half
/// of their [`NORMAL_NEIGHBOURS`] nearest kept neighbours' normals, of those near its tangent
/// plane ([`TANGENT_SLOPE`]); and how many lie on a wall thinner than the spacing
/// ([`OffsetReport::thin_wall`]).
fn opposed_normals<const D: usize>(
    tree: &Tree<D>,
    positions: &[Point<D>],
    kept: &[usize],
    normals: &[Point<D>],
) -> (Vec<bool>, usize) {
    let k = (NORMAL_NEIGHBOURS + 1).min(positions.len());
    let Some(k) = std::num::NonZero::new(k) else {
        return (vec![false; positions.len()], 0);
    };
    let mut thin = 0;
    let opposed = positions
        .iter()
        .zip(kept)
        .map(|(p, i)| {
            let n = &normals[*i];
            let found = tree
                .query(p)
                .nearest_n::<SquaredEuclidean<f64>>(k)
                .execute();
            let mut in_plane: Vec<&Point<D>> = Vec::with_capacity(found.len());
            let mut all: Vec<&Point<D>> = Vec::with_capacity(found.len());
            let mut behind_facing_away = 0;
            for f in &found {
                let (q, m) = (&positions[f.item as usize], &normals[kept[f.item as usize]]);
                let d: Point<D> = std::array::from_fn(|a| q[a] - p[a]);
                let (along, length) = (dot(&d, n), dot(&d, &d).sqrt());
                // The point itself (length 0) is left out.
                if length == 0.0 {
                    continue;
                }
                if along.abs() <= TANGENT_SLOPE * length {
                    in_plane.push(m);
                } else if along < 0.0 && dot(n, m) < WALL_FACES {
                    // A far face's: no evidence of a flip either way.
                    behind_facing_away += 1;
                    continue;
                }
                all.push(m);
            }
            thin += usize::from(behind_facing_away >= 2);
            // Too few near the plane (a noisy scan's neighbours scatter off it): all of them
            // vote but a far face's, as before the plane was looked at.
            let voters = if in_plane.len() >= 3 { &in_plane } else { &all };
            let against = voters.iter().filter(|m| dot(n, m) < 0.0).count();
            !voters.is_empty() && 2 * against > voters.len()
        })
        .collect();
    (opposed, thin)
}

/// The cloud's normals scaled to unit length, checked.
fn unit_normals<const D: usize>(cloud: &PointCloud<D>) -> Result<Vec<Point<D>>, RbfError> {
    if cloud.is_empty() {
        return Err(RbfError::Empty);
    }
    let Some(normals) = cloud.normals() else {
        return Err(RbfError::Degenerate {
            detail: "the points have no normals (off-surface and Hermite constraints need them)"
                .into(),
        });
    };
    let mut out = Vec::with_capacity(normals.len());
    for (index, (p, n)) in cloud.positions().iter().zip(normals).enumerate() {
        if let Some(&value) = p.iter().find(|v| !v.is_finite()) {
            return Err(RbfError::NonFinite {
                index,
                what: "coordinate",
                value,
            });
        }
        if let Some(&value) = n.iter().find(|v| !v.is_finite()) {
            return Err(RbfError::NonFinite {
                index,
                what: "normal",
                value,
            });
        }
        let len = point_norm(n);
        if len < 1e-12 {
            return Err(RbfError::ZeroNormal { index });
        }
        out.push(n.map(|v| v / len));
    }
    Ok(out)
}

fn squared<const D: usize>(a: &Point<D>, b: &Point<D>) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_sheets() -> PointCloud<3> {
        // Two parallel planes 0.1 apart, normals facing away from each other.
        let mut p = Vec::new();
        let mut n = Vec::new();
        for i in 0..5 {
            for j in 0..5 {
                let (x, y) = (i as f64 * 0.2, j as f64 * 0.2);
                p.push([x, y, 0.0]);
                n.push([0.0, 0.0, -1.0]);
                p.push([x, y, 0.1]);
                n.push([0.0, 0.0, 1.0]);
            }
        }
        PointCloud::with_normals(p, n).unwrap()
    }

    #[test]
    fn auto_offsets_shrink_where_the_surface_is_near() {
        let cloud = two_sheets();
        let (c, report) = Constraints::off_surface(&cloud, Offset::Auto { fraction: 0.2 }).unwrap();
        assert_eq!(c.len(), 3 * cloud.len());
        assert!(report.shrunk > 0 && report.dropped == 0, "{report:?}");
        // Inward offsets (between the sheets) end up below half the gap.
        assert!(report.smallest <= 0.05 + 1e-12, "{report:?}");
        for k in cloud.len()..c.len() {
            let Prescribed::Value(v) = c.as_slice()[k].prescribed else {
                panic!("values only")
            };
            assert!(v.abs() <= report.initial && v != 0.0);
        }
    }

    #[test]
    fn a_fixed_offset_that_crosses_is_refused_and_bad_normals_are_named() {
        let cloud = two_sheets();
        let err = Constraints::off_surface(&cloud, Offset::Fixed(0.15)).unwrap_err();
        assert!(
            matches!(err, RbfError::OffsetCrossesSurface { .. }),
            "{err}"
        );
        assert!(Constraints::off_surface(&cloud, Offset::Fixed(0.02)).is_ok());
        assert_eq!(
            Constraints::off_surface(&cloud, Offset::Fixed(-1.0)).unwrap_err(),
            RbfError::InvalidOffset(-1.0)
        );
        // A cloud at one position: the automatic offset's diagonal is 0, and the error says so
        // (it said "offset must be finite and > 0, got 0", an offset the user never gave).
        let point = PointCloud::with_normals(vec![[0.5; 3]; 4], vec![[0.0, 0.0, 1.0]; 4]).unwrap();
        let err = Constraints::off_surface(&point, Offset::default()).unwrap_err();
        assert!(
            err.to_string().contains("all 4 points lie at one position"),
            "{err}"
        );
        let zero =
            PointCloud::with_normals(vec![[0.0; 3], [1.0; 3]], vec![[0.0, 0.0, 1.0], [0.0; 3]])
                .unwrap();
        assert_eq!(
            Constraints::hermite(&zero).unwrap_err(),
            RbfError::ZeroNormal { index: 1 }
        );
        let bare = PointCloud::new(vec![[0.0; 3]]).unwrap();
        assert!(matches!(
            Constraints::hermite(&bare).unwrap_err(),
            RbfError::Degenerate { .. }
        ));
    }

    #[test]
    fn repeated_samples_are_merged_and_opposite_ones_touch() {
        let cloud = two_sheets();
        let (base, _) = Constraints::off_surface(&cloud, Offset::Auto { fraction: 0.2 }).unwrap();
        // Every point again: exactly, and moved by a tenth of the merge distance.
        let (mut p, mut n) = (
            cloud.positions().to_vec(),
            cloud.normals().unwrap().to_vec(),
        );
        let diagonal = cloud.bounds().unwrap().diagonal();
        for i in 0..cloud.len() {
            let q = p[i];
            let shift = if i % 2 == 0 {
                0.0
            } else {
                0.1 * MERGE_DISTANCE * diagonal
            };
            p.push([q[0] + shift, q[1], q[2]]);
            n.push(n[i]);
        }
        let doubled = PointCloud::with_normals(p.clone(), n.clone()).unwrap();
        let (c, report) =
            Constraints::off_surface(&doubled, Offset::Auto { fraction: 0.2 }).unwrap();
        assert_eq!(report.merged, cloud.len(), "{report:?}");
        // Hermite constraints merge the same way: a value and a gradient per kept point.
        assert_eq!(
            Constraints::hermite(&doubled).unwrap().len(),
            Constraints::hermite(&cloud).unwrap().len()
        );
        // The merged copies change nothing (but the bounding box's diagonal, by 1e-8).
        assert_eq!(c.len(), base.len());
        let moved = c
            .as_slice()
            .iter()
            .zip(base.as_slice())
            .map(|(a, b)| squared(&a.point, &b.point).sqrt())
            .fold(0.0, f64::max);
        assert!(moved < 1e-6, "constraints moved by {moved:.1e}");
        // One copy with its normal reversed: two sheets meeting there. The other sheet's
        // points (the lower plane, facing −z) lie behind the kept normal (+z): a wall pinched
        // to nothing, outside on both sides — its inside offset became a second outside one.
        n[cloud.len() + 3] = n[3].map(|v| -v);
        let conflicting = PointCloud::with_normals(p, n).unwrap();
        let (c, report) =
            Constraints::off_surface(&conflicting, Offset::Auto { fraction: 0.2 }).unwrap();
        assert_eq!((report.merged, report.touching), (cloud.len(), 1));
        assert_eq!(c.len(), base.len());
        let signs = |c: &Constraints<3>| {
            c.as_slice()
                .iter()
                .fold((0, 0), |(neg, pos), k| match k.prescribed {
                    Prescribed::Value(v) if v < 0.0 => (neg + 1, pos),
                    Prescribed::Value(v) if v > 0.0 => (neg, pos + 1),
                    _ => (neg, pos),
                })
        };
        let ((neg, pos), (base_neg, base_pos)) = (signs(&c), signs(&base));
        assert_eq!((neg + 1, pos), (base_neg, base_pos + 1));
        // Hermite constraints cannot hold both gradients: refused, naming both records.
        let err = Constraints::hermite(&conflicting).unwrap_err();
        assert!(
            matches!(err, RbfError::ConflictingDuplicates { first: 3, .. }),
            "{err}"
        );
    }

    #[test]
    fn repeated_value_rows_are_merged_and_conflicting_ones_refused() {
        let points = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        let values = [1.0, -1.0, 0.5, 0.0];
        let (base, kept) = Constraints::from_values(&points, &values).unwrap();
        assert_eq!((base.len(), kept), (4, vec![0, 1, 2, 3]));
        // The first row again, a hair off (1e-17), and the third exactly.
        let mut p = points.to_vec();
        p.extend([[1e-17, 0.0], [0.0, 1.0]]);
        let mut v = values.to_vec();
        v.extend([1.0, 0.5]);
        let (c, kept) = Constraints::from_values(&p, &v).unwrap();
        assert_eq!((c.as_slice(), kept), (base.as_slice(), vec![0, 1, 2, 3]));
        // A different value at the first row's place: refused, naming both rows.
        v[4] = -0.5;
        let err = Constraints::from_values(&p, &v).unwrap_err();
        assert!(
            matches!(
                err,
                RbfError::ConflictingValues {
                    first: 0,
                    second: 4,
                    values: (1.0, -0.5),
                    ..
                }
            ),
            "{err}"
        );
        v[4] = f64::NAN;
        assert!(matches!(
            Constraints::from_values(&p, &v).unwrap_err(),
            RbfError::NonFinite {
                index: 4,
                what: "value",
                ..
            }
        ));
        assert!(matches!(
            Constraints::<2>::from_values(&[], &[]).unwrap_err(),
            RbfError::Empty
        ));
    }

    #[test]
    fn normals_against_their_neighbours_are_counted() {
        // A sphere with outward normals, two of them flipped.
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let (mut p, mut n) = (Vec::new(), Vec::new());
        for i in 0..400 {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / 400.0;
            let r = (1.0 - z * z).sqrt();
            let q = [
                r * (golden * i as f64).cos(),
                r * (golden * i as f64).sin(),
                z,
            ];
            p.push(q);
            n.push(q);
        }
        let clean = PointCloud::with_normals(p.clone(), n.clone()).unwrap();
        let (_, report) = Constraints::off_surface(&clean, Offset::default()).unwrap();
        assert_eq!((report.opposed_normals, report.thin_wall), (0, 0));
        for i in [10, 200] {
            n[i] = n[i].map(|v| -v);
        }
        let flipped = PointCloud::with_normals(p, n).unwrap();
        let (c, report) = Constraints::off_surface(&flipped, Offset::default()).unwrap();
        assert_eq!(report.opposed_normals, 2, "{report:?}");
        // Value 0 only where flipped: 400 on the surface, two offsets for each of the others.
        assert_eq!(c.len(), 400 + 2 * 398);
    }

    /// The unit normal of the triangle `a b c`.
    pub(super) fn cross3(a: &[f64; 3], b: &[f64; 3], c: &[f64; 3]) -> [f64; 3] {
        let (e, f): ([f64; 3], [f64; 3]) = (
            std::array::from_fn(|x| b[x] - a[x]),
            std::array::from_fn(|x| c[x] - a[x]),
        );
        let n = [
            e[1] * f[2] - e[2] * f[1],
            e[2] * f[0] - e[0] * f[2],
            e[0] * f[1] - e[1] * f[0],
        ];
        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        n.map(|v| v / l)
    }

    #[test]
    fn the_other_face_of_a_thin_wall_is_not_a_flipped_normal() {
        // Both faces of a plate 0.6 spacings thick (grid step 1 on each face, the lower
        // face's normals down): every point's nearest neighbours include the other face's,
        // whose normals rightly point the other way. Counted, every point of it was
        // "flipped"; one normal really flipped is still found.
        let (mut p, mut n) = (Vec::new(), Vec::new());
        for face in [0.3, -0.3] {
            for i in 0..30 {
                for j in 0..30 {
                    p.push([f64::from(i), f64::from(j), face]);
                    n.push([0.0, 0.0, face.signum()]);
                }
            }
        }
        let plate = PointCloud::with_normals(p.clone(), n.clone()).unwrap();
        let (_, report) = Constraints::off_surface(&plate, Offset::Fixed(0.1)).unwrap();
        assert_eq!(report.opposed_normals, 0, "{report:?}");
        assert_eq!(report.thin_wall, 1800, "{report:?}");
        // A solid's sharp edges are not walls: a tetrahedron's faces meet at 109.5°, and
        // its edges counted 17.6% of its points as thin with any facing-away neighbour.
        let corners = [
            [1.0, 1.0, 1.0],
            [1.0, -1.0, -1.0],
            [-1.0, 1.0, -1.0],
            [-1.0, -1.0, 1.0],
        ];
        let (mut tp, mut tn) = (Vec::new(), Vec::new());
        for skip in 0..4 {
            let [a, b, c]: [[f64; 3]; 3] = std::array::from_fn(|k| corners[(skip + 1 + k) % 4]);
            let o = corners[skip];
            let mut normal = cross3(&a, &b, &c);
            let centre: [f64; 3] = std::array::from_fn(|x| (a[x] + b[x] + c[x]) / 3.0 - o[x]);
            if (0..3).map(|x| normal[x] * centre[x]).sum::<f64>() < 0.0 {
                normal = normal.map(|v| -v);
            }
            for i in 1..30 {
                for j in 1..30 - i {
                    let (u, v) = (f64::from(i) / 30.0, f64::from(j) / 30.0);
                    tp.push(std::array::from_fn(|x| {
                        (1.0 - u - v) * a[x] + u * b[x] + v * c[x]
                    }));
                    tn.push(normal);
                }
            }
        }
        let solid = PointCloud::with_normals(tp, tn).unwrap();
        let (_, report) = Constraints::off_surface(&solid, Offset::Fixed(0.01)).unwrap();
        assert_eq!(report.thin_wall, 0, "{report:?}");
        // (The point nearest each corner has fewer than 3 neighbours near its plane, and all
        // of them vote, as before.)
        assert!(report.opposed_normals <= 4, "{report:?}");
        n[465] = n[465].map(|v| -v);
        let flipped = PointCloud::with_normals(p, n).unwrap();
        let (_, report) = Constraints::off_surface(&flipped, Offset::Fixed(0.1)).unwrap();
        assert_eq!(report.opposed_normals, 1, "{report:?}");
    }
}
