//! Turning a reader's description of a sample array (dimensions, type, byte
//! order, axis order, where the bytes are) into an [`AnyVolume`].
//!
//! Every format other than `.vol` ends here, so the rules live in one place:
//! native-endian data without rescaling is memory-mapped (or read into RAM,
//! per [`LoadMode`]); big-endian data is byte-swapped once; data with a
//! rescale slope/intercept is converted once to the type that holds
//! `stored·slope + intercept` exactly (SPEC §7).

use std::path::Path;

use glam::{UVec3, Vec3};

use crate::error::{Error, FormatError, Result};
use crate::sample::{Sample, SampleType};
use crate::storage::{LoadMode, Storage};
use crate::volume::{AnyVolume, AxisOrder, Grid, LinearVolume};

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

    /// `"little"` or `"big"`.
    pub fn name(self) -> &'static str {
        match self {
            Endian::Little => "little",
            Endian::Big => "big",
        }
    }
}

/// `value = stored·slope + intercept` (NIfTI `scl_slope`/`scl_inter`, DICOM
/// Rescale Slope/Intercept).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rescale {
    /// Multiplier.
    pub slope: f64,
    /// Offset added after multiplying.
    pub intercept: f64,
}

impl Rescale {
    /// `None` for the identity (slope 1, intercept 0), else the rescale.
    pub fn non_identity(slope: f64, intercept: f64) -> Option<Rescale> {
        (slope != 1.0 || intercept != 0.0).then_some(Rescale { slope, intercept })
    }

    fn apply(self, v: f64) -> f64 {
        v * self.slope + self.intercept
    }
}

impl std::fmt::Display for Rescale {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "stored × {} + {}", self.slope, self.intercept)
    }
}

/// Where a reader found the samples and how they are laid out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleLayout {
    /// Samples per axis.
    pub dims: UVec3,
    /// Spacing per axis (world units).
    pub spacing: Vec3,
    /// Type as stored in the file.
    pub sample: SampleType,
    /// Byte order as stored (ignored for 1-byte types).
    pub endian: Endian,
    /// Which axis changes fastest.
    pub order: AxisOrder,
}

impl SampleLayout {
    /// Bytes the samples take, or an error naming `path` when that overflows.
    pub fn byte_len(&self, path: &Path) -> Result<u64> {
        let d = self.dims;
        (d.x as u64)
            .checked_mul(d.y as u64)
            .and_then(|n| n.checked_mul(d.z as u64))
            .and_then(|n| n.checked_mul(self.sample.size() as u64))
            .ok_or_else(|| {
                Error::format(
                    path,
                    FormatError::SizeOverflow {
                        x: d.x as u64,
                        y: d.y as u64,
                        z: d.z as u64,
                    },
                )
            })
    }

    /// Checks dimensions (>= 1) and spacing (finite, > 0).
    pub fn validate(&self, path: &Path) -> Result<()> {
        for (axis, (d, s)) in ['X', 'Y', 'Z'].into_iter().zip(
            self.dims
                .to_array()
                .into_iter()
                .zip(self.spacing.to_array()),
        ) {
            if d == 0 {
                return Err(Error::format(path, FormatError::ZeroDimension { axis }));
            }
            if !(s.is_finite() && s > 0.0) {
                return Err(Error::format(
                    path,
                    FormatError::BadSpacing { axis, value: s },
                ));
            }
        }
        if self.dims.max_element() >= 1 << 31 {
            return Err(Error::format(
                path,
                FormatError::Invalid(format!(
                    "dimensions {}x{}x{} exceed 2^31 per axis",
                    self.dims.x, self.dims.y, self.dims.z
                )),
            ));
        }
        self.byte_len(path).map(|_| ())
    }

    fn grid(&self) -> Grid {
        Grid::new(self.dims, self.spacing)
    }

    fn needs_conversion(&self, rescale: Option<Rescale>) -> bool {
        rescale.is_some() || (self.sample.size() > 1 && self.endian != Endian::NATIVE)
    }
}

/// Builds a volume from samples at byte `offset` of `path`: mapped (or read,
/// per `mode`) when the bytes can be used as they are, else read and
/// converted once. The file must hold at least the bytes the layout needs;
/// `exact` also rejects extra bytes after them.
pub fn from_file(
    path: &Path,
    offset: u64,
    layout: &SampleLayout,
    rescale: Option<Rescale>,
    mode: LoadMode,
    exact: bool,
) -> Result<AnyVolume> {
    layout.validate(path)?;
    let bytes = layout.byte_len(path)?;
    let file_len = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    let available = file_len.saturating_sub(offset);
    if available < bytes || (exact && available != bytes) {
        return Err(Error::format(
            path,
            FormatError::WrongLength {
                expected: offset.saturating_add(bytes),
                found: file_len,
                detail: format!(
                    "{} bytes of header + {}x{}x{} {} samples",
                    offset, layout.dims.x, layout.dims.y, layout.dims.z, layout.sample
                ),
            },
        ));
    }
    let count = usize::try_from(bytes / layout.sample.size() as u64).map_err(|_| {
        Error::InvalidArgument(format!("{}: too large for this machine", path.display()))
    })?;
    if !layout.needs_conversion(rescale) {
        return dispatch_type(
            layout.sample,
            MapVisitor {
                path,
                offset,
                count,
                mode,
                layout,
            },
        );
    }
    let storage = Storage::<u8>::open(path, offset, bytes as usize, LoadMode::Ram)?;
    from_bytes(path, storage.as_slice(), layout, rescale)
}

/// Builds a volume in RAM from the sample bytes `bytes` (exactly as the file
/// stores them, e.g. after gunzip).
pub fn from_bytes(
    path: &Path,
    bytes: &[u8],
    layout: &SampleLayout,
    rescale: Option<Rescale>,
) -> Result<AnyVolume> {
    layout.validate(path)?;
    let want = layout.byte_len(path)?;
    if (bytes.len() as u64) < want {
        return Err(Error::format(
            path,
            FormatError::WrongLength {
                expected: want,
                found: bytes.len() as u64,
                detail: format!(
                    "decoded data of {}x{}x{} {} samples",
                    layout.dims.x, layout.dims.y, layout.dims.z, layout.sample
                ),
            },
        ));
    }
    let bytes = &bytes[..want as usize];
    dispatch_type(
        layout.sample,
        DecodeVisitor {
            bytes,
            layout,
            rescale,
        },
    )
}

/// Builds a volume in RAM from typed samples in `order`, applying `rescale`.
pub fn from_samples<S: Sample + Decode>(
    grid: Grid,
    samples: Vec<S>,
    order: AxisOrder,
    rescale: Option<Rescale>,
) -> Result<AnyVolume>
where
    AnyVolume: From<LinearVolume<S>>,
{
    match rescale {
        None => Ok(LinearVolume::with_order(grid, Storage::from_vec(samples), order)?.into()),
        Some(r) => rescaled(grid, &samples, order, r),
    }
}

/// Converts stored samples to data units: to `i16` when the slope and
/// intercept are whole numbers and every result fits (CT in Hounsfield
/// units), else to `f32`.
fn rescaled<S: Sample>(
    grid: Grid,
    samples: &[S],
    order: AxisOrder,
    r: Rescale,
) -> Result<AnyVolume> {
    let (lo, hi) = crate::volume::fold_range_f32(samples);
    let whole = |v: f64| v.fract() == 0.0;
    let fits = |v: f64| (i16::MIN as f64..=i16::MAX as f64).contains(&v);
    let integral = !matches!(S::TYPE, SampleType::F32);
    if integral
        && r.slope.abs() < 65536.0
        && r.intercept.abs() < 65536.0
        && whole(r.slope)
        && whole(r.intercept)
        && fits(r.apply(lo as f64))
        && fits(r.apply(hi as f64))
    {
        let (m, c) = (r.slope as i32, r.intercept as i32);
        let v: Vec<i16> = samples
            .iter()
            .map(|&s| (s.to_f32() as i32 * m + c) as i16)
            .collect();
        return Ok(LinearVolume::with_order(grid, Storage::from_vec(v), order)?.into());
    }
    let v: Vec<f32> = samples
        .iter()
        .map(|&s| r.apply(s.to_f32() as f64) as f32)
        .collect();
    Ok(LinearVolume::with_order(grid, Storage::from_vec(v), order)?.into())
}

/// Sample types that can be decoded from (and encoded to) bytes in either
/// byte order.
pub trait Decode: Sample {
    /// The value from its `size_of::<Self>()` bytes in `endian` order.
    fn decode(bytes: &[u8], endian: Endian) -> Self;
    /// Appends the value's bytes in `endian` order to `out`.
    fn encode(self, endian: Endian, out: &mut Vec<u8>);
}

macro_rules! impl_decode {
    ($($t:ty),*) => {$(
        impl Decode for $t {
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
    )*};
}
impl_decode!(u8, i8, u16, i16, f32);

/// Code run with the Rust type of a [`SampleType`].
trait TypeVisitor {
    fn visit<S: Sample + Decode>(self) -> Result<AnyVolume>
    where
        AnyVolume: From<LinearVolume<S>>;
}

fn dispatch_type(t: SampleType, v: impl TypeVisitor) -> Result<AnyVolume> {
    match t {
        SampleType::U8 => v.visit::<u8>(),
        SampleType::I8 => v.visit::<i8>(),
        SampleType::U16 => v.visit::<u16>(),
        SampleType::I16 => v.visit::<i16>(),
        SampleType::F32 => v.visit::<f32>(),
    }
}

struct MapVisitor<'a> {
    path: &'a Path,
    offset: u64,
    count: usize,
    mode: LoadMode,
    layout: &'a SampleLayout,
}

impl TypeVisitor for MapVisitor<'_> {
    fn visit<S: Sample + Decode>(self) -> Result<AnyVolume>
    where
        AnyVolume: From<LinearVolume<S>>,
    {
        let storage = Storage::<S>::open(self.path, self.offset, self.count, self.mode)?;
        Ok(LinearVolume::with_order(self.layout.grid(), storage, self.layout.order)?.into())
    }
}

struct DecodeVisitor<'a> {
    bytes: &'a [u8],
    layout: &'a SampleLayout,
    rescale: Option<Rescale>,
}

impl TypeVisitor for DecodeVisitor<'_> {
    fn visit<S: Sample + Decode>(self) -> Result<AnyVolume>
    where
        AnyVolume: From<LinearVolume<S>>,
    {
        let size = std::mem::size_of::<S>();
        let samples: Vec<S> = if size == 1 || self.layout.endian == Endian::NATIVE {
            bytemuck::pod_collect_to_vec(self.bytes)
        } else {
            self.bytes
                .chunks_exact(size)
                .map(|c| S::decode(c, self.layout.endian))
                .collect()
        };
        from_samples(self.layout.grid(), samples, self.layout.order, self.rescale)
    }
}

/// Parses `x,y,z`-style triples (also space separated) of `T`.
pub(crate) fn parse_triple<T: std::str::FromStr>(text: &str) -> Option<[T; 3]> {
    let parts: Vec<T> = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().ok())
        .collect::<Option<_>>()?;
    parts.try_into().ok()
}

/// The samples of `volume` as bytes in `order` and `endian` order: what a
/// writer of a headerless array puts in a file.
pub fn encode_volume(volume: &AnyVolume, order: AxisOrder, endian: Endian) -> Vec<u8> {
    fn go<V: crate::volume::Volume>(v: &V, order: AxisOrder, endian: Endian) -> Vec<u8>
    where
        V::Sample: Decode,
    {
        let d = v.grid().dims;
        let mut out = Vec::with_capacity(v.grid().voxel_count() as usize * V::Sample::TYPE.size());
        let mut put = |x, y, z| v.voxel(UVec3::new(x, y, z)).encode(endian, &mut out);
        match order {
            AxisOrder::XFast => {
                for z in 0..d.z {
                    for y in 0..d.y {
                        for x in 0..d.x {
                            put(x, y, z);
                        }
                    }
                }
            }
            AxisOrder::ZFast => {
                for x in 0..d.x {
                    for y in 0..d.y {
                        for z in 0..d.z {
                            put(x, y, z);
                        }
                    }
                }
            }
        }
        out
    }
    crate::dispatch_volume!(volume, v => go(v, order, endian))
}
