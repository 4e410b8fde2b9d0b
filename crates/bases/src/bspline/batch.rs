//! Batched evaluation in a cache-friendly order.
//!
//! A point reads `3ᴰ` (or `4ᴰ`) coefficients spread over `3ᴰ⁻¹` rows of the grid. Points in random
//! order on a grid larger than the cache each wait on memory, one after the other (the
//! processor cannot look far enough ahead to overlap them). Reordering fixes that:
//!
//! 1. the points' continuous indices are copied into *blocks* of [`BUCKET_ROWS`] rows of axis 1
//!    (in parallel: each chunk of points writes its own part of each block) and, inside a block,
//!    counting-sorted by their plane of axis 0;
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

use super::{BSplineField, Degree};

/// Batches smaller than this are evaluated in the caller's order.
const SORT_MIN_POINTS: usize = 1 << 14;
/// Grids with fewer coefficients than this (256 KiB) stay in cache: no reordering.
const SORT_MIN_COEFFICIENTS: usize = 1 << 15;
/// Rows of axis 1 per block: with a 256² plane, a block's working set is about
/// `3 planes × (16 + 4) rows × 2 KiB = 120 KiB`.
const BUCKET_ROWS: usize = 16;
/// Points reordered at a time (larger batches go slice by slice): the buffers take about 40
/// bytes per point, plus about 36 per point of the blocks being evaluated.
const MAX_BATCH: usize = 1 << 22;
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
            || counts[0] * blocks > items.len()
        {
            items
                .par_chunks(VALUES_CHUNK)
                .zip(out.par_chunks_mut(VALUES_CHUNK))
                .for_each(|(xs, os)| self.values_run(xs, os, &to_index));
            return;
        }
        // Bound the memory of the reordering: one slice of the batch after the other.
        for (items, out) in items.chunks(MAX_BATCH).zip(out.chunks_mut(MAX_BATCH)) {
            self.values_reordered(items, out, &to_index, blocks);
        }
    }

    /// [`values_by`](Self::values_by) for one slice of at most [`MAX_BATCH`] points, reordered.
    fn values_reordered<T: Sync, F: Fn(&T) -> [f64; D] + Sync>(
        &self,
        items: &[T],
        out: &mut [f64],
        to_index: &F,
        blocks: usize,
    ) {
        let counts = self.grid.counts();
        // The sample nearest to `x` along axis `a` (saturating: NaN → 0).
        let cell = |x: &[f64; D], a: usize| -> usize {
            let i = x[a].clamp(self.lo, self.hi[a]) + 0.5;
            (i as usize).min(counts[a] - 1)
        };

        // 1. Partition into blocks, in parallel over chunks of points: first each point's block
        // and the chunk's count per block, then the continuous indices, copied block by block
        // (each chunk writing to its own part of each block), keeping the caller's order.
        let mut block_of = vec![0u32; items.len()];
        let sizes: Vec<Vec<usize>> = items
            .par_chunks(ITEM_CHUNK)
            .zip(block_of.par_chunks_mut(ITEM_CHUNK))
            .map(|(chunk, block_of)| {
                let mut sizes = vec![0usize; blocks];
                for (item, b) in chunk.iter().zip(block_of) {
                    let block = cell(&to_index(item), 1) / BUCKET_ROWS;
                    *b = block as u32;
                    sizes[block] += 1;
                }
                sizes
            })
            .collect();
        let mut block_start = vec![0usize; blocks + 1];
        for (b, start) in (0..blocks).zip(1..) {
            block_start[start] = block_start[b] + sizes.iter().map(|s| s[b]).sum::<usize>();
        }
        let mut points = vec![[0.0; D]; items.len()];
        {
            // parts[c][b]: chunk c's points of block b.
            let mut parts: Vec<Vec<&mut [[f64; D]]>> = (0..sizes.len())
                .map(|_| Vec::with_capacity(blocks))
                .collect();
            let mut rest = &mut points[..];
            for b in 0..blocks {
                for (c, chunk_sizes) in sizes.iter().enumerate() {
                    let (head, tail) = rest.split_at_mut(chunk_sizes[b]);
                    parts[c].push(head);
                    rest = tail;
                }
            }
            items
                .par_chunks(ITEM_CHUNK)
                .zip(block_of.par_chunks(ITEM_CHUNK))
                .zip(parts)
                .for_each(|((chunk, block_of), mut parts)| {
                    let mut cursor = vec![0usize; blocks];
                    for (item, &b) in chunk.iter().zip(block_of) {
                        let b = b as usize;
                        parts[b][cursor[b]] = to_index(item);
                        cursor[b] += 1;
                    }
                });
        }

        // 2. Each block, plane by plane, into `values` (laid out like `points`).
        let mut values = vec![0.0; items.len()];
        let mut tasks = Vec::with_capacity(blocks);
        let (mut xs, mut vs) = (&points[..], &mut values[..]);
        for b in 0..blocks {
            let len = block_start[b + 1] - block_start[b];
            let (x_head, x_tail) = xs.split_at(len);
            let (v_head, v_tail) = vs.split_at_mut(len);
            tasks.push((b, x_head, v_head));
            (xs, vs) = (x_tail, v_tail);
        }
        tasks
            .into_par_iter()
            .for_each(|(b, xs, vs)| self.block_values(b, xs, vs, |x| cell(x, 0)));
        drop(points);

        // 3. Back to the caller's order: chunk c's points of block b start at
        // `block_start[b] + Σ_{c' < c} sizes[c'][b]`.
        let mut cursors = Vec::with_capacity(sizes.len());
        let mut running = block_start[..blocks].to_vec();
        for chunk_sizes in &sizes {
            cursors.push(running.clone());
            for (r, n) in running.iter_mut().zip(chunk_sizes) {
                *r += n;
            }
        }
        out.par_chunks_mut(ITEM_CHUNK)
            .zip(block_of.par_chunks(ITEM_CHUNK))
            .zip(cursors)
            .for_each(|((out, block_of), mut cursor)| {
                for (o, &b) in out.iter_mut().zip(block_of) {
                    let b = b as usize;
                    *o = values[cursor[b]];
                    cursor[b] += 1;
                }
            });
    }

    /// The values of one block's points `xs` into `values` (same order), computed plane by
    /// plane: a counting sort by plane into a block-local copy, [`sweep`](Self::sweep) over it,
    /// and the values put back.
    fn block_values(
        &self,
        block: usize,
        xs: &[[f64; D]],
        values: &mut [f64],
        plane_of: impl Fn(&[f64; D]) -> usize,
    ) {
        let n0 = self.grid.counts()[0];
        // `start[p]..start[p + 1]` of `sorted` will hold plane p's points.
        let mut start = vec![0usize; n0 + 1];
        for x in xs {
            start[plane_of(x) + 1] += 1;
        }
        for p in 0..n0 {
            start[p + 1] += start[p];
        }
        let mut cursor = start.clone();
        let mut sorted = vec![[0.0; D]; xs.len()];
        let mut place = vec![0u32; xs.len()];
        for (x, place) in xs.iter().zip(&mut place) {
            let pos = &mut cursor[plane_of(x)];
            sorted[*pos] = *x;
            *place = *pos as u32;
            *pos += 1;
        }
        let mut sorted_values = vec![0.0; xs.len()];
        self.sweep(block, &start, &sorted, &mut sorted_values);
        for (v, &p) in values.iter_mut().zip(&place) {
            *v = sorted_values[p as usize];
        }
    }

    /// `out[i] = value_at_index(to_index(&items[i]))` in a plain loop, with the degree dispatched
    /// once for the whole run so that the evaluation inlines into the loop.
    fn values_run<T>(&self, items: &[T], out: &mut [f64], to_index: &impl Fn(&T) -> [f64; D]) {
        match self.degree {
            Degree::Quadratic => {
                for (item, o) in items.iter().zip(out) {
                    *o = self.value_index::<3>(to_index(item));
                }
            }
            Degree::Cubic => {
                for (item, o) in items.iter().zip(out) {
                    *o = self.value_index::<4>(to_index(item));
                }
            }
        }
    }

    /// Evaluates the plane-sorted points `xs` of one block (plane `p`'s are
    /// `start[p]..start[p + 1]`), plane after plane, loading each new plane of the block's
    /// coefficients sequentially before the points that read it.
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
            self.values_run(&xs[range.clone()], &mut values[range], &|x| *x);
        }
        // Keep the warming loads (their sum is never used).
        std::hint::black_box(sink);
    }
}
