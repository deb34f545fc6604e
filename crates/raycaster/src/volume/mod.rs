//! Volumes: a grid of samples in world space that can be sampled anywhere
//! inside it by trilinear interpolation. Sample `(x, y, z)` sits at world
//! position `origin + (x, y, z)·spacing`; values between samples are the
//! trilinear interpolation of the 8 around them.
//!
//! - [`AnyVolume`] owns a volume whose sample type and layout are known at
//!   run time (what a file reader returns): a [`Grid`], an untyped
//!   [`Storage`](crate::storage::Storage) and an [`AnyAddressing`].
//! - [`GridVolume`] is the typed view of it that hot loops use, generic over
//!   the [`Sample`] type and the [`Addressing`] ([`Linear`] or [`Bricked`]);
//!   [`AnyVolume::visit`] is the one place that picks the concrete type.
//! - [`Volume`] is what an integrator may ask of a volume: locate a cell,
//!   load its corners and gradient stencil, interpolate.
//! - [`slice`](mod@slice) cuts axis-aligned slices for slice views.

mod addressing;
mod any;
mod grid;
mod grid_volume;
mod ranges;
pub mod slice;

pub use addressing::{Addressing, AnyAddressing, AxisOrder, BrickGrid, Bricked, Layout, Linear};
pub use any::{AnyVolume, VolumeVisitor};
pub use grid::Grid;
pub use grid_volume::GridVolume;
pub(crate) use ranges::{cell_value_ranges_bricked, fold_range_f32};

use glam::{UVec3, Vec3, Vec4};

use crate::sample::Sample;

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

    /// The value of one voxel. `v` must be inside the grid (panics otherwise).
    fn voxel(&self, v: UVec3) -> Self::Sample;

    /// The interpolation cell holding voxel-space position `p` (clamped onto
    /// the grid) and the fractions of `p` inside it.
    fn locate(&self, p: Vec3) -> CellPos;

    /// The 8 voxel values at the corners of cell `cell` (from
    /// [`Volume::locate`]), in [`Corners`] order.
    fn corners(&self, cell: UVec3) -> Corners;

    /// Asks the CPU to start loading the corners of the cell holding
    /// voxel-space position `p` into cache (a hint: no effect on results).
    #[inline(always)]
    fn prefetch(&self, _p: Vec3) {}

    /// Asks the CPU to start loading the rows of that cell's [`Volume::wings`]
    /// that [`Volume::prefetch`] does not (a hint, for loops that shade).
    #[inline(always)]
    fn prefetch_wings(&self, _p: Vec3) {}

    /// The 24 voxel values one step outside cell `cell` along each axis, for
    /// the gradient (see [`Wings`]). At the grid's faces a coordinate that
    /// would leave the grid is clamped into it: a difference that would
    /// reach past a face repeats the face voxel, so the gradient there is
    /// `(v[1] − v[0]) / (2·spacing)` (SPEC §8).
    fn wings(&self, cell: UVec3) -> Wings;

    /// The trilinearly interpolated value at voxel-space position `p`.
    #[inline(always)]
    fn sample(&self, p: Vec3) -> f32 {
        let c = self.locate(p);
        interpolate(&self.corners(c.cell), c.frac)
    }

    /// Smallest and largest voxel value in the inclusive box `[lo, hi]`
    /// (clamped to the grid).
    fn value_range(&self, lo: UVec3, hi: UVec3) -> (Self::Sample, Self::Sample);

    /// The value range of every macrocell of side `cell` (cell `c` covers
    /// voxels `c·cell ..= c·cell + cell` per axis), `count` cells per axis,
    /// x slowest and z fastest, on the threads of the current rayon pool.
    fn cell_value_ranges(&self, cell: u32, count: UVec3) -> Vec<(f32, f32)>;

    /// The gradient at voxel-space position `p`, in value units per world
    /// unit: the trilinear interpolation of the voxels' central differences
    /// `(v[i+1] − v[i−1]) / (2·spacing)`, the indices clamped at the grid's
    /// faces (SPEC §8).
    #[inline(always)]
    fn gradient(&self, p: Vec3) -> Vec3 {
        GradientCache::default().gradient(self, p)
    }
}

/// [`Volume::gradient`] for a sequence of positions that often fall in
/// the same few cells (the hits of a block of neighbouring pixels): the
/// corner differences of the last [`GRADIENT_CELLS`] cells are kept, so a
/// cell's 32-value stencil is loaded once while the positions stay among
/// them (a 4×4 block's hits lie in a handful of cells, visited row by
/// row, so that one cell kept reloaded most of them). The same values as
/// [`Volume::gradient`].
#[derive(Debug, Clone, Copy)]
pub struct GradientCache {
    /// Per slot its cell's index in the grid (`x + nx·(y + ny·z)`: one
    /// compare a slot where the cell's three coordinates took three;
    /// `u64::MAX`, no cell's: empty).
    cells: [u64; GRADIENT_CELLS],
    gradients: [CornerGradients; GRADIENT_CELLS],
    /// The slot the next new cell takes (the oldest).
    next: usize,
}

/// Cells a [`GradientCache`] keeps.
pub const GRADIENT_CELLS: usize = 4;

impl Default for GradientCache {
    fn default() -> Self {
        GradientCache {
            cells: [u64::MAX; GRADIENT_CELLS],
            gradients: [[Vec4::ZERO; 8]; GRADIENT_CELLS],
            next: 0,
        }
    }
}

impl GradientCache {
    /// The gradient of `volume` at voxel-space position `p`; the cache
    /// must be used with one volume only.
    #[inline(always)]
    pub fn gradient<V: Volume + ?Sized>(&mut self, volume: &V, p: Vec3) -> Vec3 {
        let at = volume.locate(p);
        let dims = volume.grid().dims;
        let key = at.cell.x as u64
            + dims.x as u64 * (at.cell.y as u64 + dims.y as u64 * at.cell.z as u64);
        let slot = match self.cells.iter().position(|&c| c == key) {
            Some(slot) => slot,
            None => {
                let slot = self.next;
                self.next = (slot + 1) % GRADIENT_CELLS;
                self.cells[slot] = key;
                self.gradients[slot] =
                    corner_gradients(&volume.corners(at.cell), &volume.wings(at.cell));
                slot
            }
        };
        interpolate_gradient(&self.gradients[slot], at.frac, 0.5 / volume.grid().spacing)
    }
}

/// A voxel-space position split into the lower corner of its interpolation
/// cell and the fractions past it (each in [0, 1]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellPos {
    /// Lower corner voxel of the cell.
    pub cell: UVec3,
    /// Position inside the cell.
    pub frac: Vec3,
}

/// The 8 corner values of a cell: index `4i + 2j + k` holds voxel
/// `(x + i, y + j, z + k)`.
pub type Corners = [f32; 8];

/// The 24 values around a cell that the gradient stencil adds to its corners:
/// six groups of four, for `x − 1`, `x + 2`, `y − 1`, `y + 2`, `z − 1`,
/// `z + 2`; inside a group the other two axes' offsets (0/1) count in
/// x, y, z order, the later one fastest.
pub type Wings = [f32; 24];

/// Trilinear interpolation of `c` at fractions `f`.
#[inline(always)]
pub fn interpolate(c: &Corners, f: Vec3) -> f32 {
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let c00 = lerp(c[0], c[1], f.z);
    let c01 = lerp(c[2], c[3], f.z);
    let c10 = lerp(c[4], c[5], f.z);
    let c11 = lerp(c[6], c[7], f.z);
    lerp(lerp(c00, c01, f.y), lerp(c10, c11, f.y), f.x)
}

/// The central differences at a cell's 8 corners, `(v[i+1] − v[i−1])` per
/// axis (value units, not yet divided by `2·spacing`) in `xyz` of a `Vec4`,
/// in [`Corners`] order.
pub type CornerGradients = [Vec4; 8];

/// The central differences at the corners of a cell, from its corners and
/// wings: the part of the gradient that depends only on the cell, so a ray
/// computes it once for all its samples in the cell.
#[inline(always)]
pub fn corner_gradients(c: &Corners, w: &Wings) -> CornerGradients {
    // Corner n = 4i + 2j + k. Along x: at i = 0 the difference is
    // v(x+1) − v(x−1) = c[4 + 2j + k] − w[2j + k], at i = 1 it is
    // v(x+2) − v(x) = w[4 + 2j + k] − c[2j + k]; y and z likewise with
    // their wing groups (see [`Wings`]).
    let g = |n: usize| {
        let (i, j, k) = (n >> 2, (n >> 1) & 1, n & 1);
        let gx = if i == 0 {
            c[4 + 2 * j + k] - w[2 * j + k]
        } else {
            w[4 + 2 * j + k] - c[2 * j + k]
        };
        let gy = if j == 0 {
            c[4 * i + 2 + k] - w[8 + 2 * i + k]
        } else {
            w[12 + 2 * i + k] - c[4 * i + k]
        };
        let gz = if k == 0 {
            c[4 * i + 2 * j + 1] - w[16 + 2 * i + j]
        } else {
            w[20 + 2 * i + j] - c[4 * i + 2 * j]
        };
        Vec4::new(gx, gy, gz, 0.0)
    };
    [g(0), g(1), g(2), g(3), g(4), g(5), g(6), g(7)]
}

/// The gradient (value units per world unit) at fractions `f` inside a
/// cell: the trilinear interpolation of its corner central differences
/// ([`corner_gradients`]) scaled by `1 / (2·spacing)`, the three axes at
/// once in the lanes of a `Vec4`.
#[inline(always)]
pub fn interpolate_gradient(g: &CornerGradients, f: Vec3, inv_two_spacing: Vec3) -> Vec3 {
    let lerp = |a: Vec4, b: Vec4, t: Vec4| a + (b - a) * t;
    let (fx, fy, fz) = (Vec4::splat(f.x), Vec4::splat(f.y), Vec4::splat(f.z));
    let g00 = lerp(g[0], g[1], fz);
    let g01 = lerp(g[2], g[3], fz);
    let g10 = lerp(g[4], g[5], fz);
    let g11 = lerp(g[6], g[7], fz);
    lerp(lerp(g00, g01, fy), lerp(g10, g11, fy), fx).truncate() * inv_two_spacing
}

/// Loads a cell's corners from `base` with the strides to the x, y and z
/// neighbours (a stride is 0 along an axis of size 1).
#[inline(always)]
pub(crate) fn load_corners<S: Sample>(data: &[S], base: usize, stride: [usize; 3]) -> Corners {
    let [sx, sy, sz] = stride;
    let last = base + sx + sy + sz;
    // One bounds check for the whole cell instead of eight: the largest
    // offset is `last`, every other one is a sub-sum of it.
    assert!(last < data.len(), "cell outside the volume");
    // SAFETY: the strides are non-negative, so each index below lies in
    // `base..=last`, and `last < data.len()` was just checked.
    let at = |i: usize| unsafe { data.get_unchecked(i) }.to_f32();
    [
        at(base),
        at(base + sz),
        at(base + sy),
        at(base + sy + sz),
        at(base + sx),
        at(base + sx + sz),
        at(base + sx + sy),
        at(last),
    ]
}

/// Loads a cell's wings given the storage offsets of coordinates
/// `c − 1, c, c + 1, c + 2` along each axis (index = xo + yo + zo).
#[inline(always)]
pub(crate) fn load_wings<S: Sample>(
    data: &[S],
    xo: [usize; 4],
    yo: [usize; 4],
    zo: [usize; 4],
) -> Wings {
    let max = |o: [usize; 4]| o[0].max(o[1]).max(o[2]).max(o[3]);
    // One bounds check for all 24 reads: every index is at most the sum of
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
    [
        v(0, 1, 1),
        v(0, 1, 2),
        v(0, 2, 1),
        v(0, 2, 2),
        v(3, 1, 1),
        v(3, 1, 2),
        v(3, 2, 1),
        v(3, 2, 2),
        v(1, 0, 1),
        v(1, 0, 2),
        v(2, 0, 1),
        v(2, 0, 2),
        v(1, 3, 1),
        v(1, 3, 2),
        v(2, 3, 1),
        v(2, 3, 2),
        v(1, 1, 0),
        v(1, 2, 0),
        v(2, 1, 0),
        v(2, 2, 0),
        v(1, 1, 3),
        v(1, 2, 3),
        v(2, 1, 3),
        v(2, 2, 3),
    ]
}

/// True when the gradient stencil around cell `c` is inside a grid of `dims`.
#[inline(always)]
pub(crate) fn stencil_inside(c: UVec3, dims: UVec3) -> bool {
    c.cmpge(UVec3::ONE).all() && (c + UVec3::splat(2)).cmplt(dims).all()
}

/// Truncates `v` (any float, NaN included) to an integer coordinate in
/// `0..=last`, without the fix-ups of a checked float-to-int cast.
#[inline(always)]
pub fn cell_coord(v: f32, last: u32) -> u32 {
    let v = v.max(0.0).min(last as f32);
    // SAFETY: after `max`/`min` (which map NaN to 0), `v` is in
    // [0, last] with `last` < 2^31, so the truncation is representable.
    unsafe { v.to_int_unchecked::<i32>() as u32 }
}

/// Splits a clamped voxel-space coordinate into the lower corner of its cell
/// and the fraction past it. `last` is `dim − 2` (0 when `dim == 1`), so the
/// upper neighbour `i + 1` is always inside the grid.
#[inline(always)]
pub(crate) fn split_coord(p: f32, max_coord: f32, last: u32) -> (u32, f32) {
    let p = p.max(0.0).min(max_coord);
    // SAFETY: `max`/`min` map NaN to 0 and bound `p` to [0, max_coord], and
    // grid dimensions are below 2^31, so the truncation is representable.
    // The checked cast costs a NaN and overflow fix-up per axis per sample
    // (8% of a frame's instructions, measured with callgrind).
    let i = (unsafe { p.to_int_unchecked::<i32>() } as u32).min(last);
    // Through `i32` (exact: `i` < 2^31): a vector of `u32` has no
    // conversion instruction before AVX-512, and the compiler's stand-in
    // takes several.
    (i, p - i as i32 as f32)
}

#[cfg(test)]
mod tests;
