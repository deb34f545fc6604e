//! Turning a reader's description of a sample array (dimensions, type, byte
//! order, axis order, where the bytes are) into an [`AnyVolume`].
//!
//! Every format other than `.vol` ends here, so the rules live in one place:
//! native-endian data without rescaling is memory-mapped (or read into RAM,
//! per [`LoadMode`]); big-endian data is byte-swapped once; data with a
//! rescale slope/intercept is converted once to the type that holds
//! `stored·slope + intercept` exactly, so volumes hold data units.

use std::path::Path;

use glam::{UVec3, Vec3};

use crate::error::{Error, FormatError, Result};
pub use crate::sample::Endian;
use crate::sample::{Sample, SampleType, SampleTypeVisitor};
use crate::storage::{LoadMode, Storage};
use crate::volume::{AnyVolume, AxisOrder, Grid};

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

/// Refuses `bytes` of samples in RAM above `max_memory`
/// ([`OpenOptions::max_memory`](super::OpenOptions::max_memory)).
pub(crate) fn check_memory(path: &Path, bytes: u64, max_memory: Option<u64>) -> Result<()> {
    match max_memory {
        Some(max) if bytes > max => Err(Error::TooLarge {
            path: path.to_path_buf(),
            what: format!(
                "its samples need {} of memory, more than the limit of {}",
                crate::units::bytes(bytes),
                crate::units::bytes(max)
            ),
        }),
        _ => Ok(()),
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
    max_memory: Option<u64>,
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
    let count =
        usize::try_from(bytes / layout.sample.size() as u64).map_err(|_| Error::TooLarge {
            path: path.to_path_buf(),
            what: "sample count".into(),
        })?;
    if !layout.needs_conversion(rescale) {
        if mode == LoadMode::Ram {
            check_memory(path, bytes, max_memory)?;
        }
        return layout.sample.visit(MapVisitor {
            path,
            offset,
            count,
            mode,
            layout,
        });
    }
    use std::io::{Seek, SeekFrom};
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    file.seek(SeekFrom::Start(offset))
        .map_err(|e| Error::io(path, e))?;
    from_reader(
        path,
        std::io::BufReader::with_capacity(1 << 20, file),
        layout,
        rescale,
        Stream {
            offset,
            max_memory,
            ..Stream::default()
        },
    )
}

/// Where a sample stream comes from, for [`from_reader`]'s checks and error
/// messages.
#[derive(Debug, Clone, Copy, Default)]
pub struct Stream {
    /// Bytes of the file (or decompressed stream) before the samples,
    /// added to the counts in a length error.
    pub offset: u64,
    /// Bytes of the stream to read and drop before the samples (those of
    /// the `offset` that the reader has not consumed yet).
    pub skip: u64,
    /// The most bytes the stream can yield (gzip expands at most about
    /// 1032:1): a header that promises more is rejected before the memory
    /// for it is allocated.
    pub max_bytes: Option<u64>,
    /// The compression, named in errors (`Some("gzip")`); `None` for
    /// samples read as stored.
    pub compression: Option<&'static str>,
    /// [`OpenOptions::max_memory`](super::OpenOptions::max_memory).
    pub max_memory: Option<u64>,
}

impl Stream {
    /// A gzip stream inflated from `compressed` bytes on disk, its samples
    /// at its start (set `offset` and `skip` for others).
    pub(crate) fn gzip(compressed: u64) -> Stream {
        Stream {
            max_bytes: Some(super::gzip::max_inflated(compressed)),
            compression: Some("gzip"),
            ..Stream::default()
        }
    }

    /// The error for a failed read of this stream from `path`: corrupt data
    /// for a compressed stream, else what the operating system said.
    fn read_error(&self, path: &Path, e: std::io::Error) -> Error {
        match self.compression {
            Some(c) => Error::format(
                path,
                FormatError::Invalid(format!("{c} data is corrupt or truncated ({e})")),
            ),
            None => Error::io(path, e),
        }
    }
}

/// Builds a volume in RAM from the sample bytes that `reader` yields after
/// [`Stream::skip`] bytes, exactly as the file stores them (a file at the
/// samples' offset, a gzip decoder, a slice): read straight into the typed array, then byte-swapped
/// in place and rescaled, so a decode needs no second copy of the data.
pub fn from_reader(
    path: &Path,
    mut reader: impl std::io::Read,
    layout: &SampleLayout,
    rescale: Option<Rescale>,
    stream: Stream,
) -> Result<AnyVolume> {
    layout.validate(path)?;
    let bytes = layout.byte_len(path)?;
    let describe = || {
        format!(
            "{}{}-byte header + {}x{}x{} {} samples",
            if stream.compression.is_some() {
                "decompressed: "
            } else {
                ""
            },
            stream.offset,
            layout.dims.x,
            layout.dims.y,
            layout.dims.z,
            layout.sample
        )
    };
    if let Some(max) = stream.max_bytes
        && bytes > max
    {
        return Err(Error::format(
            path,
            FormatError::Invalid(format!(
                "the header promises {bytes} bytes of samples ({}), more than the {} data in the file can hold",
                describe(),
                stream.compression.unwrap_or("compressed")
            )),
        ));
    }
    check_memory(path, bytes, stream.max_memory)?;
    use std::io::Read;
    std::io::copy(&mut (&mut reader).take(stream.skip), &mut std::io::sink())
        .map_err(|e| stream.read_error(path, e))?;
    let reader: &mut dyn std::io::Read = &mut reader;
    layout.sample.visit(ReadVisitor {
        path,
        reader,
        layout,
        rescale,
        stream,
        describe: &describe,
    })
}

/// Builds a volume in RAM from typed samples in `order`, applying `rescale`.
pub fn from_samples<S: Sample>(
    grid: Grid,
    samples: Vec<S>,
    order: AxisOrder,
    rescale: Option<Rescale>,
) -> Result<AnyVolume> {
    match rescale {
        None => AnyVolume::linear(grid, Storage::from_vec(samples), order),
        Some(r) => rescaled(grid, samples, order, r),
    }
}

/// Converts stored samples to data units: to `i16` when the slope and
/// intercept are whole numbers and every result fits (CT in Hounsfield
/// units), else to `f32`.
fn rescaled<S: Sample>(
    grid: Grid,
    samples: Vec<S>,
    order: AxisOrder,
    r: Rescale,
) -> Result<AnyVolume> {
    let (lo, hi) = crate::volume::fold_range_f32(&samples);
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
        let v = convert(samples, |s| (s.to_f32() as i32 * m + c) as i16);
        return AnyVolume::linear(grid, Storage::from_vec(v), order);
    }
    let v = convert(samples, |s| r.apply(s.to_f32() as f64) as f32);
    AnyVolume::linear(grid, Storage::from_vec(v), order)
}

/// `samples` mapped by `f`, in place when the two types have the same size
/// (u16 or i16 to i16, f32 to f32: a CT volume needs no second copy).
fn convert<S: Sample, T: Sample>(mut samples: Vec<S>, f: impl Fn(S) -> T) -> Vec<T> {
    if std::mem::size_of::<S>() == std::mem::size_of::<T>()
        && std::mem::align_of::<S>() == std::mem::align_of::<T>()
    {
        let size = std::mem::size_of::<S>();
        let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut samples);
        for slot in bytes.chunks_exact_mut(size) {
            let value = f(bytemuck::pod_read_unaligned(slot));
            slot.copy_from_slice(bytemuck::bytes_of(&value));
        }
        return match bytemuck::allocation::try_cast_vec::<S, T>(samples) {
            Ok(v) => v,
            // Not expected with equal size and alignment; copy if it happens.
            Err((_, samples)) => bytemuck::cast_slice::<S, u8>(&samples)
                .chunks_exact(size)
                .map(bytemuck::pod_read_unaligned)
                .collect(),
        };
    }
    samples.into_iter().map(f).collect()
}

struct MapVisitor<'a> {
    path: &'a Path,
    offset: u64,
    count: usize,
    mode: LoadMode,
    layout: &'a SampleLayout,
}

impl SampleTypeVisitor for MapVisitor<'_> {
    type Output = Result<AnyVolume>;
    fn visit<S: Sample>(self) -> Result<AnyVolume> {
        let storage = Storage::open(self.path, self.offset, S::TYPE, self.count, self.mode)?;
        AnyVolume::linear(self.layout.grid(), storage, self.layout.order)
    }
}

struct ReadVisitor<'a> {
    path: &'a Path,
    reader: &'a mut dyn std::io::Read,
    layout: &'a SampleLayout,
    rescale: Option<Rescale>,
    stream: Stream,
    describe: &'a dyn Fn() -> String,
}

impl SampleTypeVisitor for ReadVisitor<'_> {
    type Output = Result<AnyVolume>;
    fn visit<S: Sample>(self) -> Result<AnyVolume> {
        let path = self.path;
        let count =
            usize::try_from(self.layout.dims.as_u64vec3().element_product()).map_err(|_| {
                Error::TooLarge {
                    path: path.to_path_buf(),
                    what: "sample count".into(),
                }
            })?;
        let mut samples = vec![S::zeroed(); count];
        let buf: &mut [u8] = bytemuck::cast_slice_mut(&mut samples);
        let mut filled = 0;
        while filled < buf.len() {
            match self.reader.read(&mut buf[filled..]) {
                Ok(0) => break,
                Ok(n) => filled += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(self.stream.read_error(path, e)),
            }
        }
        if filled < buf.len() {
            return Err(Error::format(
                path,
                FormatError::WrongLength {
                    expected: self.stream.offset.saturating_add(buf.len() as u64),
                    found: self.stream.offset.saturating_add(filled as u64),
                    detail: (self.describe)(),
                },
            ));
        }
        let size = std::mem::size_of::<S>();
        if size > 1 && self.layout.endian != Endian::NATIVE {
            for sample in buf.chunks_exact_mut(size) {
                sample.reverse();
            }
        }
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

/// A sample writer for [`nrrd::write`](super::nrrd::write) and
/// [`nifti::write`](super::nifti::write) that puts `le_bytes` (samples
/// already encoded, x fastest, little-endian) as they are.
pub fn bytes(le_bytes: &[u8]) -> impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()> + '_ {
    move |w| w.write_all(le_bytes)
}

/// The samples of `volume` as bytes in `order` and `endian` order: what a
/// writer of a headerless array puts in a file.
pub fn encode_volume(volume: &AnyVolume, order: AxisOrder, endian: Endian) -> Vec<u8> {
    let mut out = Vec::with_capacity(volume.memory_bytes() as usize);
    match write_samples(&mut out, volume, order, endian) {
        Ok(()) => out,
        Err(_) => unreachable!("writing to a Vec cannot fail"),
    }
}

/// Writes the samples of `volume` to `w` in `order` and `endian` order, one
/// row at a time (no copy of the whole volume in memory).
pub fn write_samples(
    w: &mut dyn std::io::Write,
    volume: &AnyVolume,
    order: AxisOrder,
    endian: Endian,
) -> std::io::Result<()> {
    struct Write<'w> {
        w: &'w mut dyn std::io::Write,
        order: AxisOrder,
        endian: Endian,
    }
    impl crate::volume::VolumeVisitor for Write<'_> {
        type Output = std::io::Result<()>;
        fn visit<V: crate::volume::Volume>(self, v: &V) -> std::io::Result<()> {
            let Write { w, order, endian } = self;
            let d = v.grid().dims;
            // Rows run along the fastest axis: x for x-fast, z for z-fast; `a`
            // counts the slowest axis and `b` counts y.
            let (row_axis, n_outer, row_start): (UVec3, u32, fn(u32, u32) -> UVec3) = match order {
                AxisOrder::XFast => (UVec3::X, d.z, |a, b| UVec3::new(0, b, a)),
                AxisOrder::ZFast => (UVec3::Z, d.x, |a, b| UVec3::new(a, b, 0)),
            };
            let n_middle = d.y;
            let row_len = (d * row_axis).max_element();
            let mut buf = Vec::with_capacity(row_len as usize * V::Sample::TYPE.size());
            for a in 0..n_outer {
                for b in 0..n_middle {
                    buf.clear();
                    let start = row_start(a, b);
                    for c in 0..row_len {
                        v.voxel(start + row_axis * c).encode(endian, &mut buf);
                    }
                    w.write_all(&buf)?;
                }
            }
            Ok(())
        }
    }
    volume.visit(Write { w, order, endian })
}
