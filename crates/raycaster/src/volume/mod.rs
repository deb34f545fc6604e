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

    /// The macrocell side (in voxels) that suits this layout: one brick for a
    /// bricked volume.
    fn preferred_macrocell(&self) -> u32;

    /// Central-difference gradient of the interpolated field at voxel-space
    /// position `p`, in value units per world unit (SPEC §5). Differences are
    /// taken one voxel apart along each axis, clamped at the grid's faces.
    #[inline]
    fn gradient(&self, p: Vec3) -> Vec3 {
        let g = self.grid();
        let hi = (g.dims.as_vec3() - Vec3::ONE).max(Vec3::ZERO);
        let mut out = [0.0f32; 3];
        for (axis, o) in out.iter_mut().enumerate() {
            let mut a = p;
            let mut b = p;
            a[axis] = (p[axis] - 1.0).max(0.0);
            b[axis] = (p[axis] + 1.0).min(hi[axis]);
            let dv = b[axis] - a[axis];
            if dv > 0.0 {
                *o = (self.sample(b) - self.sample(a)) / (dv * g.spacing[axis]);
            }
        }
        Vec3::from_array(out)
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
    let p = p.clamp(0.0, max_coord);
    let i = (p as u32).min(last);
    (i, p - i as f32)
}

/// Trilinear interpolation from `base` with the strides to the x, y and z
/// neighbours (a stride is 0 along an axis of size 1).
#[inline(always)]
pub(crate) fn trilinear<S: Sample>(data: &[S], base: usize, stride: [usize; 3], f: Vec3) -> f32 {
    let [sx, sy, sz] = stride;
    let c000 = data[base].to_f32();
    let c001 = data[base + sz].to_f32();
    let c010 = data[base + sy].to_f32();
    let c011 = data[base + sy + sz].to_f32();
    let c100 = data[base + sx].to_f32();
    let c101 = data[base + sx + sz].to_f32();
    let c110 = data[base + sx + sy].to_f32();
    let c111 = data[base + sx + sy + sz].to_f32();
    let c00 = c000 + (c001 - c000) * f.z;
    let c01 = c010 + (c011 - c010) * f.z;
    let c10 = c100 + (c101 - c100) * f.z;
    let c11 = c110 + (c111 - c110) * f.z;
    let c0 = c00 + (c01 - c00) * f.y;
    let c1 = c10 + (c11 - c10) * f.y;
    c0 + (c1 - c0) * f.x
}
