//! The linear layout: one array of samples, z fastest.

use glam::{UVec3, Vec3};

use super::{Grid, Layout, Volume, cell_value_ranges_by_rows, fold_range};
use crate::error::{Error, Result};
use crate::sample::Sample;
use crate::storage::{Storage, StorageKind};

/// Samples in one array, `index(x, y, z) = (x·Y + y)·Z + z` (SPEC §1).
#[derive(Debug)]
pub struct LinearVolume<S: Sample> {
    grid: Grid,
    data: Storage<S>,
    /// Index steps to the x, y and z neighbours (0 along an axis of size 1).
    stride: [usize; 3],
    max_coord: Vec3,
    last: UVec3,
}

impl<S: Sample> LinearVolume<S> {
    /// Wraps storage that holds exactly `grid.voxel_count()` samples in linear order.
    pub fn new(grid: Grid, data: Storage<S>) -> Result<Self> {
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
        let d = grid.dims.as_usizevec3();
        let step = |n: usize, s: usize| if n > 1 { s } else { 0 };
        Ok(LinearVolume {
            stride: [step(d.x, d.y * d.z), step(d.y, d.z), step(d.z, 1)],
            max_coord: grid.max_coord(),
            last: grid.last_cell(),
            grid,
            data,
        })
    }

    /// Builds a volume in RAM from a function of the voxel coordinate.
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

    /// The samples in file order.
    pub fn samples(&self) -> &[S] {
        self.data.as_slice()
    }

    /// Storage offsets of coordinates `c − 1 ..= c + 2` per axis (see
    /// [`load_wings`]).
    #[inline(always)]
    fn stencil_offsets(&self, c: UVec3) -> [[usize; 4]; 3] {
        let d = self.grid.dims;
        let (sx, sy) = (d.y as usize * d.z as usize, d.z as usize);
        let row = |c: u32, s: usize| {
            let b = (c as usize - 1) * s;
            [b, b + s, b + 2 * s, b + 3 * s]
        };
        [row(c.x, sx), row(c.y, sy), row(c.z, 1)]
    }

    #[inline(always)]
    fn index(&self, v: UVec3) -> usize {
        let d = self.grid.dims;
        (v.x as usize * d.y as usize + v.y as usize) * d.z as usize + v.z as usize
    }
}

impl<S: Sample> Volume for LinearVolume<S> {
    type Sample = S;

    fn grid(&self) -> &Grid {
        &self.grid
    }

    fn layout(&self) -> Layout {
        Layout::Linear
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
        for x in lo.x..=hi.x {
            for y in lo.y..=hi.y {
                let row = self.index(UVec3::new(x, y, lo.z));
                let (a, b) = fold_range(data[row..=row + (hi.z - lo.z) as usize].iter().copied());
                acc = (acc.0.min_of(a), acc.1.max_of(b));
            }
        }
        acc
    }

    fn cell_value_ranges(&self, cell: u32, count: UVec3) -> Vec<(f32, f32)> {
        let z = self.grid.dims.z as usize;
        let data = self.data.as_slice();
        cell_value_ranges_by_rows(self.grid.dims, cell, count, |x, y, row: &mut [S]| {
            let start = self.index(UVec3::new(x, y, 0));
            row.copy_from_slice(&data[start..start + z]);
        })
    }
}
