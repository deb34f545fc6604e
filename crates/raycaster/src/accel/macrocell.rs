//! The min/max grid over macrocells.

use crate::volume::{Volume, cell_coord};
use glam::{UVec3, Vec3};

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
    /// Per cell: true when the cell and its 26 neighbours hold one single
    /// value. Inside such a cell every sample has that value and every
    /// central-difference gradient is zero, so a ray can composite a run of
    /// samples there in closed form.
    pub uniform: Vec<bool>,
}

impl MacrocellGrid {
    /// Builds the grid for `volume` with cells of `cell` voxels a side (see
    /// [`Volume::cell_value_ranges`]).
    pub fn build<V: Volume>(volume: &V, cell: u32) -> Self {
        let cell = cell.max(1);
        let dims = volume.grid().dims;
        let n = |d: u32| if d <= 1 { 1 } else { (d - 1).div_ceil(cell) };
        let count = UVec3::new(n(dims.x), n(dims.y), n(dims.z));
        let ranges = volume.cell_value_ranges(cell, count);
        let uniform = uniform_cells(&ranges, count);
        MacrocellGrid {
            cell,
            count,
            ranges,
            uniform,
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
        let q = p * (1.0 / self.cell as f32);
        let last = self.count - UVec3::ONE;
        UVec3::new(
            cell_coord(q.x, last.x),
            cell_coord(q.y, last.y),
            cell_coord(q.z, last.z),
        )
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

/// Marks the cells whose 3×3×3 neighbourhood (clamped to the grid) holds one
/// value, in three separable passes (z, then y, then x).
fn uniform_cells(ranges: &[(f32, f32)], n: UVec3) -> Vec<bool> {
    let (ny, nz) = (n.y as usize, n.z as usize);
    let total = ranges.len();
    let value: Vec<f32> = ranges.iter().map(|r| r.0).collect();
    let mut cur: Vec<bool> = ranges.iter().map(|&(lo, hi)| lo == hi).collect();
    // Along each axis, a cell stays uniform when both neighbours on that
    // axis (where they exist) were uniform with the same value. Within a
    // group of lines (a row for z, a plane for y, the grid for x) the cells
    // that have a lower neighbour form one contiguous range, as do their
    // neighbours, so each sweep is a zip over two slices.
    for (stride, len) in [(1usize, nz), (nz, ny), (ny * nz, n.x as usize)] {
        if len < 2 {
            continue;
        }
        let prev = cur.clone();
        for g in (0..total).step_by(stride * len) {
            let hi = g + stride * len;
            let (upper, lower) = (g + stride..hi, g..hi - stride);
            let pairs = value[upper.clone()].iter().zip(&value[lower.clone()]);
            for ((c, &p), (a, b)) in cur[upper.clone()]
                .iter_mut()
                .zip(&prev[lower.clone()])
                .zip(pairs.clone())
            {
                *c &= p && a == b;
            }
            for ((c, &p), (a, b)) in cur[lower].iter_mut().zip(&prev[upper]).zip(pairs) {
                *c &= p && a == b;
            }
        }
    }
    cur
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_cells_match_brute_force() {
        let mut rng = fastrand::Rng::with_seed(4);
        for _ in 0..30 {
            let n = UVec3::new(rng.u32(1..7), rng.u32(1..7), rng.u32(1..7));
            let len = (n.x * n.y * n.z) as usize;
            let ranges: Vec<(f32, f32)> = (0..len)
                .map(|_| match rng.u32(0..10) {
                    0 => (0.0, 1.0),
                    1 => (2.0, 2.0),
                    _ => (0.0, 0.0),
                })
                .collect();
            let got = uniform_cells(&ranges, n);
            let at = |x: i32, y: i32, z: i32| ((x * n.y as i32 + y) * n.z as i32 + z) as usize;
            for x in 0..n.x as i32 {
                for y in 0..n.y as i32 {
                    for z in 0..n.z as i32 {
                        let me = ranges[at(x, y, z)];
                        let mut want = me.0 == me.1;
                        for dx in -1..=1 {
                            for dy in -1..=1 {
                                for dz in -1..=1 {
                                    let (qx, qy, qz) = (x + dx, y + dy, z + dz);
                                    if qx < 0
                                        || qy < 0
                                        || qz < 0
                                        || qx >= n.x as i32
                                        || qy >= n.y as i32
                                        || qz >= n.z as i32
                                    {
                                        continue;
                                    }
                                    let q = ranges[at(qx, qy, qz)];
                                    want &= q.0 == q.1 && q.0 == me.0;
                                }
                            }
                        }
                        assert_eq!(got[at(x, y, z)], want, "cell {x},{y},{z} of {n}");
                    }
                }
            }
        }
    }
}
