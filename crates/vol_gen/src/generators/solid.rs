//! `solid`: every voxel holds `--sample` (default 100). Useful as a worst
//! case for empty-space skipping and as a pure write-speed test.

use super::{Field, Region, Setup};

/// Default `--sample`.
pub const DEFAULT_SAMPLE: u8 = 100;

/// The `solid` generator.
#[derive(Debug, Clone, Copy)]
pub struct Solid {
    value: u8,
}

impl Solid {
    /// A volume of `--sample`.
    pub fn new(setup: &Setup) -> Self {
        Solid {
            value: setup.sample.unwrap_or(DEFAULT_SAMPLE),
        }
    }
}

impl Field for Solid {
    fn fill(&self, region: &Region, out: &mut [u8]) {
        if self.value != 0 {
            region.for_each_row(out, |_, _, row| row.fill(self.value));
        }
    }
}
