//! Sample types: the numeric types a volume's voxels can have.
//!
//! Renderers are generic over [`Sample`], so a `u8` volume and an `f32` volume
//! each get their own monomorphised hot loop with no conversion call through a
//! pointer.

/// The runtime tag of a sample type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SampleType {
    /// Unsigned 8-bit.
    U8,
    /// Signed 8-bit.
    I8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit.
    I16,
    /// 32-bit IEEE float.
    F32,
}

impl SampleType {
    /// Size of one sample in bytes.
    pub fn size(self) -> usize {
        match self {
            SampleType::U8 | SampleType::I8 => 1,
            SampleType::U16 | SampleType::I16 => 2,
            SampleType::F32 => 4,
        }
    }

    /// The largest value of the type: the value the `ramp` preset maps to full
    /// opacity and the divisor of the `avg` mode (SPEC §4, §5). 1.0 for floats.
    pub fn max_value(self) -> f32 {
        match self {
            SampleType::U8 => u8::MAX as f32,
            SampleType::I8 => i8::MAX as f32,
            SampleType::U16 => u16::MAX as f32,
            SampleType::I16 => i16::MAX as f32,
            SampleType::F32 => 1.0,
        }
    }

    /// Lower-case name as used on command lines (`u8`, `i16`, ...).
    pub fn name(self) -> &'static str {
        match self {
            SampleType::U8 => "u8",
            SampleType::I8 => "i8",
            SampleType::U16 => "u16",
            SampleType::I16 => "i16",
            SampleType::F32 => "f32",
        }
    }
}

impl std::fmt::Display for SampleType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A voxel value type.
pub trait Sample: bytemuck::Pod + PartialOrd + Send + Sync + std::fmt::Debug + 'static {
    /// The runtime tag of this type.
    const TYPE: SampleType;
    /// The smallest representable value (the identity of `max`).
    const LOWEST: Self;
    /// The largest representable value (the identity of `min`).
    const HIGHEST: Self;

    /// The value as a float, exactly for every integer type here.
    fn to_f32(self) -> f32;

    /// `min` written so that loops over slices vectorise.
    #[inline(always)]
    fn min_of(self, other: Self) -> Self {
        if other < self { other } else { self }
    }

    /// `max` written so that loops over slices vectorise.
    #[inline(always)]
    fn max_of(self, other: Self) -> Self {
        if other > self { other } else { self }
    }
}

macro_rules! impl_sample {
    ($t:ty, $tag:ident, $lo:expr, $hi:expr) => {
        impl Sample for $t {
            const TYPE: SampleType = SampleType::$tag;
            const LOWEST: Self = $lo;
            const HIGHEST: Self = $hi;
            #[inline(always)]
            fn to_f32(self) -> f32 {
                self as f32
            }
        }
    };
}

impl_sample!(u8, U8, u8::MIN, u8::MAX);
impl_sample!(i8, I8, i8::MIN, i8::MAX);
impl_sample!(u16, U16, u16::MIN, u16::MAX);
impl_sample!(i16, I16, i16::MIN, i16::MAX);
impl_sample!(f32, F32, f32::NEG_INFINITY, f32::INFINITY);
