//! Per-transfer-function occupancy with a distance field for skipping.

use glam::{UVec3, Vec3};

use super::MacrocellGrid;
use crate::geometry::Aabb;

/// For each macrocell: 0 when it may contribute to the image, otherwise the
/// Chebyshev distance (in cells, capped at 255) to the nearest cell that may.
#[derive(Debug, Clone)]
pub struct SkipGrid {
    cell: f32,
    inv_cell: f32,
    count: UVec3,
    distance: Vec<u8>,
}

impl SkipGrid {
    /// Marks the cells for which `occupied(min, max)` holds and computes the
    /// distance field of the rest.
    pub fn build(cells: &MacrocellGrid, occupied: impl Fn(f32, f32) -> bool) -> Self {
        let mut distance: Vec<u8> = cells
            .ranges
            .iter()
            .map(|&(lo, hi)| if occupied(lo, hi) { 0 } else { u8::MAX })
            .collect();
        chessboard_distance(&mut distance, cells.count);
        SkipGrid {
            cell: cells.cell as f32,
            inv_cell: 1.0 / cells.cell as f32,
            count: cells.count,
            distance,
        }
    }

    /// A grid where every cell is occupied (skipping disabled).
    pub fn all_occupied(cells: &MacrocellGrid) -> Self {
        Self::build(cells, |_, _| true)
    }

    /// Cells per axis.
    pub fn count(&self) -> UVec3 {
        self.count
    }

    /// Number of occupied cells.
    pub fn occupied_count(&self) -> usize {
        self.distance.iter().filter(|&&d| d == 0).count()
    }

    /// Whether cell `c` is occupied.
    pub fn is_occupied(&self, c: UVec3) -> bool {
        self.distance[self.index(c)] == 0
    }

    #[inline(always)]
    fn index(&self, c: UVec3) -> usize {
        (c.x as usize * self.count.y as usize + c.y as usize) * self.count.z as usize + c.z as usize
    }

    /// For voxel-space point `p`: `None` when its cell may contribute;
    /// otherwise the voxel-space box, around that cell, in which no cell does.
    #[inline(always)]
    pub fn empty_box(&self, p: Vec3) -> Option<Aabb> {
        let c = (p.max(Vec3::ZERO) * self.inv_cell)
            .as_uvec3()
            .min(self.count - UVec3::ONE);
        let d = self.distance[self.index(c)];
        if d == 0 {
            return None;
        }
        let r = (d - 1) as f32;
        let lo = (c.as_vec3() - Vec3::splat(r)) * self.cell;
        let hi = (c.as_vec3() + Vec3::splat(r + 1.0)) * self.cell;
        Some(Aabb::new(lo, hi))
    }

    /// For voxel-space point `p`: `Some(box)` of its cell when the cell is
    /// occupied, else `None`.
    #[inline(always)]
    pub fn occupied_cell_box(&self, p: Vec3) -> Option<Aabb> {
        let c = (p.max(Vec3::ZERO) * self.inv_cell)
            .as_uvec3()
            .min(self.count - UVec3::ONE);
        if self.distance[self.index(c)] != 0 {
            return None;
        }
        let lo = c.as_vec3() * self.cell;
        Some(Aabb::new(lo, lo + Vec3::splat(self.cell)))
    }
}

/// In-place chessboard distance transform: cells holding 0 are sources, all
/// others must hold `u8::MAX` on entry. Two raster passes with the 26-neighbour
/// chamfer mask of unit weights, which is exact for the chessboard metric.
fn chessboard_distance(d: &mut [u8], n: UVec3) {
    let (nx, ny, nz) = (n.x as i64, n.y as i64, n.z as i64);
    let idx = |x: i64, y: i64, z: i64| ((x * ny + y) * nz + z) as usize;
    let mut pass = |forward: bool| {
        let s: i64 = if forward { 1 } else { -1 };
        let range = |len: i64| -> Box<dyn Iterator<Item = i64>> {
            if forward {
                Box::new(0..len)
            } else {
                Box::new((0..len).rev())
            }
        };
        for x in range(nx) {
            for y in range(ny) {
                for z in range(nz) {
                    let here = idx(x, y, z);
                    if d[here] == 0 {
                        continue;
                    }
                    let mut best = d[here];
                    // The 13 neighbours already visited in this raster order.
                    for (dx, dy, dz) in HALF_MASK {
                        let (qx, qy, qz) = (x - s * dx, y - s * dy, z - s * dz);
                        if qx < 0 || qy < 0 || qz < 0 || qx >= nx || qy >= ny || qz >= nz {
                            continue;
                        }
                        best = best.min(d[idx(qx, qy, qz)].saturating_add(1));
                    }
                    d[here] = best;
                }
            }
        }
    };
    pass(true);
    pass(false);
}

/// Offsets of the neighbours that precede a cell in x-major, z-fastest order.
const HALF_MASK: [(i64, i64, i64); 13] = [
    (1, -1, -1),
    (1, -1, 0),
    (1, -1, 1),
    (1, 0, -1),
    (1, 0, 0),
    (1, 0, 1),
    (1, 1, -1),
    (1, 1, 0),
    (1, 1, 1),
    (0, 1, -1),
    (0, 1, 0),
    (0, 1, 1),
    (0, 0, 1),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_transform_matches_brute_force() {
        let mut rng = fastrand::Rng::with_seed(11);
        for trial in 0..20 {
            let n = UVec3::new(rng.u32(1..9), rng.u32(1..9), rng.u32(1..9));
            let len = (n.x * n.y * n.z) as usize;
            let density = if trial % 2 == 0 { 0.02 } else { 0.2 };
            let occ: Vec<bool> = (0..len).map(|_| rng.f32() < density).collect();
            let mut d: Vec<u8> = occ.iter().map(|&o| if o { 0 } else { 255 }).collect();
            chessboard_distance(&mut d, n);
            let pos = |i: usize| {
                let z = i as u32 % n.z;
                let y = (i as u32 / n.z) % n.y;
                let x = i as u32 / (n.y * n.z);
                glam::IVec3::new(x as i32, y as i32, z as i32)
            };
            for i in 0..len {
                let want = (0..len)
                    .filter(|&j| occ[j])
                    .map(|j| (pos(i) - pos(j)).abs().max_element() as u32)
                    .min()
                    .map_or(255, |v| v.min(255)) as u8;
                assert_eq!(d[i], want, "cell {i} of {n}");
            }
        }
    }
}
