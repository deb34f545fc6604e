//! NRRD (teem's "nearly raw raster data"): a text header followed by the
//! samples, in the same file (`.nrrd`) or in a detached one (`.nhdr` with a
//! `data file:` field).
//!
//! Supported: `dimension` 3 (or 4 with a size-1 first axis, or with the
//! extra axis slowest: the first volume is opened); types `uchar`, `signed
//! char`, `short`, `ushort`, `float` in all their spellings; `endian`;
//! encodings `raw` and `gzip`; `byte skip`, `line skip`; spacing from
//! `space directions` (the length of each vector) or `spacings`. The first
//! axis is the fastest, as NRRD defines. Orientation and `space origin` are
//! reported, not applied. Raw data is memory-mapped; gzip is decoded once
//! (which needs the `gzip` feature).
//! Not supported (named in the error): ascii/hex/bzip2 encodings, `int`,
//! `double` and 64-bit types, multi-file `data file: LIST`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{UVec3, Vec3};

use super::gzip::Gzip;
use super::samples::{self, Endian, SampleLayout};
use super::{FileFormat, Opened, VolumeInfo};
use crate::error::{Error, FormatError, Result};
use crate::sample::SampleType;
use crate::volume::AxisOrder;

/// The header is text; a file whose first this-many bytes hold no blank line
/// is not one we can read.
const MAX_HEADER: usize = 1 << 20;

/// How the samples are encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// As they are.
    Raw,
    /// A gzip stream.
    Gzip,
}

impl Encoding {
    /// The name in the header's `encoding` field.
    pub fn name(self) -> &'static str {
        match self {
            Encoding::Raw => "raw",
            Encoding::Gzip => "gzip",
        }
    }
}

/// The fields of an NRRD header that matter here, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct NrrdHeader {
    /// The sample layout (dimensions, spacing, type, byte order).
    pub layout: SampleLayout,
    /// Raw or gzip.
    pub encoding: Encoding,
    /// The file holding the samples (the header's own file when attached).
    pub data_file: PathBuf,
    /// Byte offset of the data in `data_file` (attached: just past the
    /// header; plus `byte skip` / `line skip`). `None` for `byte skip: -1`
    /// (the data is the file's last bytes).
    pub data_offset: Option<u64>,
    /// Volumes along a fourth (slowest) axis (1 for a 3-D file); one of
    /// them is opened ([`OpenOptions::volume`](super::OpenOptions::volume)).
    pub extra_volumes: u64,
    /// `space directions` and `space origin` as written, if any.
    pub orientation: Option<String>,
}

fn invalid(path: &Path, msg: impl Into<String>) -> Error {
    Error::format(path, FormatError::Invalid(msg.into()))
}

fn unsupported(path: &Path, msg: impl Into<String>) -> Error {
    Error::format(path, FormatError::Unsupported(msg.into()))
}

/// NRRD type names (teem's `nrrdTypeIsValid` spellings) to sample types.
fn sample_type(name: &str) -> std::result::Result<SampleType, String> {
    Ok(match name {
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => SampleType::U8,
        "signed char" | "int8" | "int8_t" => SampleType::I8,
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            SampleType::I16
        }
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => {
            SampleType::U16
        }
        "float" => SampleType::F32,
        other => {
            return Err(format!(
                "sample type \"{other}\" (supported: uchar, signed char, short, ushort, float)"
            ));
        }
    })
}

/// Parses `(x,y,z)` vectors separated by spaces; `none` entries give `None`.
fn parse_vectors(text: &str) -> Option<Vec<Option<[f64; 3]>>> {
    let mut out = Vec::new();
    let mut rest = text.trim();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("none") {
            out.push(None);
            rest = r.trim_start();
            continue;
        }
        let r = rest.strip_prefix('(')?;
        let end = r.find(')')?;
        let v = samples::parse_triple::<f64>(&r[..end])?;
        out.push(Some(v));
        rest = r[end + 1..].trim_start();
    }
    Some(out)
}

/// Splits the file's first bytes into header lines and the data offset (the
/// byte after the blank line that ends the header, or the end of `bytes`
/// for a detached header without one).
fn split_header(bytes: &[u8]) -> Option<(Vec<String>, u64)> {
    let mut lines = Vec::new();
    let mut pos = 0;
    while pos < bytes.len() {
        let end = bytes[pos..].iter().position(|&b| b == b'\n');
        let (line, next) = match end {
            Some(e) => (&bytes[pos..pos + e], pos + e + 1),
            None => (&bytes[pos..], bytes.len()),
        };
        let line = String::from_utf8_lossy(line)
            .trim_end_matches('\r')
            .to_string();
        if line.is_empty() {
            return Some((lines, next as u64));
        }
        lines.push(line);
        pos = next;
    }
    // No blank line: the whole text is a header (valid for .nhdr).
    (!lines.is_empty()).then_some((lines, bytes.len() as u64))
}

impl NrrdHeader {
    /// Reads and validates the header of `path`.
    pub fn read(path: &Path) -> Result<Self> {
        let head = super::read_head(path, MAX_HEADER)?;
        if !head.starts_with(b"NRRD000") {
            return Err(invalid(path, "not an NRRD file (no NRRD000x magic line)"));
        }
        let (lines, header_end) = split_header(&head).ok_or_else(|| {
            invalid(
                path,
                "header does not end (no blank line in the first 1 MB)",
            )
        })?;
        let mut fields = HashMap::new();
        for line in lines.iter().skip(1) {
            if line.starts_with('#') || line.contains(":=") {
                continue; // comments and key/value pairs
            }
            let Some((key, value)) = line.split_once(": ") else {
                return Err(invalid(path, format!("malformed header line \"{line}\"")));
            };
            fields.insert(key.trim().to_ascii_lowercase(), value.trim().to_string());
        }
        let get = |k: &str| fields.get(k).map(String::as_str);
        let need = |k: &str| get(k).ok_or_else(|| invalid(path, format!("missing field \"{k}\"")));

        let ty = sample_type(need("type")?).map_err(|m| unsupported(path, m))?;
        let dimension: usize = need("dimension")?
            .parse()
            .map_err(|_| invalid(path, "dimension is not a number"))?;
        let sizes: Vec<u64> = need("sizes")?
            .split_whitespace()
            .map(|s| s.parse().ok().filter(|&n| n > 0))
            .collect::<Option<_>>()
            .ok_or_else(|| invalid(path, "sizes must be positive integers"))?;
        if sizes.len() != dimension {
            return Err(invalid(
                path,
                format!(
                    "dimension is {dimension} but sizes has {} entries",
                    sizes.len()
                ),
            ));
        }
        // Which axes are the volume's x, y, z.
        let (axes, extra_volumes) = match dimension {
            3 => ([0, 1, 2], 1),
            4 if sizes[0] == 1 => ([1, 2, 3], 1),
            4 => ([0, 1, 2], sizes[3]),
            d => {
                return Err(unsupported(
                    path,
                    format!("{d}-dimensional data (3-D volumes, or 4-D sequences of them)"),
                ));
            }
        };
        let dims = axes.map(|a| sizes[a]);
        if dims.iter().any(|&d| d >= 1 << 31) {
            return Err(invalid(path, "a size exceeds 2^31"));
        }
        let dims = UVec3::new(dims[0] as u32, dims[1] as u32, dims[2] as u32);

        let endian = match get("endian") {
            Some("little") => Endian::Little,
            Some("big") => Endian::Big,
            None if ty.size() == 1 => Endian::Little,
            None => {
                return Err(invalid(
                    path,
                    "missing field \"endian\" for a multi-byte type",
                ));
            }
            Some(other) => return Err(invalid(path, format!("endian \"{other}\""))),
        };
        let encoding = match need("encoding")? {
            "raw" => Encoding::Raw,
            "gzip" | "gz" => Encoding::Gzip,
            other => {
                return Err(unsupported(
                    path,
                    format!("encoding \"{other}\" (supported: raw, gzip)"),
                ));
            }
        };

        let mut orientation = None;
        let spacing_all: Vec<f64> = if let Some(sd) = get("space directions") {
            let vectors = parse_vectors(sd)
                .filter(|v| v.len() == dimension)
                .ok_or_else(|| invalid(path, format!("malformed space directions \"{sd}\"")))?;
            let mut text = format!("space directions {sd}");
            if let Some(space) = get("space") {
                text = format!("space {space}; {text}");
            }
            if let Some(origin) = get("space origin") {
                text.push_str(&format!("; space origin {origin}"));
            }
            orientation = Some(text);
            vectors
                .iter()
                .map(|v| v.map_or(1.0, |[a, b, c]| (a * a + b * b + c * c).sqrt()))
                .collect()
        } else if let Some(sp) = get("spacings") {
            let v: Vec<f64> = sp
                .split_whitespace()
                .map(|s| {
                    // teem writes "nan" for an axis without spacing.
                    if s.eq_ignore_ascii_case("nan") {
                        Some(1.0)
                    } else {
                        s.parse().ok().filter(|v: &f64| v.is_finite())
                    }
                })
                .collect::<Option<_>>()
                .filter(|v: &Vec<f64>| v.len() == dimension)
                .ok_or_else(|| invalid(path, format!("malformed spacings \"{sp}\"")))?;
            v
        } else {
            vec![1.0; dimension]
        };
        let spacing = axes.map(|a| spacing_all[a] as f32);
        let spacing = Vec3::from_array(spacing);

        let dir = path.parent().unwrap_or(Path::new("."));
        let data_file = match get("data file").or(get("datafile")) {
            None => path.to_path_buf(),
            Some(f) if f.starts_with("LIST") || f.split_whitespace().count() > 1 => {
                return Err(unsupported(path, "data split over several files"));
            }
            Some(f) => {
                let data = dir.join(f);
                // Only a regular file has a length to check reads against: a
                // device or a pipe could be read forever.
                match std::fs::metadata(&data) {
                    Ok(m) if !m.is_file() => {
                        return Err(invalid(
                            path,
                            format!("data file {} is not a regular file", data.display()),
                        ));
                    }
                    _ => data,
                }
            }
        };
        let attached = data_file == path;
        let line_skip: u64 = get("line skip")
            .or(get("lineskip"))
            .map_or(Ok(0), |s| s.parse())
            .map_err(|_| invalid(path, "line skip is not a number"))?;
        let byte_skip: i64 = get("byte skip")
            .or(get("byteskip"))
            .map_or(Ok(0), |s| s.parse())
            .map_err(|_| invalid(path, "byte skip is not a number"))?;
        let base = if attached { header_end } else { 0 };
        let after_lines = if line_skip > 0 {
            skip_lines(&data_file, base, line_skip)?
        } else {
            base
        };
        let data_offset = match byte_skip {
            -1 if encoding == Encoding::Raw => None,
            -1 => {
                return Err(invalid(
                    path,
                    "byte skip -1 is only valid with raw encoding",
                ));
            }
            n if n < 0 => return Err(invalid(path, format!("byte skip {n}"))),
            n => Some(after_lines + n as u64),
        };
        Ok(NrrdHeader {
            layout: SampleLayout {
                dims,
                spacing,
                sample: ty,
                endian,
                order: AxisOrder::XFast,
            },
            encoding,
            data_file,
            data_offset,
            extra_volumes,
            orientation,
        })
    }
}

/// The byte offset after `n` lines starting at `from` in `path`, reading no
/// further than the file's length as it is now: a data file that never ends
/// (`/dev/zero`, a pipe) or one long line would otherwise be read forever,
/// and into memory.
fn skip_lines(path: &Path, from: u64, n: u64) -> Result<u64> {
    use std::io::{BufRead, Read, Seek, SeekFrom};
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut f = std::io::BufReader::new(file);
    f.seek(SeekFrom::Start(from))
        .map_err(|e| Error::io(path, e))?;
    let mut f = f.take(len.saturating_sub(from));
    let mut pos = from;
    for _ in 0..n {
        loop {
            let buf = f.fill_buf().map_err(|e| Error::io(path, e))?;
            if buf.is_empty() {
                return Err(invalid(path, "line skip passes the end of the file"));
            }
            match buf.iter().position(|&b| b == b'\n') {
                Some(i) => {
                    f.consume(i + 1);
                    pos += i as u64 + 1;
                    break;
                }
                None => {
                    let k = buf.len();
                    f.consume(k);
                    pos += k as u64;
                }
            }
        }
    }
    Ok(pos)
}

/// The reader of NRRD files: the `NRRD000x` magic line claims a file, the
/// names `.nrrd` and `.nhdr` claim it weakly.
#[derive(Debug, Clone, Copy)]
pub struct NrrdReader;

impl super::Reader for NrrdReader {
    fn sniff(&self, probe: &super::Probe) -> Option<super::Claim> {
        if probe.is_dir {
            None
        } else if probe.head.starts_with(b"NRRD000") {
            Some(super::Claim::Content)
        } else {
            matches!(probe.extension(), "nrrd" | "nhdr").then_some(super::Claim::Name)
        }
    }

    fn open(&self, path: &Path, options: &super::OpenOptions) -> Result<Opened> {
        open(path, options)
    }
}

fn open(path: &Path, options: &super::OpenOptions) -> Result<Opened> {
    let (mode, progress, max_memory) =
        (options.mode, options.progress.as_ref(), options.max_memory);
    let h = NrrdHeader::read(path)?;
    let layout = h.layout;
    layout.validate(path)?;
    let bytes = layout.byte_len(path)?;
    let index = super::check_volume_index(path, options.volume, h.extra_volumes)?;
    // The volumes follow each other (the fourth axis is the slowest).
    let skip = index * bytes;
    let data = &h.data_file;
    let data_len = super::file_len(data)?;
    let volume = match h.encoding {
        Encoding::Raw => {
            let offset = match h.data_offset {
                Some(o) => o,
                None => data_len
                    .checked_sub(bytes.saturating_mul(h.extra_volumes))
                    .ok_or_else(|| {
                        Error::format(
                            data,
                            FormatError::WrongLength {
                                expected: bytes.saturating_mul(h.extra_volumes),
                                found: data_len,
                                detail: "samples at the end of the file (byte skip -1)".into(),
                            },
                        )
                    })?,
            };
            samples::from_file(data, offset + skip, &layout, None, mode, false, max_memory)?
        }
        Encoding::Gzip => {
            use std::io::{Seek, SeekFrom};
            let gzip = Gzip::get(path)?;
            let start = h.data_offset.unwrap_or(0);
            let mut f = std::fs::File::open(data).map_err(|e| Error::io(data, e))?;
            f.seek(SeekFrom::Start(start))
                .map_err(|e| Error::io(data, e))?;
            let compressed = data_len.saturating_sub(start);
            let counted = super::ProgressReader::new(f, compressed, progress);
            let stream = samples::Stream {
                offset: skip,
                skip,
                max_memory,
                ..samples::Stream::gzip(compressed)
            };
            samples::from_reader(data, gzip.decoder(counted), &layout, None, stream)?
        }
    };
    let mut file_bytes = super::file_len(path)?;
    if data != path {
        file_bytes += data_len;
    }
    let mut info = VolumeInfo::new(FileFormat::Nrrd, &layout, h.encoding.name(), file_bytes);
    info.orientation = h.orientation;
    if data != path {
        info.notes.push(format!("data in {}", data.display()));
    }
    info.volumes = h.extra_volumes;
    if h.extra_volumes > 1 {
        info.notes.push(format!(
            "4-D file with {} volumes: opened volume {index}",
            h.extra_volumes
        ));
    }
    Ok(Opened { volume, info })
}

/// Writes an NRRD file with the given encoding, its samples (x fastest,
/// little-endian, of type `sample`) written by `samples` into the file or
/// the gzip stream ([`samples::bytes`] for samples already in memory): the
/// project's own writer, for converters and round-trip tests.
pub fn write(
    path: &Path,
    dims: UVec3,
    spacing: Vec3,
    sample: SampleType,
    encoding: Encoding,
    samples: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> Result<()> {
    use std::io::Write;
    let type_name = match sample {
        SampleType::U8 => "uchar",
        SampleType::I8 => "signed char",
        SampleType::U16 => "ushort",
        SampleType::I16 => "short",
        SampleType::F32 => "float",
    };
    let header = format!(
        "NRRD0004\n# written by raycaster\ntype: {type_name}\ndimension: 3\nspace: left-posterior-superior\nsizes: {} {} {}\nspace directions: ({},0,0) (0,{},0) (0,0,{})\nendian: little\nencoding: {}\nspace origin: (0,0,0)\n\n",
        dims.x,
        dims.y,
        dims.z,
        spacing.x,
        spacing.y,
        spacing.z,
        encoding.name()
    );
    // The header stays text; only the samples are compressed.
    let gzip = match encoding {
        Encoding::Raw => None,
        Encoding::Gzip => Some(Gzip::get(path)?),
    };
    super::atomic::write_atomically(path, |w| {
        w.write_all(header.as_bytes())?;
        match gzip {
            Some(gzip) => gzip.encode(w, samples),
            None => samples(w),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn space_directions_parse_with_none_and_spaces() {
        let v = parse_vectors("none (1,0,0) (0, 2.5, 0)  (0,0,-3)").unwrap();
        assert_eq!(v[0], None);
        assert_eq!(v[2], Some([0.0, 2.5, 0.0]));
        assert_eq!(v[3], Some([0.0, 0.0, -3.0]));
        assert!(parse_vectors("(1,0) (0,1,0)").is_none());
        assert!(parse_vectors("(1,0,0").is_none());
    }

    #[test]
    fn type_spellings() {
        assert_eq!(sample_type("unsigned char"), Ok(SampleType::U8));
        assert_eq!(sample_type("int16_t"), Ok(SampleType::I16));
        assert_eq!(sample_type("ushort"), Ok(SampleType::U16));
        assert!(sample_type("double").unwrap_err().contains("double"));
    }
}
