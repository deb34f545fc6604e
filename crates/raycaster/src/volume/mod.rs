//! Volumes: a grid of samples in world space that can be sampled anywhere
//! inside it by trilinear interpolation (SPEC §2).
//!
//! [`Volume`] is the one interface renderers use. Its implementations,
//! [`LinearVolume`] and [`BrickedVolume`], differ only in how a voxel
//! coordinate maps to an index in their [`Storage`](crate::storage::Storage);
//! both reduce a trilinear lookup to "a base index and three strides", so the
//! hot loop is the same code, monomorphised per layout and sample type.

mod any;
mod bricked;
mod grid;
mod linear;

pub use any::AnyVolume;
pub use bricked::{BrickGrid, BrickedVolume};
pub use grid::Grid;
pub use linear::LinearVolume;

use glam::{UVec3, Vec3};

use crate::sample::Sample;
use crate::storage::StorageKind;

/// How a volume's samples are ordered in memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// One array, z fastest (`index = (x·Y + y)·Z + z`).
    Linear,
    /// Cubic bricks of `side`³ samples overlapping by one voxel plane.
    Bricked {
        /// Brick side in voxels.
        side: u32,
    },
}

impl std::fmt::Display for Layout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Layout::Linear => f.write_str("linear"),
            Layout::Bricked { side } => write!(f, "bricked (B = {side})"),
        }
    }
}

/// A volume that renderers can sample.
///
/// Positions given to [`Volume::sample`] are in *voxel space*: voxel
/// `(x, y, z)` sits at `(x, y, z)`; use [`Grid::world_to_voxel`] to get there
/// from world space. Positions outside `[0, dims − 1]` are clamped onto the
/// grid, so a sample never reads out of bounds.
pub trait Volume: Send + Sync {
    /// The type of one voxel.
    type Sample: Sample;

    /// Dimensions, spacing and origin.
    fn grid(&self) -> &Grid;

    /// Memory order of the samples.
    fn layout(&self) -> Layout;

    /// RAM or memory-mapped.
    fn storage_kind(&self) -> StorageKind;

    /// The value of one voxel. `v` must be inside the grid (panics otherwise).
    fn voxel(&self, v: UVec3) -> Self::Sample;

    /// The trilinearly interpolated value at voxel-space position `p`.
    fn sample(&self, p: Vec3) -> f32;

    /// Smallest and largest voxel value in the inclusive box `[lo, hi]`
    /// (clamped to the grid).
    fn value_range(&self, lo: UVec3, hi: UVec3) -> (Self::Sample, Self::Sample);

    /// The value range of every macrocell of side `cell` (cell `c` covers
    /// voxels `c·cell ..= c·cell + cell` per axis), `count` cells per axis,
    /// x slowest and z fastest, on the threads of the current rayon pool.
    fn cell_value_ranges(&self, cell: u32, count: UVec3) -> Vec<(f32, f32)> {
        use rayon::prelude::*;
        let per_slab = (count.y * count.z) as usize;
        let mut ranges = vec![(0.0f32, 0.0f32); count.x as usize * per_slab];
        ranges
            .par_chunks_mut(per_slab)
            .enumerate()
            .for_each(|(cx, slab)| {
                for cy in 0..count.y {
                    for cz in 0..count.z {
                        let lo = UVec3::new(cx as u32, cy, cz) * cell;
                        let (a, b) = self.value_range(lo, lo + UVec3::splat(cell));
                        slab[(cy * count.z + cz) as usize] = (a.to_f32(), b.to_f32());
                    }
                }
            });
        ranges
    }

    /// Central-difference gradient of the interpolated field at voxel-space
    /// position `p`, in value units per world unit (SPEC §5). Differences are
    /// taken one voxel apart along each axis, clamped at the grid's faces.
    #[inline]
    fn gradient(&self, p: Vec3) -> Vec3 {
        clamped_gradient(self, p)
    }
}

/// The central-difference gradient of [`Volume::gradient`] for any position,
/// each difference shortened to stay inside the grid at its faces.
pub fn clamped_gradient<V: Volume + ?Sized>(volume: &V, p: Vec3) -> Vec3 {
    let g = volume.grid();
    let hi = g.max_coord();
    let mut out = [0.0f32; 3];
    for (axis, o) in out.iter_mut().enumerate() {
        let mut a = p;
        let mut b = p;
        a[axis] = (p[axis] - 1.0).max(0.0);
        b[axis] = (p[axis] + 1.0).min(hi[axis]);
        let dv = b[axis] - a[axis];
        if dv > 0.0 {
            *o = (volume.sample(b) - volume.sample(a)) / (dv * g.spacing[axis]);
        }
    }
    Vec3::from_array(out)
}

/// The same gradient when the stencil (voxels `x0 − 1 ..= x0 + 2` per axis)
/// is inside the grid, from 32 voxel reads instead of six separate 8-voxel
/// lookups.
///
/// The difference `f(p + eₓ) − f(p − eₓ)` is the trilinear interpolation,
/// with p's fractions, of the cell one voxel further minus the cell one voxel
/// back. Interpolating first over y and z gives four slab values `B(−1..=2)`
/// along x, and `gx = lerp(B1, B2, fx) − lerp(B−1, B0, fx)`; likewise for y
/// and z. `xo`, `yo`, `zo` are the storage offsets of coordinates
/// `c − 1, c, c + 1, c + 2` along each axis (index = xo + yo + zo).
#[inline(always)]
pub(crate) fn stencil_gradient<S: Sample>(
    data: &[S],
    xo: [usize; 4],
    yo: [usize; 4],
    zo: [usize; 4],
    f: Vec3,
    inv_two_spacing: Vec3,
) -> Vec3 {
    let max = |o: [usize; 4]| o[0].max(o[1]).max(o[2]).max(o[3]);
    // One bounds check for all 32 reads: every index is at most the sum of
    // the per-axis maxima.
    assert!(
        max(xo) + max(yo) + max(zo) < data.len(),
        "gradient stencil outside the volume"
    );
    // SAFETY: each index is xo[a] + yo[b] + zo[c] <= max(xo) + max(yo) +
    // max(zo) < data.len(), checked just above.
    let v = |a: usize, b: usize, c: usize| {
        unsafe { data.get_unchecked(xo[a] + yo[b] + zo[c]) }.to_f32()
    };
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    // Bilinear over (y, z) of the x = a slab, over (x, z) of y = b, (x, y) of z = c.
    let slab_x = |a: usize| {
        lerp(
            lerp(v(a, 1, 1), v(a, 1, 2), f.z),
            lerp(v(a, 2, 1), v(a, 2, 2), f.z),
            f.y,
        )
    };
    let slab_y = |b: usize| {
        lerp(
            lerp(v(1, b, 1), v(1, b, 2), f.z),
            lerp(v(2, b, 1), v(2, b, 2), f.z),
            f.x,
        )
    };
    let slab_z = |c: usize| {
        lerp(
            lerp(v(1, 1, c), v(1, 2, c), f.y),
            lerp(v(2, 1, c), v(2, 2, c), f.y),
            f.x,
        )
    };
    let diff = |s: [f32; 4], t: f32| lerp(s[2], s[3], t) - lerp(s[0], s[1], t);
    let gx = diff([slab_x(0), slab_x(1), slab_x(2), slab_x(3)], f.x);
    let gy = diff([slab_y(0), slab_y(1), slab_y(2), slab_y(3)], f.y);
    let gz = diff([slab_z(0), slab_z(1), slab_z(2), slab_z(3)], f.z);
    Vec3::new(gx, gy, gz) * inv_two_spacing
}

/// True when the gradient stencil around cell `c` is inside a grid of `dims`.
#[inline(always)]
pub(crate) fn stencil_inside(c: UVec3, dims: UVec3) -> bool {
    c.cmpge(UVec3::ONE).all() && (c + UVec3::splat(2)).cmplt(dims).all()
}

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

/// Splits a clamped voxel-space coordinate into the lower corner of its cell
/// and the fraction past it. `last` is `dim − 2` (0 when `dim == 1`), so the
/// upper neighbour `i + 1` is always inside the grid.
#[inline(always)]
pub(crate) fn split_coord(p: f32, max_coord: f32, last: u32) -> (u32, f32) {
    // `max`/`min` (not `clamp`) also turn NaN into 0. Dimensions are below
    // 2^31, so the i32 conversion is exact; it is several instructions
    // cheaper than a saturating f32 → u32 cast.
    let p = p.max(0.0).min(max_coord);
    let i = ((p as i32) as u32).min(last);
    (i, p - i as f32)
}

/// Trilinear interpolation from `base` with the strides to the x, y and z
/// neighbours (a stride is 0 along an axis of size 1).
#[inline(always)]
pub(crate) fn trilinear<S: Sample>(data: &[S], base: usize, stride: [usize; 3], f: Vec3) -> f32 {
    let [sx, sy, sz] = stride;
    let last = base + sx + sy + sz;
    // One bounds check for the whole cell instead of eight: the largest
    // offset is `last`, every other one is a sub-sum of it.
    assert!(last < data.len(), "trilinear cell outside the volume");
    // SAFETY: the strides are non-negative, so each index below lies in
    // `base..=last`, and `last < data.len()` was just checked.
    let at = |i: usize| unsafe { data.get_unchecked(i) }.to_f32();
    let c000 = at(base);
    let c001 = at(base + sz);
    let c010 = at(base + sy);
    let c011 = at(base + sy + sz);
    let c100 = at(base + sx);
    let c101 = at(base + sx + sz);
    let c110 = at(base + sx + sy);
    let c111 = at(last);
    let c00 = c000 + (c001 - c000) * f.z;
    let c01 = c010 + (c011 - c010) * f.z;
    let c10 = c100 + (c101 - c100) * f.z;
    let c11 = c110 + (c111 - c110) * f.z;
    let c0 = c00 + (c01 - c00) * f.y;
    let c1 = c10 + (c11 - c10) * f.y;
    c0 + (c1 - c0) * f.x
}

#[cfg(test)]
mod tests;
