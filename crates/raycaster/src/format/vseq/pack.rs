//! Writing a `.vseq` file from a sequence of volumes.

use std::io::{Seek, SeekFrom, Write};
use std::path::Path;
use std::time::Instant;

use rayon::prelude::*;

use super::codec::{self, Codec};
use super::{ENTRY_LEN, FrameEntry, HEADER_LEN, Header, StoredAs};
use crate::error::{Error, FormatError, Result};
use crate::format::Progress;
use crate::format::samples::{Endian, encode_volume};
use crate::sample::SampleType;
use crate::volume::{AnyVolume, AxisOrder};

/// How to pack a sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct PackOptions {
    /// The codec of every chunk.
    pub codec: Codec,
    /// The zstd level (1..=22; ignored by the other codecs).
    pub level: i32,
    /// Store `f32` frames as half floats (lossy: about 3 significant
    /// digits; refused for other sample types).
    pub f16: bool,
    /// Every `key_interval`-th frame is a key frame, the others difference
    /// frames (1: every frame is a key frame).
    pub key_interval: u32,
    /// Bytes of stored samples per chunk (chunks decode in parallel; many
    /// small chunks compress worse).
    pub chunk_bytes: usize,
    /// Byte-shuffle each chunk before compressing it.
    pub shuffle: bool,
    /// Store each sample of a chunk as its difference from the sample
    /// before it (smooth data: small numbers, which compress better).
    pub delta: bool,
}

impl Default for PackOptions {
    fn default() -> Self {
        PackOptions {
            codec: Codec::Lz4,
            level: 3,
            f16: false,
            key_interval: 1,
            chunk_bytes: 1 << 20,
            shuffle: true,
            // On the plume sequence the delta filter made f16 frames larger
            // (zstd 9.0 → 9.7 %, LZ4 16.6 → 20.2 %): the shuffle already
            // groups the equal high bytes, and the differences of noisy low
            // bits wrap into high ones.
            delta: false,
        }
    }
}

/// What a pack wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct PackReport {
    /// Frames written.
    pub frames: u32,
    /// Bytes of the frames' samples as given (the sample type's size).
    pub raw_bytes: u64,
    /// Bytes of the file.
    pub file_bytes: u64,
    /// Seconds spent.
    pub seconds: f64,
}

impl PackReport {
    /// The file's size as a percentage of the samples' size.
    pub fn percent(&self) -> f64 {
        100.0 * self.file_bytes as f64 / self.raw_bytes.max(1) as f64
    }
}

/// Writes `frames` volumes, frame `k` given by `frame(k)`, to `path` as a
/// `.vseq` file (atomically: the name appears when the file is complete).
/// Every frame must have the first one's dimensions, spacing and sample
/// type; an error names the frame.
pub fn pack(
    path: &Path,
    frames: u32,
    mut frame: impl FnMut(u32) -> Result<AnyVolume>,
    options: &PackOptions,
    progress: Option<&Progress>,
) -> Result<PackReport> {
    let start = Instant::now();
    let option = |m: String| Error::option("pack", m);
    if frames == 0 {
        return Err(option("a sequence needs at least one frame".into()));
    }
    if options.key_interval == 0 {
        return Err(option("the key interval must be at least 1".into()));
    }
    if options.codec == Codec::Zstd && !(1..=22).contains(&options.level) {
        return Err(option(format!(
            "zstd level {} (must be 1..=22)",
            options.level
        )));
    }
    let first = frame(0)?;
    let grid = *first.grid();
    let sample = first.sample_type();
    if options.f16 && sample != SampleType::F32 {
        return Err(option(format!(
            "half-float storage is for f32 frames; these are {sample}"
        )));
    }
    let stored = if options.f16 {
        StoredAs::F16
    } else {
        StoredAs::Samples
    };
    let mut header = Header {
        sample,
        stored,
        codec: options.codec,
        shuffle: options.shuffle,
        delta: options.delta,
        dims: grid.dims,
        spacing: grid.spacing,
        frames,
        key_interval: options.key_interval,
        chunk_samples: 0,
        index_offset: 0,
    };
    let width = header.stored_width();
    header.chunk_samples = (options.chunk_bytes / width).clamp(1, u32::MAX as usize) as u32;
    let chunk_bytes = header.chunk_samples as usize * width;

    let mut raw_bytes = 0u64;
    let mut index = Vec::with_capacity(frames as usize);
    let mut first = Some(first);
    // A frame that cannot be read or does not match fails the write; the
    // error to report is the frame's, not the writer's.
    let mut failure: Option<Error> = None;
    let written = super::super::atomic::write_atomically(path, |w| {
        let mut fail = |e: Error| {
            let message = e.to_string();
            failure = Some(e);
            std::io::Error::other(message)
        };
        w.write_all(&[0u8; HEADER_LEN])?;
        let mut offset = HEADER_LEN as u64;
        let mut prev: Option<Vec<u8>> = None;
        for k in 0..frames {
            let volume = match first.take() {
                Some(v) => v,
                None => frame(k).map_err(&mut fail)?,
            };
            let g = volume.grid();
            if g.dims != grid.dims || g.spacing != grid.spacing || volume.sample_type() != sample {
                return Err(fail(Error::format(
                    path,
                    FormatError::Invalid(format!(
                        "frame {k} is {}x{}x{} {} with spacing {}, unlike frame 0 ({}x{}x{} {} with spacing {})",
                        g.dims.x,
                        g.dims.y,
                        g.dims.z,
                        volume.sample_type(),
                        g.spacing,
                        grid.dims.x,
                        grid.dims.y,
                        grid.dims.z,
                        sample,
                        grid.spacing
                    )),
                )));
            }
            let le = encode_volume(&volume, AxisOrder::XFast, Endian::Little);
            raw_bytes += le.len() as u64;
            drop(volume);
            let (bytes, (min, max)) = to_stored(le, stored, sample);
            let difference = !header.is_key(k);
            let payload = match (&prev, difference) {
                (Some(p), true) => {
                    let mut d = bytes.clone();
                    d.par_chunks_mut(chunk_bytes)
                        .zip(p.par_chunks(chunk_bytes))
                        .for_each(|(d, p)| super::sub_wrapping(d, p, width));
                    compress_frame(&d, chunk_bytes, width, options)?
                }
                _ => compress_frame(&bytes, chunk_bytes, width, options)?,
            };
            // Only the next difference frame needs this one.
            prev = (options.key_interval > 1).then_some(bytes);
            w.write_all(&payload)?;
            index.push(FrameEntry {
                offset,
                len: payload.len() as u64,
                crc: crc32fast::hash(&payload),
                difference,
                min,
                max,
            });
            offset += payload.len() as u64;
            if let Some(p) = progress {
                p.report((k + 1) as f32 / frames as f32);
            }
        }
        let mut entries = Vec::with_capacity(index.len() * ENTRY_LEN);
        for e in &index {
            entries.extend_from_slice(&e.to_bytes());
        }
        w.write_all(&entries)?;
        w.write_all(&crc32fast::hash(&entries).to_le_bytes())?;
        header.index_offset = offset;
        w.seek(SeekFrom::Start(0))?;
        w.write_all(&header.to_bytes())?;
        Ok(())
    });
    if let Err(e) = written {
        return Err(failure.unwrap_or(e));
    }
    let file_bytes = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    Ok(PackReport {
        frames,
        raw_bytes,
        file_bytes,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// A frame's samples (little-endian bytes of `sample`) in their stored
/// form, and the smallest and largest value they hold once decoded.
fn to_stored(le: Vec<u8>, stored: StoredAs, sample: SampleType) -> (Vec<u8>, (f32, f32)) {
    let width = sample.size();
    let value = |s: &[u8]| -> f32 {
        match sample {
            SampleType::U8 => f32::from(s[0]),
            SampleType::I8 => f32::from(s[0] as i8),
            SampleType::U16 => f32::from(u16::from_le_bytes([s[0], s[1]])),
            SampleType::I16 => f32::from(i16::from_le_bytes([s[0], s[1]])),
            SampleType::F32 => f32::from_le_bytes([s[0], s[1], s[2], s[3]]),
        }
    };
    let range = |bytes: &[u8], width: usize, value: &(dyn Fn(&[u8]) -> f32 + Sync)| {
        bytes
            .par_chunks(width << 16)
            .map(|c| {
                c.chunks_exact(width)
                    .map(value)
                    .fold((f32::MAX, f32::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)))
            })
            .reduce(|| (f32::MAX, f32::MIN), |a, b| (a.0.min(b.0), a.1.max(b.1)))
    };
    match stored {
        StoredAs::Samples => {
            let r = range(&le, width, &value);
            (le, r)
        }
        StoredAs::F16 => {
            let mut out = vec![0u8; le.len() / 2];
            out.par_chunks_mut(2 << 16)
                .zip(le.par_chunks(4 << 16))
                .for_each(|(o, s)| {
                    for (o, s) in o.chunks_exact_mut(2).zip(s.chunks_exact(4)) {
                        let h = half::f16::from_f32(f32::from_le_bytes([s[0], s[1], s[2], s[3]]));
                        o.copy_from_slice(&h.to_bits().to_le_bytes());
                    }
                });
            let half_value =
                |s: &[u8]| half::f16::from_bits(u16::from_le_bytes([s[0], s[1]])).to_f32();
            let r = range(&out, 2, &half_value);
            (out, r)
        }
    }
}

/// The bytes of one frame: its chunk table, then its chunks, each shuffled
/// and compressed on its own (in parallel).
fn compress_frame(
    stored: &[u8],
    chunk_bytes: usize,
    width: usize,
    options: &PackOptions,
) -> std::io::Result<Vec<u8>> {
    let chunks: Vec<Vec<u8>> = stored
        .par_chunks(chunk_bytes)
        .map(|c| {
            let delta;
            let c = if options.delta {
                let mut d = c.to_vec();
                super::delta_wrapping(&mut d, width);
                delta = d;
                &delta[..]
            } else {
                c
            };
            if options.shuffle && width > 1 {
                let mut s = vec![0u8; c.len()];
                codec::shuffle(c, width, &mut s);
                codec::compress(options.codec, options.level, &s)
            } else {
                codec::compress(options.codec, options.level, c)
            }
        })
        .collect::<std::io::Result<_>>()?;
    let total: usize = chunks.iter().map(Vec::len).sum();
    let mut out = Vec::with_capacity(chunks.len() * 4 + total);
    for c in &chunks {
        let len = u32::try_from(c.len()).map_err(std::io::Error::other)?;
        out.extend_from_slice(&len.to_le_bytes());
    }
    for c in &chunks {
        out.extend_from_slice(c);
    }
    Ok(out)
}
