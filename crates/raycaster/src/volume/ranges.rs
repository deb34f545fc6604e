//! Value ranges of boxes of voxels: the streaming passes behind the
//! macrocell grid and `Volume::value_range`.
//!
//! Two passes compute the macrocell ranges: [`cell_value_ranges_by_rows`]
//! walks voxel rows along the stored row axis (the order of a linear file),
//! and [`cell_value_ranges_bricked`] walks a bricked file brick by brick in
//! storage order, so that every page of the file is read once, whole, and
//! by one thread.

use std::ops::Range;

use glam::UVec3;

use super::addressing::BrickGrid;
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

/// The macrocells (of side `m`, `count` of them) whose voxel span
/// `[c·m, c·m + m]` meets the voxels `v0..=v1` of one axis, each with the
/// part of `v0..=v1` it covers, as offsets from `v0`: `(c, first, last)`.
fn cell_windows(v0: usize, v1: usize, m: usize, count: usize) -> Vec<(usize, usize, usize)> {
    let first = if v0 > m { (v0 - m).div_ceil(m) } else { 0 };
    let last = (v1 / m).min(count - 1);
    (first..=last)
        .map(|c| (c, (c * m).max(v0) - v0, (c * m + m).min(v1) - v0))
        .collect()
}

/// Macrocell value ranges of a bricked volume (see [`BrickGrid`]) in one
/// pass over its storage, brick by brick.
///
/// Walking rows along z through a bricked file visits every brick many
/// times, a few dozen bytes at a time, with the rest of a brick plane of
/// the volume in between; here each brick (a few KiB, contiguous) is read
/// once. Per brick the min/max are folded separably: whole brick planes
/// (local x) element-wise into one plane per macrocell x-window, then rows
/// (local y) into one row per (x, y) window, then the few z windows of each
/// row. Bricks overlap their neighbours by one voxel plane; a shared voxel
/// is folded twice, which changes no minimum or maximum.
///
/// Brick x-slabs run in parallel on the current rayon pool. When a slab is
/// done its partial ranges are merged into the result (neighbouring slabs
/// share the macrocells on their common face), then `slab_done(storage
/// range of the slab, slabs done, slabs in all)` is called: a progress
/// report, and the moment a mapped file's pages may be let go.
pub(crate) fn cell_value_ranges_bricked<S: Sample>(
    data: &[S],
    bricks: &BrickGrid,
    dims: UVec3,
    cell: u32,
    count: UVec3,
    slab_done: &(dyn Fn(Range<usize>, usize, usize) + Sync),
) -> Vec<(f32, f32)> {
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let b = bricks.side as usize;
    let (plane, brick_len) = (b * b, b * b * b);
    let nb = bricks.count.as_usizevec3();
    let m = cell.max(1) as usize;
    let (ny, nz) = (count.y as usize, count.z as usize);
    // Per axis and brick, the macrocell windows of the voxels it holds.
    let windows = |d: u32, n: usize, cells: u32| -> Vec<Vec<(usize, usize, usize)>> {
        (0..n)
            .map(|i| {
                let v0 = i * (b - 1);
                let v1 = (v0 + b - 1).min(d.max(1) as usize - 1);
                cell_windows(v0, v1, m, cells as usize)
            })
            .collect()
    };
    let (wx, wy, wz) = (
        windows(dims.x, nb.x, count.x),
        windows(dims.y, nb.y, count.y),
        windows(dims.z, nb.z, count.z),
    );
    let mut global = vec![(S::HIGHEST, S::LOWEST); count.x as usize * ny * nz];
    let merged = parking_lot::Mutex::new(&mut global);
    let done = AtomicUsize::new(0);
    let slab_len = nb.y * nb.z * brick_len;
    (0..nb.x).into_par_iter().for_each(|i| {
        let wx = &wx[i];
        let mut lo = vec![S::HIGHEST; wx.len() * ny * nz];
        let mut hi = vec![S::LOWEST; wx.len() * ny * nz];
        let mut plo = vec![S::HIGHEST; wx.len() * plane];
        let mut phi = vec![S::LOWEST; wx.len() * plane];
        let (mut rlo, mut rhi) = (vec![S::HIGHEST; b], vec![S::LOWEST; b]);
        let slab = &data[i * slab_len..][..slab_len];
        for (j, wy) in wy.iter().enumerate() {
            for (k, wz) in wz.iter().enumerate() {
                let brick = &slab[(j * nb.z + k) * brick_len..][..brick_len];
                // Local x: fold whole planes.
                for (xi, &(_, x0, x1)) in wx.iter().enumerate() {
                    let (pl, ph) = (
                        &mut plo[xi * plane..][..plane],
                        &mut phi[xi * plane..][..plane],
                    );
                    pl.copy_from_slice(&brick[x0 * plane..][..plane]);
                    ph.copy_from_slice(pl);
                    for lx in x0 + 1..=x1 {
                        fold_row(pl, ph, &brick[lx * plane..][..plane]);
                    }
                }
                for xi in 0..wx.len() {
                    let (pl, ph) = (&plo[xi * plane..][..plane], &phi[xi * plane..][..plane]);
                    for &(cy, y0, y1) in wy {
                        // Local y: fold rows of the x-window's planes.
                        rlo.copy_from_slice(&pl[y0 * b..][..b]);
                        rhi.copy_from_slice(&ph[y0 * b..][..b]);
                        for ly in y0 + 1..=y1 {
                            fold_pair(&mut rlo, &mut rhi, &pl[ly * b..][..b], &ph[ly * b..][..b]);
                        }
                        // Local z: the few windows of the row.
                        let row = (xi * ny + cy) * nz;
                        for &(cz, z0, z1) in wz {
                            let (l, h) = rlo[z0..=z1]
                                .iter()
                                .zip(&rhi[z0..=z1])
                                .fold((lo[row + cz], hi[row + cz]), |(l, h), (&a, &b)| {
                                    (l.min_of(a), h.max_of(b))
                                });
                            (lo[row + cz], hi[row + cz]) = (l, h);
                        }
                    }
                }
            }
        }
        {
            let mut global = merged.lock();
            for (xi, &(cx, _, _)) in wx.iter().enumerate() {
                let out = &mut global[cx * ny * nz..][..ny * nz];
                let (l, h) = (
                    &lo[xi * ny * nz..][..ny * nz],
                    &hi[xi * ny * nz..][..ny * nz],
                );
                for ((o, &l), &h) in out.iter_mut().zip(l).zip(h) {
                    *o = (o.0.min_of(l), o.1.max_of(h));
                }
            }
        }
        let n = done.fetch_add(1, Ordering::Relaxed) + 1;
        slab_done(i * slab_len..(i + 1) * slab_len, n, nb.x);
    });
    global
        .into_iter()
        .map(|(l, h)| (l.to_f32(), h.to_f32()))
        .collect()
}

/// Element-wise `lo = min(lo, a)`, `hi = max(hi, b)`.
#[inline(always)]
fn fold_pair<S: Sample>(lo: &mut [S], hi: &mut [S], a: &[S], b: &[S]) {
    let n = lo.len().min(hi.len()).min(a.len()).min(b.len());
    let (lo, hi, a, b) = (&mut lo[..n], &mut hi[..n], &a[..n], &b[..n]);
    for i in 0..n {
        lo[i] = lo[i].min_of(a[i]);
        hi[i] = hi[i].max_of(b[i]);
    }
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
