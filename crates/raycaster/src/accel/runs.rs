//! [`SkipRuns`]: the samples of a ray cut into runs that are empty or lie in
//! one occupied macrocell, as a renderer's integrator consumes them.
//!
//! This is the one place where a ray walks the skip grid: an integrator asks
//! for the runs of its sample range and decides per run what to do (skip an
//! empty run, composite a cell of one colour without sampling it, march
//! sample by sample, skip a cell whose range cannot change the result).

use glam::UVec3;

use super::SkipGrid;
use super::skip::{Ahead, CellKind};
use crate::integrator::RaySegment;

/// What a run of samples lies in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunKind {
    /// Empty space: no sample of the run contributes.
    Empty,
    /// One occupied macrocell (its index in the macrocell grid).
    Cell(usize),
    /// Skipping is off: nothing is known about the samples.
    Unknown,
}

/// Samples `start..end` of a ray, all of one [`RunKind`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleRun {
    /// First sample index.
    pub start: u32,
    /// One past the last sample index. For an empty run it is the first
    /// sample after the empty box, which may lie past the range asked for;
    /// other runs end within the range.
    pub end: u32,
    /// What the samples lie in.
    pub kind: RunKind,
}

/// The runs of samples `k0..k1` of a ray (see [`SkipRuns::new`]).
///
/// Each run is the macrocell (or empty box) holding its first sample,
/// found by [`SkipGrid::classify_ahead`]'s rules, and ends at the first
/// sample at or after the ray leaves that box; empty boxes the ray jumps
/// across one after another (closing in on a surface) make one run. A
/// classification from scratch is a chain of dependent steps (the sample's
/// position, its cell, the cell's box, the box's exit, the next sample)
/// that the processor cannot overlap from one run to the next. So the runs also walk the macrocells with a
/// 3D DDA (`MacrocellWalk`), which knows the next cell and where the ray
/// leaves it from the last one, and only check that the cell of the run's
/// first sample is the one the DDA predicted: the check is a branch that
/// is almost always taken, off the chain. The runs are the same either
/// way: the DDA's exit is the cell box's slab exit, bit for bit (unless
/// merged, below: then each run's samples lie in cells of its kind).
///
/// Occupied macrocells that follow one another along the ray may make one
/// run: those for which the `key` (of the macrocell's index) is the same
/// `Some`, up to `MERGE_SAMPLES` samples, walked by the DDA alone (an
/// integrator that treats such cells alike saves a run each: the sample
/// position, lookups and bookkeeping of a run cost several DDA steps).
/// The run is `Cell` of its first macrocell. [`SkipRuns::new`] merges none.
#[derive(Debug, Clone)]
pub struct SkipRuns<'a, K = fn(usize) -> Option<u64>> {
    skip: Option<&'a SkipGrid>,
    seg: &'a RaySegment,
    k: u32,
    k1: u32,
    /// The DDA's cell, when there is a prediction.
    walk: Option<MacrocellWalk>,
    /// The empty space ahead of the ray (when skipping).
    ahead: Option<Ahead<'a>>,
    /// The ray per axis, for the DDA.
    axes: Axes,
    /// Which occupied cells one run may span (see above).
    key: K,
    /// Whether empty cells beside occupied ones go in one run too.
    merge_empty: bool,
}

/// The most samples [`SkipRuns`] puts in one run of several macrocells: a
/// ray that ends (ERT) early in a run would otherwise have walked the
/// rest of it for nothing.
pub const MERGE_SAMPLES: u32 = 64;

impl<'a> SkipRuns<'a> {
    /// The runs of samples `k0..k1` of `seg` (clamped to the ray's kept
    /// samples `first..count`) by `skip`,
    /// or, with `None`, one run of [`RunKind::Unknown`].
    #[inline(always)]
    pub fn new(skip: Option<&'a SkipGrid>, seg: &'a RaySegment, k0: u32, k1: u32) -> Self {
        SkipRuns {
            merge_empty: false,
            ..Self::merging(skip, seg, k0, k1, |_| None)
        }
    }
}

impl<'a, K: Fn(usize) -> Option<u64>> SkipRuns<'a, K> {
    /// [`SkipRuns::new`], with consecutive occupied macrocells of one
    /// `key` in one run, and consecutive empty macrocells beside occupied
    /// ones in one run.
    #[inline(always)]
    pub fn merging(
        skip: Option<&'a SkipGrid>,
        seg: &'a RaySegment,
        k0: u32,
        k1: u32,
        key: K,
    ) -> Self {
        SkipRuns {
            skip,
            seg,
            k: k0.max(seg.first),
            k1: k1.min(seg.count),
            walk: None,
            ahead: skip.map(|s| s.ahead(seg.inv_dir)),
            axes: Axes::of(seg, skip),
            key,
            merge_empty: true,
        }
    }
}

impl<K: Fn(usize) -> Option<u64>> Iterator for SkipRuns<'_, K> {
    type Item = SampleRun;

    #[inline(always)]
    fn next(&mut self) -> Option<SampleRun> {
        let (k, seg) = (self.k, self.seg);
        if k >= self.k1 {
            return None;
        }
        let (Some(skip), Some(ahead)) = (self.skip, self.ahead) else {
            self.k = self.k1;
            return Some(SampleRun {
                start: k,
                end: self.k1,
                kind: RunKind::Unknown,
            });
        };
        let (cell, index) = skip.locate(seg.pos(k));
        let kind = skip.cell_kind_ahead(cell, index, ahead);
        // Jumps over empty boxes that follow one another (a ray closing
        // in on a surface) make one run, without a DDA: the ray leaves each
        // box through its far faces and the next is found where it lands.
        if let CellKind::EmptyWithin(mut b) = kind {
            let mut end = k;
            loop {
                end = seg
                    .first_index_at_or_after(b.exit(seg.origin, seg.inv_dir))
                    .max(end + 1);
                if end >= self.k1 {
                    break;
                }
                let (cell, index) = skip.locate(seg.pos(end));
                match skip.cell_kind_ahead(cell, index, ahead) {
                    CellKind::EmptyWithin(next) => b = next,
                    _ => break,
                }
            }
            self.walk = None;
            self.k = end;
            return Some(SampleRun {
                start: k,
                end,
                kind: RunKind::Empty,
            });
        }
        let walk = match self.walk {
            Some(w) if w.cell == cell.as_ivec3().to_array() => w,
            _ => MacrocellWalk::new(skip, &self.axes, cell, index),
        };
        // The run ends at the first sample at or after the cell's exit
        // (possibly one early, never late: see `first_index_at_or_after`),
        // and always advances.
        let kind = match kind {
            CellKind::Occupied => RunKind::Cell(walk.index as usize),
            _ => RunKind::Empty,
        };
        // The run's last macrocell: the next ones along the ray while they
        // are occupied with the same key, and the run stays short; or, for
        // an empty cell beside occupied ones, the next ones like it (one in
        // empty space far from any occupied cell is left to the jumps
        // above).
        let last = match kind {
            RunKind::Cell(i) => match (self.key)(i) {
                Some(key) => {
                    let t_stop = seg.t(self.k1.min(k.saturating_add(MERGE_SAMPLES)));
                    walk.extend_while(skip, &self.axes, t_stop, |w| {
                        let j = w.index as usize;
                        skip.is_occupied_index(j) && (self.key)(j) == Some(key)
                    })
                }
                None => walk,
            },
            _ if self.merge_empty => walk.extend_while(skip, &self.axes, seg.t(self.k1), |w| {
                let cell = UVec3::from_array(w.cell.map(|c| c as u32));
                matches!(
                    skip.cell_kind_ahead(cell, w.index as usize, ahead),
                    CellKind::EmptyAlone
                )
            }),
            _ => walk,
        };
        let mut end = seg.first_index_at_or_after(last.exit()).max(k + 1);
        if kind != RunKind::Empty {
            end = end.min(self.k1);
        }
        // The prediction for the next run: the first cell along the ray
        // that the next sample can lie in (a cell whose exit comes before
        // it holds no sample).
        self.walk = None;
        let t_end = seg.t(end);
        let mut w = last;
        for _ in 0..3 {
            if !w.advance(skip, &self.axes) {
                break;
            }
            if w.exit() > t_end {
                self.walk = Some(w);
                break;
            }
        }
        self.k = end;
        Some(SampleRun {
            start: k,
            end,
            kind,
        })
    }
}

/// A 3D DDA's position among the skip grid's macrocells: the cell, its
/// index, and where the ray leaves it across the plane ahead on each axis,
/// computed as [`Aabb::exit`] computes the cell box's (so the least of
/// them is that exit exactly).
///
/// A step's chain from one to the next is only which plane is nearest and
/// the selects it drives: every field is read at fixed positions (a `glam`
/// vector or array indexed by a run-time axis went through memory, a store
/// and a reload a step), and the plane beyond the next on each axis
/// (`after`) is worked out a step ahead, off that chain.
///
/// [`Aabb::exit`]: crate::geometry::Aabb::exit
#[derive(Debug, Clone, Copy)]
struct MacrocellWalk {
    cell: [i32; 3],
    index: isize,
    next: [f32; 3],
    /// Per axis, where the ray leaves the cell after this one along it.
    after: [f32; 3],
}

impl MacrocellWalk {
    #[inline(always)]
    fn new(skip: &SkipGrid, axes: &Axes, cell: UVec3, index: usize) -> Self {
        let cell = cell.as_ivec3().to_array();
        MacrocellWalk {
            cell,
            index: index as isize,
            next: std::array::from_fn(|a| plane(skip, axes, cell[a], a)),
            after: std::array::from_fn(|a| plane(skip, axes, cell[a] + axes.step[a], a)),
        }
    }

    /// Where the ray leaves the cell.
    #[inline(always)]
    fn exit(&self) -> f32 {
        // No plane is NaN (see `plane`), so the comparisons are `min`.
        let [n0, n1, n2] = self.next;
        let m = if n1 < n0 { n1 } else { n0 };
        if n2 < m { n2 } else { m }
    }

    /// The last of this cell and the cells after it along the ray that
    /// `joins` accepts, stepping on while the ray leaves the last before
    /// `t_stop`.
    #[inline(always)]
    fn extend_while(
        self,
        skip: &SkipGrid,
        axes: &Axes,
        t_stop: f32,
        joins: impl Fn(&MacrocellWalk) -> bool,
    ) -> Self {
        let (mut last, mut w) = (self, self);
        while last.exit() < t_stop && w.advance(skip, axes) && joins(&w) {
            last = w;
        }
        last
    }

    /// Steps into the next cell along the ray; false when that is off the
    /// grid (or the ray moves along no axis).
    #[inline(always)]
    fn advance(&mut self, skip: &SkipGrid, axes: &Axes) -> bool {
        // The axis of the nearest plane, the lowest on a tie, as three
        // flags. (Forcing selects without branches on them, with
        // `select_unpredictable`, or working out only the moving axis's
        // plane measured no faster.)
        let [n0, n1, n2] = self.next;
        let y_before_x = n1 < n0;
        let z = n2 < if y_before_x { n1 } else { n0 };
        let y = y_before_x && !z;
        let x = !y_before_x && !z;
        let c: [i32; 3] = std::array::from_fn(|a| self.cell[a] + axes.step[a]);
        // One unsigned compare for both ends of the grid.
        let inside: [bool; 3] =
            std::array::from_fn(|a| axes.step[a] != 0 && (c[a] as u32) < axes.count[a]);
        if !on_moving_axis(inside, y, z) {
            return false;
        }
        self.index += on_moving_axis(axes.index_step, y, z);
        for (a, moves) in [x, y, z].into_iter().enumerate() {
            let beyond = plane(skip, axes, c[a] + axes.step[a], a);
            self.cell[a] = if moves { c[a] } else { self.cell[a] };
            self.next[a] = if moves { self.after[a] } else { self.next[a] };
            self.after[a] = if moves { beyond } else { self.after[a] };
        }
        true
    }
}

/// The entry of `v` for the axis a DDA step moves along, given as the
/// flags `y` and `z` (neither: x), chosen by selects rather than by
/// indexing with a run-time axis (see [`MacrocellWalk`]).
#[inline(always)]
fn on_moving_axis<T: Copy>(v: [T; 3], y: bool, z: bool) -> T {
    if z {
        v[2]
    } else if y {
        v[1]
    } else {
        v[0]
    }
}

/// What the DDA reads of a ray per axis, as arrays (see [`MacrocellWalk`]).
#[derive(Debug, Clone, Copy)]
struct Axes {
    origin: [f32; 3],
    inv_dir: [f32; 3],
    /// ±1, 0 where the ray does not move along the axis (or so little that
    /// `1/d` overflows: [`Aabb::exit`] ignores such an axis too).
    ///
    /// [`Aabb::exit`]: crate::geometry::Aabb::exit
    step: [i32; 3],
    /// The skip grid's cells per axis.
    count: [u32; 3],
    /// How far the index moves for a step along each axis (`step` times
    /// the index stride).
    index_step: [isize; 3],
}

impl Axes {
    /// The ray `seg` on the cells of `skip` (any grid when `None`: then
    /// the DDA is never used).
    #[inline(always)]
    fn of(seg: &RaySegment, skip: Option<&SkipGrid>) -> Self {
        let inv_dir = seg.inv_dir.to_array();
        let step = inv_dir.map(|inv| {
            if inv.abs() < f32::INFINITY {
                if inv >= 0.0 { 1 } else { -1 }
            } else {
                0
            }
        });
        let (count, strides) = skip.map_or(([0; 3], [0; 3]), |skip| {
            (skip.count().to_array(), skip.index_strides())
        });
        Axes {
            origin: seg.origin.to_array(),
            inv_dir,
            step,
            count,
            index_step: std::array::from_fn(|a| step[a] as isize * strides[a]),
        }
    }
}

/// Where the ray leaves macrocell coordinate `c` on axis `a` (+∞ when it
/// does not move along `a`), as the slab test of the cell's box computes
/// it: the box's corner `c·side`, its far side `c·side + side`. Never NaN:
/// `1/d` is finite on an axis the ray moves along.
#[inline(always)]
fn plane(skip: &SkipGrid, axes: &Axes, c: i32, a: usize) -> f32 {
    let side = skip.cell_side();
    let lo = c as f32 * side;
    match axes.step[a] {
        0 => f32::INFINITY,
        s => {
            let far = if s > 0 { lo + side } else { lo };
            (far - axes.origin[a]) * axes.inv_dir[a]
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::accel::skip::CellClass;
    use crate::geometry::Ray;
    use crate::volume::Grid;

    /// The runs of samples `k0..k1` by [`SkipGrid::classify_ahead`] of each
    /// run's first sample, without the DDA's prediction; a jump over an
    /// empty box larger than a macrocell right after another such jump
    /// extends that one's run.
    fn classified_runs(skip: &SkipGrid, seg: &RaySegment, k0: u32, k1: u32) -> Vec<SampleRun> {
        let ahead = skip.ahead(seg.inv_dir);
        let (mut k, k1) = (k0.max(seg.first), k1.min(seg.count));
        let mut runs: Vec<SampleRun> = Vec::new();
        let mut jumping = false;
        while k < k1 {
            let (bounds, kind) = match skip.classify_ahead(seg.pos(k), ahead) {
                CellClass::Occupied { bounds, index, .. } => (bounds, RunKind::Cell(index)),
                CellClass::Empty(bounds) => (bounds, RunKind::Empty),
            };
            let (cell, index) = skip.locate(seg.pos(k));
            let jump = matches!(
                skip.cell_kind_ahead(cell, index, ahead),
                CellKind::EmptyWithin(_)
            );
            let mut end = seg
                .first_index_at_or_after(bounds.exit(seg.origin, seg.inv_dir))
                .max(k + 1);
            if kind != RunKind::Empty {
                end = end.min(k1);
            }
            match runs.last_mut() {
                Some(last) if jumping && jump => last.end = end,
                _ => runs.push(SampleRun {
                    start: k,
                    end,
                    kind,
                }),
            }
            jumping = jump;
            k = end;
        }
        runs
    }

    /// The grid of a test's `count` macrocells of 4 voxels (anisotropic
    /// spacing).
    fn test_grid(count: UVec3) -> Grid {
        Grid::new(count * 4 + UVec3::ONE, Vec3::new(1.0, 0.7, 1.3))
    }

    /// The `i`-th of a test's random rays through `grid`: from outside or
    /// inside, some along the axes (a direction component of 0), at one of
    /// three steps; `None` when it misses the grid.
    fn random_segment(rng: &mut fastrand::Rng, grid: &Grid, i: usize) -> Option<RaySegment> {
        let size = grid.bounds().max;
        let inside = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * size;
        let mut dir = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 2.0 - 1.0;
        if i.is_multiple_of(5) {
            dir[rng.usize(0..3)] = 0.0;
        }
        let dir = dir.normalize_or(Vec3::X);
        let origin = if i.is_multiple_of(3) {
            inside
        } else {
            inside - dir * 3.0 * size.length()
        };
        let step = [0.2, 0.5, 1.7][i % 3];
        RaySegment::new(grid, &Ray { origin, dir }, step)
    }

    /// The runs with the DDA's predictions are those of classifying every
    /// run's first sample, on random grids, for rays from outside and
    /// inside, some along the axes (a direction component of 0), whole and
    /// in pieces (as the object renderer asks for them, brick by brick).
    #[test]
    fn predicted_runs_are_the_classified_ones() {
        let mut rng = fastrand::Rng::with_seed(31);
        for case in 0..24 {
            let count = UVec3::new(rng.u32(1..14), rng.u32(1..14), rng.u32(1..14));
            let density = [0.02, 0.1, 0.4][case % 3];
            let cells = crate::accel::random_macrocells(&mut rng, count, density);
            let skip = SkipGrid::build(&cells, |_, hi| hi > 0.5);
            let grid = test_grid(count);
            for i in 0..300 {
                let Some(seg) = random_segment(&mut rng, &grid, i) else {
                    continue;
                };
                let whole: Vec<_> = SkipRuns::new(Some(&skip), &seg, 0, u32::MAX).collect();
                assert_eq!(
                    whole,
                    classified_runs(&skip, &seg, 0, u32::MAX),
                    "case {case}"
                );
                let cut = rng.u32(0..seg.count.max(1));
                for (k0, k1) in [(0, cut), (cut, u32::MAX)] {
                    let piece: Vec<_> = SkipRuns::new(Some(&skip), &seg, k0, k1).collect();
                    assert_eq!(piece, classified_runs(&skip, &seg, k0, k1), "case {case}");
                }
            }
        }
    }

    /// Merged runs (`SkipRuns::merging`) put every sample where the
    /// classification of that sample alone puts it: an empty run's samples
    /// in empty macrocells, a cell run's in occupied macrocells of that
    /// run's key; they cover the samples asked for in order, each run
    /// starting where the last ended; and they are fewer than the runs
    /// without merging where keys repeat.
    #[test]
    fn merged_runs_hold_samples_of_their_own_kind() {
        let mut rng = fastrand::Rng::with_seed(47);
        let (mut merged_total, mut plain_total) = (0usize, 0usize);
        for case in 0..24 {
            let count = UVec3::new(rng.u32(2..14), rng.u32(2..14), rng.u32(2..14));
            let density = [0.1, 0.4, 0.8][case % 3];
            let cells = crate::accel::random_macrocells(&mut rng, count, density);
            let skip = SkipGrid::build(&cells, |_, hi| hi > 0.5);
            // Two keys (and none for some cells) over the occupied cells.
            let keys: Vec<Option<u64>> = (0..cells.ranges.len())
                .map(|_| match rng.u8(..8) {
                    0 => None,
                    k => Some((k % 2) as u64),
                })
                .collect();
            let key = |i: usize| keys[i];
            let grid = test_grid(count);
            for i in 0..200 {
                let Some(seg) = random_segment(&mut rng, &grid, i) else {
                    continue;
                };
                let ahead = skip.ahead(seg.inv_dir);
                let cut = rng.u32(0..seg.count.max(1));
                for (k0, k1) in [(0, u32::MAX), (0, cut), (cut, u32::MAX)] {
                    let runs: Vec<_> = SkipRuns::merging(Some(&skip), &seg, k0, k1, key).collect();
                    let (first, last) = (k0.max(seg.first), k1.min(seg.count));
                    let mut next = first;
                    for run in &runs {
                        assert_eq!(run.start, next, "case {case}");
                        assert!(run.end > run.start);
                        for k in run.start..run.end.min(last) {
                            match (run.kind, skip.classify_ahead(seg.pos(k), ahead)) {
                                (RunKind::Empty, CellClass::Empty(_)) => {}
                                (RunKind::Cell(i), CellClass::Occupied { index, .. }) => {
                                    assert!(
                                        index == i || (key(i).is_some() && key(index) == key(i)),
                                        "case {case}: sample {k} in cell {index}, run of {i}"
                                    );
                                }
                                (kind, class) => {
                                    panic!("case {case}: sample {k} is {class:?}, run {kind:?}")
                                }
                            }
                        }
                        next = run.end;
                    }
                    assert!(next >= last || first >= last, "case {case}");
                    if (k0, k1) == (0, u32::MAX) {
                        merged_total += runs.len();
                        plain_total += SkipRuns::new(Some(&skip), &seg, k0, k1).count();
                    }
                }
            }
        }
        assert!(
            merged_total < plain_total,
            "{merged_total} against {plain_total}"
        );
    }
}
