//! [`RayBlock`]: the rays of a block of [`PACKET_W`]×[`PACKET_H`]
//! neighbouring pixels, lane by lane (a structure of arrays).
//!
//! The frame driver sets a block's rays up together in vector instructions
//! (its `FrameJob::pixel_block`) and a packet integrator (the exact iso
//! mode, [`Integrator::integrate_packet`]) walks them together (DVR takes
//! the blocks and integrates their rays one by one); both read
//! and write the lanes where they are, so a ray is not gathered into a
//! [`RaySegment`] and scattered back into lanes on its way from one to the
//! other. Lane `l` is the pixel `(l % PACKET_W, l / PACKET_W)` of the
//! block.
//!
//! [`Integrator::integrate_packet`]: super::Integrator::integrate_packet

use glam::Vec3;

use super::RaySegment;
use super::segment::{last_estimate, sample_count};
use crate::volume::Grid;

/// Pixels per block along a row.
pub const PACKET_W: u32 = 4;
/// Pixels per block along a column.
pub const PACKET_H: u32 = 4;

/// Rays per block.
pub const BLOCK: usize = (PACKET_W * PACKET_H) as usize;

// Lane masks are `u32`s.
const _: () = assert!(BLOCK <= 32);

/// The rays of one block of pixels: per lane what a [`RaySegment`] holds,
/// and which lanes hold a ray to search.
#[derive(Debug, Clone, Copy, Default)]
pub struct RayBlock {
    /// Lanes whose ray is searched (it meets the volume's box and is not
    /// culled by the frame's proxy depths): only these lanes' fields
    /// mean anything.
    pub searched: u32,
    /// Lanes whose ray enters the volume's box but is culled by the proxy
    /// depths (it sees nothing; it counts as entering the volume).
    pub culled: u32,
    /// Ray origin in voxel space, per axis and lane.
    pub origin: [[f32; BLOCK]; 3],
    /// Ray direction in voxel space per world unit of `t`.
    pub dir: [[f32; BLOCK]; 3],
    /// `1 / dir`.
    pub inv_dir: [[f32; BLOCK]; 3],
    /// World direction (unit).
    pub world_dir: [[f32; BLOCK]; 3],
    /// [`RaySegment::t_in`] (raised to the proxy depth).
    pub t_in: [f32; BLOCK],
    /// [`RaySegment::t_out`].
    pub t_out: [f32; BLOCK],
    /// [`RaySegment::t0`].
    pub t0: [f32; BLOCK],
    /// [`RaySegment::first`].
    pub first: [u32; BLOCK],
    /// [`RaySegment::count`].
    pub count: [u32; BLOCK],
    /// [`RaySegment::step`] (one frame's: the same for every lane).
    pub step: f32,
    /// `1 / step`.
    pub inv_step: f32,
}

impl RayBlock {
    /// Lane `l`'s ray as a [`RaySegment`].
    #[inline(always)]
    pub fn segment(&self, l: usize) -> RaySegment {
        let at = |v: &[[f32; BLOCK]; 3]| Vec3::new(v[0][l], v[1][l], v[2][l]);
        RaySegment {
            origin: at(&self.origin),
            dir: at(&self.dir),
            inv_dir: at(&self.inv_dir),
            world_dir: at(&self.world_dir),
            t_in: self.t_in[l],
            t_out: self.t_out[l],
            t0: self.t0[l],
            step: self.step,
            inv_step: self.inv_step,
            first: self.first[l],
            count: self.count[l],
        }
    }

    /// Puts `seg` in lane `l` (the masks are left as they are).
    #[inline(always)]
    pub fn set(&mut self, l: usize, seg: &RaySegment) {
        for a in 0..3 {
            self.origin[a][l] = seg.origin[a];
            self.dir[a][l] = seg.dir[a];
            self.inv_dir[a][l] = seg.inv_dir[a];
            self.world_dir[a][l] = seg.world_dir[a];
        }
        self.t_in[l] = seg.t_in;
        self.t_out[l] = seg.t_out;
        self.t0[l] = seg.t0;
        self.first[l] = seg.first;
        self.count[l] = seg.count;
        self.step = seg.step;
        self.inv_step = seg.inv_step;
    }

    /// Whether clipping (or jitter) left lane `l`'s ray without a sample
    /// ([`RaySegment::is_empty`]).
    #[inline(always)]
    pub fn is_empty(&self, l: usize) -> bool {
        self.first[l] >= self.count[l]
    }

    /// Sets every lane up as [`RaySegment::with`] sets up a ray without
    /// clipping, for the rays from `origin` along the unit directions
    /// `dir[axis][lane]` whose box intervals `(t_in, t_out)` are known
    /// ([`Aabb::intersect_lanes`]): the same bits, with the divisions done
    /// for all lanes at once. Only the lanes whose ray meets the box
    /// (`t_in <= t_out`) mean anything; the masks are left as they are.
    ///
    /// [`Aabb::intersect_lanes`]: crate::geometry::Aabb::intersect_lanes
    #[inline(always)]
    pub fn set_up(
        &mut self,
        grid: &Grid,
        origin: Vec3,
        dir: &[[f32; BLOCK]; 3],
        (t_in, t_out): (&[f32; BLOCK], &[f32; BLOCK]),
        step: f32,
        jitter: &[f32; BLOCK],
    ) {
        let inv_step = 1.0 / step;
        let origin = grid.world_to_voxel(origin);
        self.step = step;
        self.inv_step = inv_step;
        for l in 0..BLOCK {
            self.t_in[l] = t_in[l];
            self.t_out[l] = t_out[l];
            self.t0[l] = t_in[l] + jitter[l] * step;
            self.first[l] = 0;
            for a in 0..3 {
                self.origin[a][l] = origin[a];
                self.dir[a][l] = dir[a][l] / grid.spacing[a];
                self.inv_dir[a][l] = 1.0 / self.dir[a][l];
                self.world_dir[a][l] = dir[a][l];
            }
        }
        // The count's search loops stay out of the lane-wise loop above,
        // which the compiler then vectorises whole.
        for ((count, &t0), &t_out) in self.count.iter_mut().zip(&self.t0).zip(t_out) {
            *count = sample_count(t0, t_out, step, last_estimate(t0, t_out, inv_step));
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::{UVec3, Vec3};

    use super::*;

    /// The lane-wise set-up counts each lane's samples as a ray set up
    /// alone does, for box intervals and steps of every scale (where the
    /// estimate's rounding is off by one either way, or more), empty
    /// intervals and jitter included.
    #[test]
    fn lanes_count_samples_as_sample_count() {
        let grid = Grid::new(UVec3::new(9, 7, 8), Vec3::new(0.5, 1.0, 2.0));
        let mut rng = fastrand::Rng::with_seed(5);
        let (mut checked, mut off) = (0, 0);
        let mut block = RayBlock::default();
        for _ in 0..20_000 {
            let step = [1e-3, 0.07, 0.2, 0.5, 3.0][rng.usize(0..5)] * (0.5 + rng.f32());
            let t_in: [f32; BLOCK] =
                std::array::from_fn(|_| rng.f32() * 10f32.powi(rng.i32(-2..4)));
            let t_out: [f32; BLOCK] = std::array::from_fn(|l| {
                match rng.u32(0..4) {
                    // A whole number of steps, give or take the rounding.
                    0 => t_in[l] + rng.u32(0..2000) as f32 * step,
                    1 => t_in[l] - rng.f32(),
                    _ => t_in[l] + rng.f32() * 10f32.powi(rng.i32(-3..3)),
                }
            });
            let jitter: [f32; BLOCK] = std::array::from_fn(|_| rng.f32());
            let dir = [[0.6f32; BLOCK], [0.0f32; BLOCK], [0.8f32; BLOCK]];
            block.set_up(&grid, Vec3::ZERO, &dir, (&t_in, &t_out), step, &jitter);
            for l in 0..BLOCK {
                let t0 = t_in[l] + jitter[l] * step;
                let last = last_estimate(t0, t_out[l], 1.0 / step);
                let want = sample_count(t0, t_out[l], step, last);
                assert_eq!(block.count[l], want, "{t0} {} {step}", t_out[l]);
                assert_eq!(block.t0[l].to_bits(), t0.to_bits());
                // Where the estimate itself was off.
                off += (want != (last as u32 + 1) && t0 <= t_out[l]) as u32;
                checked += 1;
            }
        }
        assert!(checked == 320_000 && off > 100, "{off}");
    }

    /// A segment put in a lane comes back out of it to the bit.
    #[test]
    fn a_lane_holds_a_segment() {
        let mut rng = fastrand::Rng::with_seed(8);
        let mut block = RayBlock::default();
        for l in 0..BLOCK {
            let v = |rng: &mut fastrand::Rng| Vec3::new(rng.f32(), rng.f32(), rng.f32());
            let seg = RaySegment {
                origin: v(&mut rng),
                dir: v(&mut rng),
                inv_dir: v(&mut rng),
                world_dir: v(&mut rng),
                t_in: rng.f32(),
                t_out: rng.f32(),
                t0: rng.f32(),
                step: 0.25,
                inv_step: 4.0,
                first: rng.u32(0..9),
                count: rng.u32(0..9),
            };
            block.set(l, &seg);
            let back = block.segment(l);
            assert_eq!(format!("{back:?}"), format!("{seg:?}"));
            assert_eq!(block.is_empty(l), seg.is_empty());
        }
    }
}
