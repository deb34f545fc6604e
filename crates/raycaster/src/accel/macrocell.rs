//! The min/max grid over macrocells.

use crate::format::Progress;
use crate::sample::{Sample, SampleTypeVisitor};
use crate::volume::{AnyAddressing, AnyVolume, Volume, VolumeVisitor, cell_coord};
use glam::{IVec3, UVec3, Vec3};

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
    /// Per cell: true when every voxel of the cell's box and the voxels one
    /// beyond it (clamped to the grid) hold one single value. Inside such a
    /// cell every sample has that value and every central-difference
    /// gradient is zero, so a ray can composite a run of samples there
    /// without taking them, shaded or not. [`MacrocellGrid::from_ranges`]
    /// alone finds the cells whose 26 neighbours hold the cell's value
    /// (known from the ranges); the builds that read the voxels
    /// ([`MacrocellGrid::build`], [`MacrocellGrid::build_any`]) also find
    /// the constant cells next to a mixed one whose shell of voxels still
    /// holds their value ([`MacrocellGrid::find_uniform_shells`]).
    pub uniform: Vec<bool>,
    /// Whether `uniform` includes the cells found by their voxel shells
    /// ([`MacrocellGrid::find_uniform_shells`]); false for a grid made from
    /// ranges alone (e.g. combined from the parts of a distributed run),
    /// whose flags are right but fewer.
    pub shells_found: bool,
}

impl MacrocellGrid {
    /// Builds the grid for `volume` with cells of `cell` voxels a side (see
    /// [`Volume::cell_value_ranges`]).
    pub fn build<V: Volume>(volume: &V, cell: u32) -> Self {
        let cell = cell.max(1);
        let count = Self::count_for(volume.grid().dims, cell);
        let mut grid = Self::from_ranges(cell, count, volume.cell_value_ranges(cell, count));
        grid.find_uniform_shells(volume);
        grid
    }

    /// Builds the grid for a volume of any layout on the current rayon pool,
    /// telling `progress` the fraction done. A bricked volume is read brick
    /// by brick in storage order, once, and the pages of a mapped file are
    /// let go behind the pass (see [`Storage::release_pages`]), so building
    /// costs memory bandwidth, not resident memory; a linear one is read row
    /// by row ([`Volume::cell_value_ranges`]).
    ///
    /// [`Storage::release_pages`]: crate::storage::Storage::release_pages
    pub fn build_any(volume: &AnyVolume, cell: u32, progress: Option<&Progress>) -> Self {
        let cell = cell.max(1);
        let dims = volume.grid().dims;
        let count = Self::count_for(dims, cell);
        let report = |f: f32| {
            if let Some(p) = progress {
                p.report(f)
            }
        };
        report(0.0);
        let ranges = match volume.addressing() {
            AnyAddressing::Bricked(addr) => {
                struct Bricks<'a> {
                    volume: &'a AnyVolume,
                    addr: &'a crate::volume::Bricked,
                    cell: u32,
                    count: UVec3,
                    report: &'a (dyn Fn(f32) + Sync),
                }
                impl SampleTypeVisitor for Bricks<'_> {
                    type Output = Vec<(f32, f32)>;
                    fn visit<S: Sample>(self) -> Vec<(f32, f32)> {
                        let storage = self.volume.storage();
                        let size = std::mem::size_of::<S>();
                        crate::volume::cell_value_ranges_bricked(
                            storage.as_slice::<S>(),
                            self.addr.bricks(),
                            self.volume.grid().dims,
                            self.cell,
                            self.count,
                            &|samples, done, all| {
                                storage.release_pages(samples.start * size..samples.end * size);
                                (self.report)(done as f32 / all as f32);
                            },
                        )
                    }
                }
                let report = |f: f32| report(f);
                volume.sample_type().visit(Bricks {
                    volume,
                    addr,
                    cell,
                    count,
                    report: &report,
                })
            }
            AnyAddressing::Linear(_) => {
                struct Rows(u32, UVec3);
                impl VolumeVisitor for Rows {
                    type Output = Vec<(f32, f32)>;
                    fn visit<V: Volume>(self, v: &V) -> Vec<(f32, f32)> {
                        v.cell_value_ranges(self.0, self.1)
                    }
                }
                volume.visit(Rows(cell, count))
            }
        };
        let mut grid = Self::from_ranges(cell, count, ranges);
        grid.find_uniform_shells_any(volume);
        report(1.0);
        grid
    }

    /// [`MacrocellGrid::find_uniform_shells`] for a volume of any sample
    /// type and layout; a bricked volume's mapped pages are let go after
    /// (the shells read scattered voxels a frame may never need).
    pub fn find_uniform_shells_any(&mut self, volume: &AnyVolume) {
        struct Shells<'a>(&'a mut MacrocellGrid);
        impl VolumeVisitor for Shells<'_> {
            type Output = ();
            fn visit<V: Volume>(self, v: &V) {
                self.0.find_uniform_shells(v)
            }
        }
        volume.visit(Shells(self));
        if let AnyAddressing::Bricked(_) = volume.addressing() {
            volume.storage().release_pages(0..usize::MAX);
        }
    }

    /// Marks as uniform the constant cells that [`MacrocellGrid::from_ranges`]
    /// could not: those with a neighbour of another value or range, whose
    /// voxels one beyond the cell's box (the central differences of the
    /// cell's corners reach that far) all hold the cell's value anyway.
    /// That is the common case next to a surface that does not lie on the
    /// cell's face: shaded rays then composite the cell's samples in one run
    /// instead of marching them. Only the parts of the shell inside a
    /// neighbour that is not constant at the cell's value are read.
    pub fn find_uniform_shells<V: Volume>(&mut self, volume: &V) {
        use rayon::prelude::*;
        let (m, n) = (self.cell, self.count);
        let last = volume.grid().dims.saturating_sub(UVec3::ONE);
        let ranges = &self.ranges;
        // `self.index`, while `self.uniform` is borrowed for writing.
        let index = |c: UVec3| cell_index(n, c);
        // The part of the shell of `c` in direction `d` (−1, 0, 1 per axis)
        // holds `v` (an empty part does).
        let part_holds = |c: UVec3, d: [i32; 3], v: f32| -> bool {
            let (mut lo, mut hi) = (UVec3::ZERO, UVec3::ZERO);
            for a in 0..3 {
                let (c0, c1) = (c[a] * m, (c[a] * m + m).min(last[a]));
                (lo[a], hi[a]) = match d[a] {
                    -1 if c0 == 0 => return true,
                    -1 => (c0 - 1, c0 - 1),
                    0 => (c0, c1),
                    _ if c1 + 1 > last[a] => return true,
                    _ => (c1 + 1, c1 + 1),
                };
            }
            // Voxel by voxel, to stop at the first of another value (a
            // part crossed by a surface usually has one near its start).
            (lo.x..=hi.x).all(|x| {
                (lo.y..=hi.y)
                    .all(|y| (lo.z..=hi.z).all(|z| volume.voxel(UVec3::new(x, y, z)).to_f32() == v))
            })
        };
        let cells_per_x = (n.y * n.z) as usize;
        self.uniform
            .par_chunks_mut(cells_per_x.max(1))
            .enumerate()
            .for_each(|(x, plane)| {
                for (yz, u) in plane.iter_mut().enumerate() {
                    let c = UVec3::new(
                        x as u32,
                        (yz / n.z as usize) as u32,
                        (yz % n.z as usize) as u32,
                    );
                    let (v, hi) = ranges[index(c)];
                    if *u || v != hi {
                        continue;
                    }
                    *u = SHELL_PARTS.iter().all(|&d| {
                        let nb = c.as_ivec3() + IVec3::from_array(d);
                        let inside = nb.cmpge(IVec3::ZERO).all() && nb.cmplt(n.as_ivec3()).all();
                        // A neighbour constant at `v` holds its part of
                        // the shell (which lies in its box); outside the
                        // grid there is nothing to hold.
                        !inside || ranges[index(nb.as_uvec3())] == (v, v) || part_holds(c, d, v)
                    });
                }
            });
        self.shells_found = true;
    }

    /// Cells per axis of a grid of `cell`-voxel cells over `dims` voxels.
    pub fn count_for(dims: UVec3, cell: u32) -> UVec3 {
        let cell = cell.max(1);
        let n = |d: u32| if d <= 1 { 1 } else { (d - 1).div_ceil(cell) };
        UVec3::new(n(dims.x), n(dims.y), n(dims.z))
    }

    /// The grid of cells of side `cell`, `count` per axis, with value
    /// `ranges` (x slowest, z fastest); finds the uniform cells.
    pub fn from_ranges(cell: u32, count: UVec3, ranges: Vec<(f32, f32)>) -> Self {
        let uniform = uniform_cells(&ranges, count);
        MacrocellGrid {
            cell,
            count,
            ranges,
            uniform,
            shells_found: false,
        }
    }

    /// Index of cell `c`.
    #[inline(always)]
    pub fn index(&self, c: UVec3) -> usize {
        cell_index(self.count, c)
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

    /// The grid of cells `factor` times as large per axis: coarse cell `c`
    /// covers fine cells `c·factor .. c·factor + factor` (clamped), i.e.
    /// voxels `[c·m·factor, c·m·factor + m·factor]`, and its range is theirs
    /// combined, so it is exactly the grid [`MacrocellGrid::build`] makes
    /// with the coarse side.
    pub fn coarsened(&self, factor: u32) -> MacrocellGrid {
        let k = factor.max(1);
        if k == 1 {
            return self.clone();
        }
        let count = UVec3::new(
            self.count.x.div_ceil(k),
            self.count.y.div_ceil(k),
            self.count.z.div_ceil(k),
        );
        let mut ranges = Vec::with_capacity(count.element_product() as usize);
        for x in 0..count.x {
            for y in 0..count.y {
                for z in 0..count.z {
                    let lo = UVec3::new(x, y, z) * k;
                    let hi = (lo + UVec3::splat(k)).min(self.count);
                    let mut r = (f32::INFINITY, f32::NEG_INFINITY);
                    for fx in lo.x..hi.x {
                        for fy in lo.y..hi.y {
                            let row = self.index(UVec3::new(fx, fy, 0));
                            for &(a, b) in &self.ranges[row + lo.z as usize..row + hi.z as usize] {
                                r = (r.0.min(a), r.1.max(b));
                            }
                        }
                    }
                    ranges.push(r);
                }
            }
        }
        Self::from_ranges(self.cell * k, count, ranges)
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

/// Index of cell `c` in a grid of `count` cells (x slowest, z fastest).
#[inline(always)]
fn cell_index(count: UVec3, c: UVec3) -> usize {
    (c.x as usize * count.y as usize + c.y as usize) * count.z as usize + c.z as usize
}

/// The 26 directions from a cell to its neighbours, faces first: a cell
/// next to a surface fails on a face part, and then reads no other.
const SHELL_PARTS: [[i32; 3]; 26] = {
    let mut parts = [[0; 3]; 26];
    let mut n = 0;
    // Faces (one non-zero component), then edges (two), then corners.
    let mut nonzero = 1;
    while nonzero <= 3 {
        let mut k = 0;
        while k < 27 {
            let d = [k / 9 - 1, k / 3 % 3 - 1, k % 3 - 1];
            if (d[0] != 0) as i32 + (d[1] != 0) as i32 + (d[2] != 0) as i32 == nonzero {
                parts[n] = d;
                n += 1;
            }
            k += 1;
        }
        nonzero += 1;
    }
    parts
};

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
    use crate::volume::Grid;

    /// The brick-order pass of `build_any` against the row pass of `build`
    /// over many shapes: odd sizes, axes of one voxel, brick sides that do
    /// and do not divide the cells, cells larger than a brick, every sample
    /// type.
    #[test]
    fn brick_order_ranges_equal_the_row_pass() {
        let mut rng = fastrand::Rng::with_seed(11);
        let cases = [
            (UVec3::new(70, 45, 53), 16, 8),
            (UVec3::new(31, 16, 17), 16, 4),
            (UVec3::new(1, 9, 20), 5, 3),
            (UVec3::new(12, 1, 1), 2, 1),
            (UVec3::new(1, 1, 1), 4, 8),
            (UVec3::new(33, 29, 40), 4, 16),
            (UVec3::new(46, 46, 46), 16, 15),
        ];
        for (i, &(dims, side, cell)) in cases.iter().enumerate() {
            let grid = Grid::new(dims, Vec3::ONE);
            // Noise over a few flat regions, so that both mixed and uniform
            // cells occur.
            let seed = rng.u32(..);
            let value = move |v: UVec3| {
                let h = (v.x.wrapping_mul(73856093) ^ v.y.wrapping_mul(19349663))
                    ^ v.z.wrapping_mul(83492791)
                    ^ seed;
                if v.x < dims.x / 2 {
                    7
                } else {
                    (h % 200) as i32 - 60
                }
            };
            macro_rules! check {
                ($t:ty) => {{
                    let v = AnyVolume::bricked_from_fn(grid, side, |p| value(p) as $t).unwrap();
                    let want = v.visit(Build(cell));
                    let got = MacrocellGrid::build_any(&v, cell, None);
                    assert_eq!(got.count, want.count, "case {i}");
                    assert!(got.ranges == want.ranges, "case {i} {}", stringify!($t));
                    assert!(got.uniform == want.uniform, "case {i}");
                }};
            }
            check!(u8);
            check!(i16);
            check!(f32);
        }
        struct Build(u32);
        impl VolumeVisitor for Build {
            type Output = MacrocellGrid;
            fn visit<V: Volume>(self, v: &V) -> MacrocellGrid {
                MacrocellGrid::build(v, self.0)
            }
        }
    }

    #[test]
    fn build_any_reports_progress_to_completion() {
        let grid = Grid::new(UVec3::new(40, 20, 20), Vec3::ONE);
        let v = AnyVolume::bricked_from_fn(grid, 8, |p| p.x as u8).unwrap();
        let seen = std::sync::Arc::new(parking_lot::Mutex::new(Vec::new()));
        let s = seen.clone();
        let p = Progress::new(move |f| s.lock().push(f));
        MacrocellGrid::build_any(&v, 4, Some(&p));
        let seen = seen.lock();
        assert_eq!(seen.first(), Some(&0.0));
        assert_eq!(seen.last(), Some(&1.0));
        // One report per brick slab (6 of them) between the ends.
        assert_eq!(seen.len(), 6 + 2, "{seen:?}");
    }

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

    /// The builds that read the voxels mark a cell uniform exactly when
    /// every voxel of its box and one beyond it (clamped to the grid) holds
    /// one value, checked voxel by voxel, on both layouts; and they find
    /// cells next to a mixed one that the ranges alone cannot.
    #[test]
    fn uniform_shells_match_brute_force() {
        let mut rng = fastrand::Rng::with_seed(9);
        let mut beyond_ranges = 0;
        for case in 0..40 {
            let dims = UVec3::new(rng.u32(1..30), rng.u32(1..30), rng.u32(1..30));
            let cell = rng.u32(1..6);
            let grid = Grid::new(dims, Vec3::ONE);
            // Boxes of two values on a third, with edges anywhere (on a
            // cell's face, one voxel from it, inside it), and a few lone
            // voxels of another value.
            let boxes: Vec<(UVec3, UVec3, u8)> = (0..3)
                .map(|_| {
                    let lo = UVec3::new(rng.u32(0..dims.x), rng.u32(0..dims.y), rng.u32(0..dims.z));
                    let hi = lo + UVec3::new(rng.u32(1..20), rng.u32(1..20), rng.u32(1..20));
                    (lo, hi, rng.u8(1..3))
                })
                .collect();
            let specks: Vec<UVec3> = (0..2)
                .map(|_| UVec3::new(rng.u32(0..dims.x), rng.u32(0..dims.y), rng.u32(0..dims.z)))
                .collect();
            let value = |p: UVec3| -> u8 {
                if specks.contains(&p) {
                    return 9;
                }
                boxes
                    .iter()
                    .find(|(lo, hi, _)| p.cmpge(*lo).all() && p.cmplt(*hi).all())
                    .map_or(0, |b| b.2)
            };
            let linear = AnyVolume::from_fn(grid, value);
            let bricked = AnyVolume::bricked_from_fn(grid, rng.u32(2..9), value).unwrap();
            let got = MacrocellGrid::build_any(&linear, cell, None);
            let n = got.count;
            let coarse = MacrocellGrid::from_ranges(cell, n, got.ranges.clone());
            for x in 0..n.x {
                for y in 0..n.y {
                    for z in 0..n.z {
                        let c = UVec3::new(x, y, z);
                        let lo = (c * cell).saturating_sub(UVec3::ONE);
                        let hi = (c * cell + UVec3::splat(cell + 1)).min(dims - UVec3::ONE);
                        let first = value(lo);
                        let mut want = true;
                        for vx in lo.x..=hi.x {
                            for vy in lo.y..=hi.y {
                                for vz in lo.z..=hi.z {
                                    want &= value(UVec3::new(vx, vy, vz)) == first;
                                }
                            }
                        }
                        let i = got.index(c);
                        assert_eq!(
                            got.uniform[i], want,
                            "case {case}: cell {c} of {n}, side {cell}"
                        );
                        beyond_ranges += (want && !coarse.uniform[i]) as usize;
                    }
                }
            }
            let from_bricks = MacrocellGrid::build_any(&bricked, cell, None);
            assert!(from_bricks.uniform == got.uniform, "case {case}: bricked");
            struct Build(u32);
            impl VolumeVisitor for Build {
                type Output = MacrocellGrid;
                fn visit<V: Volume>(self, v: &V) -> MacrocellGrid {
                    MacrocellGrid::build(v, self.0)
                }
            }
            assert!(
                linear.visit(Build(cell)).uniform == got.uniform,
                "case {case}: build"
            );
        }
        // The shells found cells the neighbours' ranges could not.
        assert!(beyond_ranges > 100, "{beyond_ranges}");
    }
}
