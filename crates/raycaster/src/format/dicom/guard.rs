//! A walk over a DICOM file's element headers that checks every declared
//! value length against the bytes the file still holds, before the file is
//! handed to the parser.
//!
//! Why: the parser (dicom-rs) reserves and zeroes an element's declared
//! length before reading it, so a 400-byte file claiming a 4 GB element
//! costs 4 GB of memory and seconds of zeroing before it fails. With every
//! length checked here first, nothing the parser allocates for a value
//! exceeds the file's size.
//!
//! The walk reads only headers: it seeks over values, and descends into
//! sequences and items (whose elements are headers too) instead of skipping
//! them. Fragments of encapsulated pixel data are skipped as bytes. The
//! dataset's encoding comes from the file meta group's transfer syntax; a
//! deflated dataset cannot be walked without inflating it and is refused
//! (the reader does not support it anyway).

use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::Path;

use dicom_core::Tag;
use dicom_core::VR;
use dicom_core::dictionary::{DataDictionary, DataDictionaryEntry};
use dicom_dictionary_std::StandardDataDictionary;

use crate::error::{Error, FormatError, Result};

const ITEM: Tag = Tag(0xFFFE, 0xE000);
const ITEM_END: Tag = Tag(0xFFFE, 0xE00D);
const SEQUENCE_END: Tag = Tag(0xFFFE, 0xE0DD);
const PIXEL_DATA: Tag = Tag(0x7FE0, 0x0010);
const TRANSFER_SYNTAX: Tag = Tag(0x0002, 0x0010);
const UNDEFINED: u32 = u32::MAX;

/// Why the walk ended early.
enum Stop {
    /// The file ends (or cannot be read) mid-header: the parser reports
    /// that better than the walk could.
    End,
    /// A header declares more than the file holds.
    Refuse(FormatError),
}

type Step<T = ()> = std::result::Result<T, Stop>;

/// How a dataset's element headers are encoded.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Encoding {
    explicit_vr: bool,
    big_endian: bool,
}

const EXPLICIT_LE: Encoding = Encoding {
    explicit_vr: true,
    big_endian: false,
};

/// Checks that no element of the DICOM file at `path` declares a value
/// longer than the rest of the file. Files that are not DICOM at all are
/// left to the parser's own error (the walk stops at the first header that
/// makes no sense only when it would make us allocate).
pub(super) fn check_lengths(path: &Path) -> Result<()> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut walk = Walk {
        input: BufReader::new(file),
        pos: 0,
        len,
    };
    match walk.run() {
        Ok(()) | Err(Stop::End) => Ok(()),
        Err(Stop::Refuse(problem)) => Err(Error::format(path, problem)),
    }
}

struct Walk {
    input: BufReader<File>,
    pos: u64,
    len: u64,
}

impl Walk {
    fn run(&mut self) -> Step {
        let mut head = [0u8; 132];
        if self.len >= 132 {
            self.read(&mut head)?;
        }
        if &head[128..132] != b"DICM" {
            self.seek_to(0)?;
        }
        // The file meta group: explicit VR little endian by definition.
        let mut encoding = EXPLICIT_LE;
        let mut syntax = None;
        while self.pos + 8 <= self.len {
            let at = self.pos;
            let (tag, vr, length) = self.header(EXPLICIT_LE)?;
            if tag.0 != 0x0002 {
                self.seek_to(at)?;
                break;
            }
            self.check(tag, length)?;
            if tag == TRANSFER_SYNTAX && length <= 64 {
                let mut uid = vec![0u8; length as usize];
                self.read(&mut uid)?;
                syntax = Some(
                    String::from_utf8_lossy(&uid)
                        .trim_end_matches(['\0', ' '])
                        .to_string(),
                );
            } else if vr != Some(VR::SQ) && length != UNDEFINED {
                self.skip(length)?;
            }
        }
        match syntax.as_deref() {
            Some("1.2.840.10008.1.2") => encoding.explicit_vr = false,
            Some("1.2.840.10008.1.2.2") => encoding.big_endian = true,
            Some(uid @ "1.2.840.10008.1.2.1.99") => {
                return Err(Stop::Refuse(super::header::unsupported_syntax(uid)));
            }
            // Without a meta group: implicit VR little endian, the default.
            None => encoding.explicit_vr = false,
            _ => {}
        }
        self.dataset(encoding)
    }

    /// Walks the dataset's elements (at every nesting depth) to the end of
    /// the file.
    fn dataset(&mut self, encoding: Encoding) -> Step {
        // Inside encapsulated pixel data, items are fragments of bytes.
        let mut in_fragments = false;
        while self.pos + 8 <= self.len {
            let (tag, vr, length) = self.header(encoding)?;
            if tag == ITEM {
                if length == UNDEFINED {
                    continue;
                }
                self.check(tag, length)?;
                if in_fragments {
                    self.skip(length)?;
                }
                // Otherwise an item of a sequence: its elements follow.
                continue;
            }
            if tag == ITEM_END {
                continue;
            }
            if tag == SEQUENCE_END {
                in_fragments = false;
                continue;
            }
            if length == UNDEFINED {
                // A sequence, or encapsulated pixel data: the contents follow
                // as items up to a delimiter.
                in_fragments = tag == PIXEL_DATA;
                continue;
            }
            self.check(tag, length)?;
            let vr = vr.or_else(|| implicit_vr(tag));
            self.check_unit(tag, vr, length)?;
            let sequence = match vr {
                Some(vr) => vr == VR::SQ,
                None => false,
            };
            if !sequence {
                self.skip(length)?;
            }
        }
        Ok(())
    }

    /// One element header: tag, VR (explicit encodings only) and length.
    fn header(&mut self, encoding: Encoding) -> Step<(Tag, Option<VR>, u32)> {
        let mut b = [0u8; 8];
        self.read(&mut b)?;
        let u16_at = |i: usize| {
            let w = [b[i], b[i + 1]];
            if encoding.big_endian {
                u16::from_be_bytes(w)
            } else {
                u16::from_le_bytes(w)
            }
        };
        let u32_of = |w: [u8; 4]| {
            if encoding.big_endian {
                u32::from_be_bytes(w)
            } else {
                u32::from_le_bytes(w)
            }
        };
        let tag = Tag(u16_at(0), u16_at(2));
        // Items and delimiters have no VR in any encoding.
        if tag.0 == 0xFFFE || !encoding.explicit_vr {
            return Ok((tag, None, u32_of([b[4], b[5], b[6], b[7]])));
        }
        // As the parser: an unknown VR is UN; the VRs listed in PS3.5
        // 7.1.2 have a 16-bit length, all others a reserved field and a
        // 32-bit length.
        let vr = VR::from_binary([b[4], b[5]]).unwrap_or(VR::UN);
        let short = matches!(
            vr,
            VR::AE
                | VR::AS
                | VR::AT
                | VR::CS
                | VR::DA
                | VR::DS
                | VR::DT
                | VR::FL
                | VR::FD
                | VR::IS
                | VR::LO
                | VR::LT
                | VR::PN
                | VR::SH
                | VR::SL
                | VR::SS
                | VR::ST
                | VR::TM
                | VR::UI
                | VR::UL
                | VR::US
        );
        if short {
            Ok((tag, Some(vr), u32::from(u16_at(6))))
        } else {
            let mut l = [0u8; 4];
            self.read(&mut l)?;
            Ok((tag, Some(vr), u32_of(l)))
        }
    }

    fn check(&self, tag: Tag, length: u32) -> Step {
        let left = self.len - self.pos;
        if length != UNDEFINED && u64::from(length) > left {
            return Err(Stop::Refuse(FormatError::Invalid(format!(
                "cannot read the DICOM file (element ({:04X},{:04X}) at byte {} declares \
                 {length} bytes but only {left} remain: truncated or corrupt)",
                tag.0, tag.1, self.pos
            ))));
        }
        Ok(())
    }

    /// Refuses a binary value whose length is not a whole number of its
    /// VR's values (an FD of 6 bytes): the parser reads whole values, loses
    /// its place in the file and takes the bytes after it for a header,
    /// whose made-up length it then allocates (a 496-byte file found by
    /// fuzzing made it touch 1.4 GB).
    fn check_unit(&self, tag: Tag, vr: Option<VR>, length: u32) -> Step {
        let unit = match vr {
            Some(VR::US | VR::SS | VR::OW) => 2,
            Some(VR::UL | VR::SL | VR::FL | VR::AT | VR::OF | VR::OL) => 4,
            Some(VR::FD | VR::OD | VR::OV | VR::SV | VR::UV) => 8,
            _ => 1,
        };
        if length != UNDEFINED && !length.is_multiple_of(unit) {
            return Err(Stop::Refuse(FormatError::Invalid(format!(
                "cannot read the DICOM file (element ({:04X},{:04X}) at byte {} is {} with \
                 {length} bytes, not a whole number of {unit}-byte values: corrupt)",
                tag.0,
                tag.1,
                self.pos,
                vr.map_or("?", |v| v.to_string())
            ))));
        }
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8]) -> Step {
        self.input.read_exact(buf).map_err(|_| Stop::End)?;
        self.pos += buf.len() as u64;
        Ok(())
    }

    fn skip(&mut self, n: u32) -> Step {
        self.input
            .seek_relative(i64::from(n))
            .map_err(|_| Stop::End)?;
        self.pos += u64::from(n);
        Ok(())
    }

    fn seek_to(&mut self, pos: u64) -> Step {
        self.input
            .seek(std::io::SeekFrom::Start(pos))
            .map_err(|_| Stop::End)?;
        self.pos = pos;
        Ok(())
    }
}

/// The VR the parser gives an implicit-VR element: the data dictionary's,
/// when it names exactly one.
fn implicit_vr(tag: Tag) -> Option<VR> {
    StandardDataDictionary
        .by_tag(tag)
        .and_then(|e| e.vr().exact())
}
