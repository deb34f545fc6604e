//! [`AnyVolume`]: a volume whose sample type and layout are known only at run
//! time (after opening a file), and [`VolumeVisitor`], the one way to reach
//! its concretely typed [`GridVolume`] so hot loops stay monomorphised.

use glam::UVec3;

use super::addressing::{AnyAddressing, AxisOrder, BrickGrid, Bricked, Layout, Linear};
use super::{Grid, GridVolume, Volume};
use crate::error::{Error, Result};
use crate::sample::{Sample, SampleType, SampleTypeVisitor};
use crate::storage::{Storage, StorageKind};

/// Code that runs on a concretely typed volume (a closure generic over the
/// volume type), called by [`AnyVolume::visit`].
pub trait VolumeVisitor {
    /// What the visit returns.
    type Output;
    /// Runs on the volume.
    fn visit<V: Volume>(self, volume: &V) -> Self::Output;
}

/// A volume of any layout and sample type: its grid, its samples and how
/// they are laid out.
///
/// ```
/// use glam::{UVec3, Vec3};
/// use raycaster::volume::{AnyVolume, Grid, Volume, VolumeVisitor};
///
/// let grid = Grid::new(UVec3::splat(2), Vec3::ONE);
/// let volume = AnyVolume::from_fn(grid, |v| (v.x * 10) as u8);
/// struct Centre;
/// impl VolumeVisitor for Centre {
///     type Output = f32;
///     fn visit<V: Volume>(self, v: &V) -> f32 { v.sample(Vec3::splat(0.5)) }
/// }
/// assert_eq!(volume.visit(Centre), 5.0);
/// ```
#[derive(Debug)]
pub struct AnyVolume {
    grid: Grid,
    storage: Storage,
    addressing: AnyAddressing,
}

impl AnyVolume {
    /// A volume of `storage` laid out by `addressing` on `grid`; the
    /// storage must hold exactly the samples the addressing needs.
    pub fn new(grid: Grid, storage: Storage, addressing: AnyAddressing) -> Result<Self> {
        if storage.len() != addressing.storage_len() {
            return Err(Error::InvalidVolume(format!(
                "{} {}x{}x{} needs {} samples, got {}",
                addressing.layout(),
                grid.dims.x,
                grid.dims.y,
                grid.dims.z,
                addressing.storage_len(),
                storage.len()
            )));
        }
        Ok(AnyVolume {
            grid,
            storage,
            addressing,
        })
    }

    /// The same volume placed with sample (0, 0, 0) at world position
    /// `origin` (a part of a larger volume keeps its world position).
    pub fn with_origin(mut self, origin: glam::Vec3) -> Self {
        self.grid.origin = origin;
        self
    }

    /// One array of samples in `order`.
    pub fn linear(grid: Grid, storage: Storage, order: AxisOrder) -> Result<Self> {
        let addressing = Linear::new(grid.dims, order).ok_or_else(|| {
            Error::InvalidVolume(format!("{} voxels: too large", grid.voxel_count()))
        })?;
        Self::new(grid, storage, AnyAddressing::Linear(addressing))
    }

    /// Bricks of `side` samples in file order.
    pub fn bricked(grid: Grid, side: u32, storage: Storage) -> Result<Self> {
        let addressing = Bricked::new(grid.dims, side)?;
        Self::new(grid, storage, AnyAddressing::Bricked(addressing))
    }

    /// Builds a linear volume (z fastest) in RAM from a function of the
    /// voxel coordinate.
    pub fn from_fn<S: Sample>(grid: Grid, mut f: impl FnMut(UVec3) -> S) -> Self {
        let mut v = Vec::with_capacity(grid.voxel_count() as usize);
        for x in 0..grid.dims.x {
            for y in 0..grid.dims.y {
                for z in 0..grid.dims.z {
                    v.push(f(UVec3::new(x, y, z)));
                }
            }
        }
        match Self::linear(grid, Storage::from_vec(v), AxisOrder::ZFast) {
            Ok(vol) => vol,
            Err(_) => unreachable!("from_fn produces exactly voxel_count samples"),
        }
    }

    /// Builds a bricked volume in RAM from a function of the voxel
    /// coordinate (padding past the grid's edge is 0, as in the file format).
    pub fn bricked_from_fn<S: Sample>(
        grid: Grid,
        side: u32,
        mut f: impl FnMut(UVec3) -> S,
    ) -> Result<Self> {
        let bricks = BrickGrid::new(grid.dims, side)?;
        let len = bricks.total_len().ok_or_else(|| {
            Error::InvalidVolume(format!("{} in bricks of {side}: too large", grid.dims))
        })?;
        let v = (0..len)
            .map(|i| bricks.voxel_at(i, grid.dims).map_or(S::zeroed(), &mut f))
            .collect::<Vec<S>>();
        Self::bricked(grid, side, Storage::from_vec(v))
    }

    /// A copy of this volume in RAM in another `layout`, same sample type.
    pub fn with_layout(&self, layout: Layout) -> Result<AnyVolume> {
        struct Relayout(Layout);
        impl VolumeVisitor for Relayout {
            type Output = Result<AnyVolume>;
            fn visit<V: Volume>(self, v: &V) -> Result<AnyVolume> {
                let grid = *v.grid();
                match self.0 {
                    Layout::Linear => Ok(AnyVolume::from_fn(grid, |p| v.voxel(p))),
                    Layout::LinearXFast => {
                        let d = grid.dims;
                        let mut out = Vec::with_capacity(grid.voxel_count() as usize);
                        for z in 0..d.z {
                            for y in 0..d.y {
                                for x in 0..d.x {
                                    out.push(v.voxel(UVec3::new(x, y, z)));
                                }
                            }
                        }
                        AnyVolume::linear(grid, Storage::from_vec(out), AxisOrder::XFast)
                    }
                    Layout::Bricked { side } => {
                        AnyVolume::bricked_from_fn(grid, side, |p| v.voxel(p))
                    }
                }
            }
        }
        self.visit(Relayout(layout))
    }

    /// Runs `visitor` on the concretely typed view of this volume: one
    /// monomorphised copy of the visitor per sample type and addressing.
    pub fn visit<T: VolumeVisitor>(&self, visitor: T) -> T::Output {
        struct Typed<'v, T> {
            volume: &'v AnyVolume,
            visitor: T,
        }
        impl<T: VolumeVisitor> SampleTypeVisitor for Typed<'_, T> {
            type Output = T::Output;
            fn visit<S: Sample>(self) -> T::Output {
                let v = self.volume;
                let data = v.storage.as_slice::<S>();
                match &v.addressing {
                    AnyAddressing::Linear(a) => {
                        self.visitor.visit(&GridVolume::new(&v.grid, data, a))
                    }
                    AnyAddressing::Bricked(a) => {
                        self.visitor.visit(&GridVolume::new(&v.grid, data, a))
                    }
                }
            }
        }
        self.sample_type().visit(Typed {
            volume: self,
            visitor,
        })
    }

    /// Dimensions, spacing and origin.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Memory layout.
    pub fn layout(&self) -> Layout {
        self.addressing.layout()
    }

    /// The addressing (linear or bricked).
    pub fn addressing(&self) -> &AnyAddressing {
        &self.addressing
    }

    /// The samples, untyped.
    pub(crate) fn storage(&self) -> &Storage {
        &self.storage
    }

    /// RAM or mapped.
    pub fn storage_kind(&self) -> StorageKind {
        self.storage.kind()
    }

    /// Bytes the samples take in memory (bricks include their overlap and
    /// padding), whether in RAM or mapped.
    pub fn memory_bytes(&self) -> u64 {
        self.storage.as_bytes().len() as u64
    }

    /// The sample type.
    pub fn sample_type(&self) -> SampleType {
        self.storage.sample_type()
    }

    /// The samples in storage order, when they are of type `S`.
    pub fn samples<S: Sample>(&self) -> Option<&[S]> {
        (S::TYPE == self.sample_type()).then(|| self.storage.as_slice::<S>())
    }
    /// Every value in x-fastest order (tests compare whole volumes).
    #[cfg(test)]
    pub(crate) fn all_values(&self) -> Vec<f32> {
        let d = self.grid().dims;
        let mut out = Vec::with_capacity((d.x * d.y * d.z) as usize);
        for z in 0..d.z {
            for y in 0..d.y {
                for x in 0..d.x {
                    out.push(self.value(glam::UVec3::new(x, y, z)));
                }
            }
        }
        out
    }

    /// The value of voxel `v` as a float (panics outside the grid).
    pub fn value(&self, v: UVec3) -> f32 {
        struct Value(UVec3);
        impl VolumeVisitor for Value {
            type Output = f32;
            fn visit<V: Volume>(self, volume: &V) -> f32 {
                crate::sample::Sample::to_f32(volume.voxel(self.0))
            }
        }
        self.visit(Value(v))
    }
}
