//! Partition: the volume's voxel box split into one box per rank by a k-d
//! tree (the data decomposition of sort-last rendering).
//!
//! The tree is built on a coarse grid of cells (the macrocells when their
//! occupancy is known, else cells of about 1/64 of the volume's longest
//! side): each split cuts the longest axis (in world units) of a box at a
//! cell boundary so that the weights on the two sides are in the ratio of
//! the ranks they get. A cell's weight is its voxel count, divided by 16
//! when the frame's transfer function makes it empty (an empty cell is
//! skipped, not free), so balancing by non-empty macrocells and by voxel
//! count are one mechanism.
//!
//! **Ownership.** Neighbouring boxes share their boundary plane (voxel
//! coordinates of the whole grid), and every sample position belongs to
//! exactly one box by a half-open rule: at a split on axis `a` at plane `s`
//! the lower box owns `p[a] < s`, the upper one `p[a] >= s`; a box's outer
//! faces on the volume's faces are unbounded, so a sample that rounding
//! puts a hair outside the volume still has an owner. The test is made on
//! the position the whole volume's ray computes ([`Region::owns`]), the same
//! `f32` arithmetic on every rank, so no sample is taken twice or lost.
//!
//! **Visibility order.** For a perspective camera every ray leaves the eye
//! and crosses each split plane at most once, from the eye's side to the
//! other, so visiting the eye's side of every split first gives a front to
//! back order of the boxes that holds for every ray at once (for an
//! orthographic camera, the side the view direction comes from).

use glam::{UVec3, Vec3};

use crate::accel::MacrocellGrid;
use crate::camera::Projection;
use crate::error::{Error, Result};

/// How much an empty cell weighs against an occupied one of the same size.
const EMPTY_CELL_DIVISOR: u64 = 16;

/// Cells per axis of the fallback grid (no macrocell occupancy known).
const FALLBACK_CELLS: u32 = 64;

/// What a partition balances between the ranks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Balance {
    /// The macrocells the frame's transfer function (iso value, clipping)
    /// leaves occupied: where the samples are taken.
    #[default]
    Occupancy,
    /// Voxel count alone.
    Voxels,
}

impl Balance {
    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Balance::Occupancy => "occupancy",
            Balance::Voxels => "voxels",
        }
    }
}

/// The side (voxels) of the cells an occupancy-balanced partition is built
/// on for a volume of `dims`: the multiple of the scene's macrocell side
/// ([`crate::scene::default_macrocell`]) nearest above 1/64 of the longest
/// axis, so that the value ranges of those macrocells (from the volume's
/// cache) combine exactly into the partition's cells and every region's
/// faces lie on macrocell planes.
pub fn balance_cell(dims: UVec3) -> u32 {
    let m = crate::scene::default_macrocell(dims);
    let target = (dims.max_element() / FALLBACK_CELLS).max(1);
    m * target.div_ceil(m)
}

/// The part of the volume a rank owns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    /// Which part (and, in a distributed run, which rank) this is.
    pub index: usize,
    /// Lowest voxel plane of the box, per axis.
    pub lo: UVec3,
    /// Highest voxel plane of the box (inclusive), per axis.
    pub hi: UVec3,
    /// Owned positions (voxel space of the whole grid): `own_lo <= p`;
    /// `-∞` on the volume's lower faces.
    pub own_lo: Vec3,
    /// Owned positions: `p < own_hi`; `+∞` on the volume's upper faces.
    pub own_hi: Vec3,
}

impl Region {
    /// Whether voxel-space position `p` (of the whole grid) belongs to
    /// this region.
    #[inline(always)]
    pub fn owns(&self, p: Vec3) -> bool {
        self.own_lo.cmple(p).all() && p.cmplt(self.own_hi).all()
    }

    /// The voxel box to read for this region: `lo - ghost ..= hi + ghost`,
    /// clamped to a grid of `dims`. A ghost layer of 1 serves trilinear
    /// sampling (a sample just below `lo` after rounding reads plane
    /// `lo − 1`), 2 serves central-difference gradients as well.
    pub fn data_box(&self, dims: UVec3, ghost: u32) -> (UVec3, UVec3) {
        let last = dims - UVec3::ONE;
        (
            self.lo.saturating_sub(UVec3::splat(ghost)),
            (self.hi + UVec3::splat(ghost)).min(last),
        )
    }

    /// The parameter interval `[a, b]` of the line `origin + t·dir` (voxel
    /// space of the whole grid) inside the owned region's closure (`a > b`
    /// when it misses).
    pub fn interval(&self, origin: Vec3, dir: Vec3) -> (f32, f32) {
        let (mut a, mut b) = (f32::NEG_INFINITY, f32::INFINITY);
        for i in 0..3 {
            let (o, d) = (origin[i], dir[i]);
            if d == 0.0 {
                if !(self.own_lo[i] <= o && o <= self.own_hi[i]) {
                    return (f32::INFINITY, f32::NEG_INFINITY);
                }
                continue;
            }
            let t0 = (self.own_lo[i] - o) / d;
            let t1 = (self.own_hi[i] - o) / d;
            // ±∞ planes give ±∞ (or NaN for an origin at infinity, which
            // rays never have); min/max ignore NaN.
            a = a.max(t0.min(t1));
            b = b.min(t0.max(t1));
        }
        (a, b)
    }

    /// The samples among `first..end` that this region owns, sample `k` at
    /// voxel position `pos(k)` (of the whole grid) and parameter
    /// `t0 + k·step`: a contiguous range, since the region is convex. It is
    /// estimated from the slab equations and settled on the positions, as
    /// [`crate::clip::ClipRegion::sample_range`] does, so the ends obey
    /// [`Region::owns`] exactly.
    pub fn sample_range(
        &self,
        origin: Vec3,
        dir: Vec3,
        t0: f32,
        inv_step: f32,
        (first, end): (u32, u32),
        pos: impl Fn(u32) -> Vec3,
    ) -> (u32, u32) {
        if first >= end {
            return (first, first);
        }
        let (a, b) = self.interval(origin, dir);
        let inside = |k: u32| self.owns(pos(k));
        let index = |t: f32| ((t - t0) * inv_step).ceil().max(0.0) as u32;
        let (mut lo, mut hi) = if a > b || a.is_nan() || b.is_nan() {
            (first, first)
        } else {
            let lo = index(a).clamp(first, end);
            let hi = ((((b - t0) * inv_step).floor().max(-1.0) + 1.0) as u32).clamp(lo, end);
            (lo, hi)
        };
        // Settle the ends on the positions.
        while lo > first && inside(lo - 1) {
            lo -= 1;
        }
        hi = hi.max(lo);
        while lo < hi && !inside(lo) {
            lo += 1;
        }
        if lo == hi {
            // The estimate holds no owned sample: look on each side.
            if lo < end && inside(lo) {
                hi = lo + 1;
            } else if lo > first && inside(lo - 1) {
                lo -= 1;
                hi = lo + 1;
                while lo > first && inside(lo - 1) {
                    lo -= 1;
                }
            } else {
                return (first, first);
            }
        }
        while hi < end && inside(hi) {
            hi += 1;
        }
        while hi > lo && !inside(hi - 1) {
            hi -= 1;
        }
        (lo, hi)
    }
}

/// A node of the k-d tree.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Node {
    /// A split on `axis` at voxel plane `plane`: the lower child owns
    /// `p[axis] < plane`.
    Split {
        axis: usize,
        plane: u32,
        lower: usize,
        upper: usize,
    },
    /// A region (index into [`Partition::regions`]).
    Leaf(usize),
}

/// The weight of each cell of a coarse grid over the volume.
#[derive(Debug, Clone)]
pub struct CellWeights {
    cell: u32,
    count: UVec3,
    weights: Vec<u64>,
}

impl CellWeights {
    /// Weights by voxel count alone, on a grid of about 64 cells along the
    /// longest axis.
    pub fn voxels(dims: UVec3) -> Self {
        let cell = (dims.max_element() / FALLBACK_CELLS).max(1);
        Self::from_fn(dims, cell, |_| true)
    }

    /// Weights by voxel count on cells of `cell` voxels a side.
    pub fn uniform(dims: UVec3, cell: u32) -> Self {
        Self::from_fn(dims, cell.max(1), |_| true)
    }

    /// Weights by occupancy: `occupied(i)` for macrocell `i` of `cells`
    /// (x slowest, z fastest, as [`MacrocellGrid::ranges`]), e.g. whether
    /// the frame's skip grid keeps it.
    pub fn macrocells(
        dims: UVec3,
        cells: &MacrocellGrid,
        occupied: impl Fn(usize) -> bool,
    ) -> Self {
        Self::from_fn(dims, cells.cell, occupied)
    }

    fn from_fn(dims: UVec3, cell: u32, occupied: impl Fn(usize) -> bool) -> Self {
        let count = MacrocellGrid::count_for(dims, cell);
        let extent = |c: u32, d: u32| {
            // Voxels of cell c along an axis of d voxels: the planes it
            // covers, the shared upper one counted by the next cell.
            let lo = c * cell;
            let hi = ((c + 1) * cell).min(d.saturating_sub(1));
            (hi.saturating_sub(lo)).max(1) as u64
        };
        let mut weights = Vec::with_capacity(count.element_product() as usize);
        for x in 0..count.x {
            for y in 0..count.y {
                for z in 0..count.z {
                    let i = weights.len();
                    let v = extent(x, dims.x) * extent(y, dims.y) * extent(z, dims.z);
                    weights.push(if occupied(i) {
                        v
                    } else {
                        (v / EMPTY_CELL_DIVISOR).max(1)
                    });
                }
            }
        }
        CellWeights {
            cell,
            count,
            weights,
        }
    }

    /// The weight of the cells `lo..hi` (cell coordinates, exclusive).
    fn sum(&self, lo: UVec3, hi: UVec3) -> u64 {
        let mut s = 0;
        for x in lo.x..hi.x {
            for y in lo.y..hi.y {
                let row = ((x * self.count.y + y) * self.count.z) as usize;
                s += self.weights[row + lo.z as usize..row + hi.z as usize]
                    .iter()
                    .sum::<u64>();
            }
        }
        s
    }
}

/// The volume's voxel box split into regions by a k-d tree.
#[derive(Debug, Clone)]
pub struct Partition {
    dims: UVec3,
    nodes: Vec<Node>,
    regions: Vec<Region>,
    weights: Vec<u64>,
}

impl Partition {
    /// Splits a grid of `dims` voxels with `spacing` into `parts` regions
    /// balanced by `weights`. An error when the volume is too small to give
    /// every part at least one cell.
    pub fn kd(dims: UVec3, spacing: Vec3, parts: usize, weights: &CellWeights) -> Result<Self> {
        if parts == 0 {
            return Err(Error::option("ranks", "at least one part is needed"));
        }
        let mut p = Partition {
            dims,
            nodes: Vec::new(),
            regions: Vec::new(),
            weights: Vec::new(),
        };
        p.build(UVec3::ZERO, weights.count, parts, spacing, weights)
            .ok_or_else(|| {
                Error::option(
                    "ranks",
                    format!(
                        "a {}x{}x{} volume cannot be split into {parts} parts \
                         (cells of {} voxels)",
                        dims.x, dims.y, dims.z, weights.cell
                    ),
                )
            })?;
        Ok(p)
    }

    /// Builds the subtree of cells `lo..hi` for `parts` parts; returns its
    /// node index.
    fn build(
        &mut self,
        lo: UVec3,
        hi: UVec3,
        parts: usize,
        spacing: Vec3,
        w: &CellWeights,
    ) -> Option<usize> {
        let dims = self.dims;
        let plane = move |c: u32, axis: usize| (c * w.cell).min(dims[axis] - 1);
        if parts == 1 {
            let index = self.regions.len();
            let vlo = UVec3::from_array(std::array::from_fn(|a| plane(lo[a], a)));
            let vhi = UVec3::from_array(std::array::from_fn(|a| plane(hi[a], a)));
            let own_lo = Vec3::from_array(std::array::from_fn(|a| {
                if lo[a] == 0 {
                    f32::NEG_INFINITY
                } else {
                    vlo[a] as f32
                }
            }));
            let own_hi = Vec3::from_array(std::array::from_fn(|a| {
                if hi[a] == w.count[a] {
                    f32::INFINITY
                } else {
                    vhi[a] as f32
                }
            }));
            self.regions.push(Region {
                index,
                lo: vlo,
                hi: vhi,
                own_lo,
                own_hi,
            });
            self.weights.push(w.sum(lo, hi));
            self.nodes.push(Node::Leaf(index));
            return Some(self.nodes.len() - 1);
        }
        let below = parts / 2;
        // Axes by world extent, longest first; the first that can be cut.
        let extent = (hi - lo).as_vec3() * w.cell as f32 * spacing;
        let mut axes = [0usize, 1, 2];
        axes.sort_by(|&a, &b| extent[b].total_cmp(&extent[a]));
        let axis = axes.into_iter().find(|&a| hi[a] - lo[a] >= 2)?;
        let total = w.sum(lo, hi) as f64;
        let target = total * below as f64 / parts as f64;
        let mut best = (f64::INFINITY, lo[axis] + 1);
        for c in lo[axis] + 1..hi[axis] {
            let mut h = hi;
            h[axis] = c;
            let d = (w.sum(lo, h) as f64 - target).abs();
            if d < best.0 {
                best = (d, c);
            }
        }
        let cut = best.1;
        let (mut lower_hi, mut upper_lo) = (hi, lo);
        lower_hi[axis] = cut;
        upper_lo[axis] = cut;
        // Each side needs a cell per part it gets: fall back to a split
        // that can be built, or fail.
        let node = self.nodes.len();
        self.nodes.push(Node::Leaf(usize::MAX));
        let lower = self.build(lo, lower_hi, below, spacing, w)?;
        let upper = self.build(upper_lo, hi, parts - below, spacing, w)?;
        self.nodes[node] = Node::Split {
            axis,
            plane: plane(cut, axis),
            lower,
            upper,
        };
        Some(node)
    }

    /// The regions, in the order of their indices.
    pub fn regions(&self) -> &[Region] {
        &self.regions
    }

    /// The weight each region was balanced with (same order).
    pub fn weights(&self) -> &[u64] {
        &self.weights
    }

    /// The dimensions of the partitioned grid.
    pub fn dims(&self) -> UVec3 {
        self.dims
    }

    /// The region indices front to back for a camera whose eye (perspective)
    /// or view direction (orthographic) is `view`, in the voxel space of
    /// the whole grid.
    pub fn visibility_order(&self, projection: Projection, view: Vec3) -> Vec<usize> {
        let mut order = Vec::with_capacity(self.regions.len());
        let mut stack = vec![0usize];
        while let Some(n) = stack.pop() {
            match self.nodes[n] {
                Node::Leaf(r) => order.push(r),
                Node::Split {
                    axis,
                    plane,
                    lower,
                    upper,
                } => {
                    let lower_first = lower_first(projection, view, axis, plane);
                    // Pushed in reverse: the front child is popped first.
                    if lower_first {
                        stack.extend([upper, lower]);
                    } else {
                        stack.extend([lower, upper]);
                    }
                }
            }
        }
        order
    }

    /// Binary swap's pairings for a camera whose eye (perspective) or view
    /// direction (orthographic) is `view`: for each region, one
    /// [`SwapPair`] a round, from the deepest split of the k-d tree up to
    /// the root. At a split whose two sides hold `n` regions each (listed
    /// in the tree's order), the `i`-th region of one side pairs with the
    /// `i`-th of the other, so after the rounds below it both hold the same
    /// part of the screen. `None` unless every split gives both sides the
    /// same number of regions (the balanced tree of `2^k` regions).
    pub fn swap_schedule(&self, projection: Projection, view: Vec3) -> Option<Vec<Vec<SwapPair>>> {
        let mut schedule = vec![Vec::new(); self.regions.len()];
        self.swap_subtree(0, projection, view, &mut schedule)?;
        Some(schedule)
    }

    /// The regions of the subtree at `node`, in the tree's order; pushes
    /// the rounds of its splits (deepest first) onto `schedule`.
    fn swap_subtree(
        &self,
        node: usize,
        projection: Projection,
        view: Vec3,
        schedule: &mut [Vec<SwapPair>],
    ) -> Option<Vec<usize>> {
        match self.nodes[node] {
            Node::Leaf(r) => Some(vec![r]),
            Node::Split {
                axis,
                plane,
                lower,
                upper,
            } => {
                let low = self.swap_subtree(lower, projection, view, schedule)?;
                let up = self.swap_subtree(upper, projection, view, schedule)?;
                if low.len() != up.len() {
                    return None;
                }
                let lower_front = lower_first(projection, view, axis, plane);
                for (&l, &u) in low.iter().zip(&up) {
                    schedule[l].push(SwapPair {
                        partner: u,
                        lower: true,
                        front: lower_front,
                    });
                    schedule[u].push(SwapPair {
                        partner: l,
                        lower: false,
                        front: !lower_front,
                    });
                }
                Some(low.into_iter().chain(up).collect())
            }
        }
    }
}

/// One round of binary swap for one region ([`Partition::swap_schedule`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SwapPair {
    /// The region on the other side of the round's split.
    pub partner: usize,
    /// Whether this region is on the lower side of the split (it keeps the
    /// first half of the pair's screen region).
    pub lower: bool,
    /// Whether this region's side is in front for the camera.
    pub front: bool,
}

/// Whether the lower side of the split `axis` at `plane` is in front, for
/// an eye (perspective) or view direction (orthographic) `view`: for a
/// perspective camera the eye's side (a correct order for every ray, the
/// eye inside the volume too).
fn lower_first(projection: Projection, view: Vec3, axis: usize, plane: u32) -> bool {
    match projection {
        Projection::Perspective => view[axis] < plane as f32,
        Projection::Orthographic => view[axis] >= 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_tile_the_volume_and_balance_voxels() {
        let dims = UVec3::new(129, 65, 40);
        for parts in 1..=7 {
            let p = Partition::kd(dims, Vec3::ONE, parts, &CellWeights::voxels(dims)).unwrap();
            assert_eq!(p.regions().len(), parts);
            // Every point of a lattice finer than the voxels has one owner.
            let mut rng = fastrand::Rng::with_seed(parts as u64);
            for _ in 0..5000 {
                let q =
                    Vec3::new(rng.f32(), rng.f32(), rng.f32()) * (dims.as_vec3() + 2.0) - Vec3::ONE;
                let q = (q * 4.0).round() / 4.0;
                let owners = p.regions().iter().filter(|r| r.owns(q)).count();
                assert_eq!(owners, 1, "{q} with {parts} parts");
            }
            let w = p.weights();
            let (lo, hi) = (w.iter().min().unwrap(), w.iter().max().unwrap());
            assert!(*hi as f64 <= 1.35 * *lo as f64, "{parts} parts: {w:?}");
        }
    }

    #[test]
    fn visibility_order_puts_the_eyes_side_first() {
        let dims = UVec3::new(100, 10, 10);
        let p = Partition::kd(dims, Vec3::ONE, 4, &CellWeights::voxels(dims)).unwrap();
        // Split along x only: regions sorted by lo.x.
        let by_x = |o: Vec<usize>| o.iter().map(|&i| p.regions()[i].lo.x).collect::<Vec<_>>();
        let front = by_x(p.visibility_order(Projection::Perspective, Vec3::new(-5.0, 5.0, 5.0)));
        assert!(front.windows(2).all(|w| w[0] < w[1]), "{front:?}");
        let back = by_x(p.visibility_order(Projection::Perspective, Vec3::new(500.0, 5.0, 5.0)));
        assert!(back.windows(2).all(|w| w[0] > w[1]), "{back:?}");
        // Inside, between regions: the eye's region first.
        let inside = p.visibility_order(Projection::Perspective, Vec3::new(30.0, 5.0, 5.0));
        assert!(p.regions()[inside[0]].owns(Vec3::new(30.0, 5.0, 5.0)));
        let ortho = by_x(p.visibility_order(Projection::Orthographic, Vec3::NEG_X));
        assert!(ortho.windows(2).all(|w| w[0] > w[1]), "{ortho:?}");
    }

    #[test]
    fn occupancy_moves_the_split_towards_the_occupied_cells() {
        let dims = UVec3::splat(65);
        let cells =
            MacrocellGrid::from_ranges(8, MacrocellGrid::count_for(dims, 8), vec![(0.0, 0.0); 512]);
        // Only the cells with x < 2 (voxels 0..16) are occupied.
        let w = CellWeights::macrocells(dims, &cells, |i| i / 64 < 2);
        let p = Partition::kd(dims, Vec3::ONE, 2, &w).unwrap();
        let r = p.regions();
        assert_eq!(r[0].hi.x, r[1].lo.x);
        assert!(r[0].hi.x <= 16, "{r:?}");
    }

    #[test]
    fn owned_sample_ranges_match_brute_force() {
        let dims = UVec3::new(50, 40, 30);
        let p = Partition::kd(dims, Vec3::ONE, 5, &CellWeights::voxels(dims)).unwrap();
        let mut rng = fastrand::Rng::with_seed(9);
        for trial in 0..2000 {
            let origin = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 120.0 - 35.0;
            let mut dir = Vec3::new(rng.f32(), rng.f32(), rng.f32()) - 0.5;
            if trial % 5 == 0 {
                dir.z = 0.0;
            }
            let (t0, step) = (rng.f32() * 3.0, 0.2 + rng.f32());
            let end = rng.u32(0..300);
            let first = rng.u32(0..end.max(1)).min(end);
            let pos = |k: u32| origin + dir * (t0 + k as f32 * step);
            let mut covered = 0;
            for r in p.regions() {
                let got = r.sample_range(origin, dir, t0, 1.0 / step, (first, end), pos);
                let kept: Vec<u32> = (first..end).filter(|&k| r.owns(pos(k))).collect();
                let want = match (kept.first(), kept.last()) {
                    (Some(&a), Some(&b)) => (a, b + 1),
                    _ => (got.0, got.0),
                };
                assert_eq!(got, want, "trial {trial}, region {}", r.index);
                covered += got.1 - got.0;
            }
            assert_eq!(covered, end - first, "trial {trial}");
        }
    }
}
