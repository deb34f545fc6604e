//! The min/max grid over macrocells.

use glam::{UVec3, Vec3};
use rayon::prelude::*;

use crate::sample::Sample as _;
use crate::volume::Volume;

/// Value range per macrocell.
///
/// Macrocell `c` covers voxels `[c·m, c·m + m]` along each axis (clamped to the
/// grid): neighbouring cells share a voxel plane, so every trilinear sample
/// taken inside a cell's box is bounded by that cell's range.
#[derive(Debug, Clone)]
pub struct MacrocellGrid {
    /// Cell side in voxels (m).
    pub cell: u32,
    /// Cells per axis.
    pub count: UVec3,
    /// `(min, max)` per cell, x slowest, z fastest.
    pub ranges: Vec<(f32, f32)>,
}

impl MacrocellGrid {
    /// Builds the grid for `volume` with cells of `cell` voxels a side, using
    /// all the threads of the current rayon pool.
    pub fn build<V: Volume>(volume: &V, cell: u32) -> Self {
        let cell = cell.max(1);
        let dims = volume.grid().dims;
        let n = |d: u32| if d <= 1 { 1 } else { (d - 1).div_ceil(cell) };
        let count = UVec3::new(n(dims.x), n(dims.y), n(dims.z));
        let per_slab = (count.y * count.z) as usize;
        let mut ranges = vec![(0.0f32, 0.0f32); count.x as usize * per_slab];
        ranges
            .par_chunks_mut(per_slab)
            .enumerate()
            .for_each(|(cx, slab)| {
                for cy in 0..count.y {
                    for cz in 0..count.z {
                        let lo = UVec3::new(cx as u32, cy, cz) * cell;
                        let (a, b) = volume.value_range(lo, lo + UVec3::splat(cell));
                        slab[(cy * count.z + cz) as usize] = (a.to_f32(), b.to_f32());
                    }
                }
            });
        MacrocellGrid {
            cell,
            count,
            ranges,
        }
    }

    /// Index of cell `c`.
    #[inline(always)]
    pub fn index(&self, c: UVec3) -> usize {
        (c.x as usize * self.count.y as usize + c.y as usize) * self.count.z as usize + c.z as usize
    }

    /// The cell containing voxel-space point `p` (clamped to the grid).
    #[inline(always)]
    pub fn cell_of(&self, p: Vec3) -> UVec3 {
        let c = (p.max(Vec3::ZERO) * (1.0 / self.cell as f32)).as_uvec3();
        c.min(self.count - UVec3::ONE)
    }

    /// The smallest and largest value in the whole volume.
    pub fn value_range(&self) -> (f32, f32) {
        self.ranges
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &(lo, hi)| {
                (a.min(lo), b.max(hi))
            })
    }
}
