//! The bricked layout: cubic bricks that overlap by one voxel plane, so the 8
//! samples of any trilinear lookup lie in one brick (SPEC §1).

use glam::{UVec3, Vec3};

use super::{Grid, Layout, Volume, cell_value_ranges_by_rows};
use crate::error::{Error, Result};
use crate::sample::Sample;
use crate::storage::{Storage, StorageKind};

/// How a grid is cut into overlapping bricks of `side`³ samples.
///
/// Brick `(i, j, k)` holds voxels `[i·(B−1), i·(B−1) + B − 1]` per axis; bricks
/// are stored with i slowest and k fastest, samples inside a brick in linear
/// order (local z fastest).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BrickGrid {
    /// Samples along a brick's side, B (2..=255).
    pub side: u32,
    /// Bricks per axis.
    pub count: UVec3,
}

impl BrickGrid {
    /// The brick grid for `dims` with bricks of side `side` (which must be >= 2).
    pub fn new(dims: UVec3, side: u32) -> Self {
        debug_assert!(side >= 2);
        let n = |d: u32| {
            if d <= 1 {
                1
            } else {
                (d - 1).div_ceil(side - 1)
            }
        };
        BrickGrid {
            side,
            count: UVec3::new(n(dims.x), n(dims.y), n(dims.z)),
        }
    }

    /// Samples in one brick, B³.
    pub fn brick_len(&self) -> u64 {
        (self.side as u64).pow(3)
    }

    /// Number of bricks, or `None` on overflow.
    pub fn brick_count(&self) -> Option<u64> {
        (self.count.x as u64)
            .checked_mul(self.count.y as u64)?
            .checked_mul(self.count.z as u64)
    }

    /// Total samples stored, or `None` on overflow.
    pub fn total_len(&self) -> Option<u64> {
        self.brick_count()?.checked_mul(self.brick_len())
    }

    /// The brick holding voxel coordinate `c` along one axis, and the local
    /// coordinate inside it. A voxel on a shared plane goes to the lower brick,
    /// except the grid's last plane, which only the last brick holds.
    #[inline]
    pub fn split(&self, c: u32, count: u32) -> (u32, u32) {
        let b = (c / (self.side - 1)).min(count - 1);
        (b, c - b * (self.side - 1))
    }

    /// Position in the file's sample array of voxel `v`.
    pub fn index_of(&self, v: UVec3) -> u64 {
        let (i, lx) = self.split(v.x, self.count.x);
        let (j, ly) = self.split(v.y, self.count.y);
        let (k, lz) = self.split(v.z, self.count.z);
        let brick = (i as u64 * self.count.y as u64 + j as u64) * self.count.z as u64 + k as u64;
        let b = self.side as u64;
        brick * self.brick_len() + (lx as u64 * b + ly as u64) * b + lz as u64
    }

    /// The voxel stored at position `index` of the file's sample array, or
    /// `None` for the padding past the grid's edge in the last bricks.
    pub fn voxel_at(&self, index: u64, dims: UVec3) -> Option<UVec3> {
        let b = self.side as u64;
        let brick = index / self.brick_len();
        let local = index % self.brick_len();
        let k = brick % self.count.z as u64;
        let j = (brick / self.count.z as u64) % self.count.y as u64;
        let i = brick / (self.count.z as u64 * self.count.y as u64);
        let (lx, ly, lz) = (local / (b * b), (local / b) % b, local % b);
        let step = b - 1;
        let v = [i * step + lx, j * step + ly, k * step + lz];
        (v[0] < dims.x as u64 && v[1] < dims.y as u64 && v[2] < dims.z as u64)
            .then(|| UVec3::new(v[0] as u32, v[1] as u32, v[2] as u32))
    }
}

/// Samples stored brick by brick.
#[derive(Debug)]
pub struct BrickedVolume<S: Sample> {
    grid: Grid,
    bricks: BrickGrid,
    data: Storage<S>,
    /// Per axis, the storage offset contributed by a voxel coordinate (brick
    /// offset plus local offset), so an index is three table lookups and two
    /// additions instead of three divisions.
    offset: [Vec<usize>; 3],
    stride: [usize; 3],
    max_coord: Vec3,
    last: UVec3,
}

impl<S: Sample> BrickedVolume<S> {
    /// Wraps storage that holds the bricks of `grid` with side `side`, in file order.
    pub fn new(grid: Grid, side: u32, data: Storage<S>) -> Result<Self> {
        if !(2..=255).contains(&side) {
            return Err(Error::InvalidArgument(format!(
                "brick side {side} outside 2..=255"
            )));
        }
        let bricks = BrickGrid::new(grid.dims, side);
        let need = bricks
            .total_len()
            .ok_or_else(|| Error::InvalidArgument("bricked volume too large".into()))?;
        if data.len() as u64 != need {
            return Err(Error::InvalidArgument(format!(
                "bricked volume needs {need} samples, got {}",
                data.len()
            )));
        }
        let b = side as usize;
        let brick_len = b * b * b;
        let n = bricks.count.as_usizevec3();
        let table =
            |dim: u32, count: u32, brick_stride: usize, local_stride: usize| -> Vec<usize> {
                (0..dim)
                    .map(|c| {
                        let (i, l) = bricks.split(c, count);
                        i as usize * brick_stride * brick_len + l as usize * local_stride
                    })
                    .collect()
            };
        let offset = [
            table(grid.dims.x, bricks.count.x, n.y * n.z, b * b),
            table(grid.dims.y, bricks.count.y, n.z, b),
            table(grid.dims.z, bricks.count.z, 1, 1),
        ];
        let d = grid.dims;
        let step = |n: u32, s: usize| if n > 1 { s } else { 0 };
        Ok(BrickedVolume {
            stride: [step(d.x, b * b), step(d.y, b), step(d.z, 1)],
            max_coord: grid.max_coord(),
            last: grid.last_cell(),
            offset,
            bricks,
            grid,
            data,
        })
    }

    /// Builds a bricked volume in RAM from a function of the voxel coordinate
    /// (padding past the grid's edge is 0, as in the file format).
    pub fn from_fn(grid: Grid, side: u32, mut f: impl FnMut(UVec3) -> S) -> Result<Self> {
        let bricks = BrickGrid::new(grid.dims, side.max(2));
        let len = bricks
            .total_len()
            .ok_or_else(|| Error::InvalidArgument("bricked volume too large".into()))?;
        let v = (0..len)
            .map(|i| bricks.voxel_at(i, grid.dims).map_or(S::zeroed(), &mut f))
            .collect();
        Self::new(grid, side, Storage::from_vec(v))
    }

    /// The brick decomposition.
    pub fn bricks(&self) -> &BrickGrid {
        &self.bricks
    }

    /// The samples in file order (bricks one after another).
    pub fn samples(&self) -> &[S] {
        self.data.as_slice()
    }

    /// Storage offsets of coordinates `c − 1 ..= c + 2` per axis (see
    /// [`load_wings`]). A voxel on a shared brick face may come from
    /// either brick: both copies hold the same value.
    #[inline(always)]
    fn stencil_offsets(&self, c: UVec3) -> [[usize; 4]; 3] {
        let row = |t: &[usize], c: u32| {
            let c = c as usize;
            [t[c - 1], t[c], t[c + 1], t[c + 2]]
        };
        [
            row(&self.offset[0], c.x),
            row(&self.offset[1], c.y),
            row(&self.offset[2], c.z),
        ]
    }

    #[inline(always)]
    fn index(&self, v: UVec3) -> usize {
        self.offset[0][v.x as usize] + self.offset[1][v.y as usize] + self.offset[2][v.z as usize]
    }
}

impl<S: Sample> Volume for BrickedVolume<S> {
    type Sample = S;

    fn grid(&self) -> &Grid {
        &self.grid
    }

    fn layout(&self) -> Layout {
        Layout::Bricked {
            side: self.bricks.side,
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
        for x in lo.x..=hi.x {
            for y in lo.y..=hi.y {
                let row = self.offset[0][x as usize] + self.offset[1][y as usize];
                // A z-run is contiguous while it stays in one brick.
                let mut z = lo.z;
                while z <= hi.z {
                    let (k, lz) = self.bricks.split(z, self.bricks.count.z);
                    let run_end = (hi.z).min(k * (self.bricks.side - 1) + self.bricks.side - 1);
                    let start = row + self.offset[2][z as usize];
                    let len = (run_end - z) as usize;
                    debug_assert_eq!(
                        start,
                        row + k as usize * self.bricks.brick_len() as usize + lz as usize
                    );
                    for &v in &data[start..=start + len] {
                        acc = (acc.0.min_of(v), acc.1.max_of(v));
                    }
                    z = run_end + 1;
                }
            }
        }
        acc
    }

    fn cell_value_ranges(&self, cell: u32, count: UVec3) -> Vec<(f32, f32)> {
        let data = self.data.as_slice();
        let b = self.bricks.side as usize;
        let step = b - 1;
        cell_value_ranges_by_rows(self.grid.dims, cell, count, |x, y, row: &mut [S]| {
            // The row's pieces, one per brick along z, overlap by one voxel.
            let base = self.offset[0][x as usize] + self.offset[1][y as usize];
            for (k, chunk) in row.chunks_mut(step).enumerate() {
                // Through the table: the grid's last plane may sit at the
                // far face of the last brick rather than open a new one.
                let start = base + self.offset[2][k * step];
                chunk.copy_from_slice(&data[start..start + chunk.len()]);
            }
        })
    }
}
