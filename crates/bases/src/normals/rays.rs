//! Whether given normals face into their object, read from the cloud along rays.
//!
//! A ray leaving a surface point along its outward normal starts outside the object, so the
//! first surface it meets faces back at it (`n_q · d < 0`) and it crosses the surface an even
//! number of times before it leaves the cloud's box; along the inward direction it starts
//! inside, the first surface it meets faces along it, and it crosses an odd number of times.
//! A normal turned inward reads the other way round on both counts. That tells a patch of
//! normals turned inward on a closed object (its underside's, where a program turned every
//! normal to face up) from a patch the orientation walk merely disagrees with across a sharp
//! crease (a ridge, a tetrahedron's edges), whose normals are right and whose rays read
//! outward or meet nothing.
//!
//! The surface is the cloud: along the ray, in steps of the tube radius `R` (1.5 × the median
//! spacing to the nearest point elsewhere, so a cloud merged twice has the spacing it had),
//! the points within `R` of it whose tangent planes (their lines, either sign) the ray
//! crosses within `R` of the point, not at a grazing angle; their crossing distances, sorted,
//! split into sheets where they leave a gap over `R`. Where the nearest point is farther than
//! a step reaches, the ray skips the empty stretch (a far outlier's box costs a few steps,
//! and leaves `R` as it was). The point's own sheet (closer than two spacings) is skipped.
//! Holes let a ray out without a crossing, and a concave open surface (a valley) is crossed
//! once by a ray that starts outside it: only rays on which the crossing count and the first
//! sheet's facing agree vote. The first sheet's facing is read from its points in the ray's
//! own piece of the walk only: a closed object's sides are one piece, while open sheets
//! stacked facing one way (terraces, geological horizons), which a ray from the lower one
//! meets exactly as a closed object's top is met from its turned underside, are separate
//! pieces, and say nothing of each other's side.

use rayon::prelude::*;
use zeroset_field_core::geometry::{self, Aabb, Point};

use crate::noise::Tree;

/// The most points [`orient_normals`](super::orient_normals) casts rays from: enough for a
/// share within a few points (its rule compares shares of a third), few enough to cost little
/// beside the orientation (CGAL's 100,000-point `building`, rays cast: 0.54–0.65 s a run
/// where it took 0.54–0.56 s without them).
pub const RAYS: usize = 256;

/// Rays cast from the point's own sheet start this many spacings away from it.
const OWN_SHEET: f64 = 2.0;

/// The tube around a ray that finds its crossings, in spacings.
const TUBE: f64 = 1.5;

/// A point's tangent plane met at `|cos|` under this (beyond about 73° from its normal) is
/// grazed, not crossed.
const GRAZING: f64 = 0.3;

/// The most steps a ray takes (it skips empty space, so this is only a bound on the work).
const MAX_STEPS: usize = 100_000;

/// How the rays cast from a set of points along their own normals and against them read
/// ([`Orientation::rays`](super::Orientation::rays)): a ray from a point on a closed surface
/// along its outward normal meets the surface an even number of times, the first time facing
/// back at it; against it, an odd number, the first facing along it. Up to [`RAYS`] points,
/// spread evenly over the set; the surface is the cloud, crossed where the ray passes within
/// 1.5 spacings of a point through its tangent plane.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RayVotes {
    /// Points rays were cast from (both ways along the normal).
    pub cast: usize,
    /// Points whose normal faces into the object on both counts: an odd number of crossings
    /// along it and an even number against it, and the first surface met faces along the ray.
    pub inward: usize,
    /// Points whose normal faces out of the object on both counts.
    pub outward: usize,
}

/// What a ray from a point meets.
struct Crossings {
    /// Sheets crossed.
    sheets: usize,
    /// The first sheet's facing: of its points in the ray's own piece of the walk, those whose
    /// line (as given) faces along the ray, less those facing back. 0 where it meets none, or
    /// only other pieces' points.
    first_facing: i64,
}

/// The cloud a ray runs through.
pub(super) struct Scene<'a> {
    tree: Tree,
    positions: &'a [Point<3>],
    lines: &'a [Point<3>],
    /// Each point's piece of the walk.
    piece_of: &'a [u32],
    lo: Point<3>,
    hi: Point<3>,
    /// The tube radius.
    tube: f64,
    /// The ray's farthest reach.
    reach: f64,
}

impl Scene<'_> {
    /// What the ray from `positions[from]` along `d` (unit) meets.
    fn cast(&self, from: usize, d: &Point<3>) -> Crossings {
        let p = &self.positions[from];
        let start = OWN_SHEET / TUBE * self.tube;
        let at = |t: f64| [p[0] + t * d[0], p[1] + t * d[1], p[2] + t * d[2]];
        // Balls of radius √(R² + (R/2)²) every R cover the tube of radius R. Where the
        // nearest point is farther than a ball reaches, the tube is empty for as far as that
        // distance less R allows, and the ray skips ahead (past a far outlier's empty box in a
        // few steps).
        let ball = self.tube * self.tube * 1.25;
        let mut near = Vec::new();
        let mut t = start;
        for _ in 0..MAX_STEPS {
            if t >= self.reach {
                break;
            }
            let x = at(t);
            if (0..3).any(|a| x[a] < self.lo[a] - self.tube || x[a] > self.hi[a] + self.tube) {
                break;
            }
            let nearest = self
                .tree
                .query(&x)
                .nearest_one::<kiddo::SquaredEuclidean<f64>>()
                .execute()
                .distance;
            if nearest > ball {
                // No point within √nearest of x: the tube is empty up to t + √nearest − R,
                // and the next ball covers from there.
                t += (nearest.sqrt() - 0.5 * self.tube).max(self.tube);
                continue;
            }
            near.extend(
                self.tree
                    .query(&x)
                    .within::<kiddo::SquaredEuclidean<f64>>(ball)
                    .execute()
                    .into_iter()
                    .map(|found| found.item),
            );
            t += self.tube;
        }
        near.sort_unstable();
        near.dedup();
        let own = self.piece_of[from];
        let mut hits: Vec<(f64, i64)> = near
            .into_iter()
            .filter_map(|i| {
                let q = &self.positions[i as usize];
                let line = unit(&self.lines[i as usize])?;
                let cos = geometry::dot(d, &line);
                if cos.abs() < GRAZING {
                    return None;
                }
                let t = geometry::dot(&geometry::sub(q, p), &line) / cos;
                let off = geometry::sub(&at(t), q);
                let facing = if self.piece_of[i as usize] != own {
                    0
                } else if cos > 0.0 {
                    1
                } else {
                    -1
                };
                (t >= start && geometry::dot(&off, &off) <= self.tube * self.tube)
                    .then_some((t, facing))
            })
            .collect();
        hits.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut sheets = 0;
        let mut first_facing = 0;
        let mut last = f64::NEG_INFINITY;
        for (t, facing) in hits {
            if t - last > self.tube {
                sheets += 1;
            }
            if sheets == 1 {
                first_facing += facing;
            }
            last = t;
        }
        Crossings {
            sheets,
            first_facing,
        }
    }

    /// How rays from up to [`RAYS`] of `from` (spread evenly over it) along their lines and
    /// against them read: whether those lines face into the object the cloud samples.
    pub(super) fn votes(&self, from: &[u32]) -> RayVotes {
        let stride = from.len().div_ceil(RAYS).max(1);
        let cast: Vec<u32> = from
            .iter()
            .step_by(stride)
            .copied()
            .filter(|&i| unit(&self.lines[i as usize]).is_some())
            .collect();
        let (inward, outward) = cast
            .par_iter()
            .map(|&i| {
                let d = unit(&self.lines[i as usize]).expect("filtered");
                let along = self.cast(i as usize, &d);
                let against = self.cast(i as usize, &d.map(|x| -x));
                let parity_in = along.sheets % 2 == 1 && against.sheets.is_multiple_of(2);
                let parity_out = along.sheets.is_multiple_of(2) && against.sheets % 2 == 1;
                // Along the normal the first sheet faces back where it is outward; against it,
                // along the ray.
                let met_in = along.first_facing > 0 || against.first_facing < 0;
                let met_out = along.first_facing < 0 || against.first_facing > 0;
                (
                    usize::from(parity_in && met_in && !met_out),
                    usize::from(parity_out && met_out && !met_in),
                )
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        RayVotes {
            cast: cast.len(),
            inward,
            outward,
        }
    }
}

/// The cloud `positions` (with `lines`, any sign, zero for none; its pieces of the walk
/// `piece_of`) as rays see it; `None` where it has no spacing (every point at one position).
pub(super) fn scene<'a>(
    positions: &'a [Point<3>],
    lines: &'a [Point<3>],
    piece_of: &'a [u32],
) -> Option<Scene<'a>> {
    let tree = Tree::new_from_slice(positions).ok()?;
    let bounds = Aabb::from_points(positions)?;
    let diagonal = bounds.diagonal();
    // The median distance to the nearest point elsewhere (past copies of the point itself,
    // up to 7: a cloud merged twice or written face by face), over at most 2,000 points.
    let eight = std::num::NonZero::new(8).expect("8 > 0");
    let mut spacings: Vec<f64> = positions
        .iter()
        .step_by(positions.len().div_ceil(2_000).max(1))
        .filter_map(|p| {
            let found = tree
                .query(p)
                .nearest_n::<kiddo::SquaredEuclidean<f64>>(eight)
                .execute();
            found
                .iter()
                .find(|f| f.distance > 0.0)
                .map(|f| f.distance.sqrt())
        })
        .collect();
    if spacings.is_empty() || !(diagonal > 0.0 && diagonal.is_finite()) {
        return None;
    }
    let middle = spacings.len() / 2;
    let spacing = *spacings.select_nth_unstable_by(middle, f64::total_cmp).1;
    Some(Scene {
        tree,
        positions,
        lines,
        piece_of,
        lo: bounds.min(),
        hi: bounds.max(),
        tube: TUBE * spacing,
        reach: diagonal,
    })
}

/// `v` scaled to unit length; `None` for a zero or non-finite `v`.
fn unit(v: &Point<3>) -> Option<Point<3>> {
    let length = geometry::norm(v);
    (length > 0.0 && length.is_finite()).then(|| v.map(|x| x / length))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`Scene::votes`] from `from` through the cloud, none where it has no spacing.
    fn facing_votes(
        points: &[Point<3>],
        lines: &[Point<3>],
        pieces: &[u32],
        from: &[u32],
    ) -> RayVotes {
        scene(points, lines, pieces).map_or_else(RayVotes::default, |scene| scene.votes(from))
    }

    /// Two squares `z = 0` and `z = 1`, 1 × 1, sampled every 0.05, their lines `+z`; and a
    /// wall `x = 2` beside them, its lines `+x`.
    fn two_floors_and_a_wall() -> (Vec<Point<3>>, Vec<Point<3>>) {
        let mut points = Vec::new();
        let mut lines = Vec::new();
        for i in 0..20 {
            for j in 0..20 {
                let (u, v) = (0.025 + 0.05 * i as f64, 0.025 + 0.05 * j as f64);
                for z in [0.0, 1.0] {
                    points.push([u, v, z]);
                    lines.push([0.0, 0.0, 1.0]);
                }
                points.push([2.0, u, v]);
                lines.push([1.0, 0.0, 0.0]);
            }
        }
        (points, lines)
    }

    #[test]
    fn a_ray_counts_the_sheets_it_crosses_and_how_the_first_faces() {
        let (points, lines) = two_floors_and_a_wall();
        let pieces = vec![0; points.len()];
        let scene = scene(&points, &lines, &pieces).expect("spaced");
        assert!((scene.tube - 0.075).abs() < 1e-12, "{}", scene.tube);
        let lower = points
            .iter()
            .position(|p| (p[0] - 0.475).abs() < 1e-9 && (p[1] - 0.475).abs() < 1e-9 && p[2] == 0.0)
            .expect("a point");
        let upper = lower + 1;
        // Up from the lower floor: the upper one, its lines along the ray.
        let up = scene.cast(lower, &[0.0, 0.0, 1.0]);
        assert_eq!((up.sheets, up.first_facing.signum()), (1, 1));
        // Down from the upper floor: the lower one, its lines against the ray.
        let down = scene.cast(upper, &[0.0, 0.0, -1.0]);
        assert_eq!((down.sheets, down.first_facing.signum()), (1, -1));
        // Out of the box: nothing; along x: the wall (the floors' own points are grazed).
        assert_eq!(scene.cast(upper, &[0.0, 0.0, 1.0]).sheets, 0);
        let side = scene.cast(lower, &[1.0, 0.0, 0.0]);
        assert_eq!((side.sheets, side.first_facing.signum()), (1, 1));
        // The lower floor's rays read inward (up they cross the upper floor from behind; down
        // they leave), the upper floor's outward.
        let from: Vec<u32> = (0..points.len() as u32).filter(|&i| i % 3 == 0).collect();
        let votes = facing_votes(&points, &lines, &pieces, &from);
        // Every second of the 400: the most that spreads evenly within `RAYS`.
        let inward = RayVotes {
            cast: 200,
            inward: 200,
            outward: 0,
        };
        assert_eq!(votes, inward);
        // The floors as separate pieces of the walk (stacked open sheets, not one object's
        // sides): the upper floor is met, but says nothing of the lower one's side.
        let apart: Vec<u32> = points.iter().map(|p| u32::from(p[2] == 1.0)).collect();
        let scene_apart = super::scene(&points, &lines, &apart).expect("spaced");
        let up = scene_apart.cast(lower, &[0.0, 0.0, 1.0]);
        assert_eq!((up.sheets, up.first_facing), (1, 0));
        let votes = facing_votes(&points, &lines, &apart, &from);
        assert_eq!((votes.inward, votes.outward), (0, 0), "{votes:?}");
        // Every point twice (a cloud merged twice): the same spacing, the same votes.
        let twice: Vec<Point<3>> = points.iter().flat_map(|p| [*p, *p]).collect();
        let twice_lines: Vec<Point<3>> = lines.iter().flat_map(|l| [*l, *l]).collect();
        let twice_pieces = vec![0; twice.len()];
        let doubled = super::scene(&twice, &twice_lines, &twice_pieces).expect("spaced");
        assert_eq!(doubled.tube, scene.tube);
        let from_twice: Vec<u32> = from.iter().map(|&i| 2 * i).collect();
        assert_eq!(
            facing_votes(&twice, &twice_lines, &twice_pieces, &from_twice),
            inward
        );
        // A far outlier leaves the tube as it was and the votes too (the rays skip the empty
        // box).
        let mut far = points.clone();
        far.push([1e4, 0.0, 0.0]);
        let mut far_lines = lines.clone();
        far_lines.push([0.0, 0.0, 1.0]);
        let far_pieces = vec![0; far.len()];
        let with_outlier = super::scene(&far, &far_lines, &far_pieces).expect("spaced");
        assert_eq!(with_outlier.tube, scene.tube);
        assert_eq!(facing_votes(&far, &far_lines, &far_pieces, &from), inward);
    }

    #[test]
    fn a_cloud_without_spacing_casts_nothing() {
        let points = vec![[1.0, 2.0, 3.0]; 10];
        let lines = vec![[0.0, 0.0, 1.0]; 10];
        assert_eq!(
            facing_votes(&points, &lines, &[0; 10], &[0, 1, 2]),
            RayVotes::default()
        );
    }
}
