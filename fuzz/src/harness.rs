//! What each fuzz target does with one input: write it as the file(s) of
//! its format into a scratch directory, open it through the library's
//! public path, and render a tiny frame of whatever opened, so a file that
//! parses but lies about itself is caught too.
//!
//! Errors are the expected outcome for most inputs; only a panic, an abort,
//! a hang or runaway memory is a finding. This file is compiled twice: by
//! the fuzz targets (`fuzz/fuzz_targets/*.rs`, libFuzzer) and by the normal
//! test suite (`tests/fuzz_regressions.rs`), which replays every input kept
//! in `fuzz/regressions/<target>/` through the same code.

use std::path::{Path, PathBuf};

use glam::UVec3;
use raycaster::format::{self as fmt, Endian, OpenOptions, RawOptions};
use raycaster::metaballs::{Balls, MetaballOptions, MetaballRenderer};
use raycaster::prelude::*;
use raycaster::sequence::Sequence;

/// The fuzz targets: one per input kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// `.vol`: this project's linear and bricked layouts, and UC Davis.
    Vol,
    /// NRRD with attached data.
    Nrrd,
    /// NRRD header (`.nhdr`) and a detached data file `d.raw`: the input's
    /// first blank line ends the header.
    Nhdr,
    /// NIfTI-1 `.nii`.
    Nifti,
    /// Gzip-compressed NIfTI-1 `.nii.gz`.
    NiftiGz,
    /// One DICOM file.
    Dicom,
    /// A directory of DICOM files: the input is a list of
    /// (little-endian u16 length, bytes) parts, one file each (at most 4).
    DicomSeries,
    /// Raw samples: 8 bytes of description (dims − 1 per axis, sample type,
    /// byte order, axis order, header offset), then the file.
    Raw,
    /// A transfer function as JSON, rendered over a small fixed volume.
    TfJson,
    /// A `.vseq` sequence: its first frames are decoded and frame 0 rendered.
    Vseq,
    /// A metaballs points file (`.csv`), rendered.
    Points,
}

impl Target {
    pub const ALL: [Target; 11] = [
        Target::Vol,
        Target::Nrrd,
        Target::Nhdr,
        Target::Nifti,
        Target::NiftiGz,
        Target::Dicom,
        Target::DicomSeries,
        Target::Raw,
        Target::TfJson,
        Target::Vseq,
        Target::Points,
    ];

    /// The fuzz target's (and its corpus directory's) name.
    pub fn name(self) -> &'static str {
        match self {
            Target::Vol => "vol",
            Target::Nrrd => "nrrd",
            Target::Nhdr => "nhdr",
            Target::Nifti => "nifti",
            Target::NiftiGz => "nifti_gz",
            Target::Dicom => "dicom",
            Target::DicomSeries => "dicom_series",
            Target::Raw => "raw",
            Target::TfJson => "tf_json",
            Target::Vseq => "vseq",
            Target::Points => "points",
        }
    }
}

/// Runs one input through `target`. Returns normally for every input that
/// the library handles: `true` when it opened (and was rendered), `false`
/// when it was refused with an error.
pub fn run(target: Target, data: &[u8]) -> bool {
    let dir = Scratch::new(target);
    match target {
        Target::Vol => open_and_render(&dir.write("in.vol", data), None),
        Target::Nrrd => open_and_render(&dir.write("in.nrrd", data), None),
        Target::Nhdr => {
            let split = data
                .windows(2)
                .position(|w| w == b"\n\n")
                .map_or(data.len(), |i| i + 2);
            dir.write("d.raw", &data[split..]);
            open_and_render(&dir.write("in.nhdr", &data[..split]), None)
        }
        Target::Nifti => open_and_render(&dir.write("in.nii", data), None),
        Target::NiftiGz => open_and_render(&dir.write("in.nii.gz", data), None),
        Target::Dicom => open_and_render(&dir.write("in.dcm", data), None),
        Target::DicomSeries => {
            let mut rest = data;
            let mut k = 0;
            while rest.len() >= 2 && k < 4 {
                let n = usize::from(u16::from_le_bytes([rest[0], rest[1]])).min(rest.len() - 2);
                dir.write(&format!("s{k}.dcm"), &rest[2..2 + n]);
                rest = &rest[2 + n..];
                k += 1;
            }
            open_and_render(&dir.path, None)
        }
        Target::Raw => {
            if data.len() < 8 {
                return false;
            }
            let (d, body) = data.split_at(8);
            let types = [
                SampleType::U8,
                SampleType::I8,
                SampleType::U16,
                SampleType::I16,
                SampleType::F32,
            ];
            let mut raw = RawOptions::new(
                UVec3::new(
                    u32::from(d[0]) + 1,
                    u32::from(d[1]) + 1,
                    u32::from(d[2]) + 1,
                ),
                types[usize::from(d[3]) % types.len()],
                if d[4] & 1 == 0 {
                    Endian::Little
                } else {
                    Endian::Big
                },
            );
            raw.order = if d[5] & 1 == 0 {
                AxisOrder::XFast
            } else {
                AxisOrder::ZFast
            };
            raw.offset = u64::from(d[6]);
            open_and_render(&dir.write("in.raw", body), Some(raw))
        }
        Target::TfJson => {
            let Ok(text) = std::str::from_utf8(data) else {
                return false;
            };
            let Ok(tf) = TransferFunction::from_json(text) else {
                return false;
            };
            let grid = Grid::new(UVec3::splat(8), glam::Vec3::ONE);
            let volume = AnyVolume::from_fn(grid, |p| (p.x * 32 + p.y * 4 + p.z) as u8);
            render_tiny(Scene::new(volume), &tf);
            true
        }
        Target::Vseq => {
            let path = dir.write("in.vseq", data);
            let Ok(seq) = Sequence::open(&path, &OpenOptions::default()) else {
                return false;
            };
            let mut all = true;
            for k in 0..seq.frames().min(3) {
                match seq.frame(k) {
                    Ok(volume) if k == 0 => render_with_ramp(volume),
                    Ok(_) => {}
                    Err(_) => all = false,
                }
            }
            all
        }
        Target::Points => {
            let path = dir.write("in.csv", data);
            let Ok(balls) = Balls::read_points(&path, None, Some(10_000)) else {
                return false;
            };
            let Some(bounds) = balls.bounds() else {
                return false;
            };
            let camera = Camera::framing(&bounds, 16, 16, 30.0);
            match MetaballRenderer::new(RendererKind::Serial, 1) {
                Ok(mut renderer) => renderer
                    .render(&balls, &camera, None, &MetaballOptions::default())
                    .is_ok(),
                Err(_) => false,
            }
        }
    }
}

/// Opens `path` as the command line does and renders what opened.
fn open_and_render(path: &Path, raw: Option<RawOptions>) -> bool {
    let options = OpenOptions {
        raw,
        ..OpenOptions::default()
    };
    match fmt::open_file(path, &options) {
        Ok(opened) => {
            render_with_ramp(opened.volume);
            true
        }
        Err(_) => false,
    }
}

fn render_with_ramp(volume: AnyVolume) {
    let sample = volume.sample_type();
    let Some(tf) = TransferFunction::preset("ramp", sample) else {
        return;
    };
    render_tiny(Scene::new(volume), &tf);
}

/// A 16×16 frame in DVR (shaded, with skipping) and in MIP, serially.
fn render_tiny(scene: Scene, tf: &TransferFunction) {
    let camera = Camera::framing(&scene.grid().bounds(), 16, 16, 30.0);
    for mode in [RenderMode::Dvr, RenderMode::Mip] {
        let options = RenderOptions {
            mode,
            shading: mode == RenderMode::Dvr,
            ..RenderOptions::default()
        };
        let _ = SerialRenderer::new().render(&scene, &camera, tf, &options);
    }
}

/// A directory of this process and thread, emptied for each input so files
/// of earlier inputs do not join a series.
struct Scratch {
    path: PathBuf,
}

impl Scratch {
    fn new(target: Target) -> Self {
        let path = std::env::temp_dir().join(format!(
            "raycaster-fuzz-{}-{}-{:?}",
            target.name(),
            std::process::id(),
            std::thread::current().id()
        ));
        let _ = std::fs::remove_dir_all(&path);
        std::fs::create_dir_all(&path).expect("scratch directory");
        Scratch { path }
    }

    fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.path.join(name);
        std::fs::write(&p, bytes).expect("scratch file");
        p
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}
