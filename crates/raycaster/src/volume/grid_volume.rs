//! [`GridVolume`]: the one volume type the integrators sample, generic over
//! its sample type and its [`Addressing`].

use glam::{UVec3, Vec3};

use super::addressing::{Addressing, rows_last};
use super::ranges::{cell_value_ranges_by_rows, fold_range};
use super::{CellPos, Corners, Grid, Volume, Wings, load_corners, load_wings, split_coord};
use crate::sample::Sample;

/// A typed view of a volume's samples: the grid, the sample array and its
/// addressing, with the constants of the hot loop copied in. Cheap to make;
/// [`AnyVolume::visit`](super::AnyVolume::visit) makes one per frame.
#[derive(Debug, Clone, Copy)]
pub struct GridVolume<'a, S: Sample, A: Addressing> {
    grid: &'a Grid,
    data: &'a [S],
    addr: &'a A,
    stride: [usize; 3],
    max_coord: Vec3,
    last: UVec3,
}

impl<'a, S: Sample, A: Addressing> GridVolume<'a, S, A> {
    /// A view of `data` laid out by `addr` on `grid`. `data` must hold
    /// exactly `addr.storage_len()` samples (checked: every later index is
    /// bounded by it).
    pub fn new(grid: &'a Grid, data: &'a [S], addr: &'a A) -> Self {
        assert_eq!(
            data.len(),
            addr.storage_len(),
            "storage and addressing disagree"
        );
        GridVolume {
            grid,
            data,
            addr,
            stride: addr.neighbour_strides(),
            max_coord: grid.max_coord(),
            last: grid.last_cell(),
        }
    }

    /// The samples in storage order.
    pub fn samples(&self) -> &'a [S] {
        self.data
    }

    /// The addressing.
    pub fn addressing(&self) -> &'a A {
        self.addr
    }

    /// [`Addressing::stencil_offsets`] for a cell at the grid's faces, with
    /// each coordinate `c − 1 ..= c + 2` clamped into the grid (see
    /// [`Volume::wings`]). Out of line: only face cells come here.
    #[inline(never)]
    fn clamped_stencil_offsets(&self, c: UVec3) -> [[usize; 4]; 3] {
        let last = self.grid.dims - UVec3::ONE;
        std::array::from_fn(|a| {
            std::array::from_fn(|i| {
                let coord = (c[a] + i as u32).saturating_sub(1).min(last[a]);
                self.addr.axis_offset(a, coord)
            })
        })
    }
}

impl<S: Sample, A: Addressing> Volume for GridVolume<'_, S, A> {
    type Sample = S;

    fn grid(&self) -> &Grid {
        self.grid
    }

    fn voxel(&self, v: UVec3) -> S {
        assert!(v.cmplt(self.grid.dims).all(), "voxel {v} outside the grid");
        self.data[self.addr.index(v)]
    }

    #[inline(always)]
    fn locate(&self, p: Vec3) -> CellPos {
        let (x, fx) = split_coord(p.x, self.max_coord.x, self.last.x);
        let (y, fy) = split_coord(p.y, self.max_coord.y, self.last.y);
        let (z, fz) = split_coord(p.z, self.max_coord.z, self.last.z);
        CellPos {
            cell: UVec3::new(x, y, z),
            frac: Vec3::new(fx, fy, fz),
        }
    }

    #[inline(always)]
    fn corners(&self, cell: UVec3) -> Corners {
        load_corners(self.data, self.addr.index(cell), self.stride)
    }

    #[inline(always)]
    fn prefetch(&self, p: Vec3) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let base = self.addr.index(self.locate(p).cell);
            let [sx, sy, _] = self.stride;
            for i in [base, base + sy, base + sx, base + sx + sy] {
                // `wrapping_add` keeps the address arithmetic defined even
                // past the end (clamped cells stay inside, but the hint must
                // never be a reason for undefined behaviour).
                let at = self.data.as_ptr().wrapping_add(i).cast::<i8>();
                // SAFETY: a prefetch is a hint that never faults and reads
                // nothing the program sees, whatever the address.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(at) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = p;
    }

    #[inline(always)]
    fn prefetch_wings(&self, p: Vec3) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let cell = self.locate(p).cell;
            if !super::stencil_inside(cell, self.grid.dims) {
                return;
            }
            let [xo, yo, zo] = self.addr.stencil_offsets(cell);
            // The rows one before and two after the cell across x and y (its
            // own rows hold the z wings, and `prefetch` asks for them).
            for (a, b) in [
                (0, 1),
                (0, 2),
                (3, 1),
                (3, 2),
                (1, 0),
                (2, 0),
                (1, 3),
                (2, 3),
            ] {
                let at = self.data.as_ptr().wrapping_add(xo[a] + yo[b] + zo[1]);
                // SAFETY: a prefetch is a hint that never faults and reads
                // nothing the program sees, whatever the address.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(at.cast::<i8>()) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = p;
    }

    #[inline(always)]
    fn wings(&self, cell: UVec3) -> Wings {
        let [xo, yo, zo] = if super::stencil_inside(cell, self.grid.dims) {
            self.addr.stencil_offsets(cell)
        } else {
            self.clamped_stencil_offsets(cell)
        };
        load_wings(self.data, xo, yo, zo)
    }

    fn value_range(&self, lo: UVec3, hi: UVec3) -> (S, S) {
        let hi = hi.min(self.grid.dims - UVec3::ONE);
        let mut acc = (S::HIGHEST, S::LOWEST);
        if lo.cmpgt(hi).any() {
            return acc; // an empty box
        }
        let axis = self.addr.row_axis();
        let outer = 2 - axis; // x when rows run along z, z when along x
        let mut at = UVec3::ZERO;
        for a in lo[outer]..=hi[outer] {
            for b in lo.y..=hi.y {
                at[outer] = a;
                at.y = b;
                self.addr.row_runs(at, lo[axis], hi[axis], |run, _| {
                    let (x, y) = fold_range(self.data[run].iter().copied());
                    acc = (acc.0.min_of(x), acc.1.max_of(y));
                });
            }
        }
        acc
    }

    fn cell_value_ranges(&self, cell: u32, count: UVec3) -> Vec<(f32, f32)> {
        // Stream whole rows along the stored row axis, treating the volume
        // as one with that axis last, then put the cells back in x, y, z
        // order.
        let axis = self.addr.row_axis();
        let dims = self.grid.dims;
        let len = dims[axis];
        let fill = |a: u32, y: u32, row: &mut [S]| {
            let mut at = UVec3::new(0, y, 0);
            at[2 - axis] = a;
            self.addr.row_runs(at, 0, len - 1, |run, first| {
                let first = first as usize;
                row[first..first + run.len()].copy_from_slice(&self.data[run]);
            });
        };
        let ranges =
            cell_value_ranges_by_rows(rows_last(dims, axis), cell, rows_last(count, axis), fill);
        if axis == 2 {
            return ranges;
        }
        let (cx, cy, cz) = (count.x as usize, count.y as usize, count.z as usize);
        let mut out = vec![(0.0, 0.0); ranges.len()];
        for (i, r) in ranges.into_iter().enumerate() {
            // `ranges` is indexed (z, y, x) with x fastest.
            let (z, y, x) = (i / (cy * cx), i / cx % cy, i % cx);
            out[(x * cy + y) * cz + z] = r;
        }
        out
    }
}
