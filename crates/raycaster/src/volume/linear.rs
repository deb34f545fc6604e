//! The linear layout: one array of samples, z fastest (the `.vol` order) or
//! x fastest (the order of NRRD, NIfTI, DICOM and most raw files).

use glam::{UVec3, Vec3, Vec3Swizzles};

use super::{Grid, Layout, Volume, cell_value_ranges_by_rows, fold_range};
use crate::error::{Error, Result};
use crate::sample::Sample;
use crate::storage::{Storage, StorageKind};

/// Which axis changes fastest in a linear array of samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum AxisOrder {
    /// `index(x, y, z) = (x·Y + y)·Z + z`: the `.vol` order (SPEC §1).
    #[default]
    ZFast,
    /// `index(x, y, z) = (z·Y + y)·X + x`: the order of NRRD, NIfTI, DICOM
    /// and most published raw files (SPEC §6-§7).
    XFast,
}

impl AxisOrder {
    /// Index steps along x, y and z for a grid of `dims`.
    pub fn strides(self, dims: UVec3) -> [usize; 3] {
        let d = dims.as_usizevec3();
        match self {
            AxisOrder::ZFast => [d.y * d.z, d.z, 1],
            AxisOrder::XFast => [1, d.x, d.x * d.y],
        }
    }
}

/// Samples in one array, in either [`AxisOrder`].
#[derive(Debug)]
pub struct LinearVolume<S: Sample> {
    grid: Grid,
    data: Storage<S>,
    order: AxisOrder,
    /// Index steps along x, y and z.
    step: [usize; 3],
    /// Index steps to the x, y and z neighbours (0 along an axis of size 1).
    stride: [usize; 3],
    max_coord: Vec3,
    last: UVec3,
}

impl<S: Sample> LinearVolume<S> {
    /// Wraps storage that holds exactly `grid.voxel_count()` samples in the
    /// `.vol` order (z fastest).
    pub fn new(grid: Grid, data: Storage<S>) -> Result<Self> {
        Self::with_order(grid, data, AxisOrder::ZFast)
    }

    /// Wraps storage that holds exactly `grid.voxel_count()` samples in `order`.
    pub fn with_order(grid: Grid, data: Storage<S>, order: AxisOrder) -> Result<Self> {
        if data.len() as u64 != grid.voxel_count() {
            return Err(Error::InvalidArgument(format!(
                "linear volume {}x{}x{} needs {} samples, got {}",
                grid.dims.x,
                grid.dims.y,
                grid.dims.z,
                grid.voxel_count(),
                data.len()
            )));
        }
        let step = order.strides(grid.dims);
        let d = grid.dims;
        let neighbour = |n: u32, s: usize| if n > 1 { s } else { 0 };
        Ok(LinearVolume {
            stride: [
                neighbour(d.x, step[0]),
                neighbour(d.y, step[1]),
                neighbour(d.z, step[2]),
            ],
            step,
            order,
            max_coord: grid.max_coord(),
            last: grid.last_cell(),
            grid,
            data,
        })
    }

    /// Builds a volume in RAM (z fastest) from a function of the voxel coordinate.
    pub fn from_fn(grid: Grid, mut f: impl FnMut(UVec3) -> S) -> Self {
        let mut v = Vec::with_capacity(grid.voxel_count() as usize);
        for x in 0..grid.dims.x {
            for y in 0..grid.dims.y {
                for z in 0..grid.dims.z {
                    v.push(f(UVec3::new(x, y, z)));
                }
            }
        }
        match Self::new(grid, Storage::from_vec(v)) {
            Ok(vol) => vol,
            Err(_) => unreachable!("from_fn produces exactly voxel_count samples"),
        }
    }

    /// The samples in storage order (see [`LinearVolume::order`]).
    pub fn samples(&self) -> &[S] {
        self.data.as_slice()
    }

    /// Which axis changes fastest in [`LinearVolume::samples`].
    pub fn order(&self) -> AxisOrder {
        self.order
    }

    /// Storage offsets of coordinates `c − 1 ..= c + 2` per axis (see
    /// [`load_wings`]).
    #[inline(always)]
    fn stencil_offsets(&self, c: UVec3) -> [[usize; 4]; 3] {
        let row = |c: u32, s: usize| {
            let b = (c as usize - 1) * s;
            [b, b + s, b + 2 * s, b + 3 * s]
        };
        [
            row(c.x, self.step[0]),
            row(c.y, self.step[1]),
            row(c.z, self.step[2]),
        ]
    }

    #[inline(always)]
    fn index(&self, v: UVec3) -> usize {
        v.x as usize * self.step[0] + v.y as usize * self.step[1] + v.z as usize * self.step[2]
    }
}

impl<S: Sample> Volume for LinearVolume<S> {
    type Sample = S;

    fn grid(&self) -> &Grid {
        &self.grid
    }

    fn layout(&self) -> Layout {
        match self.order {
            AxisOrder::ZFast => Layout::Linear,
            AxisOrder::XFast => Layout::LinearXFast,
        }
    }

    fn storage_kind(&self) -> StorageKind {
        self.data.kind()
    }

    fn voxel(&self, v: UVec3) -> S {
        assert!(v.cmplt(self.grid.dims).all(), "voxel {v} outside the grid");
        self.data.as_slice()[self.index(v)]
    }

    cell_access!();

    fn value_range(&self, lo: UVec3, hi: UVec3) -> (S, S) {
        let hi = hi.min(self.grid.dims - UVec3::ONE);
        let data = self.data.as_slice();
        let mut acc = (S::HIGHEST, S::LOWEST);
        if lo.cmpgt(hi).any() {
            return acc; // an empty box
        }
        // Rows along the fastest axis are contiguous; walk the other two.
        let (outer, fast) = match self.order {
            AxisOrder::ZFast => (0, 2),
            AxisOrder::XFast => (2, 0),
        };
        let base = self.index(lo);
        let run = (hi[fast] - lo[fast]) as usize;
        for a in 0..=(hi[outer] - lo[outer]) as usize {
            for b in 0..=(hi.y - lo.y) as usize {
                let row = base + a * self.step[outer] + b * self.step[1];
                let (x, y) = fold_range(data[row..=row + run].iter().copied());
                acc = (acc.0.min_of(x), acc.1.max_of(y));
            }
        }
        acc
    }

    fn cell_value_ranges(&self, cell: u32, count: UVec3) -> Vec<(f32, f32)> {
        let data = self.data.as_slice();
        match self.order {
            AxisOrder::ZFast => {
                let z = self.grid.dims.z as usize;
                cell_value_ranges_by_rows(self.grid.dims, cell, count, |x, y, row: &mut [S]| {
                    let start = self.index(UVec3::new(x, y, 0));
                    row.copy_from_slice(&data[start..start + z]);
                })
            }
            AxisOrder::XFast => {
                // Stream rows along x (contiguous) by treating the volume as
                // one with x and z swapped, then swap the cells back.
                let d = self.grid.dims;
                let nx = d.x as usize;
                let swapped =
                    cell_value_ranges_by_rows(d.zyx(), cell, count.zyx(), |z, y, row: &mut [S]| {
                        let start = self.index(UVec3::new(0, y, z));
                        row.copy_from_slice(&data[start..start + nx]);
                    });
                let (cx, cy, cz) = (count.x as usize, count.y as usize, count.z as usize);
                let mut out = vec![(0.0, 0.0); swapped.len()];
                for (i, r) in swapped.into_iter().enumerate() {
                    // `swapped` is indexed (z, y, x) with x fastest.
                    let (z, y, x) = (i / (cy * cx), i / cx % cy, i % cx);
                    out[(x * cy + y) * cz + z] = r;
                }
                out
            }
        }
    }
}
