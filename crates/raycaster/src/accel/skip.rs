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
    let (nx, ny, nz) = (n.x as usize, n.y as usize, n.z as usize);
    let row = |x: usize, y: usize| (x * ny + y) * nz;
    let mut m = vec![0u8; nz];
    let mut m3 = vec![0u8; nz];
    // One raster pass. The mask neighbours in earlier rows (the 3×3 rows of
    // the previous plane and the previous row of this plane, each at z − 1,
    // z, z + 1) are final already, so their minimum is taken row-wise
    // (vectorised); the neighbour at z ∓ 1 in the same row needs a
    // sequential scan.
    let mut pass = |forward: bool| {
        let s: isize = if forward { 1 } else { -1 };
        let xs: Vec<usize> = if forward {
            (0..nx).collect()
        } else {
            (0..nx).rev().collect()
        };
        let ys: Vec<usize> = if forward {
            (0..ny).collect()
        } else {
            (0..ny).rev().collect()
        };
        for &x in &xs {
            for &y in &ys {
                m.fill(u8::MAX);
                let px = x as isize - s;
                let py = y as isize - s;
                let mut take = |r: usize, m: &mut [u8]| {
                    min3(&d[r..r + nz], &mut m3);
                    for (a, &b) in m.iter_mut().zip(&m3) {
                        *a = (*a).min(b);
                    }
                };
                if (0..nx as isize).contains(&px) {
                    for dy in -1..=1isize {
                        let qy = y as isize + dy;
                        if (0..ny as isize).contains(&qy) {
                            take(row(px as usize, qy as usize), &mut m);
                        }
                    }
                }
                if (0..ny as isize).contains(&py) {
                    take(row(x, py as usize), &mut m);
                }
                let r = row(x, y);
                let cells = &mut d[r..r + nz];
                for (c, &v) in cells.iter_mut().zip(&m) {
                    *c = (*c).min(v.saturating_add(1));
                }
                if forward {
                    for z in 1..nz {
                        cells[z] = cells[z].min(cells[z - 1].saturating_add(1));
                    }
                } else {
                    for z in (0..nz.saturating_sub(1)).rev() {
                        cells[z] = cells[z].min(cells[z + 1].saturating_add(1));
                    }
                }
            }
        }
    };
    pass(true);
    pass(false);
}

/// `out[z] = min(row[z − 1], row[z], row[z + 1])`, ignoring missing neighbours.
fn min3(row: &[u8], out: &mut [u8]) {
    out.copy_from_slice(row);
    let n = row.len();
    if n < 2 {
        return;
    }
    for (o, &v) in out[..n - 1].iter_mut().zip(&row[1..]) {
        *o = (*o).min(v);
    }
    for (o, &v) in out[1..].iter_mut().zip(&row[..n - 1]) {
        *o = (*o).min(v);
    }
}

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
