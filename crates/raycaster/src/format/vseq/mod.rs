//! `.vseq`: this project's container for a sequence of volumes (the frames
//! of a simulation or a 4-D scan), each frame compressed on its own so that
//! any frame can be decoded without the others.
//!
//! # Layout (version 1, every number little-endian)
//!
//! ```text
//! offset  size  field
//!      0     8  magic "VSEQ\r\n\x1a\n"
//!      8     2  version (1)
//!     10     1  sample type of the frames: 0 u8, 1 i8, 2 u16, 3 i16, 4 f32
//!     11     1  storage: 0 = the sample type, 1 = IEEE half floats (f32 frames only; lossy)
//!     12     1  codec: 0 none, 1 LZ4 (block format), 2 zstd
//!     13     1  filters: bit 0 = byte shuffle within each chunk,
//!               bit 1 = delta: each sample minus the one before it in its chunk
//!     14     2  reserved (0)
//!     16    12  dimensions x, y, z (u32)
//!     28    12  spacing x, y, z (f32)
//!     40     4  frame count F (u32, at least 1)
//!     44     4  key interval K (u32, at least 1): frame k is a key frame when
//!               k mod K = 0, else a difference frame
//!     48     4  chunk samples C (u32, at least 1)
//!     52     8  index offset (u64): where the frame index starts
//!     60     4  CRC-32 of bytes 0..60
//!     64        frames, one after another
//! index:        F entries of 32 bytes:
//!                 0  u64  offset of the frame's bytes
//!                 8  u64  length of the frame's bytes
//!                16  u32  CRC-32 of the frame's bytes
//!                20  u8   kind: 0 key, 1 difference
//!                21  3    reserved (0)
//!                24  f32  smallest sample value of the frame
//!                28  f32  largest sample value
//!               then the CRC-32 of the F entries (4 bytes); the file ends there.
//! ```
//!
//! A frame is its samples in x-fastest order, in the stored type (2-byte
//! half floats when storage is 1, else the sample type's bytes), cut into
//! chunks of C samples (the last one shorter). A frame's bytes are a table
//! of its chunks' compressed lengths (one u32 each, ⌈n/C⌉ of them) followed
//! by the chunks, each shuffled (when filter bit 0 is set: see
//! [`codec`]) and compressed on its own, so that a frame decodes on every
//! core at once.
//!
//! A difference frame stores, sample by sample, its stored value minus the
//! previous frame's, as unsigned integers of the stored width with
//! wrap-around (lossless, whatever the type: a float's bits are
//! subtracted). Consecutive frames of a smooth simulation differ in their
//! low bits only, which compress much better than the values. Decoding
//! frame k starts at the key frame at or before it, so stepping backwards
//! costs at most K decodes; [`VseqFile`] keeps the last frame decoded, so
//! playing forwards costs one.
//!
//! Every length, offset and checksum is checked before it is used: a
//! truncated or corrupt file is an error naming the file and the frame.

pub mod codec;
mod pack;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{UVec3, Vec3};
use parking_lot::Mutex;
use rayon::prelude::*;

pub use codec::Codec;
pub use pack::{PackOptions, PackReport, pack};

use super::{FileFormat, Opened, VolumeInfo};
use crate::error::{Error, FormatError, Result};
use crate::sample::{Sample, SampleType};
use crate::storage::Storage;
use crate::volume::{AnyVolume, AxisOrder, Grid};

/// The first bytes of every `.vseq` file.
pub const MAGIC: &[u8; 8] = b"VSEQ\r\n\x1a\n";
/// The layout version this code writes and reads.
pub const VERSION: u16 = 1;
/// Bytes of the header.
pub const HEADER_LEN: usize = 64;
/// Bytes of a frame's entry in the index.
pub const ENTRY_LEN: usize = 32;

/// How the samples of a frame are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StoredAs {
    /// As the frames' sample type.
    Samples,
    /// As IEEE 754 half floats (f32 frames only): half the bytes, about
    /// three significant decimal digits.
    F16,
}

/// The header of a `.vseq` file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Header {
    /// The sample type of the decoded frames.
    pub sample: SampleType,
    /// How the samples are stored.
    pub stored: StoredAs,
    /// The codec of every chunk.
    pub codec: Codec,
    /// Whether chunks are byte-shuffled before compression.
    pub shuffle: bool,
    /// Whether each chunk's samples are stored as differences from the
    /// sample before them (the delta filter).
    pub delta: bool,
    /// Samples per axis.
    pub dims: UVec3,
    /// Spacing per axis.
    pub spacing: Vec3,
    /// Frames in the file.
    pub frames: u32,
    /// Every `key_interval`-th frame is a key frame (1: all of them).
    pub key_interval: u32,
    /// Samples per chunk.
    pub chunk_samples: u32,
    /// Where the index starts.
    pub index_offset: u64,
}

fn sample_code(t: SampleType) -> u8 {
    match t {
        SampleType::U8 => 0,
        SampleType::I8 => 1,
        SampleType::U16 => 2,
        SampleType::I16 => 3,
        SampleType::F32 => 4,
    }
}

fn sample_of_code(c: u8) -> Option<SampleType> {
    Some(match c {
        0 => SampleType::U8,
        1 => SampleType::I8,
        2 => SampleType::U16,
        3 => SampleType::I16,
        4 => SampleType::F32,
        _ => return None,
    })
}

impl Header {
    /// The header's bytes, checksum included.
    pub fn to_bytes(&self) -> [u8; HEADER_LEN] {
        let mut h = [0u8; HEADER_LEN];
        h[..8].copy_from_slice(MAGIC);
        h[8..10].copy_from_slice(&VERSION.to_le_bytes());
        h[10] = sample_code(self.sample);
        h[11] = match self.stored {
            StoredAs::Samples => 0,
            StoredAs::F16 => 1,
        };
        h[12] = self.codec.code();
        h[13] = u8::from(self.shuffle) | (u8::from(self.delta) << 1);
        for i in 0..3 {
            h[16 + 4 * i..20 + 4 * i].copy_from_slice(&self.dims[i].to_le_bytes());
            h[28 + 4 * i..32 + 4 * i].copy_from_slice(&self.spacing[i].to_le_bytes());
        }
        h[40..44].copy_from_slice(&self.frames.to_le_bytes());
        h[44..48].copy_from_slice(&self.key_interval.to_le_bytes());
        h[48..52].copy_from_slice(&self.chunk_samples.to_le_bytes());
        h[52..60].copy_from_slice(&self.index_offset.to_le_bytes());
        let crc = crc32fast::hash(&h[..60]);
        h[60..64].copy_from_slice(&crc.to_le_bytes());
        h
    }

    /// Parses and checks a header; the message says what is wrong.
    pub fn parse(h: &[u8]) -> std::result::Result<Header, String> {
        if h.len() < HEADER_LEN {
            return Err(format!(
                "file is {} bytes long, shorter than the {HEADER_LEN}-byte header",
                h.len()
            ));
        }
        if &h[..8] != MAGIC {
            return Err("not a .vseq file (bad magic)".into());
        }
        let u32_at = |o: usize| u32::from_le_bytes([h[o], h[o + 1], h[o + 2], h[o + 3]]);
        let f32_at = |o: usize| f32::from_bits(u32_at(o));
        if crc32fast::hash(&h[..60]) != u32_at(60) {
            return Err("header checksum mismatch (the header is corrupt)".into());
        }
        let version = u16::from_le_bytes([h[8], h[9]]);
        if version != VERSION {
            return Err(format!(
                "version {version} (this build reads version {VERSION})"
            ));
        }
        let sample = sample_of_code(h[10]).ok_or(format!("unknown sample type code {}", h[10]))?;
        let stored = match h[11] {
            0 => StoredAs::Samples,
            1 if sample == SampleType::F32 => StoredAs::F16,
            1 => return Err(format!("half-float storage of {sample} samples")),
            c => return Err(format!("unknown storage code {c}")),
        };
        let codec = Codec::from_code(h[12]).ok_or(format!("unknown codec code {}", h[12]))?;
        if h[13] > 3 {
            return Err(format!("unknown filter bits {:#x}", h[13]));
        }
        let dims = UVec3::new(u32_at(16), u32_at(20), u32_at(24));
        let spacing = Vec3::new(f32_at(28), f32_at(32), f32_at(36));
        let header = Header {
            sample,
            stored,
            codec,
            shuffle: h[13] & 1 == 1,
            delta: h[13] & 2 == 2,
            dims,
            spacing,
            frames: u32_at(40),
            key_interval: u32_at(44),
            chunk_samples: u32_at(48),
            index_offset: u64::from_le_bytes(h[52..60].try_into().map_err(|_| "header")?),
        };
        if header.frames == 0 {
            return Err("frame count is 0".into());
        }
        if header.key_interval == 0 {
            return Err("key interval is 0".into());
        }
        if header.chunk_samples == 0 {
            return Err("chunk size is 0 samples".into());
        }
        Ok(header)
    }

    /// Bytes of one stored sample.
    pub fn stored_width(&self) -> usize {
        match self.stored {
            StoredAs::Samples => self.sample.size(),
            StoredAs::F16 => 2,
        }
    }

    /// Whether frame `k` is a key frame.
    pub fn is_key(&self, k: u32) -> bool {
        k.is_multiple_of(self.key_interval)
    }
}

/// A frame's entry in the index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameEntry {
    /// Offset of the frame's bytes in the file.
    pub offset: u64,
    /// Length of the frame's bytes.
    pub len: u64,
    /// CRC-32 of the frame's bytes.
    pub crc: u32,
    /// Whether it is a difference frame.
    pub difference: bool,
    /// The smallest sample value of the frame (as decoded).
    pub min: f32,
    /// The largest.
    pub max: f32,
}

impl FrameEntry {
    fn to_bytes(self) -> [u8; ENTRY_LEN] {
        let mut e = [0u8; ENTRY_LEN];
        e[..8].copy_from_slice(&self.offset.to_le_bytes());
        e[8..16].copy_from_slice(&self.len.to_le_bytes());
        e[16..20].copy_from_slice(&self.crc.to_le_bytes());
        e[20] = u8::from(self.difference);
        e[24..28].copy_from_slice(&self.min.to_le_bytes());
        e[28..32].copy_from_slice(&self.max.to_le_bytes());
        e
    }

    fn parse(e: &[u8]) -> FrameEntry {
        let u32_at = |o: usize| u32::from_le_bytes([e[o], e[o + 1], e[o + 2], e[o + 3]]);
        let u64_at = |o: usize| u64::from(u32_at(o)) | (u64::from(u32_at(o + 4)) << 32);
        FrameEntry {
            offset: u64_at(0),
            len: u64_at(8),
            crc: u32_at(16),
            difference: e[20] != 0,
            min: f32::from_bits(u32_at(24)),
            max: f32::from_bits(u32_at(28)),
        }
    }
}

/// An open `.vseq` file: its header and index, read and checked; frames are
/// read from the file when asked for (by positioned reads, so many threads
/// may decode at once).
#[derive(Debug)]
pub struct VseqFile {
    path: PathBuf,
    file: std::fs::File,
    header: Header,
    index: Vec<FrameEntry>,
    /// The stored bytes of the last frame decoded, the start of the next
    /// difference frame's decode.
    last: Mutex<Option<(u32, Arc<Vec<u8>>)>>,
}

impl VseqFile {
    /// Opens `path` and checks its header and index.
    pub fn open(path: &Path) -> Result<VseqFile> {
        use std::io::Read;
        let invalid = |m: String| Error::format(path, FormatError::Invalid(m));
        let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        let mut head = Vec::with_capacity(HEADER_LEN);
        (&mut file)
            .take(HEADER_LEN as u64)
            .read_to_end(&mut head)
            .map_err(|e| Error::io(path, e))?;
        let header = Header::parse(&head).map_err(invalid)?;
        let index_len = u64::from(header.frames) * ENTRY_LEN as u64 + 4;
        let expected = header.index_offset.checked_add(index_len);
        if header.index_offset < HEADER_LEN as u64 || expected != Some(len) {
            return Err(Error::format(
                path,
                FormatError::WrongLength {
                    expected: expected.unwrap_or(u64::MAX),
                    found: len,
                    detail: format!(
                        "an index of {} frames at byte {}: the file is truncated or corrupt",
                        header.frames, header.index_offset
                    ),
                },
            ));
        }
        let mut raw = vec![0u8; index_len as usize];
        read_at(&file, &mut raw, header.index_offset).map_err(|e| Error::io(path, e))?;
        let (entries, crc) = raw.split_at(raw.len() - 4);
        if crc32fast::hash(entries) != u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]) {
            return Err(invalid(
                "index checksum mismatch (the frame index is corrupt)".into(),
            ));
        }
        let index: Vec<FrameEntry> = entries
            .chunks_exact(ENTRY_LEN)
            .map(FrameEntry::parse)
            .collect();
        for (k, e) in index.iter().enumerate() {
            let end = e.offset.checked_add(e.len);
            if e.offset < HEADER_LEN as u64 || end.is_none_or(|end| end > header.index_offset) {
                return Err(invalid(format!(
                    "frame {k}: bytes {}..+{} lie outside the frame area",
                    e.offset, e.len
                )));
            }
            if e.difference == header.is_key(k as u32) {
                return Err(invalid(format!(
                    "frame {k}: kind disagrees with the key interval {}",
                    header.key_interval
                )));
            }
        }
        let n = header_samples(&header).ok_or_else(|| {
            invalid(format!(
                "dimensions {}x{}x{} overflow",
                header.dims.x, header.dims.y, header.dims.z
            ))
        })?;
        // A frame's chunk table alone must fit in its bytes; this bounds the
        // memory a decode allocates by what the file can hold.
        let chunks = n.div_ceil(header.chunk_samples as u64);
        if let Some((k, _)) = index.iter().enumerate().find(|(_, e)| e.len < chunks * 4) {
            return Err(invalid(format!(
                "frame {k}: {} bytes cannot hold the table of its {chunks} chunks",
                index[k].len
            )));
        }
        Ok(VseqFile {
            path: path.to_path_buf(),
            file,
            header,
            index,
            last: Mutex::new(None),
        })
    }

    /// The header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The frame index.
    pub fn index(&self) -> &[FrameEntry] {
        &self.index
    }

    /// The number of frames.
    pub fn frames(&self) -> u32 {
        self.header.frames
    }

    /// The grid of every frame.
    pub fn grid(&self) -> Grid {
        Grid::new(self.header.dims, self.header.spacing)
    }

    /// The smallest and largest sample value over all frames.
    pub fn value_range(&self) -> (f32, f32) {
        self.index.iter().fold((f32::MAX, f32::MIN), |(lo, hi), e| {
            (lo.min(e.min), hi.max(e.max))
        })
    }

    /// A description of the file for `vol_app info`.
    pub fn info(&self) -> VolumeInfo {
        let h = &self.header;
        let file_bytes = self.header.index_offset + (self.index.len() * ENTRY_LEN) as u64 + 4;
        let layout = super::SampleLayout {
            dims: h.dims,
            spacing: h.spacing,
            sample: h.sample,
            endian: super::Endian::Little,
            order: AxisOrder::XFast,
        };
        let mut encoding = h.codec.name().to_string();
        if h.stored == StoredAs::F16 {
            encoding += " of f16";
        }
        if h.delta {
            encoding += ", delta";
        }
        if h.shuffle {
            encoding += ", shuffled";
        }
        let mut info = VolumeInfo::new(FileFormat::Vseq, &layout, &encoding, file_bytes);
        info.volumes = u64::from(h.frames);
        info.notes.push(format!(
            "{} frames, {}",
            h.frames,
            if h.key_interval == 1 {
                "all key frames".to_string()
            } else {
                format!("a key frame every {}", h.key_interval)
            }
        ));
        info
    }

    /// Decodes frame `k` into a volume in RAM.
    pub fn frame(&self, k: u32) -> Result<AnyVolume> {
        let name = self.frame_error(k);
        if k >= self.header.frames {
            return Err(name(format!(
                "there are {} frames (numbered from 0)",
                self.header.frames
            )));
        }
        let storage = match self.header.stored {
            StoredAs::F16 => {
                let mut bits = self.buffer()?;
                self.stored_into(k, &mut bits)?;
                Storage::from_vec(f16_to_f32(&bits))
            }
            StoredAs::Samples => {
                // The stored bytes are the samples' little-endian bytes:
                // decode straight into the volume's array.
                struct Decode<'a>(&'a VseqFile, u32);
                impl crate::sample::SampleTypeVisitor for Decode<'_> {
                    type Output = Result<Storage>;
                    fn visit<S: Sample>(self) -> Result<Storage> {
                        let Decode(file, k) = self;
                        let n = file.stored_len() / std::mem::size_of::<S>();
                        let mut v: Vec<S> = zeroed(n).ok_or_else(|| file.too_large())?;
                        file.stored_into(k, bytemuck::cast_slice_mut::<S, u8>(&mut v))?;
                        from_le(&mut v);
                        Ok(Storage::from_vec(v))
                    }
                }
                self.header.sample.visit(Decode(self, k))?
            }
        };
        AnyVolume::linear(self.grid(), storage, AxisOrder::XFast)
    }

    /// A zeroed buffer for one frame's stored bytes.
    fn buffer(&self) -> Result<Vec<u8>> {
        zeroed(self.stored_len()).ok_or_else(|| self.too_large())
    }

    fn too_large(&self) -> Error {
        Error::TooLarge {
            path: self.path.clone(),
            what: format!("a frame of {} bytes", self.stored_len()),
        }
    }

    /// Decodes the stored bytes of frame `k` (differences undone) into
    /// `out`: directly in a file of key frames only; else from the key
    /// frame at or before `k`, or from the last frame decoded when that is
    /// on the way, keeping frame `k` for the next call.
    fn stored_into(&self, k: u32, out: &mut [u8]) -> Result<()> {
        if self.header.key_interval == 1 {
            return self.decode_stored(k, None, out);
        }
        let key = k - k % self.header.key_interval;
        let cached = self.last.lock().clone();
        let (mut next, mut prev) = match cached {
            Some((j, bytes)) if j == k => {
                out.copy_from_slice(&bytes);
                return Ok(());
            }
            Some((j, bytes)) if (key..k).contains(&j) => (j + 1, Some(bytes)),
            _ => (key, None),
        };
        while next <= k {
            let mut buf = self.buffer()?;
            self.decode_stored(next, prev.as_deref().map(Vec::as_slice), &mut buf)?;
            prev = Some(Arc::new(buf));
            next += 1;
        }
        if let Some(bytes) = prev {
            out.copy_from_slice(&bytes);
            *self.last.lock() = Some((k, bytes));
        }
        Ok(())
    }

    fn stored_len(&self) -> usize {
        header_samples(&self.header).unwrap_or(0) as usize * self.header.stored_width()
    }

    /// An error about frame `k` of this file.
    fn frame_error(&self, k: u32) -> impl Fn(String) -> Error + '_ {
        move |m| Error::format(&self.path, FormatError::Invalid(format!("frame {k}: {m}")))
    }

    /// Reads frame `k`'s bytes, checks them and decodes its chunks in
    /// parallel into `out` (stored bytes), adding `prev` for a difference
    /// frame.
    fn decode_stored(&self, k: u32, prev: Option<&[u8]>, out: &mut [u8]) -> Result<()> {
        let fail = self.frame_error(k);
        let e = self.index[k as usize];
        let mut payload = vec![0u8; e.len as usize];
        read_at(&self.file, &mut payload, e.offset).map_err(|err| Error::io(&self.path, err))?;
        if crc32fast::hash(&payload) != e.crc {
            return Err(fail(
                "checksum mismatch (the frame's bytes are corrupt)".into(),
            ));
        }
        let width = self.header.stored_width();
        let chunk_bytes = self.header.chunk_samples as usize * width;
        let chunks = out.len().div_ceil(chunk_bytes);
        let (table, mut body) = payload.split_at(chunks * 4);
        let mut packed = Vec::with_capacity(chunks);
        for len in table.chunks_exact(4) {
            let len = u32::from_le_bytes([len[0], len[1], len[2], len[3]]) as usize;
            if len > body.len() {
                return Err(fail(format!(
                    "a chunk of {len} bytes runs past the frame's end"
                )));
            }
            let (chunk, rest) = body.split_at(len);
            packed.push(chunk);
            body = rest;
        }
        if !body.is_empty() {
            return Err(fail(format!("{} bytes after the last chunk", body.len())));
        }
        let difference = e.difference;
        let (codec, shuffle, delta) = (self.header.codec, self.header.shuffle, self.header.delta);
        out.par_chunks_mut(chunk_bytes)
            .zip(packed.par_iter())
            .enumerate()
            .try_for_each(|(i, (out, packed))| {
                if shuffle && width > 1 {
                    if codec == Codec::None {
                        if packed.len() != out.len() {
                            return Err(format!(
                                "a stored chunk holds {} bytes, expected {}",
                                packed.len(),
                                out.len()
                            ));
                        }
                        codec::unshuffle(packed, width, out);
                    } else {
                        SCRATCH.with_borrow_mut(|scratch| {
                            scratch.resize(out.len(), 0);
                            codec::decompress(codec, packed, scratch)?;
                            codec::unshuffle(scratch, width, out);
                            Ok::<(), String>(())
                        })?;
                    }
                } else {
                    codec::decompress(codec, packed, out)?;
                }
                if delta {
                    prefix_sum_wrapping(out, width);
                }
                if difference {
                    let prev = prev.ok_or("a difference frame without its predecessor")?;
                    let start = i * chunk_bytes;
                    add_wrapping(out, &prev[start..start + out.len()], width);
                }
                Ok::<(), String>(())
            })
            .map_err(|m| fail(format!("chunk: {m}")))
    }
}

thread_local! {
    /// A decoding thread's buffer for one decompressed, still shuffled
    /// chunk.
    static SCRATCH: std::cell::RefCell<Vec<u8>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Runs `$f::<W>(args)` with `W` the stored width in bytes (1, 2 or 4), so
/// each word loop below is compiled for a constant width.
macro_rules! with_width {
    ($width:expr, $f:ident($($arg:expr),*)) => {
        match $width {
            1 => $f::<1>($($arg),*),
            2 => $f::<2>($($arg),*),
            _ => $f::<4>($($arg),*),
        }
    };
}

/// Undoes the delta filter in place: sample i becomes the wrapping sum of
/// samples 0..=i (little-endian unsigned integers of `width` bytes).
fn prefix_sum_wrapping(out: &mut [u8], width: usize) {
    with_width!(width, prefix_sum_words(out))
}

fn prefix_sum_words<const W: usize>(out: &mut [u8]) {
    let mut acc = 0u32;
    for o in out.chunks_exact_mut(W) {
        acc = acc.wrapping_add(load::<W>(o));
        store::<W>(acc, o);
    }
}

/// The delta filter in place: each sample minus the one before it
/// (wrapping), the first kept.
fn delta_wrapping(out: &mut [u8], width: usize) {
    with_width!(width, delta_words(out))
}

fn delta_words<const W: usize>(out: &mut [u8]) {
    let mut prev = 0u32;
    for o in out.chunks_exact_mut(W) {
        let v = load::<W>(o);
        store::<W>(v.wrapping_sub(prev), o);
        prev = v;
    }
}

/// `n` zero bytes, or `None` when the memory cannot be had (a header may
/// claim any size; the allocation must fail softly, not abort).
fn zeroed<S: bytemuck::Zeroable + bytemuck::Pod>(n: usize) -> Option<Vec<S>> {
    let mut probe: Vec<S> = Vec::new();
    probe.try_reserve_exact(n).ok()?;
    drop(probe);
    // Zeroed by the allocator: fresh pages come zeroed, not written twice.
    Some(bytemuck::zeroed_vec(n))
}

/// Samples per frame, `None` on overflow.
fn header_samples(h: &Header) -> Option<u64> {
    (h.dims.x as u64)
        .checked_mul(h.dims.y as u64)?
        .checked_mul(h.dims.z as u64)
}

/// The little-endian unsigned integer of a `W`-byte word, widened.
#[inline]
fn load<const W: usize>(b: &[u8]) -> u32 {
    let mut w = [0u8; 4];
    w[..W].copy_from_slice(&b[..W]);
    u32::from_le_bytes(w)
}

/// Stores the low `W` bytes of `v` (arithmetic modulo 2^(8·W) done in
/// `u32` and truncated is arithmetic in `W` bytes).
#[inline]
fn store<const W: usize>(v: u32, b: &mut [u8]) {
    b[..W].copy_from_slice(&v.to_le_bytes()[..W]);
}

fn zip_words<const W: usize>(out: &mut [u8], prev: &[u8], op: impl Fn(u32, u32) -> u32) {
    for (o, p) in out.chunks_exact_mut(W).zip(prev.chunks_exact(W)) {
        store::<W>(op(load::<W>(o), load::<W>(p)), o);
    }
}

/// `out[i] += prev[i]` for little-endian unsigned integers of `width`
/// bytes, wrapping.
fn add_wrapping(out: &mut [u8], prev: &[u8], width: usize) {
    with_width!(width, zip_words(out, prev, u32::wrapping_add))
}

/// `out[i] -= prev[i]`, the inverse of [`add_wrapping`].
fn sub_wrapping(out: &mut [u8], prev: &[u8], width: usize) {
    with_width!(width, zip_words(out, prev, u32::wrapping_sub))
}

/// Half floats (little-endian bytes) to `f32`, in parallel (`half`'s slice
/// conversion uses the F16C instructions where the processor has them).
fn f16_to_f32(stored: &[u8]) -> Vec<f32> {
    use half::slice::{HalfBitsSliceExt, HalfFloatSliceExt};
    const BLOCK: usize = 1 << 14;
    let mut out = vec![0f32; stored.len() / 2];
    out.par_chunks_mut(BLOCK)
        .zip(stored.par_chunks(2 * BLOCK))
        .for_each(|(o, s)| {
            let bits: Vec<u16> = s
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]))
                .collect();
            bits.reinterpret_cast::<half::f16>().convert_to_f32_slice(o);
        });
    out
}

/// Little-endian samples to the machine's order, in place.
fn from_le<S: Sample>(v: &mut [S]) {
    if cfg!(target_endian = "big") {
        for s in bytemuck::cast_slice_mut::<S, u8>(v).chunks_exact_mut(std::mem::size_of::<S>()) {
            s.reverse();
        }
    }
}

/// Reads exactly `buf.len()` bytes at `offset` without moving a shared
/// file position.
fn read_at(file: &std::fs::File, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
    }
    #[cfg(windows)]
    {
        let mut done = 0;
        while done < buf.len() {
            let n = std::os::windows::fs::FileExt::seek_read(
                file,
                &mut buf[done..],
                offset + done as u64,
            )?;
            if n == 0 {
                return Err(std::io::ErrorKind::UnexpectedEof.into());
            }
            done += n;
        }
        Ok(())
    }
}

/// The reader of `.vseq` files for [`open_file`](super::open_file): frame
/// [`OpenOptions::volume`](super::OpenOptions::volume) as a volume.
#[derive(Debug, Clone, Copy)]
pub struct VseqReader;

impl super::Reader for VseqReader {
    fn sniff(&self, probe: &super::Probe) -> Option<super::Claim> {
        if probe.is_dir {
            None
        } else if probe.head.starts_with(MAGIC) {
            Some(super::Claim::Content)
        } else {
            (probe.extension() == "vseq").then_some(super::Claim::Name)
        }
    }

    fn open(&self, path: &Path, options: &super::OpenOptions) -> Result<Opened> {
        let file = VseqFile::open(path)?;
        let k = super::check_volume_index(path, options.volume, u64::from(file.frames()))?;
        let h = file.header();
        let bytes = h.dims.as_u64vec3().element_product() * h.sample.size() as u64;
        super::samples::check_memory(path, bytes, options.max_memory)?;
        let volume = file.frame(k as u32)?;
        let mut info = file.info();
        info.notes.push(format!("opened frame {k}"));
        Ok(Opened { volume, info })
    }
}

#[cfg(test)]
mod tests;
