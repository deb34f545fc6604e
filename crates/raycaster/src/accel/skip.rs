//! Per-transfer-function occupancy with a distance field for skipping.
//!
//! Correctness needs only that every box handed out as empty contains no
//! occupied macrocell; the tests check that against brute force.

#[cfg(target_arch = "x86_64")]
use glam::Vec3A;
use std::sync::OnceLock;

use glam::{UVec3, Vec3};

use super::{IsoCells, MacrocellGrid};
use crate::clip::ClipRegion;
use crate::geometry::Aabb;
use crate::volume::AnyVolume;
#[cfg(any(test, not(target_arch = "x86_64")))]
use crate::volume::cell_coord;

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
        /// Its coordinates in the macrocell grid.
        coords: UVec3,
    },
}

/// [`SkipGrid::cell_kind`]'s answer.
#[derive(Debug, Clone, Copy)]
pub(crate) enum CellKind {
    /// The cell may contribute.
    Occupied,
    /// The cell contributes nothing, but a neighbour may.
    EmptyAlone,
    /// Nothing in this box around the cell (voxel space) contributes.
    EmptyWithin(Aabb),
}

/// Which macrocells may contribute, and how far empty space extends.
///
/// Two levels: occupancy per macrocell, and a distance field over *coarse*
/// cells of 2×2×2 macrocells, holding for each coarse cell 0 when any of its
/// macrocells is occupied, otherwise the Chebyshev distance (in coarse cells,
/// capped at 255) to the nearest coarse cell that is. Occupancy stays fine,
/// the distance field costs an eighth as much to build. Rays jump by a
/// third level, built per direction octant on first use
/// ([`SkipGrid::ahead`]): the empty cube ahead of each coarse cell.
#[derive(Debug, Clone)]
pub struct SkipGrid {
    cell: f32,
    inv_cell: f32,
    count: UVec3,
    /// Occupancy per macrocell, a bit each (bit `i % 64` of word `i / 64`
    /// for the macrocell of index `i`): rays classify a macrocell at
    /// every step of their walk, and a byte per macrocell (8 MB at 800³)
    /// missed the caches where a bit (1 MB) mostly stays in L2.
    occupied: Vec<u64>,
    coarse_count: UVec3,
    distance: Vec<u8>,
    /// Per direction octant (bit `a` set: moving towards lower coordinates
    /// on axis `a`), per coarse cell: how many coarse cells a side the
    /// empty cube has that has this cell as its corner and extends in that
    /// octant's direction (0 when the cell is occupied). A ray leaves only
    /// through the faces ahead of it, and ahead of a ray that has just
    /// passed an object lies far more empty space than around it, which
    /// is all `distance` knows. Built on first use: a frame's rays mostly
    /// share one or a few octants.
    ahead: [OnceLock<Vec<u8>>; 8],
    /// For an iso value, the fine level: which interpolation cells of the
    /// occupied macrocells straddle it.
    iso_cells: Option<IsoCells>,
    /// The occupied cells as runs along z ([`SkipGrid::occupied_runs`]),
    /// listed on first use.
    runs: OnceLock<Vec<(UVec3, u32)>>,
    /// The occupied cells on the surface of the occupied region as runs
    /// along z ([`SkipGrid::surface_runs`]), listed on first use.
    surface_runs: OnceLock<Vec<(UVec3, u32)>>,
    /// Per 64 cells (as `occupied`), the surface cells' bits
    /// ([`SkipGrid::surface_runs`]), found on first use.
    surface: OnceLock<Vec<u64>>,
    /// [`SkipGrid::visible_runs`] of the surface runs and of the occupied
    /// ones, each found on first use.
    visible_surface: OnceLock<NarrowedRuns>,
    visible_occupied: OnceLock<NarrowedRuns>,
    /// Set by the first DVR frame that draws this grid's proxy runs
    /// ([`SkipGrid::proxy_drawn_before`]).
    proxy_drawn: OnceLock<()>,
    /// Per 64 cells (as `occupied`), two words of flags of the occupied
    /// ones: uniform, and flat under the TF ([`SkipGrid::with_steady`]);
    /// empty when not built. A DVR ray asks for both at every occupied
    /// cell it meets, and reading them here, a cache line for 64 cells,
    /// costs less than the macrocell grid's value ranges (8 bytes a cell)
    /// and uniform flags (a byte) do.
    steady: Vec<[u64; 2]>,
}

/// Runs of cells along z (first cell, length) and, per run, how far its
/// box is narrowed (voxels: from its lower corner up and from its upper
/// corner down, per axis).
type NarrowedRuns = (Vec<(UVec3, u32)>, Vec<[u8; 6]>);

/// The bounding box of `b` (if any) and `[lo, hi]`.
fn union(b: Option<[UVec3; 2]>, [lo, hi]: [UVec3; 2]) -> [UVec3; 2] {
    match b {
        Some([a, z]) => [a.min(lo), z.max(hi)],
        None => [lo, hi],
    }
}

/// The most cells in one of [`SkipGrid::occupied_runs`]: a run is one box
/// to the proxy depths, which bound every ray meeting it by the box's
/// nearest point, so a long box starts the rays that meet its far end
/// early.
const MAX_RUN: u32 = 4;

impl SkipGrid {
    /// Marks the cells for which `occupied(min, max)` holds and computes the
    /// distance field of the rest.
    pub fn build(cells: &MacrocellGrid, occupied: impl Fn(f32, f32) -> bool + Sync) -> Self {
        Self::build_clipped(cells, occupied, None)
    }

    /// [`SkipGrid::build`] where, besides, every cell that holds no point
    /// `clip` keeps is empty: clipped space is skipped like transparent
    /// space (and the object renderer culls bricks made only of it).
    pub fn build_clipped(
        cells: &MacrocellGrid,
        occupied: impl Fn(f32, f32) -> bool + Sync,
        clip: Option<&ClipRegion>,
    ) -> Self {
        use rayon::prelude::*;
        let n = cells.count;
        let (ny, nz) = (n.y as usize, n.z as usize);
        let slab = ny * nz;
        // One x-slab of cells per task, on the current rayon pool: a TF
        // edit in the viewer waits for this (8 M cells at 800³).
        let mut occ = vec![false; cells.ranges.len()];
        occ.par_chunks_mut(slab)
            .zip(cells.ranges.par_chunks(slab))
            .enumerate()
            .for_each(|(x, (occ, ranges))| {
                // Neighbouring cells often share a range (all-empty space
                // above all), so remember the last answer.
                let mut last = (f32::NAN, f32::NAN, false);
                for (o, &(lo, hi)) in occ.iter_mut().zip(ranges) {
                    if lo != last.0 || hi != last.1 {
                        last = (lo, hi, occupied(lo, hi));
                    }
                    *o = last.2;
                }
                if let Some(clip) = clip {
                    let side = cells.cell as f32;
                    for (i, o) in occ.iter_mut().enumerate().filter(|(_, o)| **o) {
                        let c = UVec3::new(x as u32, (i / nz) as u32, (i % nz) as u32);
                        let lo = c.as_vec3() * side;
                        *o = clip.may_hold(lo, lo + Vec3::splat(side));
                    }
                }
            });
        let occupied = occ;
        // The coarse level: a coarse cell (2×2×2 cells) is occupied when
        // any of its cells is; each coarse x-slab is written by one task
        // from the two cell slabs it covers.
        let coarse_count = (n + UVec3::ONE) / 2;
        let (cy, cz) = (coarse_count.y as usize, coarse_count.z as usize);
        let mut distance = vec![u8::MAX; coarse_count.x as usize * cy * cz];
        distance
            .par_chunks_mut(cy * cz)
            .enumerate()
            .for_each(|(cx, coarse)| {
                for x in (2 * cx..2 * cx + 2).filter(|&x| x < n.x as usize) {
                    for y in 0..ny {
                        let row = &occupied[(x * ny + y) * nz..][..nz];
                        let out = &mut coarse[(y / 2) * cz..][..cz];
                        for (z, _) in row.iter().enumerate().filter(|(_, o)| **o) {
                            out[z / 2] = 0;
                        }
                    }
                }
            });
        chessboard_distance(&mut distance, coarse_count);
        let occupied = occupied.par_chunks(64).map(pack_bits).collect();
        SkipGrid {
            cell: cells.cell as f32,
            inv_cell: 1.0 / cells.cell as f32,
            count: n,
            occupied,
            coarse_count,
            distance,
            ahead: Default::default(),
            iso_cells: None,
            runs: OnceLock::new(),
            surface_runs: OnceLock::new(),
            surface: OnceLock::new(),
            visible_surface: OnceLock::new(),
            visible_occupied: OnceLock::new(),
            proxy_drawn: OnceLock::new(),
            steady: Vec::new(),
        }
    }

    /// The two-level occupancy of iso value `iso`: the macrocells whose
    /// value range holds it, and in those the interpolation cells whose
    /// corners straddle it ([`IsoCells`]).
    pub fn for_iso(volume: &AnyVolume, cells: &MacrocellGrid, iso: f32) -> Self {
        Self::for_iso_clipped(volume, cells, iso, None)
    }

    /// [`SkipGrid::for_iso`] with the cells outside `clip` empty (see
    /// [`SkipGrid::build_clipped`]).
    pub fn for_iso_clipped(
        volume: &AnyVolume,
        cells: &MacrocellGrid,
        iso: f32,
        clip: Option<&ClipRegion>,
    ) -> Self {
        let mut grid = Self::build_clipped(cells, |lo, hi| lo <= iso && iso <= hi, clip);
        grid.iso_cells = Some(IsoCells::build(volume, cells, &grid, iso));
        grid
    }

    /// The fine level, when built ([`SkipGrid::for_iso`]).
    #[inline(always)]
    pub fn iso_cells(&self) -> Option<&IsoCells> {
        self.iso_cells.as_ref()
    }

    /// Whether the cell with index `i` in the macrocell grid is occupied.
    #[inline(always)]
    pub fn is_occupied_index(&self, i: usize) -> bool {
        self.occupied[i >> 6] >> (i & 63) & 1 != 0
    }

    /// A grid where every cell is occupied (skipping disabled).
    pub fn all_occupied(cells: &MacrocellGrid) -> Self {
        Self::build(cells, |_, _| true)
    }

    /// Cells per axis.
    pub fn count(&self) -> UVec3 {
        self.count
    }

    /// This grid with the flags [`SkipGrid::steady`] reads, for each
    /// occupied cell of `cells`: whether it is uniform
    /// ([`MacrocellGrid::uniform`]) and whether `flat(min, max)` holds (the
    /// TF maps its value range to one colour).
    pub fn with_steady(
        mut self,
        cells: &MacrocellGrid,
        flat: impl Fn(f32, f32) -> bool + Sync,
    ) -> Self {
        use rayon::prelude::*;
        self.steady = self
            .occupied
            .par_iter()
            .enumerate()
            .map(|(w, &occupied)| {
                let mut out = [0u64; 2];
                let mut bits = occupied;
                while bits != 0 {
                    let b = bits.trailing_zeros();
                    bits &= bits - 1;
                    let i = w * 64 + b as usize;
                    let (lo, hi) = cells.ranges[i];
                    out[0] |= (cells.uniform[i] as u64) << b;
                    out[1] |= (flat(lo, hi) as u64) << b;
                }
                out
            })
            .collect();
        self
    }

    /// For the occupied cell of index `i`: whether it is uniform and
    /// whether the TF maps its value range to one colour (both false where
    /// [`SkipGrid::with_steady`] did not build them).
    #[inline(always)]
    pub fn steady(&self, i: usize) -> (bool, bool) {
        match self.steady.get(i >> 6) {
            Some(&[uniform, flat]) => (uniform >> (i & 63) & 1 != 0, flat >> (i & 63) & 1 != 0),
            None => (false, false),
        }
    }

    /// The occupied cells as runs along z: the first cell of each run and
    /// how many cells it holds (consecutive along z in one row, at most
    /// `MAX_RUN`), row by row in index order; listed on first use, then
    /// kept. The proxy depths of a DVR frame draw them as boxes.
    pub fn occupied_runs(&self) -> &[(UVec3, u32)] {
        self.runs.get_or_init(|| self.list_occupied_runs())
    }

    /// [`SkipGrid::occupied_runs`] without the cells inside the occupied
    /// region: those off the grid's faces whose 6 face neighbours are all
    /// occupied. A ray from outside the grid meets the occupied cells first
    /// at a point `q` where it comes from outside the grid or from an empty
    /// cell. Of the cells whose (closed) boxes hold `q`, stepping face to
    /// face from an occupied one to that empty one (or out of the grid)
    /// leaves some occupied cell through a face into empty space or out of
    /// the grid: a surface cell, which holds `q`. So for eyes outside the
    /// grid, the nearest entry into these cells' boxes along a ray is the
    /// nearest entry into an occupied one. Listed on first use, then kept.
    pub fn surface_runs(&self) -> &[(UVec3, u32)] {
        self.surface_runs.get_or_init(|| {
            let mut out = Vec::new();
            super::bit_runs(
                self.surface_words(),
                self.count.z as usize,
                MAX_RUN,
                |first, len| out.push((self.cell_at(first), len)),
            );
            out
        })
    }

    /// The runs a DVR frame's proxy draws: [`SkipGrid::surface_runs`] for
    /// an eye outside the grid (`surface`), else
    /// [`SkipGrid::occupied_runs`].
    pub fn proxy_runs(&self, surface: bool) -> &[(UVec3, u32)] {
        if surface {
            self.surface_runs()
        } else {
            self.occupied_runs()
        }
    }

    /// The surface cells' bits, per 64 cells as `occupied`.
    fn surface_words(&self) -> &[u64] {
        self.surface.get_or_init(|| {
            use rayon::prelude::*;
            (0..self.occupied.len())
                .into_par_iter()
                .map(|w| self.surface_bits(w))
                .collect()
        })
    }

    /// [`SkipGrid::proxy_runs`], each with its box narrowed to where a
    /// ray can first meet a visible sample: per run, the offsets (voxels,
    /// in each axis from the run's lower corner up and from its upper
    /// corner down) of the bounding box of its cells' `visible` boxes (the
    /// voxel box of the interpolation cells of a macrocell the TF can make
    /// visible, or `None`) and, for the surface runs, of the faces, edges
    /// and corners they share with interior occupied cells (which rays
    /// reach only through a surface cell); runs whose box is empty are
    /// left out. Why that is enough: every occupied cell drawn, a ray's
    /// first visible sample lies in one of their visible boxes wherever
    /// the ray starts. With only the surface ones, for rays from outside
    /// the grid: a ray meets the occupied region first in a surface cell;
    /// from there it reaches its first visible sample in that cell (inside
    /// the cell's visible box), or through a part it shares with an
    /// interior cell (inside the box), or through another surface cell, to
    /// which the same applies, or through empty cells into another surface
    /// cell. Found on first use with `visible`, then kept: the grid belongs
    /// to one TF.
    pub fn visible_runs(
        &self,
        surface: bool,
        visible: impl Fn(UVec3) -> Option<[UVec3; 2]> + Sync,
    ) -> (&[(UVec3, u32)], &[[u8; 6]]) {
        let (runs, shrink) = if surface {
            &self.visible_surface
        } else {
            &self.visible_occupied
        }
        .get_or_init(|| self.narrow(self.proxy_runs(surface), surface, visible));
        (runs, shrink)
    }

    /// Notes a DVR frame that draws this grid's proxy runs; true when one
    /// did before. The narrowed runs ([`SkipGrid::visible_runs`]) cost a
    /// pass over the surface cells' corners, which a frame with a new TF
    /// (one of many while a TF is dragged in the viewer, or the only frame
    /// of a render) would not win back: such a frame draws the plain runs.
    pub(crate) fn proxy_drawn_before(&self) -> bool {
        self.proxy_drawn.set(()).is_err()
    }

    /// `runs` with their boxes narrowed to the bounding box of their cells'
    /// `visible` boxes and, with `interior`, of the parts they share with
    /// interior occupied cells (see [`SkipGrid::visible_runs`]);
    /// runs whose box is empty left out.
    fn narrow(
        &self,
        runs: &[(UVec3, u32)],
        interior_parts: bool,
        visible: impl Fn(UVec3) -> Option<[UVec3; 2]> + Sync,
    ) -> NarrowedRuns {
        use rayon::prelude::*;
        let surface = if interior_parts {
            self.surface_words()
        } else {
            &[]
        };
        let n = self.count.as_ivec3();
        let side = self.cell as u32;
        let interior = |c: glam::IVec3| {
            if c.cmplt(glam::IVec3::ZERO).any() || c.cmpge(n).any() {
                return false;
            }
            let i = self.index(c.as_uvec3());
            self.is_occupied_index(i) && surface[i >> 6] >> (i & 63) & 1 == 0
        };
        // A cell's box (voxels, relative to its lower corner).
        let cell_box = |c: UVec3| -> Option<[UVec3; 2]> {
            let base = c * side;
            let mut b = visible(c).map(|[lo, hi]| [lo - base, hi - base]);
            if !interior_parts {
                return b;
            }
            let ci = c.as_ivec3();
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let d = glam::IVec3::new(dx, dy, dz);
                        if d == glam::IVec3::ZERO || !interior(ci + d) {
                            continue;
                        }
                        let shared = |d: i32| match d {
                            -1 => (0, 0),
                            0 => (0, side),
                            _ => (side, side),
                        };
                        let (x, y, z) = (shared(dx), shared(dy), shared(dz));
                        let s = [UVec3::new(x.0, y.0, z.0), UVec3::new(x.1, y.1, z.1)];
                        b = Some(union(b, s));
                    }
                }
            }
            b
        };
        let boxes: Vec<Option<[u8; 6]>> = runs
            .par_iter()
            .map(|&(c, len)| {
                let mut b: Option<[UVec3; 2]> = None;
                for k in 0..len {
                    let Some([lo, hi]) = cell_box(c + UVec3::new(0, 0, k)) else {
                        continue;
                    };
                    let lift = UVec3::new(0, 0, k * side);
                    b = Some(union(b, [lo + lift, hi + lift]));
                }
                // Offsets beyond a byte narrow less than they could.
                b.map(|[lo, hi]| {
                    let down = UVec3::new(side, side, len * side) - hi;
                    [lo.x, lo.y, lo.z, down.x, down.y, down.z].map(|v| v.min(255) as u8)
                })
            })
            .collect();
        let mut kept = Vec::new();
        let mut shrink = Vec::new();
        for (&run, b) in runs.iter().zip(boxes) {
            if let Some(b) = b {
                kept.push(run);
                shrink.push(b);
            }
        }
        (kept, shrink)
    }

    /// Word `w` of the occupancy bits with only the surface cells' set
    /// (see [`SkipGrid::surface_runs`]).
    fn surface_bits(&self, w: usize) -> u64 {
        let n = self.count;
        let (nx, ny, nz) = (n.x as usize, n.y as usize, n.z as usize);
        let occupied = |x: usize, y: usize, z: usize| self.is_occupied_index((x * ny + y) * nz + z);
        let mut bits = self.occupied[w];
        let mut surface = 0;
        while bits != 0 {
            let b = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let i = w * 64 + b;
            let [x, y, z] = cell_of_index(n, i).to_array().map(|c| c as usize);
            let inside = x > 0
                && y > 0
                && z > 0
                && x + 1 < nx
                && y + 1 < ny
                && z + 1 < nz
                && occupied(x - 1, y, z)
                && occupied(x + 1, y, z)
                && occupied(x, y - 1, z)
                && occupied(x, y + 1, z)
                && occupied(x, y, z - 1)
                && occupied(x, y, z + 1);
            if !inside {
                surface |= 1 << b;
            }
        }
        surface
    }

    /// The cell of index `i`.
    fn cell_at(&self, i: usize) -> UVec3 {
        cell_of_index(self.count, i)
    }

    fn list_occupied_runs(&self) -> Vec<(UVec3, u32)> {
        let mut out = Vec::new();
        super::bit_runs(
            &self.occupied,
            self.count.z as usize,
            MAX_RUN,
            |first, len| out.push((self.cell_at(first), len)),
        );
        out
    }

    /// Number of occupied cells.
    pub fn occupied_count(&self) -> usize {
        self.occupied.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// Whether cell `c` is occupied.
    pub fn is_occupied(&self, c: UVec3) -> bool {
        self.is_occupied_index(self.index(c))
    }

    #[inline(always)]
    fn index(&self, c: UVec3) -> usize {
        (c.x as usize * self.count.y as usize + c.y as usize) * self.count.z as usize + c.z as usize
    }

    /// The cell holding voxel-space point `p`, clamped onto the grid (NaN
    /// to 0): [`cell_coord`] per axis, the three at once in SSE lanes.
    #[inline(always)]
    fn cell_of(&self, p: Vec3) -> UVec3 {
        let last = self.count - UVec3::ONE;
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_cvttps_epi32, _mm_storeu_si128};
            // `maxps` returns its second operand (0) for a NaN lane, then
            // the clamp to `last` (< 2^31) makes the truncation exact.
            let q = (Vec3A::from(p) * self.inv_cell)
                .max(Vec3A::ZERO)
                .min(last.as_vec3a());
            let mut out = [0i32; 4];
            // SAFETY: SSE2 is part of x86_64, so both intrinsics are
            // available; the unaligned store writes the 16 bytes of `out`.
            unsafe { _mm_storeu_si128(out.as_mut_ptr().cast(), _mm_cvttps_epi32(q.into())) };
            UVec3::new(out[0] as u32, out[1] as u32, out[2] as u32)
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let q = p * self.inv_cell;
            UVec3::new(
                cell_coord(q.x, last.x),
                cell_coord(q.y, last.y),
                cell_coord(q.z, last.z),
            )
        }
    }

    /// What the cell holding voxel-space point `p` is: empty (with a box
    /// around the point, in voxel space, in which no cell contributes) or
    /// occupied (with its own box and its index in the macrocell grid).
    #[inline(always)]
    pub fn classify(&self, p: Vec3) -> CellClass {
        let (c, index) = self.locate(p);
        self.class_of(c, index, self.cell_kind(c, index))
    }

    /// [`SkipGrid::classify`] for a ray moving into the empty space `ahead`
    /// ([`SkipGrid::ahead`]): an empty box extends ahead of the ray
    /// (`SkipGrid::cell_kind_ahead`), so it is mostly longer along it.
    #[inline(always)]
    pub fn classify_ahead(&self, p: Vec3, ahead: Ahead<'_>) -> CellClass {
        let (c, index) = self.locate(p);
        self.class_of(c, index, self.cell_kind_ahead(c, index, ahead))
    }

    /// The empty space ahead of rays with inverse direction `inv_dir`
    /// (for [`SkipGrid::classify_ahead`]): its direction octant's field,
    /// built by the first ray that asks for it.
    #[inline]
    pub fn ahead(&self, inv_dir: Vec3) -> Ahead<'_> {
        // Bit `a` set: towards lower coordinates on axis `a` (an axis the
        // ray does not move along may take either side).
        let octant = (inv_dir.x < 0.0) as usize
            | ((inv_dir.y < 0.0) as usize) << 1
            | ((inv_dir.z < 0.0) as usize) << 2;
        self.ahead_of(octant)
    }

    fn ahead_of(&self, octant: usize) -> Ahead<'_> {
        let sides = self.ahead[octant]
            .get_or_init(|| octant_distances(&self.distance, self.coarse_count, octant));
        Ahead { octant, sides }
    }

    #[inline(always)]
    fn class_of(&self, c: UVec3, index: usize, kind: CellKind) -> CellClass {
        let own_box = || {
            let lo = c.as_vec3() * self.cell;
            Aabb::new(lo, lo + Vec3::splat(self.cell))
        };
        match kind {
            CellKind::Occupied => CellClass::Occupied {
                bounds: own_box(),
                index,
                coords: c,
            },
            CellKind::EmptyAlone => CellClass::Empty(own_box()),
            CellKind::EmptyWithin(b) => CellClass::Empty(b),
        }
    }

    /// [`SkipGrid::classify`] of cell `c` (index `index`) without its own
    /// box, which a walk that knows where it leaves the cell does not need.
    #[inline(always)]
    pub(crate) fn cell_kind(&self, c: UVec3, index: usize) -> CellKind {
        if self.is_occupied_index(index) {
            return CellKind::Occupied;
        }
        let cc = c / 2;
        let d = self.distance[(cc.x as usize * self.coarse_count.y as usize + cc.y as usize)
            * self.coarse_count.z as usize
            + cc.z as usize];
        if d == 0 {
            // A sibling is occupied: only this cell is known empty.
            return CellKind::EmptyAlone;
        }
        // The coarse cells within Chebyshev distance d − 1 are all empty.
        let coarse = 2.0 * self.cell;
        let r = (d - 1) as f32;
        let lo = (cc.as_vec3() - Vec3::splat(r)) * coarse;
        let hi = (cc.as_vec3() + Vec3::splat(r + 1.0)) * coarse;
        CellKind::EmptyWithin(Aabb::new(lo, hi))
    }

    /// [`SkipGrid::cell_kind`] for a ray moving into the empty space
    /// `ahead`: an empty box is the largest empty cube of coarse cells that
    /// has the cell's coarse cell as its corner and extends ahead of the
    /// ray, which the ray leaves only through its far faces.
    #[inline(always)]
    pub(crate) fn cell_kind_ahead(&self, c: UVec3, index: usize, ahead: Ahead<'_>) -> CellKind {
        let Ahead { octant, sides } = ahead;
        if self.is_occupied_index(index) {
            return CellKind::Occupied;
        }
        let cc = c / 2;
        let d = sides[(cc.x as usize * self.coarse_count.y as usize + cc.y as usize)
            * self.coarse_count.z as usize
            + cc.z as usize];
        if d == 0 {
            return CellKind::EmptyAlone;
        }
        let coarse = 2.0 * self.cell;
        let cf = cc.as_vec3();
        let reach = (d - 1) as f32;
        let (mut lo, mut hi) = (cf, cf + Vec3::ONE);
        for a in 0..3 {
            if octant >> a & 1 == 0 {
                hi[a] += reach;
            } else {
                lo[a] -= reach;
            }
        }
        CellKind::EmptyWithin(Aabb::new(lo * coarse, hi * coarse))
    }

    /// The macrocell holding voxel-space point `p` (clamped onto the grid)
    /// and its index.
    #[inline(always)]
    pub(crate) fn locate(&self, p: Vec3) -> (UVec3, usize) {
        let c = self.cell_of(p);
        (c, self.index(c))
    }

    /// A macrocell's side (voxels).
    #[inline(always)]
    pub(crate) fn cell_side(&self) -> f32 {
        self.cell
    }

    /// How far apart in the index neighbouring macrocells lie along each
    /// axis.
    #[inline(always)]
    pub(crate) fn index_strides(&self) -> [isize; 3] {
        let (ny, nz) = (self.count.y as isize, self.count.z as isize);
        [ny * nz, nz, 1]
    }

    /// For voxel-space point `p`: `None` when its cell may contribute;
    /// otherwise a voxel-space box around it in which no cell does.
    #[inline(always)]
    pub fn empty_box(&self, p: Vec3) -> Option<Aabb> {
        match self.classify(p) {
            CellClass::Empty(b) => Some(b),
            CellClass::Occupied { .. } => None,
        }
    }

    /// For voxel-space point `p`: `Some(box)` of its cell when the cell is
    /// occupied, else `None`.
    #[inline(always)]
    pub fn occupied_cell_box(&self, p: Vec3) -> Option<Aabb> {
        match self.classify(p) {
            CellClass::Occupied { bounds, .. } => Some(bounds),
            CellClass::Empty(_) => None,
        }
    }
}

/// Up to 64 flags as the bits of a word, flag `i` in bit `i`: eight at a
/// time, the multiplication gathering the low bit of each byte of a word
/// of eight bools (0 or 1) into its top byte.
fn pack_bits(flags: &[bool]) -> u64 {
    let mut word = 0u64;
    for (k, eight) in flags.chunks(8).enumerate() {
        let mut bytes = [0u8; 8];
        for (b, &f) in bytes.iter_mut().zip(eight) {
            *b = f as u8;
        }
        let gathered = u64::from_le_bytes(bytes).wrapping_mul(0x0102_0408_1020_4080) >> 56;
        word |= gathered << (8 * k);
    }
    word
}

/// The empty space ahead of the rays of one direction octant
/// ([`SkipGrid::ahead`]).
#[derive(Debug, Clone, Copy)]
pub struct Ahead<'a> {
    /// Bit `a` set: towards lower coordinates on axis `a`.
    octant: usize,
    /// Per coarse cell, the side of the empty cube ahead.
    sides: &'a [u8],
}

/// The field of [`SkipGrid::ahead`] for `octant` from the coarse cells'
/// chessboard distances (`0`: occupied): one raster pass against the
/// direction: the empty cube of side `n` at a cell is the cell and the
/// cubes of side `n − 1` at its seven neighbours ahead, so a cell's side is
/// one more than the least of theirs (a neighbour off the grid counts as
/// unbounded: rays leave the grid there).
fn octant_distances(distance: &[u8], n: UVec3, octant: usize) -> Vec<u8> {
    let (nx, ny, nz) = (n.x as usize, n.y as usize, n.z as usize);
    let row = |x: usize, y: usize| (x * ny + y) * nz;
    let back = |a: usize| octant >> a & 1 == 1;
    // Coordinates in the order of the pass (the neighbours ahead come
    // first), each with its neighbour ahead on its axis.
    let order = |len: usize, a: usize| -> Vec<(usize, Option<usize>)> {
        if back(a) {
            (0..len).map(|i| (i, i.checked_sub(1))).collect()
        } else {
            (0..len)
                .rev()
                .map(|i| (i, Some(i + 1).filter(|&j| j < len)))
                .collect()
        }
    };
    let (xs, ys) = (order(nx, 0), order(ny, 1));
    let mut d = vec![u8::MAX; distance.len()];
    let mut m = vec![u8::MAX; nz];
    let mut shifted = vec![u8::MAX; nz];
    for &(x, ax) in &xs {
        for &(y, ay) in &ys {
            // The least side at the neighbours ahead in earlier rows:
            // (x', y), (x, y'), (x', y'), each at z and at z ahead.
            m.fill(u8::MAX);
            let rows = [
                ax.map(|x2| row(x2, y)),
                ay.map(|y2| row(x, y2)),
                ax.zip(ay).map(|(x2, y2)| row(x2, y2)),
            ];
            for r in rows.into_iter().flatten() {
                let src = &d[r..r + nz];
                shift_ahead(src, &mut shifted, back(2));
                for ((a, &b), &c) in m.iter_mut().zip(src).zip(&shifted) {
                    *a = (*a).min(b).min(c);
                }
            }
            // Then the neighbour ahead along z, in the pass's order.
            let r = row(x, y);
            let (occupied, cells) = (&distance[r..r + nz], &mut d[r..r + nz]);
            let mut ahead = u8::MAX;
            let mut set = |z: usize| {
                ahead = if occupied[z] == 0 {
                    0
                } else {
                    m[z].min(ahead).saturating_add(1)
                };
                cells[z] = ahead;
            };
            if back(2) {
                (0..nz).for_each(&mut set);
            } else {
                (0..nz).rev().for_each(&mut set);
            }
        }
    }
    d
}

/// `out[z]` = `row` at the neighbour ahead of `z` along z (the previous
/// entry when `back`, else the next), `u8::MAX` off the row.
fn shift_ahead(row: &[u8], out: &mut [u8], back: bool) {
    let n = row.len();
    if n == 0 {
        return;
    }
    if back {
        out[0] = u8::MAX;
        out[1..].copy_from_slice(&row[..n - 1]);
    } else {
        out[..n - 1].copy_from_slice(&row[1..]);
        out[n - 1] = u8::MAX;
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

/// The cell of index `i` in a grid of `count` cells stored z fastest.
fn cell_of_index(count: UVec3, i: usize) -> UVec3 {
    let (ny, nz) = (count.y as usize, count.z as usize);
    UVec3::new(
        (i / (ny * nz)) as u32,
        (i / nz % ny) as u32,
        (i % nz) as u32,
    )
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
    fn flags_pack_into_their_bits() {
        let mut rng = fastrand::Rng::with_seed(3);
        for n in [0, 1, 7, 8, 9, 63, 64] {
            let flags: Vec<bool> = (0..n).map(|_| rng.bool()).collect();
            let word = pack_bits(&flags);
            for (i, &f) in flags.iter().enumerate() {
                assert_eq!(word >> i & 1 == 1, f, "flag {i} of {n}");
            }
            if n < 64 {
                assert_eq!(word >> n, 0, "bits past {n}");
            }
        }
    }

    /// The occupied runs hold every occupied cell once and nothing else,
    /// each run consecutive along z in one row and at most `MAX_RUN` long,
    /// and neighbouring runs are not left unmerged below that length.
    #[test]
    fn occupied_runs_hold_each_occupied_cell_once() {
        let mut rng = fastrand::Rng::with_seed(5);
        for density in [0.0, 0.03, 0.3, 0.9, 1.0] {
            for _ in 0..10 {
                let count = UVec3::new(rng.u32(1..9), rng.u32(1..9), rng.u32(1..70));
                let cells = crate::accel::random_macrocells(&mut rng, count, density);
                let skip = SkipGrid::build(&cells, |_, hi| hi > 0.5);
                let runs = skip.occupied_runs();
                let mut seen = vec![0u32; cells.ranges.len()];
                for (k, &(c, len)) in runs.iter().enumerate() {
                    assert!((1..=MAX_RUN).contains(&len), "{count} run {c} of {len}");
                    assert!(c.z + len <= count.z, "{count} run {c} of {len}");
                    for z in c.z..c.z + len {
                        seen[skip.index(UVec3::new(c.x, c.y, z))] += 1;
                    }
                    // Runs follow in index order; one that ends short of
                    // `MAX_RUN` ends at an empty cell or the row's end.
                    if let Some(&(next, _)) = runs.get(k + 1) {
                        assert!(skip.index(next) >= skip.index(c) + len as usize);
                    }
                    let end = UVec3::new(c.x, c.y, c.z + len);
                    if len < MAX_RUN && end.z < count.z {
                        assert!(!skip.is_occupied(end), "{count} run {c} of {len}");
                    }
                }
                for (i, &n) in seen.iter().enumerate() {
                    assert_eq!(n, skip.is_occupied_index(i) as u32, "{count} cell {i}");
                }
                assert_eq!(runs.is_empty(), skip.occupied_count() == 0);
            }
        }
    }

    /// The surface runs hold the occupied cells that lie on a face of the
    /// grid or have an empty face neighbour, each once, and no others
    /// (dense random grids have interior cells to leave out); and for rays
    /// from outside the grid, the nearest entry into their boxes is the
    /// nearest entry into an occupied cell's box.
    #[test]
    fn surface_runs_hold_the_cells_rays_can_meet_first() {
        let mut rng = fastrand::Rng::with_seed(12);
        let mut left_out = 0;
        // Random cells (dense: interior cells next to empty ones), and
        // balls in empty space (rays reach them from every side).
        for density in [0.0, 0.5, 0.9, 0.97, 1.0, -1.0] {
            for _ in 0..10 {
                let count = UVec3::new(rng.u32(1..9), rng.u32(1..9), rng.u32(1..70));
                let mut cells = crate::accel::random_macrocells(&mut rng, count, density);
                if density < 0.0 {
                    let balls: Vec<(Vec3, f32)> = (0..rng.u32(1..4))
                        .map(|_| {
                            let centre =
                                Vec3::new(rng.f32(), rng.f32(), rng.f32()) * count.as_vec3();
                            (centre, 1.0 + 3.0 * rng.f32())
                        })
                        .collect();
                    for (i, r) in cells.ranges.iter_mut().enumerate() {
                        let c = cell_of_index(count, i).as_vec3();
                        let inside = balls.iter().any(|&(o, rad)| (c + 0.5).distance(o) < rad);
                        *r = if inside { (1.0, 1.0) } else { (0.0, 0.0) };
                    }
                }
                let skip = SkipGrid::build(&cells, |_, hi| hi > 0.5);
                let mut seen = vec![0u32; cells.ranges.len()];
                for &(c, len) in skip.surface_runs() {
                    assert!((1..=MAX_RUN).contains(&len), "{count} run {c} of {len}");
                    for z in c.z..c.z + len {
                        seen[skip.index(UVec3::new(c.x, c.y, z))] += 1;
                    }
                }
                let on_surface = |c: UVec3| {
                    let faces = [glam::IVec3::X, glam::IVec3::Y, glam::IVec3::Z];
                    faces.into_iter().flat_map(|f| [f, -f]).any(|f| {
                        let n = c.as_ivec3() + f;
                        n.cmplt(glam::IVec3::ZERO).any()
                            || n.cmpge(count.as_ivec3()).any()
                            || !skip.is_occupied(n.as_uvec3())
                    })
                };
                for (i, &n) in seen.iter().enumerate() {
                    let c = skip.cell_at(i);
                    let expect = skip.is_occupied(c) && on_surface(c);
                    assert_eq!(n, expect as u32, "{count} cell {c}");
                    left_out += (skip.is_occupied(c) && !expect) as usize;
                }
                // Rays from outside the grid's box: the nearest entry into
                // an occupied cell's box is an entry into a surface cell's.
                let side = skip.cell_side();
                let size = count.as_vec3() * side;
                let cell_box = |i: usize| {
                    let lo = skip.cell_at(i).as_vec3() * side;
                    Aabb::new(lo, lo + Vec3::splat(side))
                };
                for _ in 0..50 {
                    let dir = Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5)
                        .normalize_or(Vec3::X);
                    let target = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * size;
                    let ray = crate::geometry::Ray {
                        origin: target - dir * (size.length() + 1.0),
                        dir,
                    };
                    let nearest = |surface_only: bool| {
                        (0..seen.len())
                            .filter(|&i| {
                                skip.is_occupied_index(i) && (!surface_only || seen[i] == 1)
                            })
                            .filter_map(|i| cell_box(i).intersect(&ray))
                            .map(|(t, _)| t)
                            .fold(f32::INFINITY, f32::min)
                    };
                    assert_eq!(nearest(true), nearest(false), "{count} ray {ray:?}");
                }
            }
        }
        assert!(left_out > 0, "no grid had interior cells");
    }

    /// `steady` reads, for every occupied cell, the macrocell grid's
    /// uniform flag and the `flat` test of its range; nothing for empty
    /// cells or where the flags were not built.
    #[test]
    fn steady_flags_are_the_cells_own() {
        let mut rng = fastrand::Rng::with_seed(8);
        let (mut uniform, mut flats) = (0, 0);
        for _ in 0..10 {
            let count = UVec3::new(rng.u32(1..9), rng.u32(1..9), rng.u32(1..40));
            let mut cells = crate::accel::random_macrocells(&mut rng, count, 0.5);
            for (r, u) in cells.ranges.iter_mut().zip(&mut cells.uniform) {
                let lo = rng.u32(0..4) as f32;
                *r = (lo, lo + rng.u32(0..3) as f32);
                *u = rng.bool();
            }
            let flat = |lo: f32, hi: f32| lo + hi < 3.5;
            let plain = SkipGrid::build(&cells, |_, hi| hi > 1.5);
            let skip = plain.clone().with_steady(&cells, flat);
            for i in 0..cells.ranges.len() {
                assert_eq!(plain.steady(i), (false, false));
                let (lo, hi) = cells.ranges[i];
                let want = match skip.is_occupied_index(i) {
                    true => (cells.uniform[i], flat(lo, hi)),
                    false => (false, false),
                };
                assert_eq!(skip.steady(i), want, "{count} cell {i}");
                uniform += want.0 as u32;
                flats += want.1 as u32;
            }
        }
        assert!(uniform > 50 && flats > 50, "{uniform} {flats}");
    }

    #[test]
    fn empty_boxes_never_hold_an_occupied_cell() {
        let mut rng = fastrand::Rng::with_seed(12);
        for _ in 0..20 {
            let count = UVec3::new(rng.u32(1..12), rng.u32(1..12), rng.u32(1..12));
            let cells = crate::accel::random_macrocells(&mut rng, count, 0.03);
            let skip = SkipGrid::build(&cells, |_, hi| hi > 0.5);
            for _ in 0..300 {
                let p = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * count.as_vec3() * 4.0;
                let CellClass::Empty(b) = skip.classify(p) else {
                    continue;
                };
                assert!(b.contains(p), "{p} outside its empty box {b:?}");
                for x in 0..count.x {
                    for y in 0..count.y {
                        for z in 0..count.z {
                            let c = UVec3::new(x, y, z);
                            let lo = c.as_vec3() * 4.0;
                            let inside =
                                lo.cmplt(b.max).all() && (lo + Vec3::splat(4.0)).cmpgt(b.min).all();
                            assert!(
                                !(inside && skip.is_occupied(c)),
                                "occupied cell {c} inside empty box {b:?}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn the_empty_cubes_ahead_are_the_largest_and_hold_no_occupied_cell() {
        let mut rng = fastrand::Rng::with_seed(14);
        for case in 0..30 {
            let count = UVec3::new(rng.u32(1..16), rng.u32(1..16), rng.u32(1..16));
            let density = [0.0, 0.005, 0.03, 0.2][case % 4];
            let cells = crate::accel::random_macrocells(&mut rng, count, density);
            let skip = SkipGrid::build(&cells, |_, hi| hi > 0.5);
            let cc_count = skip.coarse_count.as_ivec3();
            let coarse_occupied = |c: glam::IVec3| {
                (0..8).any(|k| {
                    let m = c * 2 + glam::IVec3::new(k & 1, k >> 1 & 1, k >> 2 & 1);
                    m.cmplt(count.as_ivec3()).all() && skip.is_occupied(m.as_uvec3())
                })
            };
            for octant in 0..8 {
                let dir = glam::IVec3::new(
                    1 - 2 * (octant & 1),
                    1 - 2 * (octant >> 1 & 1),
                    1 - 2 * (octant >> 2 & 1),
                );
                for x in 0..cc_count.x {
                    for y in 0..cc_count.y {
                        for z in 0..cc_count.z {
                            let c = glam::IVec3::new(x, y, z);
                            // The least chessboard offset of an occupied
                            // coarse cell ahead (255 when none).
                            let mut want = 255;
                            for (i, j, k) in all_below(cc_count) {
                                let o = (glam::IVec3::new(i, j, k) - c) * dir;
                                if o.cmpge(glam::IVec3::ZERO).all()
                                    && coarse_occupied(glam::IVec3::new(i, j, k))
                                {
                                    want = want.min(o.max_element());
                                }
                            }
                            let index = ((x * cc_count.y + y) * cc_count.z + z) as usize;
                            assert_eq!(
                                skip.ahead_of(octant as usize).sides[index] as i32,
                                want,
                                "case {case}, octant {octant}, coarse cell {c}"
                            );
                        }
                    }
                }
            }
            // The boxes handed out hold the point and no occupied cell.
            for _ in 0..200 {
                let p = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * count.as_vec3() * 4.0;
                let octant = rng.usize(0..8);
                let (c, index) = skip.locate(p);
                let CellKind::EmptyWithin(b) =
                    skip.cell_kind_ahead(c, index, skip.ahead_of(octant))
                else {
                    continue;
                };
                let own = c.as_vec3() * 4.0;
                assert!(
                    b.contains(own) && b.contains(own + 4.0),
                    "{p}: cell outside {b:?}"
                );
                for (x, y, z) in all_below(count.as_ivec3()) {
                    let m = glam::IVec3::new(x, y, z).as_uvec3();
                    let lo = m.as_vec3() * 4.0;
                    let inside =
                        lo.cmplt(b.max).all() && (lo + Vec3::splat(4.0)).cmpgt(b.min).all();
                    assert!(
                        !(inside && skip.is_occupied(m)),
                        "occupied {m} inside {b:?}"
                    );
                }
            }
        }
    }

    /// Every `(x, y, z)` below `n`.
    fn all_below(n: glam::IVec3) -> impl Iterator<Item = (i32, i32, i32)> {
        (0..n.x).flat_map(move |x| (0..n.y).flat_map(move |y| (0..n.z).map(move |z| (x, y, z))))
    }

    #[test]
    fn cells_of_points_match_the_scalar_clamp() {
        let mut rng = fastrand::Rng::with_seed(13);
        let count = UVec3::new(7, 5, 9);
        let len = (count.x * count.y * count.z) as usize;
        let cells = MacrocellGrid {
            cell: 4,
            count,
            ranges: vec![(0.0, 0.0); len],
            uniform: vec![false; len],
            shells_found: false,
        };
        let skip = SkipGrid::all_occupied(&cells);
        let last = count - UVec3::ONE;
        let mut points: Vec<Vec3> = (0..2000)
            .map(|_| Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 50.0 - 10.0)
            .collect();
        points.extend([
            Vec3::new(f32::NAN, 3.0, 4.0),
            Vec3::splat(f32::INFINITY),
            Vec3::splat(f32::NEG_INFINITY),
            Vec3::new(4.0, 8.0, 35.99),
        ]);
        for p in points {
            let q = p / 4.0;
            let want = UVec3::new(
                cell_coord(q.x, last.x),
                cell_coord(q.y, last.y),
                cell_coord(q.z, last.z),
            );
            assert_eq!(skip.cell_of(p), want, "{p}");
        }
    }

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
