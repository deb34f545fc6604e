//! Value ranges of boxes of voxels: the streaming passes behind the
//! macrocell grid and `Volume::value_range`.

use glam::UVec3;

use crate::sample::Sample;

/// Macrocell value ranges in one streaming pass over rows of voxels along z.
///
/// Each x-slab of cells (in parallel) folds its voxel rows element-wise into
/// per-(cell row, z) accumulators — min/max over whole rows, which vectorises
/// — then reduces the z windows. `fill(x, y, row)` copies voxel row `(x, y)`
/// (all z) into `row`.
pub(crate) fn cell_value_ranges_by_rows<S: Sample>(
    dims: UVec3,
    cell: u32,
    count: UVec3,
    fill: impl Fn(u32, u32, &mut [S]) + Sync,
) -> Vec<(f32, f32)> {
    use rayon::prelude::*;
    let (ny, nz) = (count.y as usize, count.z as usize);
    let zlen = dims.z as usize;
    let mut ranges = vec![(0.0f32, 0.0f32); count.x as usize * ny * nz];
    ranges
        .par_chunks_mut(ny * nz)
        .enumerate()
        .for_each(|(cx, slab)| {
            let mut lo = vec![S::HIGHEST; ny * zlen];
            let mut hi = vec![S::LOWEST; ny * zlen];
            let mut row = vec![S::zeroed(); zlen];
            let x_end = (cx as u32 * cell + cell).min(dims.x - 1);
            for x in cx as u32 * cell..=x_end {
                for y in 0..dims.y {
                    fill(x, y, &mut row);
                    // Row y belongs to cell rows c with c·cell <= y <= c·cell + cell.
                    let c_hi = (y / cell).min(count.y - 1);
                    let c_lo = if y >= cell {
                        (y - cell).div_ceil(cell)
                    } else {
                        0
                    };
                    for cy in c_lo..=c_hi {
                        let o = cy as usize * zlen;
                        fold_row(&mut lo[o..o + zlen], &mut hi[o..o + zlen], &row);
                    }
                }
            }
            let m = cell as usize;
            let mut wlo = vec![S::HIGHEST; zlen];
            let mut whi = vec![S::LOWEST; zlen];
            let mut tmp = vec![S::HIGHEST; zlen];
            for cy in 0..ny {
                // Window minima of length m + 1 at every z, by doubling
                // (vectorised passes over the row), then one per cell.
                window_extreme(
                    &lo[cy * zlen..][..zlen],
                    m + 1,
                    &mut wlo,
                    &mut tmp,
                    |a, b| a.min_of(b),
                );
                window_extreme(
                    &hi[cy * zlen..][..zlen],
                    m + 1,
                    &mut whi,
                    &mut tmp,
                    |a, b| a.max_of(b),
                );
                for (cz, out) in slab[cy * nz..][..nz].iter_mut().enumerate() {
                    let z0 = cz * m;
                    *out = (wlo[z0].to_f32(), whi[z0].to_f32());
                }
            }
        });
    ranges
}

/// `out[z] = op(row[z], …, row[z + len − 1])`, with the window cut at the
/// row's end. Doubling: windows of 1, 2, 4, … elements, each pass one
/// element-wise operation over shifted slices (vectorised), then one more
/// pass to reach exactly `len`.
fn window_extreme<S: Sample>(
    row: &[S],
    len: usize,
    out: &mut [S],
    tmp: &mut [S],
    op: impl Fn(S, S) -> S + Copy,
) {
    let n = row.len();
    let (out, tmp) = (&mut out[..n], &mut tmp[..n]);
    out.copy_from_slice(row);
    let mut have = 1;
    while have * 2 <= len && have < n {
        // out holds windows of `have`; combine with the window `have` ahead.
        tmp.copy_from_slice(out);
        for ((o, &a), &b) in out[..n - have]
            .iter_mut()
            .zip(&tmp[..n - have])
            .zip(&tmp[have..])
        {
            *o = op(a, b);
        }
        have *= 2;
    }
    if have < len && n > 1 {
        // Windows of `have` at i and at i + len − have cover [i, i + len).
        let shift = (len - have).min(n - 1);
        tmp.copy_from_slice(out);
        for ((o, &a), &b) in out[..n - shift]
            .iter_mut()
            .zip(&tmp[..n - shift])
            .zip(&tmp[shift..])
        {
            *o = op(a, b);
        }
        let last = tmp[n - 1];
        for o in &mut out[n - shift..] {
            *o = op(*o, last);
        }
    }
}

/// Element-wise `lo = min(lo, row)`, `hi = max(hi, row)`; written with
/// equal-length slices and indices so that it vectorises.
#[inline(always)]
fn fold_row<S: Sample>(lo: &mut [S], hi: &mut [S], row: &[S]) {
    let n = row.len().min(lo.len()).min(hi.len());
    let (lo, hi, row) = (&mut lo[..n], &mut hi[..n], &row[..n]);
    for i in 0..n {
        lo[i] = lo[i].min_of(row[i]);
        hi[i] = hi[i].max_of(row[i]);
    }
}

/// Smallest and largest of the values yielded, as `f32`.
pub(crate) fn fold_range<S: Sample>(values: impl Iterator<Item = S>) -> (S, S) {
    values.fold((S::HIGHEST, S::LOWEST), |(lo, hi), v| {
        (lo.min_of(v), hi.max_of(v))
    })
}

/// Smallest and largest of `samples` as `f32` ((+inf, −inf) when empty).
pub(crate) fn fold_range_f32<S: Sample>(samples: &[S]) -> (f32, f32) {
    let (lo, hi) = fold_range(samples.iter().copied());
    if samples.is_empty() {
        (f32::INFINITY, f32::NEG_INFINITY)
    } else {
        (lo.to_f32(), hi.to_f32())
    }
}
