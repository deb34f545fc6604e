//! gzip streams, for the formats that may compress their samples (NRRD's
//! `encoding: gzip`, `.nii.gz`, the image file of a `.hdr`).
//!
//! The codec (`flate2`) is behind the `gzip` cargo feature. Readers and
//! writers reach it only through a [`Gzip`] value, which [`Gzip::get`] hands
//! out when the feature is on and refuses with an error naming the file and
//! the feature when it is off: then `Gzip` has no values at all, so no code
//! path can use a codec that is not there.

use std::io::{Read, Write};
use std::path::Path;

use crate::error::Result;

/// Access to the gzip codec (see the module documentation).
#[cfg(feature = "gzip")]
#[derive(Debug, Clone, Copy)]
pub(crate) struct Gzip(());

/// Access to the gzip codec: without the `gzip` feature there is none, and
/// this type has no values.
#[cfg(not(feature = "gzip"))]
#[derive(Debug, Clone, Copy)]
pub(crate) enum Gzip {}

#[cfg(feature = "gzip")]
impl Gzip {
    /// The codec (`path` is the file that needs it, named in the error a
    /// build without the feature gives).
    pub(crate) fn get(_path: &Path) -> Result<Gzip> {
        Ok(Gzip(()))
    }

    /// The bytes that the gzip members of `input` inflate to.
    pub(crate) fn decoder<'a>(self, input: impl Read + 'a) -> Box<dyn Read + 'a> {
        Box::new(flate2::read::MultiGzDecoder::new(std::io::BufReader::new(
            input,
        )))
    }

    /// Writes to `out` the gzip stream of what `fill` writes (fast
    /// compression: volumes are large and mostly compress well anyway).
    pub(crate) fn encode(
        self,
        out: &mut dyn Write,
        fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        let mut e = flate2::write::GzEncoder::new(out, flate2::Compression::fast());
        fill(&mut e)?;
        e.finish().map(|_| ())
    }
}

#[cfg(not(feature = "gzip"))]
impl Gzip {
    /// The error saying that `path` needs the `gzip` feature.
    pub(crate) fn get(path: &Path) -> Result<Gzip> {
        Err(crate::error::Error::format(
            path,
            crate::error::FormatError::NotCompiledIn {
                support: "gzip",
                feature: "gzip",
            },
        ))
    }

    /// Never called: there is no `Gzip` value to call it on.
    pub(crate) fn decoder<'a>(self, _input: impl Read + 'a) -> Box<dyn Read + 'a> {
        match self {}
    }

    /// Never called: there is no `Gzip` value to call it on.
    pub(crate) fn encode(
        self,
        _out: &mut dyn Write,
        _fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        match self {}
    }
}

/// Whether `head` (a file's first bytes) starts a gzip stream.
pub(crate) fn is_gzip(head: &[u8]) -> bool {
    head.starts_with(&[0x1f, 0x8b])
}

/// The most bytes `compressed` bytes of gzip can inflate to (deflate's
/// best ratio is about 1032:1), with room for small streams: a header that
/// promises more samples is rejected before their memory is allocated.
pub(crate) fn max_inflated(compressed: u64) -> u64 {
    compressed.saturating_mul(1032).saturating_add(1 << 16)
}
