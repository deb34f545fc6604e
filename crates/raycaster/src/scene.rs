//! A [`Scene`]: a volume together with the acceleration data built from it
//! once, ready to be rendered any number of times.
//!
//! Renderers reach the volume's concrete type once per frame through
//! [`AnyVolume::visit`], never per sample.

use crate::accel::MacrocellGrid;
use crate::volume::{AnyVolume, Grid, Volume, VolumeVisitor};

/// A volume and its macrocell value ranges.
#[derive(Debug)]
pub struct Scene {
    id: u64,
    volume: AnyVolume,
    macrocells: MacrocellGrid,
    value_range: (f32, f32),
}

struct BuildMacrocells(Option<u32>);

impl VolumeVisitor for BuildMacrocells {
    type Output = MacrocellGrid;
    fn visit<V: Volume>(self, volume: &V) -> MacrocellGrid {
        MacrocellGrid::build(
            volume,
            self.0
                .unwrap_or_else(|| default_macrocell(volume.grid().dims)),
        )
    }
}

impl Scene {
    /// Builds the macrocell grid of `volume` (one pass over the data) with
    /// the default macrocell size (see [`default_macrocell`]).
    pub fn new(volume: AnyVolume) -> Self {
        Self::build(volume, None)
    }

    /// As [`Scene::new`] with an explicit macrocell side in voxels.
    pub fn with_macrocell(volume: AnyVolume, cell: u32) -> Self {
        Self::build(volume, Some(cell))
    }

    fn build(volume: AnyVolume, cell: Option<u32>) -> Self {
        let macrocells = volume.visit(BuildMacrocells(cell));
        let value_range = macrocells.value_range();
        static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        Scene {
            id: NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            volume,
            macrocells,
            value_range,
        }
    }

    /// A number unique to this scene in this process (keys renderers' caches).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// The volume.
    pub fn volume(&self) -> &AnyVolume {
        &self.volume
    }

    /// Dimensions, spacing and origin.
    pub fn grid(&self) -> &Grid {
        self.volume.grid()
    }

    /// The macrocell grid.
    pub fn macrocells(&self) -> &MacrocellGrid {
        &self.macrocells
    }

    /// Smallest and largest voxel value.
    pub fn value_range(&self) -> (f32, f32) {
        self.value_range
    }
}

/// The macrocell side used by [`Scene::new`]: the smallest of 4, 8, 16, 32
/// voxels that keeps the grid within 16 M cells. Small cells skip more empty
/// space and find more uniform regions (measured on the 800³ benchmark: 4³
/// cells take 24% fewer instructions per frame than 8³); the cap bounds the
/// memory and the per-transfer-function rebuild time of huge volumes.
pub fn default_macrocell(dims: glam::UVec3) -> u32 {
    let cells = |m: u32| {
        let n = |d: u32| (d.max(2) - 1).div_ceil(m) as u64;
        n(dims.x) * n(dims.y) * n(dims.z)
    };
    [4, 8, 16]
        .into_iter()
        .find(|&m| cells(m) <= 1 << 24)
        .unwrap_or(32)
}
