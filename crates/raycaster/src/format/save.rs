//! Writing a volume of any sample type to a file, the format chosen by the
//! file name: `.vol` (8-bit), `.nrrd`, `.nii`, `.nii.gz`, or raw (`.raw`,
//! `.bin`: x fastest, little-endian). Each file appears under its name only
//! when complete.

use std::path::Path;

use glam::UVec3;

use super::nrrd::Encoding;
use super::samples::{Endian, write_samples};
use super::vol::VolLayout;
use crate::error::{Error, FormatError, Result};
use crate::sample::{Sample, SampleType};
use crate::volume::{AnyVolume, AxisOrder, Volume, VolumeVisitor};

/// The formats [`save`] writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    /// `.vol` in the given layout (8-bit samples).
    Vol(VolLayout),
    /// NRRD with raw or gzip encoding.
    Nrrd(Encoding),
    /// NIfTI-1, gzip-compressed or not.
    Nifti {
        /// `.nii.gz`.
        gzip: bool,
    },
    /// Headerless, x fastest, little-endian.
    Raw,
}

/// How to write.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SaveOptions {
    /// Layout of a `.vol` output (default linear).
    pub vol_layout: Option<VolLayout>,
    /// gzip-encode an `.nrrd` output.
    pub gzip: bool,
    /// For an 8-bit `.vol` from wider data: the values mapped to 0 and 255
    /// (default: the volume's value range).
    pub window: Option<(f32, f32)>,
}

/// The output format for `path`'s name, or an error naming the supported
/// extensions.
pub fn output_format(path: &Path, options: &SaveOptions) -> Result<OutputFormat> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let ext = name.rsplit_once('.').map_or("", |(_, e)| e);
    Ok(match ext {
        "vol" => OutputFormat::Vol(options.vol_layout.unwrap_or(VolLayout::Linear)),
        "nrrd" => OutputFormat::Nrrd(if options.gzip {
            Encoding::Gzip
        } else {
            Encoding::Raw
        }),
        "nii" => OutputFormat::Nifti { gzip: false },
        "gz" if name.ends_with(".nii.gz") => OutputFormat::Nifti { gzip: true },
        "raw" | "bin" => OutputFormat::Raw,
        _ => {
            return Err(Error::format(
                path,
                FormatError::Unrecognised(
                    "cannot tell the output format from the name; use .vol, .nrrd, .nii, .nii.gz, .raw or .bin".into(),
                ),
            ));
        }
    })
}

/// Writes `volume` to `path` in the format its name says (see
/// [`output_format`]) and returns that format. Samples keep their type,
/// except for `.vol`, which holds 8 bits: wider data is mapped linearly from
/// `options.window` (default: the value range) to 0..=255.
pub fn save(path: &Path, volume: &AnyVolume, options: &SaveOptions) -> Result<OutputFormat> {
    let format = output_format(path, options)?;
    let grid = *volume.grid();
    match format {
        OutputFormat::Vol(layout) => {
            let window = options.window.unwrap_or_else(|| {
                if volume.sample_type() == SampleType::U8 {
                    (0.0, 255.0)
                } else {
                    value_range(volume)
                }
            });
            let eight_bit = to_u8(volume, window)?;
            super::vol::write(path, &eight_bit, layout)?;
        }
        OutputFormat::Nrrd(encoding) => {
            let t = volume.sample_type();
            super::nrrd::write(path, grid.dims, grid.spacing, t, encoding, |w| {
                write_samples(w, volume, AxisOrder::XFast, Endian::Little)
            })?;
        }
        OutputFormat::Nifti { .. } => {
            let t = volume.sample_type();
            super::nifti::write(path, grid.dims, grid.spacing, t, None, |w| {
                write_samples(w, volume, AxisOrder::XFast, Endian::Little)
            })?;
        }
        OutputFormat::Raw => {
            super::raw::write(path, volume, AxisOrder::XFast, Endian::Little)?;
        }
    }
    Ok(format)
}

/// Smallest and largest voxel value.
fn value_range(volume: &AnyVolume) -> (f32, f32) {
    struct Range;
    impl VolumeVisitor for Range {
        type Output = (f32, f32);
        fn visit<V: Volume>(self, v: &V) -> (f32, f32) {
            let (lo, hi) = v.value_range(UVec3::ZERO, v.grid().dims - UVec3::ONE);
            (lo.to_f32(), hi.to_f32())
        }
    }
    volume.visit(Range)
}

/// The volume as 8-bit samples: `window.0` → 0, `window.1` → 255, rounded
/// and clamped (u8 data with the window 0..255 stays as it is).
fn to_u8(volume: &AnyVolume, window: (f32, f32)) -> Result<AnyVolume> {
    let (lo, hi) = window;
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(Error::option("window", format!("{lo}..{hi} is not finite")));
    }
    let scale = if hi > lo { 255.0 / (hi - lo) } else { 0.0 };
    struct Window(f32, f32);
    impl VolumeVisitor for Window {
        type Output = AnyVolume;
        fn visit<V: Volume>(self, v: &V) -> AnyVolume {
            let Window(lo, scale) = self;
            AnyVolume::from_fn(*v.grid(), |p| {
                ((v.voxel(p).to_f32() - lo) * scale)
                    .round()
                    .clamp(0.0, 255.0) as u8
            })
        }
    }
    Ok(volume.visit(Window(lo, scale)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Grid;
    use glam::Vec3;

    #[test]
    fn vol_output_maps_the_window_to_eight_bits() {
        let grid = Grid::new(UVec3::new(3, 1, 1), Vec3::ONE);
        let values = [-1000i16, 0, 1000];
        let v = AnyVolume::from_fn(grid, |p| values[p.x as usize]);
        let eight = to_u8(&v, (-1000.0, 1000.0)).unwrap();
        assert_eq!(eight.samples::<u8>(), Some(&[0, 128, 255][..]));
        let clamped = to_u8(&v, (-500.0, 500.0)).unwrap();
        assert_eq!(clamped.samples::<u8>(), Some(&[0, 128, 255][..]));
        assert_eq!(value_range(&v), (-1000.0, 1000.0));
        let u8v = AnyVolume::from_fn(grid, |p| [3u8, 7, 250][p.x as usize]);
        assert_eq!(
            to_u8(&u8v, (0.0, 255.0)).unwrap().samples::<u8>(),
            Some(&[3, 7, 250][..])
        );
    }

    #[test]
    fn output_format_follows_the_name() {
        let o = SaveOptions::default();
        let f = |n: &str| output_format(Path::new(n), &o);
        assert_eq!(f("a.VOL").unwrap(), OutputFormat::Vol(VolLayout::Linear));
        assert_eq!(f("a.nii.gz").unwrap(), OutputFormat::Nifti { gzip: true });
        assert_eq!(f("a.nii").unwrap(), OutputFormat::Nifti { gzip: false });
        assert_eq!(f("a.nrrd").unwrap(), OutputFormat::Nrrd(Encoding::Raw));
        assert_eq!(f("a.bin").unwrap(), OutputFormat::Raw);
        assert!(f("a.tar.gz").unwrap_err().to_string().contains("a.tar.gz"));
    }
}
