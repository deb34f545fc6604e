//! [`SampleBatch`]: up to [`LANES`] consecutive samples of a ray, located and
//! interpolated lane by lane.
//!
//! Most of the work of a sample does not depend on the sample before it: its
//! position, its cell and fractions, the trilinear blend of the corners, its
//! place in the TF table. The batch writes each of those as a loop over the
//! lanes of fixed-size arrays, which the compiler turns into vector
//! instructions (8 lanes per instruction with AVX2, see [`crate::simd`]).
//! What stays lane by
//! lane is what cannot be vectorised: loading the eight corners of each new
//! cell the ray enters (consecutive samples often share a cell, so a batch
//! loads each distinct cell once and splats each corner into the lanes from
//! the first in that cell on, a blend in a register per corner), and
//! compositing (each sample depends on the last).
//!
//! The arithmetic is the scalar path's, operation for operation, so a batch
//! gives the same values as [`Volume::sample`](crate::volume::Volume::sample)
//! at [`RaySegment::pos`], bit for bit.

// Lane-wise loops index several arrays by the lane: clearer as `for l`.
#![allow(clippy::needless_range_loop)]

use glam::{UVec3, Vec3};

use super::RaySegment;
use crate::simd::{self, Isa, Kernel, LANES};
use crate::volume::{Corners, Grid, Volume, split_coord};

/// How many batches ahead of the one it fills [`SampleBatch::fill`] asks the
/// memory for a cell (6 measured no better than 4).
pub const PREFETCH_BATCHES: u32 = 4;

/// Up to [`LANES`] consecutive samples `k..k + len` of one ray: their cells,
/// fractions, corners and interpolated values, lane `l` holding sample
/// `k + l`. Lanes at and past `len` hold values that mean nothing. Filling
/// the next batch of the ray reuses the last valid lane's corners when the
/// ray is still in that cell.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(32))]
pub struct SampleBatch {
    /// Interpolated value per lane.
    pub value: [f32; LANES],
    /// Corner `j` (in [`Corners`] order) of each lane's cell.
    pub corners: [[f32; LANES]; 8],
    /// Cell coordinate per axis and lane.
    pub cell: [[u32; LANES]; 3],
    /// Fraction within the cell per axis and lane.
    pub frac: [[f32; LANES]; 3],
    /// Valid lanes (0 before the first fill).
    pub len: usize,
    /// The grid's largest coordinate and last cell per axis (clamping).
    max_coord: [f32; 3],
    last: [u32; 3],
}

impl SampleBatch {
    /// An empty batch for sampling a volume on `grid`.
    #[inline(always)]
    pub fn new(grid: &Grid) -> Self {
        SampleBatch {
            value: [0.0; LANES],
            corners: [[0.0; LANES]; 8],
            cell: [[0; LANES]; 3],
            frac: [[0.0; LANES]; 3],
            len: 0,
            max_coord: grid.max_coord().to_array(),
            last: grid.last_cell().to_array(),
        }
    }

    /// Samples `k..k + len` of `seg` (`len <= LANES`).
    #[inline(always)]
    pub fn fill<V: Volume, I: Isa>(
        &mut self,
        isa: I,
        volume: &V,
        seg: &RaySegment,
        k: u32,
        len: usize,
    ) {
        debug_assert!(len <= LANES && k < i32::MAX as u32 - LANES as u32);
        // The previous fill's last cell, before this fill overwrites it.
        let (prev_cell, prev_corners) = match self.len {
            0 => (UVec3::MAX, [0.0; 8]),
            n => (self.cell(n - 1), self.corners(n - 1)),
        };
        self.len = len;
        let (max_coord, last) = (self.max_coord, self.last);
        let origin = seg.origin.to_array();
        let dir = seg.dir.to_array();
        // Positions, cells and fractions: `seg.pos` and `Volume::locate`,
        // lane-wise.
        // `seg.t`, converted through `i32` (exact: a ray has at most
        // `MAX_SAMPLES_PER_RAY` samples), which a vector instruction does.
        let mut t = [0.0f32; LANES];
        for (l, t) in t.iter_mut().enumerate() {
            *t = seg.t0 + (k + l as u32) as i32 as f32 * seg.step;
        }
        for a in 0..3 {
            for l in 0..LANES {
                let p = origin[a] + dir[a] * t[l];
                let (i, f) = split_coord(p, max_coord[a], last[a]);
                self.cell[a][l] = i;
                self.frac[a][l] = f;
            }
        }
        // The corners `PREFETCH_BATCHES` batches ahead are on their way
        // while this one works (rays through a large volume miss the cache
        // on most new cells).
        volume.prefetch(seg.pos(k + PREFETCH_BATCHES * LANES as u32));
        // Corners: lane l starts a new cell when its cell differs from lane
        // l − 1's (lane 0 compares with the previous fill's last lane). The
        // cells are loaded in lane order, each corner splatted into the lanes
        // from its first on, so each lane ends with its own cell's. (Writing
        // the cells into a table in memory lane by lane and permuting it
        // made every batch wait for those stores: a vector load of several
        // scalar stores cannot be forwarded from them.)
        let mut diff = [0u32; LANES];
        for a in 0..3 {
            let c = &self.cell[a];
            let mut prev = [0u32; LANES];
            prev[0] = prev_cell[a];
            prev[1..].copy_from_slice(&c[..LANES - 1]);
            for l in 0..LANES {
                diff[l] |= c[l] ^ prev[l];
            }
        }
        let starts = isa.nonzero_mask(&diff) & ((1u32 << len) - 1);
        let mut corners = prev_corners.map(|v| [v; LANES]);
        let mut pending = starts;
        while pending != 0 {
            let l = pending.trailing_zeros() as usize;
            pending &= pending - 1;
            let c = volume.corners(self.cell(l));
            for j in 0..8 {
                corners[j] = isa.splat_from(corners[j], c[j], l);
            }
        }
        // Trilinear blend: `volume::interpolate`, lane-wise, from the corners
        // still in registers.
        self.corners = corners;
        let c = &corners;
        let [fx, fy, fz] = &self.frac;
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        for l in 0..LANES {
            let c00 = lerp(c[0][l], c[1][l], fz[l]);
            let c01 = lerp(c[2][l], c[3][l], fz[l]);
            let c10 = lerp(c[4][l], c[5][l], fz[l]);
            let c11 = lerp(c[6][l], c[7][l], fz[l]);
            self.value[l] = lerp(lerp(c00, c01, fy[l]), lerp(c10, c11, fy[l]), fx[l]);
        }
    }

    /// Lane `l`'s cell.
    #[inline(always)]
    pub fn cell(&self, l: usize) -> UVec3 {
        UVec3::new(self.cell[0][l], self.cell[1][l], self.cell[2][l])
    }

    /// Lane `l`'s fractions within its cell.
    #[inline(always)]
    pub fn frac(&self, l: usize) -> Vec3 {
        Vec3::new(self.frac[0][l], self.frac[1][l], self.frac[2][l])
    }

    /// Lane `l`'s corners.
    #[inline(always)]
    pub fn corners(&self, l: usize) -> Corners {
        std::array::from_fn(|j| self.corners[j][l])
    }
}

/// Folds `f` over the interpolated values of samples `k..end` of `seg`, in
/// sample order, a batch at a time in the best instruction set.
#[inline(always)]
pub fn fold_values<V: Volume, T, F: FnMut(T, f32) -> T>(
    volume: &V,
    seg: &RaySegment,
    k: u32,
    end: u32,
    init: T,
    f: F,
) -> T {
    simd::dispatch(FoldValues {
        volume,
        seg,
        k,
        end,
        init,
        f,
    })
}

/// [`fold_values`] as a [`Kernel`].
struct FoldValues<'a, V, T, F> {
    volume: &'a V,
    seg: &'a RaySegment,
    k: u32,
    end: u32,
    init: T,
    f: F,
}

impl<V: Volume, T, F: FnMut(T, f32) -> T> Kernel for FoldValues<'_, V, T, F> {
    type Output = T;

    #[inline(always)]
    fn run<I: Isa>(self, isa: I) -> T {
        let FoldValues {
            volume,
            seg,
            k,
            end,
            mut init,
            mut f,
        } = self;
        let mut batch = SampleBatch::new(volume.grid());
        let mut b = k;
        while b < end {
            let len = ((end - b) as usize).min(LANES);
            batch.fill(isa, volume, seg, b, len);
            for &v in &batch.value[..len] {
                init = f(init, v);
            }
            b += len as u32;
        }
        init
    }
}

#[cfg(test)]
mod tests {
    use glam::{UVec3, Vec3};

    use super::*;
    use crate::geometry::Ray;
    use crate::simd::Portable;
    use crate::volume::{AnyVolume, Grid, VolumeVisitor};

    /// Checks that batches of every length, reusing corners from batch to
    /// batch, give exactly `Volume::sample` at `seg.pos` in every
    /// instruction set, along rays that cross many cells and that linger in
    /// one (fine steps), and that the cell and fraction of each lane are
    /// `Volume::locate`'s.
    struct AgreesWithSample;

    impl VolumeVisitor for AgreesWithSample {
        type Output = ();
        fn visit<V: Volume>(self, volume: &V) {
            let grid = *volume.grid();
            let mut rng = fastrand::Rng::with_seed(7);
            for step in [0.05, 0.3, 1.7] {
                for _ in 0..40 {
                    let origin = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 80.0 - 20.0;
                    let target =
                        grid.bounds().center() + Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 10.0;
                    let ray = Ray {
                        origin,
                        dir: (target - origin).normalize(),
                    };
                    let Some(seg) = RaySegment::new(&grid, &ray, step) else {
                        continue;
                    };
                    check(Portable, volume, &seg, &mut rng);
                    #[cfg(target_arch = "x86_64")]
                    if let Some(avx2) = crate::simd::Avx2::detect() {
                        check(avx2, volume, &seg, &mut rng);
                    }
                }
            }
        }
    }

    fn check<I: Isa, V: Volume>(isa: I, volume: &V, seg: &RaySegment, rng: &mut fastrand::Rng) {
        let mut batch = SampleBatch::new(volume.grid());
        let mut k = 0;
        while k < seg.count {
            let len = rng.usize(1..=LANES).min((seg.count - k) as usize);
            batch.fill(isa, volume, seg, k, len);
            for l in 0..len {
                let p = seg.pos(k + l as u32);
                let at = volume.locate(p);
                assert_eq!(batch.value[l].to_bits(), volume.sample(p).to_bits());
                assert_eq!((batch.cell(l), batch.frac(l)), (at.cell, at.frac));
                assert_eq!(batch.corners(l), volume.corners(at.cell));
            }
            k += len as u32;
        }
    }

    #[test]
    fn batches_give_the_samples_of_the_scalar_path() {
        let grid = Grid::new(UVec3::new(37, 29, 41), Vec3::new(1.0, 0.7, 1.3));
        let f = |v: UVec3| ((v.x * 7 + v.y * 13 + v.z * 29) % 251) as u8;
        AnyVolume::from_fn(grid, f).visit(AgreesWithSample);
        AnyVolume::from_fn(grid, |v| f(v) as f32 * 0.37 - 20.0).visit(AgreesWithSample);
        AnyVolume::bricked_from_fn(grid, 8, f)
            .unwrap()
            .visit(AgreesWithSample);
    }
}
