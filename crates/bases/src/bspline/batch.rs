//! Batched evaluation in a cache-friendly order.
//!
//! A point reads `3ᴰ` (or `4ᴰ`) coefficients spread over `3ᴰ⁻¹` rows of the grid. Points in random
//! order on a grid larger than the cache each wait on memory, one after the other (the
//! processor cannot look far enough ahead to overlap them). Reordering fixes that:
//!
//! 1. the points are split into *blocks* of [`BUCKET_ROWS`] rows of axis 1 and, inside a block,
//!    bucketed by their plane of axis 0 (a counting sort), all in parallel and without a global
//!    scatter;
//! 2. each block is swept plane by plane (one rayon task per block): before a plane's points,
//!    the one new plane of coefficients they read is loaded sequentially (one value per cache
//!    line, which the hardware prefetcher streams), so that the points' scattered reads hit the
//!    cache;
//! 3. the values are put back in the caller's order.
//!
//! Every value is computed by the same function as a single evaluation, so the result is
//! bit-identical to pointwise evaluation, whatever the order or the number of threads.

use rayon::prelude::*;
use zeroset_field_core::field::VALUES_CHUNK;

use super::BSplineField;

/// Batches smaller than this are evaluated in the caller's order.
const SORT_MIN_POINTS: usize = 1 << 14;
/// Grids with fewer coefficients than this (256 KiB) stay in cache: no reordering.
const SORT_MIN_COEFFICIENTS: usize = 1 << 15;
/// Rows of axis 1 per block: with a 256² plane, a block's working set is about
/// `3 planes × (16 + 4) rows × 2 KiB = 120 KiB`.
const BUCKET_ROWS: usize = 16;
/// Points per task of the partition and assembly passes.
const ITEM_CHUNK: usize = 1 << 15;

impl<const D: usize> BSplineField<D> {
    /// `out[i] = value_at_index(to_index(&items[i]))`, in parallel, reordered for the cache
    /// when that pays (see the module docs).
    pub(super) fn values_by<T: Sync>(
        &self,
        items: &[T],
        out: &mut [f64],
        to_index: impl Fn(&T) -> [f64; D] + Sync,
    ) {
        let counts = self.grid.counts();
        let blocks = if D >= 2 {
            counts[1].div_ceil(BUCKET_ROWS)
        } else {
            1
        };
        if D < 2
            || items.len() < SORT_MIN_POINTS
            || self.coefficients.len() < SORT_MIN_COEFFICIENTS
            || items.len() > u32::MAX as usize
            || counts[0] * blocks > items.len()
        {
            items
                .par_chunks(VALUES_CHUNK)
                .zip(out.par_chunks_mut(VALUES_CHUNK))
                .for_each(|(xs, os)| {
                    for (x, o) in xs.iter().zip(os) {
                        *o = self.value_at_index(to_index(x));
                    }
                });
            return;
        }
        // The sample nearest to `x` along axis `a` (saturating: NaN → 0).
        let cell = |x: &[f64; D], a: usize| -> usize {
            let i = x[a].clamp(self.lo, self.hi[a]) + 0.5;
            (i as usize).min(counts[a] - 1)
        };

        // 1. Partition: per chunk of points and per block, the block's continuous indices in
        // the caller's order (copied, so that step 2 streams through them).
        let mut block_of = vec![0u32; items.len()];
        let lists: Vec<Vec<Vec<[f64; D]>>> = items
            .par_chunks(ITEM_CHUNK)
            .zip(block_of.par_chunks_mut(ITEM_CHUNK))
            .map(|(chunk, block_of)| {
                let mut sizes = vec![0usize; blocks];
                for (item, b) in chunk.iter().zip(block_of.iter_mut()) {
                    let block = cell(&to_index(item), 1) / BUCKET_ROWS;
                    *b = block as u32;
                    sizes[block] += 1;
                }
                let mut lists: Vec<Vec<[f64; D]>> =
                    sizes.iter().map(|&n| Vec::with_capacity(n)).collect();
                for (item, &b) in chunk.iter().zip(block_of.iter()) {
                    lists[b as usize].push(to_index(item));
                }
                lists
            })
            .collect();

        // 2. Each block, plane by plane: its values in the order of its points.
        let values: Vec<Vec<f64>> = (0..blocks)
            .into_par_iter()
            .map(|block| {
                let parts: Vec<&[[f64; D]]> = lists.iter().map(|l| &l[block][..]).collect();
                self.block_values(block, &parts, |x| cell(x, 0))
            })
            .collect();

        // 3. Back to the caller's order: each chunk knows where its points start in each block.
        let mut cursors = Vec::with_capacity(lists.len());
        let mut running = vec![0usize; blocks];
        for chunk_lists in &lists {
            cursors.push(running.clone());
            for (r, l) in running.iter_mut().zip(chunk_lists) {
                *r += l.len();
            }
        }
        drop(lists);
        out.par_chunks_mut(ITEM_CHUNK)
            .zip(block_of.par_chunks(ITEM_CHUNK))
            .zip(cursors)
            .for_each(|((out, block_of), mut cursor)| {
                for (o, &b) in out.iter_mut().zip(block_of) {
                    let b = b as usize;
                    *o = values[b][cursor[b]];
                    cursor[b] += 1;
                }
            });
    }

    /// The values of one block's points (`parts`, in the caller's order), computed plane by
    /// plane.
    fn block_values(
        &self,
        block: usize,
        parts: &[&[[f64; D]]],
        plane_of: impl Fn(&[f64; D]) -> usize,
    ) -> Vec<f64> {
        let n0 = self.grid.counts()[0];
        // Counting sort by plane: `start[p]..start[p + 1]` will hold plane p's points.
        let mut start = vec![0usize; n0 + 1];
        for x in parts.iter().copied().flatten() {
            start[plane_of(x) + 1] += 1;
        }
        for p in 0..n0 {
            start[p + 1] += start[p];
        }
        let m = start[n0];
        let mut cursor = start.clone();
        let mut xs = vec![[0.0; D]; m];
        let mut place = Vec::with_capacity(m);
        for x in parts.iter().copied().flatten() {
            let pos = &mut cursor[plane_of(x)];
            xs[*pos] = *x;
            place.push(*pos as u32);
            *pos += 1;
        }
        let mut sorted = vec![0.0; m];
        self.sweep(block, &start, &xs, &mut sorted);
        place.iter().map(|&p| sorted[p as usize]).collect()
    }

    /// Evaluates the plane-sorted points `xs` of one block (plane `p`'s are
    /// `start[p]..start[p + 1]`), loading each new plane of the block's coefficients
    /// sequentially before the points that read it.
    fn sweep(&self, block: usize, start: &[usize], xs: &[[f64; D]], values: &mut [f64]) {
        let n0 = self.grid.counts()[0];
        let n1 = self.grid.counts()[1];
        // The farthest plane ahead of a point's nearest plane that it reads: 1 quadratic,
        // 2 cubic; rows likewise, with a margin.
        let lead = self.degree.stencil_len() / 2;
        let rows = (block * BUCKET_ROWS).saturating_sub(lead + 1)
            ..((block + 1) * BUCKET_ROWS + lead + 1).min(n1);
        let c = &self.coefficients;
        let warm = |plane: usize| -> f64 {
            if plane >= n0 {
                return 0.0;
            }
            let base = plane * self.strides[0];
            let span = &c[base + rows.start * self.strides[1]..base + rows.end * self.strides[1]];
            span.iter().step_by(8).fold(0.0, |acc, v| acc + v)
        };
        let mut sink = (0..lead).map(warm).sum::<f64>();
        for plane in 0..n0 {
            let range = start[plane]..start[plane + 1];
            if range.is_empty() {
                continue;
            }
            sink += warm(plane + lead);
            for (x, v) in xs[range.clone()].iter().zip(&mut values[range]) {
                *v = self.value_at_index(*x);
            }
        }
        // Keep the warming loads (their sum is never used).
        std::hint::black_box(sink);
    }
}
