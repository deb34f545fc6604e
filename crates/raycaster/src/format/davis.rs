//! The UC Davis `.vol` format (the volume data sets of O. Kreylos's ECS 277
//! course, classic test volumes for ray casting): a 28-byte big-endian
//! header — dimensions X, Y, Z (`u32`), a border width (`u32`), cell size
//! sx, sy, sz (`f32`) — followed by X·Y·Z `u8` samples, z fastest. It shares
//! the extension with this project's `.vol` (see [`super::vol`]) and is told
//! apart by which header's implied length matches the file.

use std::path::Path;

use glam::{UVec3, Vec3};

use super::samples::{self, Endian, SampleLayout};
use super::{FileFormat, Opened, VolumeInfo};
use crate::error::{Error, FormatError, Result};
use crate::sample::SampleType;
use crate::volume::AxisOrder;

/// Header length in bytes.
pub const HEADER_LEN: usize = 28;

/// The parsed header.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DavisHeader {
    /// Samples per axis, border included.
    pub dims: UVec3,
    /// Border width in voxels as stored (reported; the samples include it).
    pub border: u32,
    /// Cell size per axis.
    pub spacing: Vec3,
}

impl DavisHeader {
    /// Parses the first 28 bytes (no validation).
    pub fn parse(b: &[u8]) -> Option<Self> {
        let b: &[u8; HEADER_LEN] = b.get(..HEADER_LEN)?.try_into().ok()?;
        let u = |i: usize| u32::from_be_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        let f = |i: usize| f32::from_bits(u(i));
        Some(DavisHeader {
            dims: UVec3::new(u(0), u(4), u(8)),
            border: u(12),
            spacing: Vec3::new(f(16), f(20), f(24)),
        })
    }

    /// Bytes of the whole file this header implies.
    pub fn file_len(&self) -> Option<u64> {
        let d = self.dims.as_u64vec3();
        d.x.checked_mul(d.y)?
            .checked_mul(d.z)?
            .checked_add(HEADER_LEN as u64)
    }

    /// Writes the header (for tests and converters).
    pub fn to_bytes(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        let words = [
            self.dims.x,
            self.dims.y,
            self.dims.z,
            self.border,
            self.spacing.x.to_bits(),
            self.spacing.y.to_bits(),
            self.spacing.z.to_bits(),
        ];
        for (i, w) in words.iter().enumerate() {
            b[4 * i..4 * i + 4].copy_from_slice(&w.to_be_bytes());
        }
        b
    }
}

/// True when `head` parses as a UC Davis header whose dimensions are non-zero
/// and whose implied length is `file_len`.
fn header_matches(head: &[u8], file_len: u64) -> bool {
    DavisHeader::parse(head)
        .is_some_and(|h| h.dims.min_element() > 0 && h.file_len() == Some(file_len))
}

/// True when `head` parses as a UC Davis header with sensible fields
/// (dimensions 1..=65536, border below 256, finite positive cell sizes),
/// whatever the file's length.
fn header_plausible(head: &[u8]) -> bool {
    DavisHeader::parse(head).is_some_and(|h| {
        h.dims.min_element() > 0
            && h.dims.max_element() <= 1 << 16
            && h.border < 256
            && h.spacing.is_finite()
            && h.spacing.min_element() > 0.0
    })
}

/// The reader of UC Davis `.vol` files: it claims the file firmly when its
/// header's implied length matches, and by name when the bytes are no valid
/// `.vol` header but a plausible UC Davis one (a truncated file, whose
/// length this reader then reports).
#[derive(Debug, Clone, Copy)]
pub struct DavisReader;

impl super::Reader for DavisReader {
    fn sniff(&self, probe: &super::Probe) -> Option<super::Claim> {
        if probe.is_dir || !matches!(probe.extension(), "vol" | "") {
            return None;
        }
        if header_matches(probe.head, probe.len) {
            Some(super::Claim::Content)
        } else if super::vol::VolHeader::parse(probe.head).is_err() && header_plausible(probe.head)
        {
            Some(super::Claim::Name)
        } else {
            None
        }
    }

    fn open(&self, path: &Path, options: &super::OpenOptions) -> Result<Opened> {
        let head = super::read_head(path, HEADER_LEN)?;
        let len = super::file_len(path)?;
        let header = DavisHeader::parse(&head).ok_or_else(|| {
            Error::format(
                path,
                FormatError::TooShortForHeader {
                    expected: HEADER_LEN as u64,
                    found: len,
                },
            )
        })?;
        let layout = SampleLayout {
            dims: header.dims,
            spacing: header.spacing,
            sample: SampleType::U8,
            endian: Endian::Big,
            order: AxisOrder::ZFast,
        };
        let volume = samples::from_file(
            path,
            HEADER_LEN as u64,
            &layout,
            None,
            options.mode,
            true,
            options.max_memory,
        )?;
        let mut info = VolumeInfo::new(FileFormat::DavisVol, &layout, "raw", len);
        if header.border > 0 {
            info.notes.push(format!(
                "border of {} voxels (kept as samples)",
                header.border
            ));
        }
        Ok(Opened { volume, info })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(dims: [u32; 3]) -> DavisHeader {
        DavisHeader {
            dims: UVec3::from_array(dims),
            border: 0,
            spacing: Vec3::new(1.0, 1.0, 2.0),
        }
    }

    #[test]
    fn a_truncated_davis_file_is_reported_as_one() {
        let dir = std::env::temp_dir().join(format!("rc-davis-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cut.vol");
        let mut bytes = header([4, 5, 6]).to_bytes().to_vec();
        bytes.extend(vec![7u8; 100]); // 120 samples needed
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(super::super::detect(&path).unwrap(), FileFormat::DavisVol);
        let e = super::super::open_file(&path, &Default::default()).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("expected 148 bytes"), "{msg}");
        assert!(msg.contains("cut.vol"), "{msg}");
        bytes.extend(vec![7u8; 20]);
        std::fs::write(&path, &bytes).unwrap();
        let ok = super::super::open_file(&path, &Default::default()).unwrap();
        assert_eq!(ok.info.dims, UVec3::new(4, 5, 6));
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn plausibility_rejects_garbage() {
        assert!(header_plausible(&header([4, 5, 6]).to_bytes()));
        assert!(!header_plausible(&header([0, 5, 6]).to_bytes()));
        assert!(!header_plausible(&header([4, 5, 1 << 20]).to_bytes()));
        assert!(!header_plausible(&[0u8; 10]));
    }
}
