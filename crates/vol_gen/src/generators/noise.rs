//! `noise`: smooth fractal value noise (not white noise). Random values on an
//! integer lattice are interpolated with a quintic fade; `--octaves` layers
//! (default 4), each with half the cell size and half the amplitude of the
//! previous one, are summed and scaled to `0..=--sample` (default 255). The
//! first octave's cell is `--object-size` voxels (default 32), measured in
//! units of the finest voxel spacing.
//!
//! Lattice values come from a hash of the lattice point and the seed, so any
//! voxel can be computed on its own; along a row the lattice values are
//! reused until z crosses a lattice plane, so a voxel costs about one
//! interpolation per octave.

use glam::Vec3;

use super::{Field, Region, Setup, fade, to_u8};

/// Default `--octaves`.
pub const DEFAULT_OCTAVES: u32 = 4;
/// Most `--octaves` accepted.
pub const MAX_OCTAVES: u32 = 16;
/// Default `--object-size`: the first octave's lattice cell.
pub const DEFAULT_SIZE: u32 = 32;
/// Default `--sample`: the largest value.
pub const DEFAULT_SAMPLE: u8 = 255;

#[derive(Debug, Clone, Copy)]
struct Octave {
    /// Lattice cells per unit of voxel coordinate, per axis.
    freq: Vec3,
    /// Weight, already divided by the sum of all weights.
    amplitude: f32,
    seed: u64,
}

/// The `noise` generator.
#[derive(Debug, Clone)]
pub struct Noise {
    octaves: Vec<Octave>,
    max: f32,
}

/// SplitMix64's finaliser: a cheap, well-mixed 64-bit hash.
#[inline(always)]
pub(crate) fn mix(mut h: u64) -> u64 {
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^ (h >> 31)
}

/// The lattice value at `(x, y, z)`, in `[0, 1)`.
#[inline(always)]
pub(crate) fn lattice(seed: u64, x: i32, y: i32, z: i32) -> f32 {
    let h = mix(seed ^ (x as u32 as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
    let h = mix(h ^ (y as u32 as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f));
    let h = mix(h ^ (z as u32 as u64).wrapping_mul(0x1656_67b1_9e37_79f9));
    (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

impl Noise {
    /// The noise described by `setup`.
    pub fn new(setup: &Setup) -> Result<Self, String> {
        let count = setup.octaves.unwrap_or(DEFAULT_OCTAVES);
        if !(1..=MAX_OCTAVES).contains(&count) {
            return Err(format!(
                "--octaves {count} is out of range (1..={MAX_OCTAVES})"
            ));
        }
        let size = super::object_size(setup, DEFAULT_SIZE as f64)? as f32;
        let total: f32 = (0..count).map(|o| 0.5f32.powi(o as i32)).sum();
        let scale = setup.scale();
        let octaves = (0..count)
            .map(|o| Octave {
                freq: scale * (2f32.powi(o as i32) / size),
                amplitude: 0.5f32.powi(o as i32) / total,
                seed: mix(setup.seed ^ mix(o as u64 + 1)),
            })
            .collect();
        Ok(Noise {
            octaves,
            max: setup.sample.unwrap_or(DEFAULT_SAMPLE) as f32,
        })
    }
}

impl Field for Noise {
    fn fill(&self, region: &Region, out: &mut [u8]) {
        let mut acc = vec![0f32; region.row_len()];
        region.for_each_row(out, |x, y, row| {
            acc.fill(0.0);
            for o in &self.octaves {
                let (ix, tx) = split(x as f32 * o.freq.x);
                let (iy, ty) = split(y as f32 * o.freq.y);
                let (tx, ty) = (fade(tx), fade(ty));
                // Bilinear value of the xy cell on lattice plane z = iz.
                let plane = |iz: i32| {
                    let l = |dx: i32, dy: i32| lattice(o.seed, ix + dx, iy + dy, iz);
                    let (l00, l01, l10, l11) = (l(0, 0), l(0, 1), l(1, 0), l(1, 1));
                    let a = l00 + (l01 - l00) * ty;
                    let b = l10 + (l11 - l10) * ty;
                    a + (b - a) * tx
                };
                let mut cached = i32::MIN;
                let (mut b0, mut b1) = (0.0, 0.0);
                for (i, a) in acc.iter_mut().enumerate() {
                    let (iz, tz) = split((region.lo.z + i as u32) as f32 * o.freq.z);
                    if iz != cached {
                        // Moving to the next lattice cell reuses its lower plane.
                        b0 = if iz == cached.wrapping_add(1) {
                            b1
                        } else {
                            plane(iz)
                        };
                        b1 = plane(iz + 1);
                        cached = iz;
                    }
                    *a += o.amplitude * (b0 + (b1 - b0) * fade(tz));
                }
            }
            for (v, a) in row.iter_mut().zip(&acc) {
                *v = to_u8(a * self.max);
            }
        });
    }
}

/// Integer part and fraction of a coordinate (floor, so also below 0).
#[inline(always)]
pub(crate) fn split(p: f32) -> (i32, f32) {
    let i = p.floor();
    (i as i32, p - i)
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;
    use glam::UVec3;

    #[test]
    fn smooth_and_spread_out() {
        let dims = UVec3::new(40, 40, 40);
        let n = Noise::new(&Setup::new(dims, 5)).unwrap();
        let data = render(&n, dims);
        let (lo, hi) = (data.iter().min().unwrap(), data.iter().max().unwrap());
        assert!(hi - lo > 60, "range {lo}..{hi}");
        // Neighbours along z differ a little, unlike white noise.
        let steps: u64 = data
            .windows(2)
            .map(|w| (w[0] as i32 - w[1] as i32).unsigned_abs() as u64)
            .sum();
        assert!(
            steps / (data.len() as u64) < 12,
            "mean step {}",
            steps / data.len() as u64
        );
        assert_region_independent(&n, UVec3::new(9, 7, 13));
    }

    #[test]
    fn seeds_differ() {
        let dims = UVec3::splat(8);
        let a = render(&Noise::new(&Setup::new(dims, 1)).unwrap(), dims);
        let b = render(&Noise::new(&Setup::new(dims, 2)).unwrap(), dims);
        assert_ne!(a, b);
    }
}
