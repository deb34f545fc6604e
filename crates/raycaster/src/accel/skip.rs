//! Per-transfer-function occupancy with a distance field for skipping.

use glam::{UVec3, Vec3};

use super::MacrocellGrid;
use crate::geometry::Aabb;

/// The answer of [`SkipGrid::classify`].
#[derive(Debug, Clone, Copy)]
pub enum CellClass {
    /// Nothing here contributes; the box around the point (voxel space) in
    /// which no cell does.
    Empty(Aabb),
    /// The cell may contribute.
    Occupied {
        /// The cell's box (voxel space).
        bounds: Aabb,
        /// Its index in the macrocell grid.
        index: usize,
    },
}

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

    /// What the cell holding voxel-space point `p` is: empty (with the empty
    /// box around it) or occupied (with its own box and its index in the
    /// macrocell grid).
    #[inline(always)]
    pub fn classify(&self, p: Vec3) -> CellClass {
        let c = (p.max(Vec3::ZERO) * self.inv_cell)
            .as_uvec3()
            .min(self.count - UVec3::ONE);
        let index = self.index(c);
        let d = self.distance[index];
        let r = d.saturating_sub(1) as f32;
        let lo = (c.as_vec3() - Vec3::splat(r)) * self.cell;
        let hi = (c.as_vec3() + Vec3::splat(r + 1.0)) * self.cell;
        let bounds = Aabb::new(lo, hi);
        if d == 0 {
            CellClass::Occupied { bounds, index }
        } else {
            CellClass::Empty(bounds)
        }
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
    // Work on a copy padded by one never-source cell per face, so the
    // neighbour loop needs no bounds tests.
    let (nx, ny, nz) = (n.x as usize, n.y as usize, n.z as usize);
    let (py, pz) = (ny + 2, nz + 2);
    let mut pad = vec![u8::MAX; (nx + 2) * py * pz];
    let at = |x: usize, y: usize, z: usize| (x * py + y) * pz + z;
    for x in 0..nx {
        for y in 0..ny {
            let src = (x * ny + y) * nz;
            let dst = at(x + 1, y + 1, 1);
            pad[dst..dst + nz].copy_from_slice(&d[src..src + nz]);
        }
    }
    let offsets: [usize; 13] =
        HALF_MASK.map(|(dx, dy, dz)| ((dx * py as i64 + dy) * pz as i64 + dz) as usize);
    // Forward pass: neighbours at lower indices; backward: at higher ones.
    for x in 1..=nx {
        for y in 1..=ny {
            let row = at(x, y, 0);
            for i in row + 1..=row + nz {
                if pad[i] != 0 {
                    let m = offsets.iter().map(|&o| pad[i - o]).min().unwrap_or(u8::MAX);
                    pad[i] = pad[i].min(m.saturating_add(1));
                }
            }
        }
    }
    for x in (1..=nx).rev() {
        for y in (1..=ny).rev() {
            let row = at(x, y, 0);
            for i in (row + 1..=row + nz).rev() {
                if pad[i] != 0 {
                    let m = offsets.iter().map(|&o| pad[i + o]).min().unwrap_or(u8::MAX);
                    pad[i] = pad[i].min(m.saturating_add(1));
                }
            }
        }
    }
    for x in 0..nx {
        for y in 0..ny {
            let dst = (x * ny + y) * nz;
            let src = at(x + 1, y + 1, 1);
            d[dst..dst + nz].copy_from_slice(&pad[src..src + nz]);
        }
    }
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
            for (i, &got) in d.iter().enumerate() {
                let want = (0..len)
                    .filter(|&j| occ[j])
                    .map(|j| (pos(i) - pos(j)).abs().max_element() as u32)
                    .min()
                    .map_or(255, |v| v.min(255)) as u8;
                assert_eq!(got, want, "cell {i} of {n}");
            }
        }
    }
}
