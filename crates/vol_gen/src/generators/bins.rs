//! Spatial binning of objects: a coarse grid of cells, each listing the
//! objects whose bounding box overlaps it, so a region only tests the objects
//! that can touch it.

use glam::UVec3;

use super::{IBox, Region};

/// The most cells a grid may have (keeps the index small for huge volumes).
const MAX_CELLS: u64 = 1 << 20;

/// Objects (by index) binned into cubic cells.
#[derive(Debug, Clone)]
pub struct Bins {
    cell: u32,
    count: UVec3,
    /// `items[offsets[c]..offsets[c + 1]]` are the objects of cell `c`, ascending.
    offsets: Vec<usize>,
    items: Vec<u32>,
}

impl Bins {
    /// Bins `boxes` (object `i` has bounding box `boxes[i]`; `None` = touches no
    /// voxel) over a grid of `dims`, with cells of about `cell_hint` voxels.
    pub fn new(dims: UVec3, boxes: &[Option<IBox>], cell_hint: u32) -> Self {
        let mut cell = cell_hint.clamp(8, 1 << 30);
        let cells = |c: u32| {
            dims.x.div_ceil(c) as u64 * dims.y.div_ceil(c) as u64 * dims.z.div_ceil(c) as u64
        };
        while cells(cell) > MAX_CELLS {
            cell *= 2;
        }
        let count = UVec3::new(
            dims.x.div_ceil(cell),
            dims.y.div_ceil(cell),
            dims.z.div_ceil(cell),
        );
        let n_cells = (count.x * count.y * count.z) as usize;
        let index = |c: UVec3| ((c.x * count.y + c.y) * count.z + c.z) as usize;
        let each_cell = |b: &IBox, f: &mut dyn FnMut(usize)| {
            let (lo, hi) = (b.lo / cell, b.hi / cell);
            for x in lo.x..=hi.x {
                for y in lo.y..=hi.y {
                    for z in lo.z..=hi.z {
                        f(index(UVec3::new(x, y, z)));
                    }
                }
            }
        };
        let mut offsets = vec![0usize; n_cells + 1];
        for b in boxes.iter().flatten() {
            each_cell(b, &mut |c| offsets[c + 1] += 1);
        }
        for c in 0..n_cells {
            offsets[c + 1] += offsets[c];
        }
        let mut fill = offsets.clone();
        let mut items = vec![0u32; offsets[n_cells]];
        for (i, b) in boxes.iter().enumerate() {
            if let Some(b) = b {
                each_cell(b, &mut |c| {
                    items[fill[c]] = i as u32;
                    fill[c] += 1;
                });
            }
        }
        Bins {
            cell,
            count,
            offsets,
            items,
        }
    }

    /// The indices, ascending and without repeats, of the objects binned in
    /// the cells that `region` overlaps (a superset of those touching it).
    pub fn query(&self, region: &Region) -> Vec<u32> {
        let mut out = Vec::new();
        if region.is_empty() {
            return out;
        }
        let lo = region.lo / self.cell;
        let hi = ((region.hi - UVec3::ONE) / self.cell).min(self.count - UVec3::ONE);
        let mut cells = 0;
        for x in lo.x..=hi.x {
            for y in lo.y..=hi.y {
                for z in lo.z..=hi.z {
                    let c = ((x * self.count.y + y) * self.count.z + z) as usize;
                    out.extend_from_slice(&self.items[self.offsets[c]..self.offsets[c + 1]]);
                    cells += 1;
                }
            }
        }
        if cells > 1 {
            out.sort_unstable();
            out.dedup();
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn query_finds_exactly_the_overlapping_cells_objects() {
        let dims = UVec3::new(100, 50, 30);
        let boxes = vec![
            Some(IBox {
                lo: UVec3::new(0, 0, 0),
                hi: UVec3::new(5, 5, 5),
            }),
            None,
            Some(IBox {
                lo: UVec3::new(40, 10, 10),
                hi: UVec3::new(90, 20, 12),
            }),
        ];
        let bins = Bins::new(dims, &boxes, 10);
        let region = |lo: [u32; 3], hi: [u32; 3]| Region {
            lo: UVec3::from_array(lo),
            hi: UVec3::from_array(hi),
            stride_x: 1,
            stride_y: 1,
        };
        assert_eq!(bins.query(&region([0, 0, 0], [100, 50, 30])), vec![0, 2]);
        assert_eq!(bins.query(&region([0, 0, 0], [3, 3, 3])), vec![0]);
        assert_eq!(
            bins.query(&region([60, 30, 0], [100, 50, 30])),
            Vec::<u32>::new()
        );
        assert_eq!(bins.query(&region([85, 15, 11], [86, 16, 12])), vec![2]);
    }
}
