//! The compression of one chunk of a frame: a byte shuffle, then a
//! general-purpose codec.
//!
//! The shuffle (as in Blosc) puts byte 0 of every sample of the chunk first,
//! then byte 1, and so on. Neighbouring samples of a smooth field share their
//! high bytes (the sign and exponent of a float, the top of an integer), so
//! after the shuffle the chunk starts with long runs that LZ4 and zstd find
//! cheaply; the low, noisy bytes end up together where they cost what they
//! must. It is a permutation, so it loses nothing.

use std::fmt;

/// The general-purpose codec of a `.vseq` file's chunks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Codec {
    /// Stored as is (after the shuffle): the fastest to decode.
    None,
    /// LZ4 (`lz4_flex`, block format): fast decoding, a moderate ratio.
    #[default]
    Lz4,
    /// Zstandard (the `zstd` crate, the reference C library): a better
    /// ratio at a higher decoding cost.
    Zstd,
}

impl Codec {
    /// The code stored in the header.
    pub(super) fn code(self) -> u8 {
        match self {
            Codec::None => 0,
            Codec::Lz4 => 1,
            Codec::Zstd => 2,
        }
    }

    /// The codec of a header code.
    pub(super) fn from_code(code: u8) -> Option<Codec> {
        Some(match code {
            0 => Codec::None,
            1 => Codec::Lz4,
            2 => Codec::Zstd,
            _ => return None,
        })
    }

    /// The name used on command lines.
    pub fn name(self) -> &'static str {
        match self {
            Codec::None => "none",
            Codec::Lz4 => "lz4",
            Codec::Zstd => "zstd",
        }
    }
}

impl fmt::Display for Codec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Byte-shuffles `input` (samples of `width` bytes) into `out` (same
/// length): byte `b` of sample `i` goes to `b·n + i`.
pub(super) fn shuffle(input: &[u8], width: usize, out: &mut [u8]) {
    debug_assert_eq!(input.len(), out.len());
    if width == 1 {
        out.copy_from_slice(input);
        return;
    }
    let n = input.len() / width;
    for (b, plane) in out.chunks_exact_mut(n).enumerate().take(width) {
        for (i, o) in plane.iter_mut().enumerate() {
            *o = input[i * width + b];
        }
    }
}

/// Undoes [`shuffle`].
pub(super) fn unshuffle(input: &[u8], width: usize, out: &mut [u8]) {
    debug_assert_eq!(input.len(), out.len());
    match width {
        1 => out.copy_from_slice(input),
        2 => {
            let n = input.len() / 2;
            let (lo, hi) = input.split_at(n);
            for ((o, &l), &h) in out.chunks_exact_mut(2).zip(lo).zip(hi) {
                o[0] = l;
                o[1] = h;
            }
        }
        4 => {
            let n = input.len() / 4;
            let (b0, rest) = input.split_at(n);
            let (b1, rest) = rest.split_at(n);
            let (b2, b3) = rest.split_at(n);
            let planes = b0.iter().zip(b1).zip(b2).zip(b3);
            for (o, (((&a, &b), &c), &d)) in out.chunks_exact_mut(4).zip(planes) {
                o.copy_from_slice(&[a, b, c, d]);
            }
        }
        _ => {
            let n = input.len() / width;
            for (i, o) in out.chunks_exact_mut(width).enumerate() {
                for (b, byte) in o.iter_mut().enumerate() {
                    *byte = input[b * n + i];
                }
            }
        }
    }
}

/// Compresses `raw` (already shuffled) with `codec` at `level` (zstd only).
pub(super) fn compress(codec: Codec, level: i32, raw: &[u8]) -> std::io::Result<Vec<u8>> {
    match codec {
        Codec::None => Ok(raw.to_vec()),
        Codec::Lz4 => Ok(lz4_flex::block::compress(raw)),
        Codec::Zstd => zstd_compress(raw, level),
    }
}

/// Decompresses `packed` into `out`, which must come out exactly full.
pub(super) fn decompress(codec: Codec, packed: &[u8], out: &mut [u8]) -> Result<(), String> {
    let n = match codec {
        Codec::None => {
            if packed.len() != out.len() {
                return Err(format!(
                    "a stored chunk holds {} bytes, expected {}",
                    packed.len(),
                    out.len()
                ));
            }
            out.copy_from_slice(packed);
            out.len()
        }
        Codec::Lz4 => lz4_flex::block::decompress_into(packed, out).map_err(|e| e.to_string())?,
        Codec::Zstd => zstd_decompress(packed, out)?,
    };
    if n != out.len() {
        return Err(format!(
            "a chunk decompressed to {n} bytes, expected {}",
            out.len()
        ));
    }
    Ok(())
}

#[cfg(feature = "zstd")]
fn zstd_compress(raw: &[u8], level: i32) -> std::io::Result<Vec<u8>> {
    zstd::bulk::compress(raw, level)
}

#[cfg(feature = "zstd")]
fn zstd_decompress(packed: &[u8], out: &mut [u8]) -> Result<usize, String> {
    // The bulk API decodes into the buffer without growing it, so a frame
    // that claims more than the chunk holds fails instead of allocating.
    zstd::bulk::decompress_to_buffer(packed, out).map_err(|e| e.to_string())
}

#[cfg(not(feature = "zstd"))]
fn zstd_compress(_: &[u8], _: i32) -> std::io::Result<Vec<u8>> {
    Err(std::io::Error::other(
        "zstd support is not compiled in (enable the `zstd` feature of raycaster)",
    ))
}

#[cfg(not(feature = "zstd"))]
fn zstd_decompress(_: &[u8], _: &mut [u8]) -> Result<usize, String> {
    Err("zstd support is not compiled in (enable the `zstd` feature of raycaster)".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shuffle_round_trips_for_every_width() {
        let mut rng = fastrand::Rng::with_seed(5);
        for width in [1, 2, 3, 4, 8] {
            let n = 37;
            let data: Vec<u8> = (0..n * width).map(|_| rng.u8(..)).collect();
            let mut shuffled = vec![0; data.len()];
            shuffle(&data, width, &mut shuffled);
            if width > 1 {
                // Byte 1 of sample 0 sits at the start of the second plane.
                assert_eq!(shuffled[n], data[1]);
            }
            let mut back = vec![0; data.len()];
            unshuffle(&shuffled, width, &mut back);
            assert_eq!(back, data, "width {width}");
        }
    }

    #[test]
    fn every_codec_round_trips_and_rejects_a_wrong_length() {
        let raw: Vec<u8> = (0..10_000u32).map(|i| (i / 7 % 251) as u8).collect();
        for codec in [Codec::None, Codec::Lz4, Codec::Zstd] {
            if codec == Codec::Zstd && !cfg!(feature = "zstd") {
                continue;
            }
            let packed = compress(codec, 3, &raw).unwrap();
            if codec != Codec::None {
                assert!(packed.len() < raw.len() / 4, "{codec}: {}", packed.len());
            }
            let mut out = vec![0; raw.len()];
            decompress(codec, &packed, &mut out).unwrap();
            assert_eq!(out, raw, "{codec}");
            // A buffer one byte short or long is an error, not a panic.
            let mut short = vec![0; raw.len() - 1];
            assert!(decompress(codec, &packed, &mut short).is_err(), "{codec}");
            let mut long = vec![0; raw.len() + 1];
            assert!(decompress(codec, &packed, &mut long).is_err(), "{codec}");
            // Garbage is an error, not a panic.
            let garbage: Vec<u8> = packed.iter().map(|b| b ^ 0x5a).collect();
            let _ = decompress(codec, &garbage, &mut out);
        }
    }
}
