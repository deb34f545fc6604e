//! Sequences of volumes: the frames of a simulation or of a 4-D scan, all
//! with the same dimensions, sample type and spacing.
//!
//! A [`Sequence`] is opened from
//! - a 4-D NIfTI or NRRD file (every 3-D volume of it, in file order),
//! - a directory of volume files of any supported format (the frames in
//!   name order; a directory of DICOM files stays one DICOM series; a
//!   directory holding one volume file, beside a licence or a readme, is
//!   that file: see [`resolve_dir`]),
//! - a packed `.vseq` file ([`format::vseq`](crate::format::vseq)), whose
//!   frames are compressed one by one and decoded on every core,
//! - or any other volume file, as a sequence of one frame.
//!
//! [`Sequence::frame`] decodes one frame on the calling thread;
//! [`Playback`] keeps the next frames decoded ahead of a player on a
//! thread of its own.
//!
//! ```no_run
//! use raycaster::prelude::*;
//! use raycaster::sequence::Sequence;
//! let seq = Sequence::open("plume.vseq".as_ref(), &Default::default())?;
//! for k in 0..seq.frames() {
//!     let scene = Scene::new(seq.frame(k)?);
//!     // render the scene ...
//! }
//! # Ok::<(), raycaster::Error>(())
//! ```

mod playback;

use std::path::{Path, PathBuf};

use parking_lot::Mutex;

pub use playback::{Playback, PlaybackFrame};

use crate::error::{Error, FormatError, Result};
use crate::format::vseq::VseqFile;
use crate::format::{Claim, FileFormat, OpenOptions, Opened, VolumeInfo};
use crate::sample::SampleType;
use crate::volume::AnyVolume;

/// An ordered list of volumes of one geometry and sample type.
#[derive(Debug)]
pub struct Sequence {
    path: PathBuf,
    source: Source,
    info: VolumeInfo,
    /// The sample type of the first frame's volume (after any rescale).
    sample_type: SampleType,
    /// Frame 0 as read by the open, kept until it is first asked for.
    first: Mutex<Option<AnyVolume>>,
}

#[derive(Debug)]
enum Source {
    /// The volumes of one file, picked by [`OpenOptions::volume`].
    File { path: PathBuf, options: OpenOptions },
    /// A packed sequence.
    Packed(VseqFile),
    /// One file per frame, in name order.
    Directory {
        files: Vec<PathBuf>,
        options: OpenOptions,
    },
}

impl Sequence {
    /// Opens the sequence at `path` (see the module documentation for what
    /// it may be). Only the first frame is read; the others are checked
    /// against it when they are read (or all at once by
    /// [`Sequence::check_all`]).
    pub fn open(path: &Path, options: &OpenOptions) -> Result<Sequence> {
        let frame0 = OpenOptions {
            volume: 0,
            ..options.clone()
        };
        if options.raw.is_none() && path.is_dir() {
            let files = list_frame_files(path)?;
            if let [only] = files.as_slice() {
                return Sequence::open(only, options);
            }
            if !files.is_empty() {
                let Opened { volume, mut info } = crate::format::open_file(&files[0], &frame0)?;
                if info.volumes > 1 {
                    return Err(Error::format(
                        &files[0],
                        FormatError::Unsupported(format!(
                            "a frame of the sequence in {} holds {} volumes (frames must be 3-D)",
                            path.display(),
                            info.volumes
                        )),
                    ));
                }
                info.volumes = files.len() as u64;
                info.notes.push(format!(
                    "sequence of {} files in {}, first {}",
                    files.len(),
                    path.display(),
                    files[0].display()
                ));
                return Ok(Sequence {
                    path: path.to_path_buf(),
                    sample_type: volume.sample_type(),
                    first: Mutex::new(Some(volume)),
                    source: Source::Directory {
                        files,
                        options: frame0,
                    },
                    info,
                });
            }
        }
        if options.raw.is_none() && crate::format::detect(path).ok() == Some(FileFormat::Vseq) {
            let file = VseqFile::open(path)?;
            let info = file.info();
            return Ok(Sequence {
                path: path.to_path_buf(),
                sample_type: file.header().sample,
                first: Mutex::new(None),
                source: Source::Packed(file),
                info,
            });
        }
        let Opened { volume, info } = crate::format::open_file(path, &frame0)?;
        Ok(Sequence {
            path: path.to_path_buf(),
            sample_type: volume.sample_type(),
            first: Mutex::new(Some(volume)),
            source: Source::File {
                path: path.to_path_buf(),
                options: frame0,
            },
            info,
        })
    }

    /// The number of frames.
    pub fn frames(&self) -> u32 {
        u32::try_from(self.info.volumes).unwrap_or(u32::MAX)
    }

    /// What the first frame's file stores; [`VolumeInfo::volumes`] is the
    /// frame count.
    pub fn info(&self) -> &VolumeInfo {
        &self.info
    }

    /// The packed file, when the sequence is one.
    pub fn packed(&self) -> Option<&VseqFile> {
        match &self.source {
            Source::Packed(f) => Some(f),
            _ => None,
        }
    }

    /// Where frame `k` comes from, for messages: its file, and the frame
    /// within the file where the file holds several.
    pub fn frame_name(&self, k: u32) -> String {
        match &self.source {
            Source::Directory { files, .. } => files
                .get(k as usize)
                .map_or_else(|| format!("frame {k}"), |f| f.display().to_string()),
            _ if self.frames() == 1 => self.path.display().to_string(),
            _ => format!("{} frame {k}", self.path.display()),
        }
    }

    /// The path the sequence was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The sample type of every frame's volume.
    pub fn sample_type(&self) -> SampleType {
        self.sample_type
    }

    /// Reads (or decodes) frame `k`. A frame whose dimensions, spacing or
    /// sample type differ from the first frame's is an error naming its
    /// file.
    pub fn frame(&self, k: u32) -> Result<AnyVolume> {
        let frames = self.frames();
        if k >= frames {
            return Err(Error::option(
                "frame",
                format!("frame {k} asked for, but the sequence has {frames} (numbered from 0)"),
            ));
        }
        if k == 0
            && let Some(v) = self.first.lock().take()
        {
            return Ok(v);
        }
        let (path, options) = match &self.source {
            Source::Packed(file) => return file.frame(k),
            Source::File { path, options } => (
                path,
                OpenOptions {
                    volume: u64::from(k),
                    ..options.clone()
                },
            ),
            Source::Directory { files, options } => (&files[k as usize], options.clone()),
        };
        let opened = crate::format::open_file(path, &options)?;
        self.check(path, k, opened)
    }

    /// Reads every frame once, checking it against the first (for `info`,
    /// and before a long job); `progress` is told the fraction done.
    pub fn check_all(&self, progress: Option<&crate::format::Progress>) -> Result<()> {
        let n = self.frames();
        for k in 1..n {
            self.frame(k)?;
            if let Some(p) = progress {
                p.report((k + 1) as f32 / n as f32);
            }
        }
        Ok(())
    }

    /// `opened` when it has the first frame's geometry and type, else an
    /// error naming `path`.
    fn check(&self, path: &Path, k: u32, opened: Opened) -> Result<AnyVolume> {
        let want = &self.info;
        let volume = opened.volume;
        let (dims, spacing, ty) = (
            volume.grid().dims,
            volume.grid().spacing,
            volume.sample_type(),
        );
        if dims != want.dims || spacing != want.spacing || ty != self.sample_type {
            return Err(Error::format(
                path,
                FormatError::Invalid(format!(
                    "frame {k} is {}x{}x{} {ty} with spacing {spacing}, unlike the first frame ({}x{}x{} {} with spacing {})",
                    dims.x,
                    dims.y,
                    dims.z,
                    want.dims.x,
                    want.dims.y,
                    want.dims.z,
                    self.sample_type,
                    want.spacing
                )),
            ));
        }
        Ok(volume)
    }
}

/// The frame files of a directory: its files that a volume reader other
/// than DICOM claims by name or content, in name order (a file with no
/// extension and no known header, such as a `LICENSE`, is not a frame).
/// Empty when `dir` is not a directory, holds DICOM files (it is then one
/// series), holds one volume file only (see [`resolve_dir`]) or none, or
/// cannot be listed.
pub fn frame_files(dir: &Path) -> Vec<PathBuf> {
    if !dir.is_dir() {
        return Vec::new();
    }
    match list_frame_files(dir) {
        Ok(files) if files.len() > 1 => files,
        _ => Vec::new(),
    }
}

/// The file to open for `path`: a directory that holds exactly one volume
/// file (a scan shipped with its licence or readme) is that file; any
/// other path is itself. So `vol_app FOLDER` opens the scan in it, with
/// the macrocell cache of a single file and, for a 4-D file, all its
/// frames.
pub fn resolve_dir(path: &Path) -> std::borrow::Cow<'_, Path> {
    if path.is_dir()
        && let Ok(files) = list_frame_files(path)
        && let [only] = files.as_slice()
    {
        return std::borrow::Cow::Owned(only.clone());
    }
    std::borrow::Cow::Borrowed(path)
}

fn list_frame_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let path = entry.path();
        let hidden = entry.file_name().to_string_lossy().starts_with('.');
        if hidden || !path.is_file() {
            continue;
        }
        match crate::format::detect_claim(&path) {
            Ok((FileFormat::Dicom, _)) => return Ok(Vec::new()),
            Ok((FileFormat::Vseq, _) | (_, Claim::Fallback)) | Err(_) => {}
            Ok(_) => files.push(path),
        }
    }
    files.sort();
    Ok(files)
}

#[cfg(test)]
mod tests;
