//! Sample types: the numeric types a volume's voxels can have.
//!
//! Renderers are generic over [`Sample`], so a `u8` volume and an `f32` volume
//! each get their own monomorphised hot loop with no conversion call through a
//! pointer. [`SampleType`] is the same choice made at run time (after reading
//! a file header); [`SampleType::visit`] is the one place where a run-time
//! tag becomes a Rust type.

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

/// Code that runs with the Rust type of a [`SampleType`] (a closure generic
/// over the sample type).
pub trait SampleTypeVisitor {
    /// What the visit returns.
    type Output;
    /// Runs with `S` the type the tag names.
    fn visit<S: Sample>(self) -> Self::Output;
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

    /// The largest value of the type: the value the `ramp` preset maps to
    /// full opacity and the divisor of the `avg` mode. 1.0 for floats.
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

    /// Runs `visitor` with the Rust type this tag names.
    pub fn visit<T: SampleTypeVisitor>(self, visitor: T) -> T::Output {
        match self {
            SampleType::U8 => visitor.visit::<u8>(),
            SampleType::I8 => visitor.visit::<i8>(),
            SampleType::U16 => visitor.visit::<u16>(),
            SampleType::I16 => visitor.visit::<i16>(),
            SampleType::F32 => visitor.visit::<f32>(),
        }
    }
}

impl std::fmt::Display for SampleType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Byte order of multi-byte samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Endian {
    /// Least significant byte first (x86, ARM).
    Little,
    /// Most significant byte first.
    Big,
}

impl Endian {
    /// The byte order of this machine.
    pub const NATIVE: Endian = if cfg!(target_endian = "little") {
        Endian::Little
    } else {
        Endian::Big
    };

    /// `little` or `big`.
    pub fn name(self) -> &'static str {
        match self {
            Endian::Little => "little",
            Endian::Big => "big",
        }
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

    /// The value from its first `size_of::<Self>()` bytes in `endian` order.
    fn decode(bytes: &[u8], endian: Endian) -> Self;

    /// Appends the value's bytes in `endian` order to `out`.
    fn encode(self, endian: Endian, out: &mut Vec<u8>);

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
            #[inline]
            fn decode(bytes: &[u8], endian: Endian) -> Self {
                let mut a = [0u8; std::mem::size_of::<$t>()];
                a.copy_from_slice(&bytes[..std::mem::size_of::<$t>()]);
                match endian {
                    Endian::Little => <$t>::from_le_bytes(a),
                    Endian::Big => <$t>::from_be_bytes(a),
                }
            }
            #[inline]
            fn encode(self, endian: Endian, out: &mut Vec<u8>) {
                match endian {
                    Endian::Little => out.extend_from_slice(&self.to_le_bytes()),
                    Endian::Big => out.extend_from_slice(&self.to_be_bytes()),
                }
            }
        }
    };
}

impl_sample!(u8, U8, u8::MIN, u8::MAX);
impl_sample!(i8, I8, i8::MIN, i8::MAX);
impl_sample!(u16, U16, u16::MIN, u16::MAX);
impl_sample!(i16, I16, i16::MIN, i16::MAX);
impl_sample!(f32, F32, f32::NEG_INFINITY, f32::INFINITY);
