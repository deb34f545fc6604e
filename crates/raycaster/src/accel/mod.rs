//! Acceleration structures for empty-space skipping (ESS).
//!
//! [`MacrocellGrid`] holds the value range of every macrocell (a cube of
//! voxels; one brick in a bricked volume). It depends only on the data, so it
//! is built once when a volume is opened. [`SkipGrid`] is derived from it for
//! one transfer function (or iso value): which macrocells can contribute, and
//! for each empty one its Chebyshev distance, in cells, to the nearest
//! non-empty one. A ray in an empty cell with distance `d` can jump straight
//! out of the cube of `2d − 1` empty cells around it, so crossing empty space
//! costs a handful of box exits instead of one test per step. [`SkipRuns`]
//! hands a ray's samples to an integrator as empty and occupied runs.
//! [`cache`] keeps a volume file's macrocell grid in a sidecar file, so that
//! opening it again does not read every sample.

pub mod cache;
mod iso_cells;
mod macrocell;
mod runs;
mod skip;

pub use iso_cells::{CellMasks, CellState, IsoCells};
pub use macrocell::MacrocellGrid;
pub use runs::{RunKind, SampleRun, SkipRuns};
pub use skip::{Ahead, CellClass, SkipGrid};

/// The set bits of `words` (bit `i % 64` of word `i / 64` for index `i`) as
/// runs of consecutive indices, each within one row of `row` indices (a
/// run never crosses a multiple of `row`) and at most `max_len` long:
/// `run(first index, length)` for each, in index order. The cells of a grid
/// stored z fastest become runs along z, which the proxy depths draw as one
/// box each ([`SkipGrid::occupied_runs`], [`IsoCells::straddling_runs`]).
pub(crate) fn bit_runs(words: &[u64], row: usize, max_len: u32, mut run: impl FnMut(usize, u32)) {
    // The run being gathered: its first index and length.
    let mut open: Option<(usize, u32)> = None;
    for (w, &word) in words.iter().enumerate() {
        let mut bits = word;
        while bits != 0 {
            let i = w * 64 + bits.trailing_zeros() as usize;
            bits &= bits - 1;
            open = match open {
                Some((first, len))
                    if i == first + len as usize && !i.is_multiple_of(row) && len < max_len =>
                {
                    Some((first, len + 1))
                }
                _ => {
                    if let Some((first, len)) = open {
                        run(first, len);
                    }
                    Some((i, 1))
                }
            };
        }
    }
    if let Some((first, len)) = open {
        run(first, len);
    }
}

/// For tests: macrocells of side 4, `count` of them per axis, each occupied
/// (value range 1..1, else 0..0) with probability `density`.
#[cfg(test)]
pub(crate) fn random_macrocells(
    rng: &mut fastrand::Rng,
    count: glam::UVec3,
    density: f32,
) -> MacrocellGrid {
    let len = (count.x * count.y * count.z) as usize;
    MacrocellGrid {
        cell: 4,
        shells_found: false,
        count,
        ranges: (0..len)
            .map(|_| {
                if rng.f32() < density {
                    (1.0, 1.0)
                } else {
                    (0.0, 0.0)
                }
            })
            .collect(),
        uniform: vec![false; len],
    }
}
