//! Pass 2 of reading a series: the pixel format every slice must share,
//! and reading the native pixel data of all slices (in parallel) into one
//! x-fast array of the stored type.

use dicom_core::value::{DicomValueType, PrimitiveValue, Value};
use dicom_dictionary_std::tags;
use dicom_object::OpenFileOptions;
use rayon::prelude::*;

use super::header::{
    Header, invalid, native_endian_of, unreadable, unsupported, unsupported_syntax,
};
use crate::error::{Error, FormatError, Result};
use crate::format::Progress;
use crate::format::samples::{self, Endian, Rescale};
use crate::sample::{Sample, SampleType};
use crate::volume::{AnyVolume, AxisOrder, Grid};

/// Bits Allocated per pixel: the two sizes this reader handles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Allocated {
    /// 8 bits: `u8` or `i8` samples.
    Eight,
    /// 16 bits: `u16` or `i16` samples.
    Sixteen,
}

impl Allocated {
    /// The number of bits.
    pub(super) fn bits(self) -> u32 {
        match self {
            Allocated::Eight => 8,
            Allocated::Sixteen => 16,
        }
    }
}

/// How the pixel data of every slice is stored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PixelFormat {
    pub(super) rows: u32,
    pub(super) columns: u32,
    pub(super) allocated: Allocated,
    /// 1 ..= the allocated bits.
    pub(super) bits_stored: u32,
    pub(super) signed: bool,
}

impl PixelFormat {
    /// The sample type that holds a pixel as stored.
    pub(super) fn sample_type(&self) -> SampleType {
        match (self.allocated, self.signed) {
            (Allocated::Eight, false) => SampleType::U8,
            (Allocated::Eight, true) => SampleType::I8,
            (Allocated::Sixteen, false) => SampleType::U16,
            (Allocated::Sixteen, true) => SampleType::I16,
        }
    }

    fn pixels(&self) -> usize {
        self.rows as usize * self.columns as usize
    }

    /// Masks the bits above Bits Stored off, or extends the sign from there.
    #[inline]
    pub(super) fn fix(&self, word: u16) -> u16 {
        if self.bits_stored >= self.allocated.bits() {
            return word;
        }
        let mask = (1u32 << self.bits_stored) as u16 - 1;
        let w = word & mask;
        if self.signed && (w >> (self.bits_stored - 1)) & 1 == 1 {
            let sign = match self.allocated {
                Allocated::Eight => 0xff,
                Allocated::Sixteen => 0xffff,
            };
            (w | !mask) & sign
        } else {
            w
        }
    }

    /// `16-bit (12 stored, signed)`: for messages.
    pub(super) fn describe(&self) -> String {
        format!(
            "{}-bit ({} stored, {})",
            self.allocated.bits(),
            self.bits_stored,
            if self.signed { "signed" } else { "unsigned" }
        )
    }
}

/// One slice to read: its file, byte order and rescale.
#[derive(Debug, Clone)]
pub(super) struct Slice<'a> {
    pub(super) header: &'a Header,
    pub(super) endian: Endian,
    pub(super) rescale: (f64, f64),
}

/// The byte order of `h`'s pixel data; an error naming the file when its
/// transfer syntax is not an uncompressed one.
pub(super) fn slice_endian(h: &Header) -> Result<Endian> {
    native_endian_of(&h.transfer_syntax)
        .ok_or_else(|| Error::format(&h.path, unsupported_syntax(&h.transfer_syntax)))
}

/// The pixel format of one slice, checked against what this reader handles.
pub(super) fn pixel_format(h: &Header) -> Result<PixelFormat> {
    slice_endian(h)?;
    let spp = h.samples_per_pixel.unwrap_or(1);
    if spp != 1 {
        return Err(unsupported(
            h,
            format!("{spp} samples per pixel (only grey-scale images, 1 sample per pixel)"),
        ));
    }
    match h.photometric.as_deref() {
        None | Some("MONOCHROME1") | Some("MONOCHROME2") => {}
        Some(p) => {
            return Err(unsupported(
                h,
                format!("photometric interpretation {p} (only MONOCHROME1/MONOCHROME2)"),
            ));
        }
    }
    if let Some(n) = h.frames
        && n != 1
    {
        return Err(unsupported(
            h,
            format!("multi-frame file ({n} frames); only single-frame slices are read"),
        ));
    }
    let Some(bits_allocated) = h.bits_allocated else {
        return Err(invalid(h, "Bits Allocated (0028,0100) is missing".into()));
    };
    let allocated = match bits_allocated {
        8 => Allocated::Eight,
        16 => Allocated::Sixteen,
        other => {
            return Err(unsupported(
                h,
                format!("Bits Allocated {other} (only 8 or 16)"),
            ));
        }
    };
    let bits_stored = h.bits_stored.unwrap_or(bits_allocated);
    if bits_stored == 0 || bits_stored > bits_allocated {
        return Err(invalid(
            h,
            format!("Bits Stored {bits_stored} with Bits Allocated {bits_allocated}"),
        ));
    }
    if let Some(hb) = h.high_bit
        && hb + 1 != bits_stored
    {
        return Err(unsupported(
            h,
            format!(
                "High Bit {hb} with Bits Stored {bits_stored} (only High Bit = Bits Stored - 1)"
            ),
        ));
    }
    let signed = match h.pixel_representation.unwrap_or(0) {
        0 => false,
        1 => true,
        p => {
            return Err(invalid(
                h,
                format!("Pixel Representation {p} (must be 0 or 1)"),
            ));
        }
    };
    if h.rows == 0 || h.columns == 0 {
        return Err(invalid(
            h,
            format!("image of {} rows x {} columns", h.rows, h.columns),
        ));
    }
    Ok(PixelFormat {
        rows: h.rows,
        columns: h.columns,
        allocated,
        bits_stored,
        signed,
    })
}

/// The sample built from a (fixed) 8- or 16-bit pixel word: its low byte
/// for 8-bit types, the word for 16-bit ones.
#[inline]
fn from_word<S: Sample>(w: u16) -> S {
    S::decode(
        &[w.to_le_bytes()[0], w.to_le_bytes()[1], 0, 0],
        Endian::Little,
    )
}

/// Pass 2 with the Rust type of the stored samples.
pub(super) struct ReadVolume<'a> {
    pub(super) grid: Grid,
    pub(super) format: &'a PixelFormat,
    /// In volume order (z = 0 first), at least one.
    pub(super) slices: &'a [Slice<'a>],
    /// Whether all slices share one rescale (then `rescale` is it).
    pub(super) uniform: bool,
    pub(super) rescale: Option<Rescale>,
    pub(super) progress: Option<&'a Progress>,
}

impl crate::sample::SampleTypeVisitor for ReadVolume<'_> {
    type Output = Result<AnyVolume>;
    fn visit<S: Sample>(self) -> Result<AnyVolume> {
        read_volume::<S>(
            self.grid,
            self.format,
            self.slices,
            self.uniform,
            self.rescale,
            self.progress,
        )
    }
}

/// Pass 2: reads every slice's pixel data (in parallel) into one x-fast
/// array and builds the volume.
fn read_volume<S: Sample>(
    grid: Grid,
    format: &PixelFormat,
    slices: &[Slice],
    uniform: bool,
    rescale: Option<Rescale>,
    progress: Option<&Progress>,
) -> Result<AnyVolume> {
    let per_slice = format.pixels();
    let total = per_slice
        .checked_mul(slices.len())
        .ok_or_else(|| Error::TooLarge {
            path: slices[0].header.path.clone(),
            what: format!(
                "a series of {} slices of {}x{}",
                slices.len(),
                format.columns,
                format.rows
            ),
        })?;
    // Rows and Columns come from the file: before allocating for them,
    // check that every slice's file could hold its pixel data at all.
    let slice_bytes = (per_slice as u64).saturating_mul(u64::from(format.allocated.bits() / 8));
    for slice in slices {
        let path = &slice.header.path;
        let len = std::fs::metadata(path)
            .map_err(|e| Error::io(path, e))?
            .len();
        if len < slice_bytes {
            return Err(Error::format(
                path,
                FormatError::WrongLength {
                    expected: slice_bytes,
                    found: len,
                    detail: format!(
                        "a file of {len} bytes cannot hold pixel data of {}x{} {}-bit samples",
                        format.columns,
                        format.rows,
                        format.allocated.bits()
                    ),
                },
            ));
        }
    }
    let mut data = Vec::new();
    data.try_reserve_exact(total).map_err(|_| Error::TooLarge {
        path: slices[0].header.path.clone(),
        what: format!("{total} samples of pixel data"),
    })?;
    data.resize(total, S::zeroed());
    let read = std::sync::atomic::AtomicUsize::new(0);
    data.par_chunks_mut(per_slice)
        .zip(slices.par_iter())
        .try_for_each(|(out, slice)| {
            read_slice(slice, format, out)?;
            if let Some(p) = progress {
                let done = read.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                p.report(done as f32 / slices.len() as f32);
            }
            Ok::<(), Error>(())
        })?;
    if uniform {
        return samples::from_samples(grid, data, AxisOrder::XFast, rescale);
    }
    let mut values = Vec::with_capacity(total);
    for (chunk, slice) in data.chunks(per_slice).zip(slices) {
        let (m, c) = slice.rescale;
        values.extend(chunk.iter().map(|&s| (s.to_f32() as f64 * m + c) as f32));
    }
    samples::from_samples::<f32>(grid, values, AxisOrder::XFast, None)
}

/// Reads one slice's native pixel data into `out` (rows × columns samples).
fn read_slice<S: Sample>(slice: &Slice, format: &PixelFormat, out: &mut [S]) -> Result<()> {
    let h = slice.header;
    let obj = OpenFileOptions::new()
        .read_to(tags::PIXEL_DATA)
        .open_file(&h.path)
        .map_err(|e| unreadable(&h.path, &e))?;
    let Some(element) = obj.element_opt(tags::PIXEL_DATA).ok().flatten() else {
        return Err(invalid(h, "no Pixel Data element (7FE0,0010)".into()));
    };
    let n = out.len();
    let short = |found: usize, unit: &str| {
        Error::format(
            &h.path,
            FormatError::WrongLength {
                expected: (n * format.allocated.bits() as usize / 8) as u64,
                found: found as u64,
                detail: format!(
                    "pixel data of {}x{} {}-bit samples, found {unit}",
                    format.columns,
                    format.rows,
                    format.allocated.bits()
                ),
            },
        )
    };
    let prim = match element.value() {
        Value::Primitive(p) => p,
        Value::PixelSequence(_) => {
            return Err(Error::format(
                &h.path,
                unsupported_syntax(&h.transfer_syntax),
            ));
        }
        Value::Sequence(_) => return Err(invalid(h, "Pixel Data is a sequence".into())),
    };
    let put = |out: &mut [S], words: &mut dyn Iterator<Item = u16>| {
        for (o, w) in out.iter_mut().zip(words) {
            *o = from_word::<S>(format.fix(w));
        }
    };
    match (prim, format.allocated) {
        (PrimitiveValue::Empty, _) => {
            return Err(invalid(h, "Pixel Data (7FE0,0010) is empty".into()));
        }
        // Bytes as the file stores them (OB, or OW kept as bytes).
        (PrimitiveValue::U8(bytes), Allocated::Eight) => {
            if bytes.len() < n {
                return Err(short(bytes.len(), "bytes"));
            }
            put(out, &mut bytes.iter().map(|&b| b as u16));
        }
        (PrimitiveValue::U8(bytes), Allocated::Sixteen) => {
            if bytes.len() < 2 * n {
                return Err(short(bytes.len(), "bytes"));
            }
            let e = slice.endian;
            put(out, &mut bytes.chunks_exact(2).map(|c| u16::decode(c, e)));
        }
        // Words already decoded in the transfer syntax's byte order.
        (PrimitiveValue::U16(words), Allocated::Sixteen) => {
            if words.len() < n {
                return Err(short(2 * words.len(), "bytes"));
            }
            put(out, &mut words.iter().copied());
        }
        (PrimitiveValue::I16(words), Allocated::Sixteen) => {
            if words.len() < n {
                return Err(short(2 * words.len(), "bytes"));
            }
            put(out, &mut words.iter().map(|&w| w as u16));
        }
        // 8-bit samples in OW words: back to the byte stream.
        (PrimitiveValue::U16(words), Allocated::Eight) => {
            if 2 * words.len() < n {
                return Err(short(2 * words.len(), "bytes"));
            }
            let e = slice.endian;
            let bytes = words.iter().flat_map(|&w| match e {
                Endian::Little => w.to_le_bytes(),
                Endian::Big => w.to_be_bytes(),
            });
            put(out, &mut bytes.map(|b| b as u16));
        }
        (other, _) => {
            return Err(invalid(
                h,
                format!(
                    "Pixel Data holds {:?} values, not 8- or 16-bit samples",
                    other.value_type()
                ),
            ));
        }
    }
    Ok(())
}
