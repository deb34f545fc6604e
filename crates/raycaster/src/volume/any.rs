//! [`AnyVolume`]: a volume whose layout and sample type are known only at run
//! time (after opening a file), with [`dispatch_volume!`](crate::dispatch_volume)
//! to reach the concretely typed volume, so hot loops stay monomorphised.

use super::{BrickedVolume, Grid, Layout, LinearVolume, Volume};
use crate::sample::SampleType;
use crate::storage::StorageKind;

macro_rules! any_volume {
    ($($variant:ident => $ty:ty),* $(,)?) => {
        /// A volume of any layout and sample type.
        #[derive(Debug)]
        pub enum AnyVolume {
            $(
                #[doc = concat!("`", stringify!($ty), "`")]
                $variant($ty),
            )*
        }

        $(
            impl From<$ty> for AnyVolume {
                fn from(v: $ty) -> Self {
                    AnyVolume::$variant(v)
                }
            }
        )*

    };
}

any_volume! {
    LinearU8 => LinearVolume<u8>,
    LinearI8 => LinearVolume<i8>,
    LinearU16 => LinearVolume<u16>,
    LinearI16 => LinearVolume<i16>,
    LinearF32 => LinearVolume<f32>,
    BrickedU8 => BrickedVolume<u8>,
    BrickedI8 => BrickedVolume<i8>,
    BrickedU16 => BrickedVolume<u16>,
    BrickedI16 => BrickedVolume<i16>,
    BrickedF32 => BrickedVolume<f32>,
}

/// Runs `$body` with `$v` bound to the concretely typed volume inside an
/// [`AnyVolume`](crate::volume::AnyVolume): one monomorphised copy of `$body`
/// per layout and sample type.
///
/// ```
/// # use raycaster::volume::{AnyVolume, Grid, LinearVolume, Volume};
/// let any = AnyVolume::from(LinearVolume::from_fn(Grid::new(glam::UVec3::splat(2), glam::Vec3::ONE), |_| 7u8));
/// let value = raycaster::dispatch_volume!(&any, v => v.sample(glam::Vec3::splat(0.5)));
/// assert_eq!(value, 7.0);
/// ```
#[macro_export]
macro_rules! dispatch_volume {
    ($any:expr, $v:ident => $body:expr) => {
        match $any {
            $crate::volume::AnyVolume::LinearU8($v) => $body,
            $crate::volume::AnyVolume::LinearI8($v) => $body,
            $crate::volume::AnyVolume::LinearU16($v) => $body,
            $crate::volume::AnyVolume::LinearI16($v) => $body,
            $crate::volume::AnyVolume::LinearF32($v) => $body,
            $crate::volume::AnyVolume::BrickedU8($v) => $body,
            $crate::volume::AnyVolume::BrickedI8($v) => $body,
            $crate::volume::AnyVolume::BrickedU16($v) => $body,
            $crate::volume::AnyVolume::BrickedI16($v) => $body,
            $crate::volume::AnyVolume::BrickedF32($v) => $body,
        }
    };
}

impl AnyVolume {
    /// Dimensions, spacing and origin.
    pub fn grid(&self) -> &Grid {
        crate::dispatch_volume!(self, v => v.grid())
    }

    /// Memory layout.
    pub fn layout(&self) -> Layout {
        crate::dispatch_volume!(self, v => v.layout())
    }

    /// RAM or mapped.
    pub fn storage_kind(&self) -> StorageKind {
        crate::dispatch_volume!(self, v => v.storage_kind())
    }

    /// Bytes the samples take in memory (bricks include their overlap and
    /// padding), whether in RAM or mapped.
    pub fn memory_bytes(&self) -> u64 {
        crate::dispatch_volume!(self, v => std::mem::size_of_val(v.samples()) as u64)
    }

    /// The sample type.
    pub fn sample_type(&self) -> SampleType {
        fn tag<V: Volume>(_: &V) -> SampleType {
            <V::Sample as crate::sample::Sample>::TYPE
        }
        crate::dispatch_volume!(self, v => tag(v))
    }
}
