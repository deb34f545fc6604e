//! [`IsoCells`]: the fine level of the isosurface's two-level occupancy
//! grid, which interpolation cells of each occupied macrocell straddle the
//! iso value.
//!
//! The coarse level is the [`SkipGrid`](super::SkipGrid) built for the iso
//! value (macrocells whose value range holds it). For each of those
//! macrocells this keeps two bit sets over its `m³` interpolation cells (as
//! the seed thesis's bit grid of 4×4×4 fine cells per coarse cell): the
//! cells whose 8 corners straddle the iso value, where a ray must solve for
//! the crossing, and the cells that lie wholly at or above it, so a ray
//! walking past cells it need not open still knows which side of the
//! surface it is on. Only occupied macrocells are visited, so a new iso
//! value costs a pass over the surface's macrocells, not over the volume.

use std::sync::OnceLock;

use glam::UVec3;
use rayon::prelude::*;

use super::{MacrocellGrid, SkipGrid};
use crate::volume::{AnyVolume, Volume, VolumeVisitor};

/// Per occupied macrocell, which of its interpolation cells straddle the
/// iso value and which lie at or above it.
#[derive(Debug, Clone)]
pub struct IsoCells {
    side: u32,
    /// `log2(side)` when the side is a power of two.
    shift: Option<u32>,
    /// Macrocells per axis.
    count: UVec3,
    words: usize,
    /// Per macrocell: the index of its bit sets in `bits`, or `u32::MAX`
    /// for a macrocell the coarse level calls empty.
    slot: Vec<u32>,
    /// Per occupied macrocell `2·words` words: straddling cells, then cells
    /// at or above the iso value; bit `(x·m + y)·m + z` is local cell
    /// `(x, y, z)`.
    bits: Vec<u64>,
    /// [`IsoCells::straddling_runs`], listed on first use.
    straddling: OnceLock<Vec<(UVec3, u32)>>,
}

/// The bit sets of one occupied macrocell.
#[derive(Debug, Clone, Copy)]
pub struct CellMasks<'a> {
    side: u32,
    straddle: &'a [u64],
    above: &'a [u64],
}

/// One interpolation cell of an occupied macrocell ([`IsoCells::cell_state`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CellState {
    /// Its corners straddle the iso value.
    pub straddles: bool,
    /// It lies wholly at or above the iso value (when it does not straddle).
    pub above: bool,
}

impl CellMasks<'_> {
    /// The macrocell side `m`.
    #[inline(always)]
    pub fn side(&self) -> u32 {
        self.side
    }

    /// Whether local cell `local` (each coordinate `< m`) straddles the iso
    /// value.
    #[inline(always)]
    pub fn straddles(&self, local: UVec3) -> bool {
        self.straddles_at(self.index(local))
    }

    /// Whether local cell `local` lies wholly at or above the iso value
    /// (meaningful for a cell that does not straddle it).
    #[inline(always)]
    pub fn above(&self, local: UVec3) -> bool {
        self.above_at(self.index(local))
    }

    /// The bit index of local cell `local`: `(x·m + y)·m + z`. Stepping
    /// one cell along an axis moves it by `m²`, `m` or 1, so a walk can
    /// keep it up to date instead of recomputing it.
    #[inline(always)]
    pub fn index(&self, local: UVec3) -> u32 {
        bit_index(self.side, local)
    }

    /// [`CellMasks::straddles`] by bit index ([`CellMasks::index`]).
    #[inline(always)]
    pub fn straddles_at(&self, i: u32) -> bool {
        self.straddle[(i >> 6) as usize] & (1u64 << (i & 63)) != 0
    }

    /// [`CellMasks::above`] by bit index ([`CellMasks::index`]).
    #[inline(always)]
    pub fn above_at(&self, i: u32) -> bool {
        self.above[(i >> 6) as usize] & (1u64 << (i & 63)) != 0
    }

    /// True when no cell of the macrocell straddles the iso value.
    #[inline(always)]
    pub fn none_straddle(&self) -> bool {
        self.straddle.iter().all(|&w| w == 0)
    }
}

impl IsoCells {
    /// The bit sets of the macrocells `skip` marks occupied, for `iso`.
    pub fn build(
        volume: &AnyVolume,
        macrocells: &MacrocellGrid,
        skip: &SkipGrid,
        iso: f32,
    ) -> Self {
        struct Build<'a> {
            macrocells: &'a MacrocellGrid,
            skip: &'a SkipGrid,
            iso: f32,
        }
        impl VolumeVisitor for Build<'_> {
            type Output = IsoCells;
            fn visit<V: Volume>(self, volume: &V) -> IsoCells {
                IsoCells::build_typed(volume, self.macrocells, self.skip, self.iso)
            }
        }
        volume.visit(Build {
            macrocells,
            skip,
            iso,
        })
    }

    fn build_typed<V: Volume>(
        volume: &V,
        macrocells: &MacrocellGrid,
        skip: &SkipGrid,
        iso: f32,
    ) -> Self {
        let m = macrocells.cell;
        let n = macrocells.count;
        let words = ((m * m * m) as usize).div_ceil(64);
        let occupied: Vec<u32> = (0..n.x * n.y * n.z)
            .filter(|&i| skip.is_occupied_index(i as usize))
            .collect();
        let mut slot = vec![u32::MAX; macrocells.ranges.len()];
        for (s, &i) in occupied.iter().enumerate() {
            slot[i as usize] = s as u32;
        }
        let dims = volume.grid().dims;
        let last = dims.max(UVec3::splat(2)) - UVec3::splat(2);
        let mut bits = vec![0u64; occupied.len() * 2 * words];
        bits.par_chunks_mut(2 * words)
            .zip(occupied.par_iter())
            .for_each(|(out, &i)| {
                let (straddle, above) = out.split_at_mut(words);
                let origin = macrocell_of(i, n) * m;
                for x in 0..m {
                    for y in 0..m {
                        for z in 0..m {
                            let cell = origin + UVec3::new(x, y, z);
                            if cell.cmpgt(last).any() {
                                continue;
                            }
                            let corners = volume.corners(cell);
                            let (lo, hi) = corners
                                .iter()
                                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                                    (lo.min(v), hi.max(v))
                                });
                            let b = bit_index(m, UVec3::new(x, y, z)) as usize;
                            let (w, bit) = (b >> 6, 1u64 << (b & 63));
                            if lo >= iso {
                                above[w] |= bit;
                            } else if hi >= iso {
                                straddle[w] |= bit;
                            }
                        }
                    }
                }
            });
        IsoCells {
            side: m,
            shift: m.is_power_of_two().then(|| m.trailing_zeros()),
            count: n,
            words,
            slot,
            bits,
            straddling: OnceLock::new(),
        }
    }

    /// The macrocell side these masks are for.
    pub fn side(&self) -> u32 {
        self.side
    }

    /// Macrocells per axis.
    #[inline(always)]
    pub fn count(&self) -> UVec3 {
        self.count
    }

    /// The bit sets of macrocell `index` (its index in the macrocell grid),
    /// `None` when the coarse level calls it empty.
    #[inline(always)]
    pub fn masks(&self, index: usize) -> Option<CellMasks<'_>> {
        let s = self.slot[index];
        if s == u32::MAX {
            return None;
        }
        let at = s as usize * 2 * self.words;
        Some(CellMasks {
            side: self.side,
            straddle: &self.bits[at..at + self.words],
            above: &self.bits[at + self.words..at + 2 * self.words],
        })
    }

    /// Interpolation cell `cell` as [`CellMasks::straddles`] and
    /// [`CellMasks::above`] see it, `None` when the coarse level calls its
    /// macrocell empty: the two bits without building the masks (a packet
    /// of rays asks this of every cell across its rays). Its macrocell by
    /// a shift where the side is a power of two.
    #[inline(always)]
    pub fn cell_state(&self, cell: UVec3) -> Option<CellState> {
        let mc = match self.shift {
            Some(sh) => cell >> sh,
            None => cell / self.side,
        };
        let n = self.count;
        let s = self.slot[((mc.x * n.y + mc.y) * n.z + mc.z) as usize];
        if s == u32::MAX {
            return None;
        }
        let b = bit_index(self.side, cell - mc * self.side);
        let w = s as usize * 2 * self.words + (b >> 6) as usize;
        let bit = 1u64 << (b & 63);
        Some(CellState {
            straddles: self.bits[w] & bit != 0,
            above: self.bits[w + self.words] & bit != 0,
        })
    }

    /// The interpolation cells that straddle the iso value as runs along
    /// z: the lower corner of a run's first cell and the number of cells
    /// in it (consecutive along z, within one macrocell), macrocell by
    /// macrocell; listed on first use, then kept. A run is one box to the
    /// proxy depths, which draw it for every frame: a surface's shell of
    /// straddling cells holds about half as many runs as cells.
    pub fn straddling_runs(&self) -> &[(UVec3, u32)] {
        self.straddling.get_or_init(|| self.list_straddling_runs())
    }

    /// The lower corners of the interpolation cells that straddle the iso
    /// value ([`IsoCells::straddling_runs`] cell by cell).
    pub fn straddling_cells(&self) -> impl Iterator<Item = UVec3> + '_ {
        self.straddling_runs()
            .iter()
            .flat_map(|&(c, n)| (0..n).map(move |z| c + UVec3::new(0, 0, z)))
    }

    fn list_straddling_runs(&self) -> Vec<(UVec3, u32)> {
        let (m, n) = (self.side, self.count);
        let mut out = Vec::new();
        for (i, &s) in self.slot.iter().enumerate() {
            if s == u32::MAX {
                continue;
            }
            let origin = macrocell_of(i as u32, n) * m;
            let local = |b: u32| origin + UVec3::new(b / (m * m), (b / m) % m, b % m);
            // The macrocell's straddling cells, bit `b` for local cell `b`:
            // runs along z within its rows of `m` cells.
            let at = s as usize * 2 * self.words;
            super::bit_runs(
                &self.bits[at..at + self.words],
                m as usize,
                u32::MAX,
                |b, len| out.push((local(b as u32), len)),
            );
        }
        out
    }

    /// How many interpolation cells straddle the iso value.
    pub fn straddling_count(&self) -> usize {
        self.bits
            .chunks(2 * self.words)
            .map(|c| {
                c[..self.words]
                    .iter()
                    .map(|w| w.count_ones() as usize)
                    .sum::<usize>()
            })
            .sum()
    }
}

/// The bit of local cell `local` in a macrocell of side `m`'s bit sets:
/// `(x·m + y)·m + z`.
#[inline(always)]
fn bit_index(m: u32, local: UVec3) -> u32 {
    (local.x * m + local.y) * m + local.z
}

/// The coordinates of the macrocell with index `i` in a grid of `n`
/// macrocells (z fastest, as [`MacrocellGrid::index`]).
#[inline]
fn macrocell_of(i: u32, n: UVec3) -> UVec3 {
    UVec3::new(i / (n.y * n.z), (i / n.z) % n.y, i % n.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Grid;
    use glam::Vec3;

    #[test]
    fn masks_agree_with_each_cells_corners() {
        let grid = Grid::new(UVec3::new(19, 14, 23), Vec3::ONE);
        let f = |v: UVec3| {
            let d = v.as_vec3() - Vec3::new(9.0, 7.0, 11.0);
            (d.length() * 10.0) as u8
        };
        let volume = AnyVolume::from_fn(grid, f);
        for side in [2, 4, 5] {
            let cells = MacrocellGrid::build_any(&volume, side, None);
            for iso in [35.5f32, 60.0, 61.0] {
                let skip = SkipGrid::build(&cells, |lo, hi| lo <= iso && iso <= hi);
                let masks = IsoCells::build(&volume, &cells, &skip, iso);
                let mut straddling = 0;
                let mut listed = Vec::new();
                for x in 0..18 {
                    for y in 0..13 {
                        for z in 0..22 {
                            let cell = UVec3::new(x, y, z);
                            let corners: Vec<f32> = (0..8)
                                .map(|n| f(cell + UVec3::new(n >> 2, (n >> 1) & 1, n & 1)) as f32)
                                .collect();
                            let lo = corners.iter().copied().fold(f32::INFINITY, f32::min);
                            let hi = corners.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                            let mc = cell / side;
                            let index =
                                ((mc.x * cells.count.y + mc.y) * cells.count.z + mc.z) as usize;
                            let want = lo < iso && iso <= hi;
                            straddling += want as usize;
                            if want {
                                listed.push(cell.to_array());
                            }
                            let local = cell - mc * side;
                            match masks.masks(index) {
                                Some(m) => {
                                    assert_eq!(m.straddles(local), want, "cell {cell}");
                                    if !want {
                                        assert_eq!(m.above(local), lo >= iso, "cell {cell}");
                                    }
                                    // The two bits read alone are the masks'.
                                    let state = CellState {
                                        straddles: m.straddles(local),
                                        above: m.above(local),
                                    };
                                    assert_eq!(masks.cell_state(cell), Some(state));
                                }
                                None => {
                                    assert!(!want, "cell {cell} in an empty macrocell");
                                    assert_eq!(masks.cell_state(cell), None);
                                }
                            }
                        }
                    }
                }
                assert!(straddling > 0);
                assert_eq!(masks.straddling_count(), straddling);
                let mut got: Vec<[u32; 3]> =
                    masks.straddling_cells().map(|c| c.to_array()).collect();
                // Runs are maximal: the cell after a run's last along z is
                // not straddling, or in another macrocell.
                for &(c, len) in masks.straddling_runs() {
                    let next = c + UVec3::new(0, 0, len);
                    assert!(len >= 1 && (c.z % side) + len <= side);
                    if !next.z.is_multiple_of(side) {
                        assert!(!masks.cell_state(next).is_some_and(|st| st.straddles));
                    }
                }
                got.sort_unstable();
                assert_eq!(got, listed, "side {side}, iso {iso}");
            }
        }
    }
}
