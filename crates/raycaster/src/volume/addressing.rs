//! Addressing: how a voxel coordinate becomes an index into a volume's
//! sample array.
//!
//! A volume is one generic type, [`GridVolume`](super::GridVolume), over its
//! sample type and its [`Addressing`]. The addressings here are
//! [`Linear`] (one array, z or x fastest) and [`Bricked`] (cubic bricks
//! that overlap by one voxel plane, so the 8 samples of any trilinear lookup
//! lie in one brick). Each reduces a trilinear lookup to "a base index and
//! three strides", so the hot loop is the same code for both.

use std::ops::Range;

use glam::{UVec3, Vec3Swizzles};

use crate::error::{Error, Result};

/// How a volume's samples are ordered in memory (the run-time description of
/// its [`Addressing`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// One array, z fastest (`index = (x·Y + y)·Z + z`).
    Linear,
    /// One array, x fastest (`index = (z·Y + y)·X + x`).
    LinearXFast,
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
            Layout::LinearXFast => f.write_str("linear (x fastest)"),
            Layout::Bricked { side } => write!(f, "bricked (B = {side})"),
        }
    }
}

/// Which axis changes fastest in a linear array of samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum AxisOrder {
    /// `index(x, y, z) = (x·Y + y)·Z + z`: the `.vol` order.
    #[default]
    ZFast,
    /// `index(x, y, z) = (z·Y + y)·X + x`: the order of NRRD, NIfTI, DICOM
    /// and most published raw files.
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

/// What the generic volume needs to know about a memory layout.
///
/// Rows: every layout stores the voxels of a row along one axis
/// ([`Addressing::row_axis`]) in contiguous runs, which the value-range
/// passes stream through ([`Addressing::row_runs`]).
pub trait Addressing: Send + Sync + std::fmt::Debug + 'static {
    /// The run-time description of this layout.
    fn layout(&self) -> Layout;

    /// Number of samples the storage must hold.
    fn storage_len(&self) -> usize;

    /// Storage index of voxel `v` (inside the grid).
    fn index(&self, v: UVec3) -> usize;

    /// Index steps from a cell's lower corner to its x, y and z neighbours
    /// (0 along an axis of size 1): the same for every cell.
    fn neighbour_strides(&self) -> [usize; 3];

    /// Storage offsets of coordinates `c − 1 ..= c + 2` per axis, for the
    /// gradient stencil around cell `c` (index = x + y + z offsets). Only
    /// called when the stencil is inside the grid.
    fn stencil_offsets(&self, c: UVec3) -> [[usize; 4]; 3];

    /// Storage offset of coordinate `coord` (inside the grid) along `axis`:
    /// [`Addressing::index`] is the sum of the three axes' offsets.
    fn axis_offset(&self, axis: usize, coord: u32) -> usize;

    /// The axis (0 = x or 2 = z) along which rows are stored in runs.
    fn row_axis(&self) -> usize;

    /// Calls `run(storage range, first coordinate)` for contiguous runs that
    /// together hold, in order, the voxels `lo..=hi` along the row axis of
    /// the row through voxel `at` (whose row-axis coordinate is ignored).
    fn row_runs(&self, at: UVec3, lo: u32, hi: u32, run: impl FnMut(Range<usize>, u32));
}

/// One array of samples in either [`AxisOrder`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Linear {
    order: AxisOrder,
    len: usize,
    /// Index steps along x, y and z.
    step: [usize; 3],
    /// Index steps to the x, y and z neighbours (0 along an axis of size 1).
    neighbour: [usize; 3],
}

impl Linear {
    /// The addressing of a `dims` grid stored in `order`; `None` when the
    /// sample count overflows `usize`.
    pub fn new(dims: UVec3, order: AxisOrder) -> Option<Self> {
        let len = (dims.x as usize)
            .checked_mul(dims.y as usize)?
            .checked_mul(dims.z as usize)?;
        let step = order.strides(dims);
        let neighbour = |n: u32, s: usize| if n > 1 { s } else { 0 };
        Some(Linear {
            order,
            len,
            step,
            neighbour: [
                neighbour(dims.x, step[0]),
                neighbour(dims.y, step[1]),
                neighbour(dims.z, step[2]),
            ],
        })
    }

    /// Which axis changes fastest.
    pub fn order(&self) -> AxisOrder {
        self.order
    }
}

impl Addressing for Linear {
    fn layout(&self) -> Layout {
        match self.order {
            AxisOrder::ZFast => Layout::Linear,
            AxisOrder::XFast => Layout::LinearXFast,
        }
    }

    fn storage_len(&self) -> usize {
        self.len
    }

    #[inline(always)]
    fn index(&self, v: UVec3) -> usize {
        v.x as usize * self.step[0] + v.y as usize * self.step[1] + v.z as usize * self.step[2]
    }

    #[inline(always)]
    fn axis_offset(&self, axis: usize, coord: u32) -> usize {
        coord as usize * self.step[axis]
    }

    #[inline(always)]
    fn neighbour_strides(&self) -> [usize; 3] {
        self.neighbour
    }

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

    fn row_axis(&self) -> usize {
        match self.order {
            AxisOrder::ZFast => 2,
            AxisOrder::XFast => 0,
        }
    }

    #[inline]
    fn row_runs(&self, at: UVec3, lo: u32, hi: u32, mut run: impl FnMut(Range<usize>, u32)) {
        let mut start = at;
        start[self.row_axis()] = lo;
        let i = self.index(start);
        run(i..i + (hi - lo) as usize + 1, lo);
    }
}

/// How a grid is cut into overlapping bricks of `side`³ samples.
///
/// Brick `(i, j, k)` holds voxels `[i·(B−1), i·(B−1) + B − 1]` per axis; bricks
/// are stored with i slowest and k fastest, samples inside a brick in linear
/// order (local z fastest). Voxels past the grid's edge in the last bricks
/// are padding.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BrickGrid {
    /// Samples along a brick's side, B (2..=255).
    pub side: u32,
    /// Bricks per axis.
    pub count: UVec3,
}

impl BrickGrid {
    /// The brick grid for `dims` with bricks of side `side`, which must be
    /// in 2..=255.
    pub fn new(dims: UVec3, side: u32) -> Result<Self> {
        if !(2..=255).contains(&side) {
            return Err(Error::InvalidVolume(format!(
                "brick side {side} outside 2..=255"
            )));
        }
        let n = |d: u32| {
            if d <= 1 {
                1
            } else {
                (d - 1).div_ceil(side - 1)
            }
        };
        Ok(BrickGrid {
            side,
            count: UVec3::new(n(dims.x), n(dims.y), n(dims.z)),
        })
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

/// Samples stored brick by brick (see [`BrickGrid`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bricked {
    bricks: BrickGrid,
    len: usize,
    /// Per axis, the storage offset contributed by a voxel coordinate (brick
    /// offset plus local offset), so an index is three table lookups and two
    /// additions instead of three divisions.
    offset: [Vec<usize>; 3],
    /// Per z, the last z of the contiguous run it starts (the end of its
    /// brick along z), so walking a row needs no division.
    run_end: Vec<u32>,
    neighbour: [usize; 3],
}

impl Bricked {
    /// The addressing of a `dims` grid in bricks of `side` samples.
    pub fn new(dims: UVec3, side: u32) -> Result<Self> {
        let bricks = BrickGrid::new(dims, side)?;
        let len = bricks
            .total_len()
            .and_then(|n| usize::try_from(n).ok())
            .ok_or_else(|| {
                Error::InvalidVolume(format!("{dims} in bricks of {side}: too large"))
            })?;
        let b = side as usize;
        let brick_len = b * b * b;
        let n = bricks.count.as_usizevec3();
        let table = |dim: u32, count: u32, brick_stride: usize, local_stride: usize| {
            (0..dim)
                .map(|c| {
                    let (i, l) = bricks.split(c, count);
                    i as usize * brick_stride * brick_len + l as usize * local_stride
                })
                .collect()
        };
        let step = |n: u32, s: usize| if n > 1 { s } else { 0 };
        let run_end = (0..dims.z)
            .map(|z| {
                let (k, _) = bricks.split(z, bricks.count.z);
                (k * (side - 1) + side - 1).min(dims.z - 1)
            })
            .collect();
        Ok(Bricked {
            run_end,
            offset: [
                table(dims.x, bricks.count.x, n.y * n.z, b * b),
                table(dims.y, bricks.count.y, n.z, b),
                table(dims.z, bricks.count.z, 1, 1),
            ],
            neighbour: [step(dims.x, b * b), step(dims.y, b), step(dims.z, 1)],
            bricks,
            len,
        })
    }

    /// The brick decomposition.
    pub fn bricks(&self) -> &BrickGrid {
        &self.bricks
    }
}

impl Addressing for Bricked {
    fn layout(&self) -> Layout {
        Layout::Bricked {
            side: self.bricks.side,
        }
    }

    fn storage_len(&self) -> usize {
        self.len
    }

    #[inline(always)]
    fn index(&self, v: UVec3) -> usize {
        self.offset[0][v.x as usize] + self.offset[1][v.y as usize] + self.offset[2][v.z as usize]
    }

    #[inline(always)]
    fn axis_offset(&self, axis: usize, coord: u32) -> usize {
        self.offset[axis][coord as usize]
    }

    #[inline(always)]
    fn neighbour_strides(&self) -> [usize; 3] {
        self.neighbour
    }

    /// A voxel on a shared brick face may come from either brick: both
    /// copies hold the same value.
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

    fn row_axis(&self) -> usize {
        2
    }

    /// Rows along z are contiguous while they stay in one brick; the runs
    /// of neighbouring bricks overlap by one voxel, of which each run below
    /// starts at the first voxel not yet given.
    #[inline]
    fn row_runs(&self, at: UVec3, lo: u32, hi: u32, mut run: impl FnMut(Range<usize>, u32)) {
        let base = self.offset[0][at.x as usize] + self.offset[1][at.y as usize];
        let mut z = lo;
        while z <= hi {
            // Through the tables: the grid's last plane may sit at the far
            // face of the last brick rather than open a new one.
            let end = hi.min(self.run_end[z as usize]);
            let start = base + self.offset[2][z as usize];
            run(start..start + (end - z) as usize + 1, z);
            z = end + 1;
        }
    }
}

/// The addressing of a volume whose layout is known only at run time.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum AnyAddressing {
    /// [`Linear`].
    Linear(Linear),
    /// [`Bricked`].
    Bricked(Bricked),
}

impl AnyAddressing {
    /// The run-time description.
    pub fn layout(&self) -> Layout {
        match self {
            AnyAddressing::Linear(a) => a.layout(),
            AnyAddressing::Bricked(a) => a.layout(),
        }
    }

    /// Samples the storage must hold.
    pub fn storage_len(&self) -> usize {
        match self {
            AnyAddressing::Linear(a) => a.storage_len(),
            AnyAddressing::Bricked(a) => a.storage_len(),
        }
    }
}

/// `dims` with the row axis moved to z: the value-range pass always walks
/// rows along its last axis.
pub(crate) fn rows_last(dims: UVec3, row_axis: usize) -> UVec3 {
    if row_axis == 0 { dims.zyx() } else { dims }
}
