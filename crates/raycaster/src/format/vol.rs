//! This project's `.vol` format: a 26-byte little-endian header (dimensions
//! X, Y, Z as `u32`; spacing X, Y, Z as `f32`; a layout byte; a brick side
//! byte) followed by `u8` samples, linear (z fastest) or in overlapping
//! bricks. The file holds exactly the bytes the header implies.

use std::io::Write;
use std::path::Path;

use glam::{UVec3, Vec3};
use nom::Parser;
use nom::number::complete::{le_f32, le_u32, u8 as byte};

use super::samples::{Endian, write_samples};
use crate::error::{Error, FormatError, Result};
use crate::sample::{Sample, SampleType};
use crate::storage::{LoadMode, Storage};
use crate::volume::{AnyVolume, AxisOrder, BrickGrid, Grid, Volume, VolumeVisitor};

/// Header length in bytes.
pub const HEADER_LEN: usize = 26;

/// Layout byte value for the linear layout.
pub const LAYOUT_LINEAR: u8 = 1;
/// Layout byte value for the bricked layout.
pub const LAYOUT_BRICKED: u8 = 2;

/// The sample order of a `.vol` file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VolLayout {
    /// z fastest, one array.
    Linear,
    /// Overlapping bricks of side B.
    Bricked {
        /// B, 2..=255.
        side: u8,
    },
}

/// A parsed and validated `.vol` header.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VolHeader {
    /// Dimensions, each >= 1.
    pub dims: UVec3,
    /// Spacing, each finite and > 0.
    pub spacing: Vec3,
    /// Sample order.
    pub layout: VolLayout,
}

/// The raw fields, before validation.
struct RawHeader {
    dims: [u32; 3],
    spacing: [f32; 3],
    layout: u8,
    extra: u8,
}

fn raw_header(input: &[u8]) -> nom::IResult<&[u8], RawHeader> {
    let (rest, (x, y, z, sx, sy, sz, layout, extra)) =
        (le_u32, le_u32, le_u32, le_f32, le_f32, le_f32, byte, byte).parse(input)?;
    Ok((
        rest,
        RawHeader {
            dims: [x, y, z],
            spacing: [sx, sy, sz],
            layout,
            extra,
        },
    ))
}

impl VolHeader {
    /// Parses and validates the first 26 bytes of `bytes`.
    pub fn parse(bytes: &[u8]) -> Result<Self, FormatError> {
        let (_, raw) = raw_header(bytes).map_err(|_| FormatError::TooShortForHeader {
            expected: HEADER_LEN as u64,
            found: bytes.len() as u64,
        })?;
        for (axis, &d) in ['X', 'Y', 'Z'].iter().zip(&raw.dims) {
            if d == 0 {
                return Err(FormatError::ZeroDimension { axis: *axis });
            }
        }
        for (axis, &s) in ['X', 'Y', 'Z'].iter().zip(&raw.spacing) {
            if !(s.is_finite() && s > 0.0) {
                return Err(FormatError::BadSpacing {
                    axis: *axis,
                    value: s,
                });
            }
        }
        let layout = match raw.layout {
            LAYOUT_LINEAR => VolLayout::Linear,
            LAYOUT_BRICKED if raw.extra >= 2 => VolLayout::Bricked { side: raw.extra },
            LAYOUT_BRICKED => return Err(FormatError::BadBrickSize(raw.extra)),
            other => return Err(FormatError::UnknownLayout(other)),
        };
        let header = VolHeader {
            dims: UVec3::from_array(raw.dims),
            spacing: Vec3::from_array(raw.spacing),
            layout,
        };
        header.sample_count()?;
        Ok(header)
    }

    /// The 26 header bytes.
    pub fn to_bytes(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        for i in 0..3 {
            b[i * 4..i * 4 + 4].copy_from_slice(&self.dims[i].to_le_bytes());
            b[12 + i * 4..16 + i * 4].copy_from_slice(&self.spacing[i].to_le_bytes());
        }
        match self.layout {
            VolLayout::Linear => b[24] = LAYOUT_LINEAR,
            VolLayout::Bricked { side } => {
                b[24] = LAYOUT_BRICKED;
                b[25] = side;
            }
        }
        b
    }

    /// Number of sample bytes the header implies.
    pub fn sample_count(&self) -> Result<u64, FormatError> {
        let d = self.dims.as_u64vec3();
        let overflow = FormatError::SizeOverflow {
            x: d.x,
            y: d.y,
            z: d.z,
        };
        match self.layout {
            VolLayout::Linear => {
                d.x.checked_mul(d.y)
                    .and_then(|v| v.checked_mul(d.z))
                    .ok_or(overflow)
            }
            VolLayout::Bricked { side } => BrickGrid::new(self.dims, side as u32)
                .map_err(|_| FormatError::BadBrickSize(side))?
                .total_len()
                .ok_or(overflow),
        }
    }

    /// Total file length the header implies.
    pub fn file_len(&self) -> Result<u64, FormatError> {
        let d = self.dims;
        self.sample_count()?
            .checked_add(HEADER_LEN as u64)
            .ok_or(FormatError::SizeOverflow {
                x: d.x as u64,
                y: d.y as u64,
                z: d.z as u64,
            })
    }

    fn length_detail(&self) -> String {
        let d = self.dims;
        match self.layout {
            VolLayout::Linear => {
                format!("{HEADER_LEN}-byte header + {}x{}x{} samples", d.x, d.y, d.z)
            }
            VolLayout::Bricked { side } => {
                let n = BrickGrid::new(d, side as u32).map_or(UVec3::ZERO, |b| b.count);
                format!(
                    "{HEADER_LEN}-byte header + {}x{}x{} bricks of {side}^3 samples",
                    n.x, n.y, n.z
                )
            }
        }
    }

    /// The grid this header describes (origin 0).
    pub fn grid(&self) -> Grid {
        Grid::new(self.dims, self.spacing)
    }
}

/// Reads and validates the header of `path` and checks the file's length.
pub fn read_header(path: &Path) -> Result<VolHeader> {
    use std::io::Read;
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = f.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut buf = Vec::with_capacity(HEADER_LEN);
    Read::by_ref(&mut f)
        .take(HEADER_LEN as u64)
        .read_to_end(&mut buf)
        .map_err(|e| Error::io(path, e))?;
    let header = VolHeader::parse(&buf).map_err(|k| Error::format(path, k))?;
    let expected = header.file_len().map_err(|k| Error::format(path, k))?;
    if expected != len {
        return Err(Error::format(
            path,
            FormatError::WrongLength {
                expected,
                found: len,
                detail: header.length_detail(),
            },
        ));
    }
    Ok(header)
}

/// Opens a `.vol` file, mapped or read into RAM.
pub fn open(path: &Path, mode: LoadMode) -> Result<AnyVolume> {
    open_read_header(path, mode, None).map(|(volume, _)| volume)
}

/// [`open`], also returning the header it read.
fn open_read_header(
    path: &Path,
    mode: LoadMode,
    max_memory: Option<u64>,
) -> Result<(AnyVolume, VolHeader)> {
    let header = read_header(path)?;
    let count = header.sample_count().map_err(|k| Error::format(path, k))?;
    if mode == LoadMode::Ram {
        super::samples::check_memory(path, count, max_memory)?;
    }
    let count = usize::try_from(count).map_err(|_| Error::TooLarge {
        path: path.to_path_buf(),
        what: format!("{count} samples"),
    })?;
    let storage = Storage::open(path, HEADER_LEN as u64, SampleType::U8, count, mode)?;
    let volume = match header.layout {
        VolLayout::Linear => AnyVolume::linear(header.grid(), storage, AxisOrder::ZFast)?,
        VolLayout::Bricked { side } => AnyVolume::bricked(header.grid(), side as u32, storage)?,
    };
    Ok((volume, header))
}

/// True when `head` is a valid header whose implied length is `file_len`.
fn header_matches(head: &[u8], file_len: u64) -> bool {
    VolHeader::parse(head).is_ok_and(|h| h.file_len() == Ok(file_len))
}

/// The reader of `.vol` files. It claims the `.vol` extension (and names
/// without one) firmly when the header's implied length matches the file,
/// and otherwise only as a fallback, so that a UC Davis file with the same
/// extension goes to its own reader while a broken `.vol` header is
/// reported by this one.
#[derive(Debug, Clone, Copy)]
pub struct VolReader;

impl super::Reader for VolReader {
    fn sniff(&self, probe: &super::Probe) -> Option<super::Claim> {
        if probe.is_dir || !matches!(probe.extension(), "vol" | "") {
            return None;
        }
        Some(if header_matches(probe.head, probe.len) {
            super::Claim::Content
        } else {
            super::Claim::Fallback
        })
    }

    fn open(&self, path: &Path, options: &super::OpenOptions) -> Result<super::Opened> {
        let (volume, header) = open_read_header(path, options.mode, options.max_memory)?;
        let layout = super::SampleLayout {
            dims: header.dims,
            spacing: header.spacing,
            sample: SampleType::U8,
            endian: Endian::Little,
            order: AxisOrder::ZFast,
        };
        let encoding = match header.layout {
            VolLayout::Linear => "raw, z fastest".to_string(),
            VolLayout::Bricked { side } => format!("bricked (B = {side})"),
        };
        let info = super::VolumeInfo::new(
            super::FileFormat::Vol,
            &layout,
            &encoding,
            header.file_len().unwrap_or(0),
        );
        Ok(super::Opened { volume, info })
    }
}

/// Writes `volume` to `path` in `layout`. The file is written under a
/// temporary name in the same directory and renamed when complete, so a
/// reader never sees a partial file.
pub fn write(path: &Path, volume: &AnyVolume, layout: VolLayout) -> Result<()> {
    if volume.sample_type() != SampleType::U8 {
        return Err(Error::InvalidVolume(format!(
            "{}: .vol holds u8 samples, not {}",
            path.display(),
            volume.sample_type()
        )));
    }
    let grid = volume.grid();
    let header = VolHeader {
        dims: grid.dims,
        spacing: grid.spacing,
        layout,
    };
    let bricks = match layout {
        VolLayout::Linear => None,
        VolLayout::Bricked { side } => Some(
            BrickGrid::new(grid.dims, side as u32)
                .map_err(|_| Error::format(path, FormatError::BadBrickSize(side)))?,
        ),
    };
    /// Writes the samples brick by brick, 0 past the grid's edge.
    struct Bricks<'w> {
        w: &'w mut dyn Write,
        bricks: BrickGrid,
    }
    impl VolumeVisitor for Bricks<'_> {
        type Output = std::io::Result<()>;
        fn visit<V: Volume>(self, volume: &V) -> std::io::Result<()> {
            let Bricks { w, bricks } = self;
            let d = volume.grid().dims;
            let len = bricks.brick_len();
            let total = bricks.total_len().unwrap_or(0);
            let mut buf = Vec::with_capacity(len as usize);
            for b in 0..total / len {
                buf.clear();
                for i in b * len..(b + 1) * len {
                    match bricks.voxel_at(i, d) {
                        Some(v) => volume.voxel(v).encode(Endian::Little, &mut buf),
                        None => buf.push(0),
                    }
                }
                w.write_all(&buf)?;
            }
            Ok(())
        }
    }
    super::atomic::write_atomically(path, |w| {
        w.write_all(&header.to_bytes())?;
        match bricks {
            None => write_samples(w, volume, AxisOrder::ZFast, Endian::Little),
            Some(bricks) => volume.visit(Bricks { w, bricks }),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header_bytes(dims: [u32; 3], spacing: [f32; 3], layout: u8, extra: u8) -> Vec<u8> {
        let mut b = Vec::new();
        for d in dims {
            b.extend_from_slice(&d.to_le_bytes());
        }
        for s in spacing {
            b.extend_from_slice(&s.to_le_bytes());
        }
        b.push(layout);
        b.push(extra);
        b
    }

    #[test]
    fn header_round_trip() {
        let h = VolHeader {
            dims: UVec3::new(3, 4, 5),
            spacing: Vec3::new(1.0, 0.5, 2.0),
            layout: VolLayout::Bricked { side: 7 },
        };
        assert_eq!(VolHeader::parse(&h.to_bytes()).unwrap(), h);
    }

    #[test]
    fn every_bad_header_case_is_a_typed_error() {
        use FormatError::*;
        type Check = fn(&FormatError) -> bool;
        let cases: Vec<(Vec<u8>, Check)> = vec![
            (vec![1, 2, 3], |e| {
                matches!(e, TooShortForHeader { found: 3, .. })
            }),
            (header_bytes([0, 1, 1], [1.0; 3], 1, 0), |e| {
                matches!(e, ZeroDimension { axis: 'X' })
            }),
            (header_bytes([1, 1, 0], [1.0; 3], 1, 0), |e| {
                matches!(e, ZeroDimension { axis: 'Z' })
            }),
            (header_bytes([1, 1, 1], [1.0, f32::NAN, 1.0], 1, 0), |e| {
                matches!(e, BadSpacing { axis: 'Y', .. })
            }),
            (
                header_bytes([1, 1, 1], [1.0, 1.0, f32::INFINITY], 1, 0),
                |e| matches!(e, BadSpacing { axis: 'Z', .. }),
            ),
            (header_bytes([1, 1, 1], [0.0, 1.0, 1.0], 1, 0), |e| {
                matches!(e, BadSpacing { axis: 'X', .. })
            }),
            (header_bytes([1, 1, 1], [-1.0, 1.0, 1.0], 1, 0), |e| {
                matches!(e, BadSpacing { axis: 'X', .. })
            }),
            (header_bytes([1, 1, 1], [1.0; 3], 3, 0), |e| {
                matches!(e, UnknownLayout(3))
            }),
            (header_bytes([1, 1, 1], [1.0; 3], 0, 0), |e| {
                matches!(e, UnknownLayout(0))
            }),
            (header_bytes([1, 1, 1], [1.0; 3], 2, 1), |e| {
                matches!(e, BadBrickSize(1))
            }),
            (header_bytes([1, 1, 1], [1.0; 3], 2, 0), |e| {
                matches!(e, BadBrickSize(0))
            }),
            (header_bytes([u32::MAX; 3], [1.0; 3], 1, 0), |e| {
                matches!(e, SizeOverflow { .. })
            }),
            (header_bytes([u32::MAX; 3], [1.0; 3], 2, 2), |e| {
                matches!(e, SizeOverflow { .. })
            }),
        ];
        for (bytes, check) in cases {
            let err = VolHeader::parse(&bytes).unwrap_err();
            assert!(check(&err), "unexpected error {err:?} for {bytes:?}");
        }
    }
}
