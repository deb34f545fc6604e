//! Volume file formats: detecting them, parsing headers and bringing samples
//! into memory.
//!
//! [`open_file`] detects the format from the file's content and name and
//! returns the volume as an [`AnyVolume`] (its sample type known only at
//! run time) plus a [`VolumeInfo`] describing what the file stores. Each
//! format has its own module with a [`Reader`]; detection asks every reader
//! in [`READERS`] how strongly it claims the file (see [`reader`]). All
//! formats but `.vol` describe their samples with a [`SampleLayout`] and
//! leave the decoding to [`samples`], so byte order, axis order, memory
//! mapping and rescaling are handled once.
//!
//! | module | files |
//! |---|---|
//! | [`vol`] | this project's `.vol`: a 26-byte header, 8-bit samples, linear or bricked |
//! | [`davis`] | the UC Davis `.vol` (28-byte big-endian header) |
//! | [`nrrd`] | `.nrrd`, `.nhdr` + detached data; raw or gzip |
//! | [`nifti`] | NIfTI-1 `.nii`, `.nii.gz`, `.hdr` + `.img` |
//! | [`dicom`] | a directory (or one file) of a DICOM series |
//! | [`raw`] | headerless samples described by the caller |
//! | [`vseq`] | this project's `.vseq` sequence container (frames compressed one by one) |
//!
//! [`save::save`] writes any volume as `.vol`, NRRD, NIfTI-1 or raw, the
//! format chosen by the file name; every writer goes through
//! [`atomic::write_atomically`].
//!
//! DICOM series and gzip streams need the `dicom` and `gzip` cargo features
//! (on by default). Without them such files are still detected, and opening
//! one is an error that names the file and the missing feature.
//!
//! ```no_run
//! use raycaster::format::{open_file, OpenOptions};
//! let opened = open_file("head.nii.gz".as_ref(), &OpenOptions::default())?;
//! println!("{} {:?} {}", opened.info.format, opened.info.dims, opened.info.stored_type);
//! let scene = raycaster::scene::Scene::new(opened.volume);
//! # Ok::<(), raycaster::Error>(())
//! ```

pub mod atomic;
pub mod davis;
pub mod dicom;
mod gzip;
pub mod nifti;
pub mod nrrd;
pub mod raw;
pub mod reader;
pub mod samples;
pub mod save;
pub mod vol;
pub mod vseq;

use std::path::Path;

use glam::{UVec3, Vec3};

pub use raw::RawOptions;
pub use reader::{Claim, Probe, READERS, Reader, detect, detect_claim, reader_for};
pub use samples::{Endian, Rescale, SampleLayout};

use crate::error::{Error, FormatError, Result};
use crate::sample::SampleType;
use crate::storage::LoadMode;
use crate::volume::AnyVolume;

/// The formats this build can read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FileFormat {
    /// This project's `.vol` format: a 26-byte header, 8-bit samples.
    Vol,
    /// The UC Davis `.vol` format (28-byte big-endian header).
    DavisVol,
    /// NRRD (`.nrrd`, or `.nhdr` with detached data).
    Nrrd,
    /// NIfTI-1 (`.nii`, `.nii.gz`).
    Nifti,
    /// A DICOM series.
    Dicom,
    /// Headerless samples described by [`RawOptions`] (never detected).
    Raw,
    /// This project's packed sequence of volumes (`.vseq`).
    Vseq,
}

impl FileFormat {
    /// A short human-readable name.
    pub fn name(self) -> &'static str {
        match self {
            FileFormat::Vol => ".vol (26-byte header)",
            FileFormat::DavisVol => "UC Davis .vol",
            FileFormat::Nrrd => "NRRD",
            FileFormat::Nifti => "NIfTI-1",
            FileFormat::Dicom => "DICOM series",
            FileFormat::Raw => "raw",
            FileFormat::Vseq => ".vseq sequence",
        }
    }
}

impl std::fmt::Display for FileFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// How to open a file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OpenOptions {
    /// Map or read into RAM, where the data can be used as stored.
    pub mode: LoadMode,
    /// The description of a headerless file; when given, the file is read as
    /// raw whatever its extension.
    pub raw: Option<RawOptions>,
    /// Told how far a decode that takes time has come (gzip streams, DICOM
    /// slices); mapping a file needs no progress.
    pub progress: Option<Progress>,
    /// Which 3-D volume of a file that holds several (a 4-D NIfTI or NRRD,
    /// a packed `.vseq` sequence) to open, from 0; [`VolumeInfo::volumes`]
    /// says how many there are. Any other index than 0 of a 3-D file is an
    /// error.
    pub volume: u64,
    /// The most bytes of samples a volume may take when it is decoded or
    /// read into RAM (gzip, converted or byte-swapped samples, DICOM,
    /// [`LoadMode::Ram`]); a larger one is an error before anything is
    /// allocated. Mapped files are not counted: the page cache holds them.
    /// `None`: no limit beyond what the allocator grants.
    pub max_memory: Option<u64>,
}

/// `index` when the file holds more volumes than that, else the error that
/// names `path` and the count.
pub(crate) fn check_volume_index(path: &Path, index: u64, volumes: u64) -> Result<u64> {
    if index < volumes {
        Ok(index)
    } else {
        Err(Error::format(
            path,
            FormatError::Invalid(format!(
                "volume {index} asked for, but the file holds {volumes} (numbered from 0)"
            )),
        ))
    }
}

/// A callback that receives the fraction (0 to 1) of a long decode done,
/// from the thread that opens the file (or, for DICOM series, from the
/// reading threads).
#[derive(Clone)]
pub struct Progress(std::sync::Arc<dyn Fn(f32) + Send + Sync>);

impl Progress {
    /// Wraps `report`.
    pub fn new(report: impl Fn(f32) + Send + Sync + 'static) -> Self {
        Progress(std::sync::Arc::new(report))
    }

    /// Reports `fraction` done.
    pub fn report(&self, fraction: f32) {
        (self.0)(fraction.clamp(0.0, 1.0))
    }
}

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Progress(..)")
    }
}

impl PartialEq for Progress {
    fn eq(&self, other: &Self) -> bool {
        std::sync::Arc::ptr_eq(&self.0, &other.0)
    }
}

/// A reader that reports the fraction of `total` bytes read through it
/// (in steps of about 1%).
pub(crate) struct ProgressReader<R> {
    inner: R,
    read: u64,
    total: u64,
    next_report: u64,
    progress: Option<Progress>,
}

impl<R: std::io::Read> ProgressReader<R> {
    pub(crate) fn new(inner: R, total: u64, progress: Option<&Progress>) -> Self {
        ProgressReader {
            inner,
            read: 0,
            total: total.max(1),
            next_report: 0,
            progress: progress.cloned(),
        }
    }
}

impl<R: std::io::Read> std::io::Read for ProgressReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.read += n as u64;
        if let Some(p) = &self.progress
            && self.read >= self.next_report
        {
            p.report(self.read as f32 / self.total as f32);
            self.next_report = self.read + self.total / 100;
        }
        Ok(n)
    }
}

/// What a file stores, as its header says (before any conversion).
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeInfo {
    /// The format detected.
    pub format: FileFormat,
    /// Samples per axis.
    pub dims: UVec3,
    /// Spacing per axis (world units, usually mm).
    pub spacing: Vec3,
    /// The sample type in the file (the volume may hold another one after a
    /// rescale: see [`VolumeInfo::rescale`]).
    pub stored_type: SampleType,
    /// Byte order of multi-byte samples (`None` for 1-byte types).
    pub byte_order: Option<Endian>,
    /// How the samples are encoded: `raw`, `gzip`, `bricked (B = 16)`, ...
    pub encoding: String,
    /// `value = stored·slope + intercept`, when not the identity.
    pub rescale: Option<Rescale>,
    /// The orientation as stored (NRRD space directions, NIfTI q/sform, DICOM
    /// orientation), reported but not applied: the volume's axes are the
    /// file's.
    pub orientation: Option<String>,
    /// Anything else the user should know (e.g. "4-D file: volume 1 of 3").
    pub notes: Vec<String>,
    /// The 3-D volumes the file holds (frames of a 4-D file or a `.vseq`
    /// sequence; 1 for most files); [`OpenOptions::volume`] picks one.
    pub volumes: u64,
    /// The imaging modality when the file says (DICOM `Modality`: `CT`,
    /// `MR`, ...), to pick a fitting transfer function.
    pub modality: Option<String>,
    /// Bytes on disk (all files of a series or detached header).
    pub file_bytes: u64,
}

impl VolumeInfo {
    /// A description with the fields every reader knows; the optional ones
    /// empty.
    pub fn new(format: FileFormat, layout: &SampleLayout, encoding: &str, file_bytes: u64) -> Self {
        VolumeInfo {
            format,
            dims: layout.dims,
            spacing: layout.spacing,
            stored_type: layout.sample,
            byte_order: (layout.sample.size() > 1).then_some(layout.endian),
            encoding: encoding.to_string(),
            rescale: None,
            orientation: None,
            notes: Vec::new(),
            volumes: 1,
            modality: None,
            file_bytes,
        }
    }
}

/// An opened volume and the description of its file.
#[derive(Debug)]
pub struct Opened {
    /// The samples, ready to render.
    pub volume: AnyVolume,
    /// What the file stores.
    pub info: VolumeInfo,
}

/// The file `options` open for `path`: a folder holding one volume file is
/// that file ([`crate::sequence::resolve_dir`]), except for raw options,
/// which describe the path as given.
pub(crate) fn volume_path<'a>(path: &'a Path, options: &OpenOptions) -> std::borrow::Cow<'a, Path> {
    match options.raw {
        None => crate::sequence::resolve_dir(path),
        Some(_) => std::borrow::Cow::Borrowed(path),
    }
}

/// Opens a volume file of any supported format, as described in the module
/// documentation. A folder holding one volume file (beside a licence or a
/// readme) opens that file ([`crate::sequence::resolve_dir`]).
pub fn open_file(path: &Path, options: &OpenOptions) -> Result<Opened> {
    let path = &*volume_path(path, options);
    let opened = reader_for(path, options)
        .and_then(|reader| reader.open(path, options))
        .and_then(|opened| {
            // Readers of 3-D-only formats do not look at the index.
            check_volume_index(path, options.volume, opened.info.volumes)?;
            Ok(opened)
        });
    if let Some(p) = &options.progress {
        // Done (or failed): the reader may have stopped short of its input's
        // end (the first volume of a 4-D file), so say it here.
        p.report(1.0);
    }
    opened
}

/// Opens a volume file of any supported format (see [`open_file`]) and
/// returns just the volume.
pub fn open(path: &Path, mode: LoadMode) -> Result<AnyVolume> {
    open_file(
        path,
        &OpenOptions {
            mode,
            ..OpenOptions::default()
        },
    )
    .map(|o| o.volume)
}

/// Up to `n` first bytes of `path`.
fn read_head(path: &Path, n: usize) -> Result<Vec<u8>> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut head = Vec::with_capacity(n);
    file.take(n as u64)
        .read_to_end(&mut head)
        .map_err(|e| Error::io(path, e))?;
    Ok(head)
}

/// Size of `path` in bytes.
fn file_len(path: &Path) -> Result<u64> {
    Ok(std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len())
}
