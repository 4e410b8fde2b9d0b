//! The adaptive octree and the interaction lists of the multipole method.
//!
//! The root is a cube covering the sources and the region where targets are expected. A cell
//! with more than `leaf_size` sources is split into all eight children (empty ones included, so
//! that every point of the root lies in exactly one leaf), down to `max_depth`. Sources are
//! reordered so that every cell's sources are one contiguous range.
//!
//! The lists come from one dual traversal of the tree with itself, starting at (root, root).
//! For two *adjacent* cells of one level (touching or equal), with sources in `S`:
//!
//! | `T` | `S` | what is recorded |
//! |---|---|---|
//! | leaf | leaf | `S` in `T`'s **near** list (direct sums, P2P) |
//! | split | split | every pair of children: adjacent → recurse; otherwise a **M2L** pair of their level (a **P2L** entry if the source child has at most `FEW` sources) |
//! | leaf | split | `S`'s descendants against `T`: well separated → `T`'s **M2P** list (or near, if it has fewer sources than nodes), leaves → near |
//! | split | leaf | `T`'s descendants against `S`: well separated → their **P2L** list (or, where fewer than `p³` evaluation points are expected in the cell, the near lists of its leaves), leaves → near |
//!
//! "Well separated" for cells of different sizes: the gap between the cubes (∞-norm) is at
//! least the smaller cell's width, the same ratio as the M2L pairs of one level, which are at
//! least one width apart. This is the adaptive FMM's U, V, W and X lists (Carrier, Greengard &
//! Rokhlin 1988) without a balance condition.

/// No cell.
pub(crate) const NONE: u32 = u32::MAX;

/// A leaf is split when its direct work per target exceeds this many leaf sizes.
const REFINE: usize = 8;

/// A well-separated source cell with at most this many sources goes into the target's P2L
/// list (`count · p³` kernel evaluations, exact) instead of an M2L pair (`≈ 4 p³ r` flops with
/// ranks `r` of 20–70, plus the gather and scatter).
const FEW: usize = 4;

/// One cube of the tree.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Cell {
    pub centre: [f64; 3],
    pub half: f64,
    pub level: u32,
    /// Integer position at its level: `centre = root_lo + (coord + ½) · width`.
    pub coord: [i64; 3],
    /// The first of eight consecutive children, or [`NONE`] for a leaf.
    pub first_child: u32,
    /// The cell's sources: `begin..end` in tree order.
    pub begin: u32,
    pub end: u32,
}

impl Cell {
    pub fn is_leaf(&self) -> bool {
        self.first_child == NONE
    }

    pub fn count(&self) -> usize {
        (self.end - self.begin) as usize
    }

    /// The cell's sources as `(begin, end)` in tree order.
    pub fn range(&self) -> (u32, u32) {
        (self.begin, self.end)
    }

    pub fn children(&self) -> impl DoubleEndedIterator<Item = u32> + use<> {
        let first = self.first_child;
        (0..if first == NONE { 0 } else { 8 }).map(move |k| first + k)
    }
}

/// A M2L pair of one level: the target cell, the source cell and their offset
/// `coord_T − coord_S` encoded by [`offset_code`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct M2lPair {
    pub target: u32,
    pub source: u32,
}

/// `(t + 3)` in base 7, for offsets with components in `−3..=3`.
pub(crate) fn offset_code(t: [i64; 3]) -> usize {
    ((t[0] + 3) * 49 + (t[1] + 3) * 7 + (t[2] + 3)) as usize
}

/// The offset of a code.
pub(crate) fn offset_of(code: usize) -> [i64; 3] {
    let c = code as i64;
    [c / 49 - 3, (c / 7) % 7 - 3, c % 7 - 3]
}

/// The octree, its source order and its interaction lists.
#[derive(Debug, Clone)]
pub(crate) struct Tree {
    pub cells: Vec<Cell>,
    /// Cell indices per level.
    pub levels: Vec<Vec<u32>>,
    /// `order[i]` is the original index of the `i`-th source in tree order.
    pub order: Vec<u32>,
    /// Per cell: source cells summed directly at targets in it (leaves only).
    pub near: Vec<Vec<u32>>,
    /// Per cell: the sources of its near cells as ranges `begin..end` in tree order, sorted,
    /// with touching ranges merged (siblings are contiguous), so that a direct sum runs over a
    /// few long slices.
    pub near_runs: Vec<Vec<(u32, u32)>>,
    /// Per cell: source cells whose multipole expansion is evaluated at targets in it.
    pub m2p: Vec<Vec<u32>>,
    /// Per cell: source leaves whose sources go straight into its local expansion.
    pub p2l: Vec<Vec<u32>>,
    /// `m2l[level][code]`: the M2L pairs of a level with one offset, sorted by target.
    pub m2l: Vec<Vec<Vec<M2lPair>>>,
    /// Where the evaluation points are expected, once the tree's shape is settled.
    expected: Option<ExpectedPoints>,
}

/// About `count` evaluation points spread uniformly over the box `lo..hi`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ExpectedPoints {
    pub count: f64,
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

impl ExpectedPoints {
    /// The points expected in `cell` (`None` if the box has no volume).
    fn in_cell(&self, cell: &Cell) -> Option<f64> {
        let volume: f64 = (0..3).map(|a| self.hi[a] - self.lo[a]).product();
        if volume.is_nan() || volume <= 0.0 {
            return None;
        }
        let overlap: f64 = (0..3)
            .map(|a| {
                let lo = self.lo[a].max(cell.centre[a] - cell.half);
                let hi = self.hi[a].min(cell.centre[a] + cell.half);
                (hi - lo).max(0.0)
            })
            .product();
        Some(self.count * overlap / volume)
    }
}

/// Tree parameters.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TreeShape {
    pub centre: [f64; 3],
    pub half: f64,
    pub leaf_size: usize,
    pub max_depth: u32,
    /// Sources a multipole expansion stands for (`p³`): cheaper to sum fewer directly.
    pub nodes: usize,
    /// Where the points the tree will be evaluated at are expected (`None`: everywhere, many).
    pub expected: Option<ExpectedPoints>,
}

impl Tree {
    /// Builds the tree over `points` (all inside the root cube) and its lists.
    ///
    /// Splitting by sources alone leaves large empty leaves next to finely split ones, and a
    /// target in such a leaf would sum most of its neighbours' sources directly. So, once the
    /// source tree is built, every leaf whose direct work per target (its near sources plus
    /// `p³` per M2P cell) exceeds [`REFINE`] leaf sizes is split too, and the lists are redone,
    /// until no leaf is that costly or the depth limit is reached. Their children take the
    /// far part of that work into their local expansions (M2L), computed once per cell.
    pub fn build(points: &[[f64; 3]], shape: TreeShape) -> Self {
        let mut tree = Self {
            cells: vec![Cell {
                centre: shape.centre,
                half: shape.half,
                level: 0,
                coord: [0; 3],
                first_child: NONE,
                begin: 0,
                end: points.len() as u32,
            }],
            levels: Vec::new(),
            order: (0..points.len() as u32).collect(),
            near: Vec::new(),
            near_runs: Vec::new(),
            m2p: Vec::new(),
            p2l: Vec::new(),
            m2l: Vec::new(),
            expected: None,
        };
        let mut stack = vec![0u32];
        let mut scratch = Vec::new();
        while let Some(c) = stack.pop() {
            let cell = tree.cells[c as usize];
            if cell.count() <= shape.leaf_size || cell.level >= shape.max_depth {
                continue;
            }
            let first = tree.split(c, points, &mut scratch);
            // Children are pushed so that they are split in order (a stable numbering).
            for k in (0..8).rev() {
                stack.push(first + k);
            }
        }
        let budget = REFINE * shape.leaf_size.max(1);
        loop {
            tree.lists(shape.nodes);
            let costly: Vec<u32> = (0..tree.cells.len() as u32)
                .filter(|&c| {
                    let cell = tree.cells[c as usize];
                    cell.is_leaf()
                        && cell.level < shape.max_depth
                        && tree.cost(c, shape.nodes) > budget
                })
                .collect();
            if costly.is_empty() {
                break;
            }
            for c in costly {
                tree.split(c, points, &mut scratch);
            }
        }
        // The expected points change which far sources a cell takes into its expansion (not
        // where cells are split, which would feed back into the split rule).
        if shape.expected.is_some() {
            tree.expected = shape.expected;
            tree.lists(shape.nodes);
        }
        tree.near_runs = tree
            .near
            .iter()
            .map(|list| {
                let mut ranges: Vec<(u32, u32)> = list
                    .iter()
                    .map(|&s| (tree.cells[s as usize].begin, tree.cells[s as usize].end))
                    .collect();
                ranges.sort_unstable();
                let mut runs: Vec<(u32, u32)> = Vec::with_capacity(ranges.len());
                for (b, e) in ranges {
                    match runs.last_mut() {
                        Some(last) if last.1 == b => last.1 = e,
                        _ => runs.push((b, e)),
                    }
                }
                runs
            })
            .collect();
        tree
    }

    /// The direct work per target in leaf `c`: near sources, plus `nodes` per M2P cell.
    fn cost(&self, c: u32, nodes: usize) -> usize {
        let near: usize = self.near[c as usize]
            .iter()
            .map(|&s| self.cells[s as usize].count())
            .sum();
        near + nodes * self.m2p[c as usize].len()
    }

    /// Splits leaf `c` into eight children, sorting its sources into them; returns the first
    /// child.
    fn split(&mut self, c: u32, points: &[[f64; 3]], scratch: &mut Vec<u32>) -> u32 {
        let cell = self.cells[c as usize];
        // Stable counting sort of the cell's sources into the eight octants.
        let range = cell.begin as usize..cell.end as usize;
        let octant = |i: u32| octant_of(&points[i as usize], &cell.centre);
        let mut counts = [0usize; 8];
        for &i in &self.order[range.clone()] {
            counts[octant(i)] += 1;
        }
        let mut starts = [0usize; 8];
        for k in 1..8 {
            starts[k] = starts[k - 1] + counts[k - 1];
        }
        scratch.clear();
        scratch.resize(range.len(), 0);
        let mut next = starts;
        for &i in &self.order[range.clone()] {
            let o = octant(i);
            scratch[next[o]] = i;
            next[o] += 1;
        }
        self.order[range].copy_from_slice(scratch);
        let first = self.cells.len() as u32;
        self.cells[c as usize].first_child = first;
        let h = 0.5 * cell.half;
        for k in 0..8 {
            let bit = |a: usize| (k >> (2 - a)) & 1;
            self.cells.push(Cell {
                centre: std::array::from_fn(|a| cell.centre[a] + if bit(a) == 1 { h } else { -h }),
                half: h,
                level: cell.level + 1,
                coord: std::array::from_fn(|a| 2 * cell.coord[a] + bit(a) as i64),
                first_child: NONE,
                begin: cell.begin + starts[k] as u32,
                end: cell.begin + (starts[k] + counts[k]) as u32,
            });
        }
        first
    }

    /// The levels and the interaction lists, from scratch.
    fn lists(&mut self, nodes: usize) {
        let depth = self.cells.iter().map(|c| c.level).max().unwrap_or(0) as usize;
        self.levels = vec![Vec::new(); depth + 1];
        for (i, c) in self.cells.iter().enumerate() {
            self.levels[c.level as usize].push(i as u32);
        }
        let n = self.cells.len();
        self.near = vec![Vec::new(); n];
        self.m2p = vec![Vec::new(); n];
        self.p2l = vec![Vec::new(); n];
        self.m2l = vec![vec![Vec::new(); 343]; depth + 1];
        self.adjacent_pair(0, 0, nodes);
        for level in &mut self.m2l {
            for pairs in level.iter_mut() {
                pairs.sort_unstable();
            }
        }
    }

    /// The leaf containing `x`, or `None` outside the root (closed) cube.
    pub fn leaf_of(&self, x: &[f64; 3]) -> Option<u32> {
        let root = &self.cells[0];
        let outside = |a: usize| {
            matches!(
                (x[a] - root.centre[a]).abs().partial_cmp(&root.half),
                None | Some(std::cmp::Ordering::Greater)
            )
        };
        if (0..3).any(outside) {
            return None;
        }
        let mut c = 0u32;
        loop {
            let cell = &self.cells[c as usize];
            if cell.is_leaf() {
                return Some(c);
            }
            c = cell.first_child + octant_of(x, &cell.centre) as u32;
        }
    }

    fn cell(&self, c: u32) -> &Cell {
        &self.cells[c as usize]
    }

    /// Two adjacent cells of one level (see the module docs).
    fn adjacent_pair(&mut self, t: u32, s: u32, nodes: usize) {
        let (tc, sc) = (*self.cell(t), *self.cell(s));
        if sc.count() == 0 {
            return;
        }
        match (tc.is_leaf(), sc.is_leaf()) {
            (true, true) => self.near[t as usize].push(s),
            (true, false) => {
                for child in sc.children() {
                    self.target_leaf(t, child, nodes);
                }
            }
            (false, true) => {
                for child in tc.children() {
                    self.source_leaf(child, s, nodes);
                }
            }
            (false, false) => {
                for tchild in tc.children() {
                    for schild in sc.children() {
                        let (a, b) = (self.cell(tchild).coord, self.cell(schild).coord);
                        let d: [i64; 3] = std::array::from_fn(|k| a[k] - b[k]);
                        let count = self.cell(schild).count();
                        if d.iter().all(|v| v.abs() <= 1) {
                            self.adjacent_pair(tchild, schild, nodes);
                        } else if count > 0 && count <= FEW {
                            self.p2l[tchild as usize].push(schild);
                        } else if count > 0 {
                            let level = self.cell(tchild).level as usize;
                            self.m2l[level][offset_code(d)].push(M2lPair {
                                target: tchild,
                                source: schild,
                            });
                        }
                    }
                }
            }
        }
    }

    /// Targets in the leaf `t`, sources in the smaller cell `s`.
    fn target_leaf(&mut self, t: u32, s: u32, nodes: usize) {
        let sc = *self.cell(s);
        if sc.count() == 0 {
            return;
        }
        if separated(self.cell(t), &sc) {
            if sc.count() <= nodes {
                self.near[t as usize].push(s);
            } else {
                self.m2p[t as usize].push(s);
            }
        } else if sc.is_leaf() {
            self.near[t as usize].push(s);
        } else {
            for child in sc.children() {
                self.target_leaf(t, child, nodes);
            }
        }
    }

    /// Targets in the smaller cell `t`, sources in the leaf `s`.
    fn source_leaf(&mut self, t: u32, s: u32, nodes: usize) {
        let tc = *self.cell(t);
        if separated(&tc, self.cell(s)) {
            // P2L costs `|S| p³` kernel evaluations once; summing `S` at every point of `t`
            // costs `|S|` per point: cheaper where fewer than `p³` points are expected.
            let few = self
                .expected
                .and_then(|e| e.in_cell(&tc))
                .is_some_and(|points| points < nodes as f64);
            if few {
                self.near_below(t, s);
            } else {
                self.p2l[t as usize].push(s);
            }
        } else if tc.is_leaf() {
            self.near[t as usize].push(s);
        } else {
            for child in tc.children() {
                self.source_leaf(child, s, nodes);
            }
        }
    }

    /// `s` in the near list of every leaf in `t`.
    fn near_below(&mut self, t: u32, s: u32) {
        let tc = *self.cell(t);
        if tc.is_leaf() {
            self.near[t as usize].push(s);
        } else {
            for child in tc.children() {
                self.near_below(child, s);
            }
        }
    }
}

/// The octant of `x` around `centre`: bit 2 for x, 1 for y, 0 for z; `≥` goes up.
#[inline]
pub(crate) fn octant_of(x: &[f64; 3], centre: &[f64; 3]) -> usize {
    (usize::from(x[0] >= centre[0]) << 2)
        | (usize::from(x[1] >= centre[1]) << 1)
        | usize::from(x[2] >= centre[2])
}

/// The ∞-norm gap between two cubes is at least the smaller one's width (up to rounding of the
/// centres, which are exact binary fractions of the root's).
pub(crate) fn separated(a: &Cell, b: &Cell) -> bool {
    let gap = (0..3)
        .map(|k| (a.centre[k] - b.centre[k]).abs() - a.half - b.half)
        .fold(f64::NEG_INFINITY, f64::max);
    gap >= 2.0 * a.half.min(b.half) * (1.0 - 1e-12)
}

/// `x` is at least `cell`'s width away from it (∞-norm): its multipole expansion converges
/// there as fast as at the M2L pairs.
pub(crate) fn point_separated(x: &[f64; 3], cell: &Cell) -> bool {
    let gap = (0..3)
        .map(|k| (x[k] - cell.centre[k]).abs() - cell.half)
        .fold(f64::NEG_INFINITY, f64::max);
    gap >= 2.0 * cell.half * (1.0 - 1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cloud(n: usize) -> Vec<[f64; 3]> {
        // A deterministic, clustered cloud: points on a sphere plus a small far cluster.
        (0..n)
            .map(|i| {
                let t = i as f64 * 2.399963;
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                if i % 10 == 0 {
                    [
                        1.8 + 0.01 * t.cos(),
                        1.8,
                        -1.8 + 0.001 * i as f64 / n as f64,
                    ]
                } else {
                    [r * t.cos(), r * t.sin(), z]
                }
            })
            .collect()
    }

    /// Every (target leaf, source) pair is covered exactly once: by the near list, a M2P
    /// cell, a P2L cell of the leaf or an ancestor, or a M2L pair of an ancestor (or itself);
    /// with and without expected points (fewer P2L entries, more near ones).
    #[test]
    fn interaction_lists_cover_every_pair_exactly_once() {
        let expected = [
            None,
            Some(ExpectedPoints {
                count: 20_000.0,
                lo: [-1.0; 3],
                hi: [1.9; 3],
            }),
        ]
        .map(lists_cover_every_pair_exactly_once);
        assert!(
            expected[1] < expected[0],
            "P2L entries without and with expected points: {expected:?}"
        );
    }

    /// Checks the coverage; returns the number of P2L entries.
    fn lists_cover_every_pair_exactly_once(expected: Option<ExpectedPoints>) -> usize {
        let points = cloud(3000);
        let tree = Tree::build(
            &points,
            TreeShape {
                centre: [0.0; 3],
                half: 2.0,
                leaf_size: 20,
                max_depth: 10,
                nodes: 27,
                expected,
            },
        );
        let mut parent = vec![NONE; tree.cells.len()];
        for (i, c) in tree.cells.iter().enumerate() {
            for ch in c.children() {
                parent[ch as usize] = i as u32;
            }
        }
        let mut m2l_sources: Vec<Vec<u32>> = vec![Vec::new(); tree.cells.len()];
        for level in &tree.m2l {
            for pairs in level {
                for p in pairs {
                    m2l_sources[p.target as usize].push(p.source);
                }
            }
        }
        let n = points.len();
        for (leaf, cell) in tree.cells.iter().enumerate() {
            if !cell.is_leaf() {
                continue;
            }
            let mut hits = vec![0u32; n];
            // The near field as evaluation sums it: merged runs of tree order.
            for &(b, e) in &tree.near_runs[leaf] {
                for i in b..e {
                    hits[i as usize] += 1;
                }
            }
            let mut add = |c: u32| {
                let s = tree.cells[c as usize];
                for i in s.begin..s.end {
                    hits[i as usize] += 1;
                }
            };
            tree.m2p[leaf].iter().for_each(|&c| add(c));
            let mut a = leaf as u32;
            while a != NONE {
                tree.p2l[a as usize].iter().for_each(|&c| add(c));
                m2l_sources[a as usize].iter().for_each(|&c| add(c));
                a = parent[a as usize];
            }
            assert!(hits.iter().all(|&h| h == 1), "leaf {leaf}: {:?}", {
                let bad: Vec<_> = hits
                    .iter()
                    .enumerate()
                    .filter(|(_, h)| **h != 1)
                    .take(5)
                    .collect();
                bad
            });
        }
        tree.p2l.iter().map(Vec::len).sum()
    }

    #[test]
    fn leaves_partition_the_root_and_hold_their_sources() {
        let points = cloud(500);
        let tree = Tree::build(
            &points,
            TreeShape {
                centre: [0.0; 3],
                half: 2.0,
                leaf_size: 8,
                max_depth: 12,
                nodes: 8,
                expected: None,
            },
        );
        for (i, &o) in tree.order.iter().enumerate() {
            let leaf = tree.leaf_of(&points[o as usize]).expect("inside");
            let c = tree.cells[leaf as usize];
            assert!((c.begin..c.end).contains(&(i as u32)));
        }
        assert_eq!(tree.leaf_of(&[2.5, 0.0, 0.0]), None);
        assert!(tree.leaf_of(&[2.0, -2.0, 2.0]).is_some());
        for code in 0..343 {
            assert_eq!(offset_code(offset_of(code)), code);
        }
    }
}
