//! Writing a time series (`--generator plume --frames N`): a directory of
//! frame files `frame_0000.nrrd`, `frame_0001.nrrd`, … (zero-padded, so name
//! order is frame order, which is how a directory of volumes is read as a
//! sequence), or one `.nrrd`/`.nii`/`.nii.gz` file when there is one frame.
//!
//! Each frame is f32 raw NRRD written by the library's writer, atomically
//! (temporary name, then rename). Frame k+1 is computed on all cores while
//! frame k is written. An error or Ctrl-C removes the frames this run wrote
//! (and the directory, if this run created it), so nothing half-made is
//! left behind; `--force` is needed to write into a non-empty directory, and
//! then `frame_*.nrrd` files beyond the new count are removed so that the
//! directory holds exactly the new sequence.
//!
//! A name ending in `.vseq` writes the frames packed into one file (the
//! library's container, LZ4, lossless; `vol_app pack` repacks it with
//! another codec or half floats), written atomically as a whole.
//!
//! [`Output`] decides what the output path means.

use std::path::{Path, PathBuf};
use std::time::Instant;

use raycaster::format::save::{OutputFormat, SaveOptions, output_format, save};
use raycaster::units::bytes;

use crate::cli::Config;
use crate::error::{Error, Result};
use crate::plume::Plume;
use crate::progress::Progress;
use crate::{Summary, disk, signal};

/// Bytes of an f32 raw NRRD frame's text header (an upper bound), for the
/// free-space check.
const HEADER_BYTES: u64 = 512;

/// Where the frames go.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Output {
    /// One volume file (a single frame), in the format its name says.
    File(PathBuf),
    /// A directory of `frame_NNNN.nrrd` files.
    Directory(PathBuf),
    /// One packed `.vseq` file.
    Packed(PathBuf),
}

/// What `path` means for a sequence of `frames` frames: a directory when it
/// ends in `/`, is an existing directory or has no volume extension; a
/// `.nrrd`, `.nii` or `.nii.gz` file for a single frame; an error otherwise.
pub fn output(path: &Path, frames: u32) -> Result<Output> {
    let text = path.to_string_lossy();
    if text.is_empty() {
        return Err(Error::Usage("--output-file is empty".into()));
    }
    if text.ends_with(std::path::MAIN_SEPARATOR) || text.ends_with('/') || path.is_dir() {
        return Ok(Output::Directory(path.to_path_buf()));
    }
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if ext == "vseq" {
        return Ok(Output::Packed(path.to_path_buf()));
    }
    match output_format(path, &SaveOptions::default()) {
        Ok(OutputFormat::Nrrd(_) | OutputFormat::Nifti { .. }) if frames == 1 => {
            Ok(Output::File(path.to_path_buf()))
        }
        Ok(OutputFormat::Nrrd(_) | OutputFormat::Nifti { .. }) => Err(Error::Usage(format!(
            "{text}: --frames {frames} writes a directory of frame files; \
             name a directory (for example -o {}/)",
            path.with_extension("").display()
        ))),
        Ok(OutputFormat::Vol(_) | OutputFormat::Raw) => Err(Error::Usage(format!(
            "{text}: --generator plume writes f32 frames, which need a float format \
             with a spacing: name a directory (-o DIR/) or, for one frame, a .nrrd, \
             .nii or .nii.gz file (.vol holds 8-bit samples only)"
        ))),
        // No volume extension: a directory to be created.
        Err(_) => Ok(Output::Directory(path.to_path_buf())),
    }
}

/// The file name of frame `k` of `frames`: `frame_` and k zero-padded to
/// at least 4 digits and to as many as the last frame needs.
pub fn frame_name(k: u32, frames: u32) -> String {
    let width = frames.saturating_sub(1).to_string().len().max(4);
    format!("frame_{k:0width$}.nrrd")
}

/// True for names this writer gives frames (`frame_` digits `.nrrd`).
fn is_frame_name(name: &str) -> bool {
    name.strip_prefix("frame_")
        .and_then(|r| r.strip_suffix(".nrrd"))
        .is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
}

/// Checks a directory output and creates it if missing. Returns whether it
/// was created (so that a failed run removes it again).
fn prepare_directory(dir: &Path, force: bool, need: u64) -> Result<bool> {
    let shown = dir.display();
    let created = match std::fs::metadata(dir) {
        Ok(m) if !m.is_dir() => {
            return Err(Error::Failed(format!(
                "{shown} exists and is not a directory (the frames need a directory)"
            )));
        }
        Ok(_) => {
            let mut entries =
                std::fs::read_dir(dir).map_err(|e| Error::Failed(format!("{shown}: {e}")))?;
            if entries.next().is_some() && !force {
                return Err(Error::Failed(format!(
                    "{shown} is not empty (pass --force to write the frames into it)"
                )));
            }
            false
        }
        Err(_) => {
            std::fs::create_dir_all(dir)
                .map_err(|e| Error::Failed(format!("{shown}: cannot create the directory: {e}")))?;
            true
        }
    };
    if let Some(free) = disk::available_bytes(dir)
        && free < need
    {
        if created {
            let _ = std::fs::remove_dir(dir);
        }
        return Err(Error::Failed(format!(
            "not enough free space in {shown}: the frames need {} ({need} bytes), {} available",
            bytes(need),
            bytes(free)
        )));
    }
    Ok(created)
}

/// Runs `vol_gen --generator plume`: frames 0..N with a progress bar over
/// frames, into a directory (or one file, see [`output`]).
pub fn run(config: &Config) -> Result<Summary> {
    let plume = Plume::new(&config.setup).map_err(Error::Usage)?;
    let frames = config.frames;
    let target = output(&config.output, frames)?;
    let frame_bytes = plume
        .voxel_count()
        .checked_mul(4)
        .filter(|&b| usize::try_from(b).is_ok())
        .ok_or_else(|| Error::Usage("--dims: the volume is too large".into()))?;
    let need = (frame_bytes + HEADER_BYTES).saturating_mul(u64::from(frames));
    let start = Instant::now();
    let (paths, created): (Vec<PathBuf>, Option<&Path>) = match &target {
        Output::Packed(file) => {
            crate::check_output(file, config.force, need)?;
            if config.seed_was_random {
                eprintln!(
                    "vol_gen: seed {} (pass --seed {} to repeat this sequence)",
                    config.setup.seed, config.setup.seed
                );
            }
            return write_packed(config, &plume, file, start);
        }
        Output::File(file) => {
            crate::check_output(file, config.force, need)?;
            (vec![file.clone()], None)
        }
        Output::Directory(dir) => {
            let created = prepare_directory(dir, config.force, need)?;
            let paths = (0..frames).map(|k| dir.join(frame_name(k, frames)));
            (paths.collect(), created.then_some(dir.as_path()))
        }
    };
    if config.seed_was_random {
        eprintln!(
            "vol_gen: seed {} (pass --seed {} to repeat this sequence)",
            config.setup.seed, config.setup.seed
        );
    }
    signal::install();
    let progress = Progress::frames(u64::from(frames), !config.quiet);
    let result = write_frames(&plume, &paths, &progress);
    progress.finish();
    let written = match result {
        Ok(n) => n,
        Err((e, written)) => {
            // Leave nothing half-made: this run's frames, its directory.
            for p in &paths[..written] {
                let _ = std::fs::remove_file(p);
            }
            if let Some(dir) = created {
                let _ = std::fs::remove_dir(dir);
            }
            return Err(e);
        }
    };
    if let Output::Directory(dir) = &target {
        remove_stale_frames(dir, &paths);
    }
    let seconds = start.elapsed().as_secs_f64();
    let total: u64 = paths
        .iter()
        .map(|p| std::fs::metadata(p).map_or(frame_bytes, |m| m.len()))
        .sum();
    let shown = match &target {
        Output::File(f) | Output::Directory(f) | Output::Packed(f) => f.clone(),
    };
    if !config.quiet {
        let d = config.header.dims;
        eprintln!(
            "vol_gen: wrote {} ({written} frame{} of {}x{}x{} plume, f32, {}) in {seconds:.2} s",
            shown.display(),
            if written == 1 { "" } else { "s" },
            d.x,
            d.y,
            d.z,
            bytes(total)
        );
    }
    Ok(Summary {
        path: shown,
        bytes: total,
        seconds,
    })
}

/// Writes every frame into one `.vseq` file (LZ4, lossless), computing each
/// frame as the packer asks for it.
fn write_packed(config: &Config, plume: &Plume, file: &Path, start: Instant) -> Result<Summary> {
    use raycaster::format::vseq::{PackOptions, pack};
    signal::install();
    let frames = config.frames;
    let progress = Progress::frames(u64::from(frames), !config.quiet);
    let report = pack(
        file,
        frames,
        |k| {
            let samples = plume
                .samples(k, &signal::interrupted)
                .map_err(raycaster::Error::InvalidVolume)?;
            let volume = plume
                .volume(samples)
                .map_err(raycaster::Error::InvalidVolume)?;
            progress.advance(1);
            Ok(volume)
        },
        &PackOptions::default(),
        None,
    );
    progress.finish();
    if signal::interrupted() {
        return Err(Error::Interrupted);
    }
    let report = report?;
    let seconds = start.elapsed().as_secs_f64();
    if !config.quiet {
        let d = config.header.dims;
        eprintln!(
            "vol_gen: wrote {} ({frames} frames of {}x{}x{} plume, f32, LZ4: {} = {:.1} % of the samples) in {seconds:.2} s",
            file.display(),
            d.x,
            d.y,
            d.z,
            bytes(report.file_bytes),
            report.percent()
        );
    }
    Ok(Summary {
        path: file.to_path_buf(),
        bytes: report.file_bytes,
        seconds,
    })
}

/// Computes and saves frame k to `paths[k]` for every k, frame k+1 computed
/// while frame k is written. Returns how many were written, or the error and
/// how many had been written before it.
fn write_frames(
    plume: &Plume,
    paths: &[PathBuf],
    progress: &Progress,
) -> std::result::Result<usize, (Error, usize)> {
    let compute = |k: usize| -> Result<Vec<f32>> {
        if signal::interrupted() {
            return Err(Error::Interrupted);
        }
        let k = u32::try_from(k).map_err(|_| Error::Usage("--frames: too many".into()))?;
        plume.samples(k, &signal::interrupted).map_err(|e| {
            if signal::interrupted() {
                Error::Interrupted
            } else {
                Error::Failed(e)
            }
        })
    };
    let write = |k: usize, samples: Vec<f32>| -> Result<()> {
        let volume = plume.volume(samples).map_err(Error::Failed)?;
        save(&paths[k], &volume, &SaveOptions::default())?;
        Ok(())
    };
    let mut pending = match compute(0) {
        Ok(s) => s,
        Err(e) => return Err((e, 0)),
    };
    for k in 0..paths.len() {
        let next = k + 1;
        let (written, computed) = rayon::join(
            || write(k, pending),
            || (next < paths.len()).then(|| compute(next)).transpose(),
        );
        // A frame is on disk once `write` returned, even if the next failed.
        written.map_err(|e| (e, k))?;
        progress.advance(1);
        match computed {
            Ok(Some(s)) => pending = s,
            Ok(None) => return Ok(paths.len()),
            Err(e) => return Err((e, k + 1)),
        }
    }
    Ok(paths.len())
}

/// Removes `frame_*.nrrd` files of an earlier run that are not among
/// `kept` (a longer run, or another zero-padding), so that the directory
/// holds exactly the new sequence.
fn remove_stale_frames(dir: &Path, kept: &[PathBuf]) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let path = entry.path();
        if is_frame_name(&name.to_string_lossy()) && !kept.contains(&path) {
            let _ = std::fs::remove_file(path);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_sort_in_frame_order() {
        assert_eq!(frame_name(0, 1), "frame_0000.nrrd");
        assert_eq!(frame_name(149, 150), "frame_0149.nrrd");
        assert_eq!(frame_name(7, 10_000), "frame_0007.nrrd");
        assert_eq!(frame_name(7, 10_001), "frame_00007.nrrd");
        let names: Vec<String> = (0..12_000).map(|k| frame_name(k, 12_000)).collect();
        assert!(names.windows(2).all(|w| w[0] < w[1]));
        assert!(names.iter().all(|n| is_frame_name(n)));
        assert!(!is_frame_name("frame_.nrrd") && !is_frame_name("frame_1.nii"));
    }

    #[test]
    fn what_the_output_path_means() {
        let dir = |p: &str| Output::Directory(PathBuf::from(p));
        assert_eq!(
            output(Path::new("out/plume/"), 5).unwrap(),
            dir("out/plume/")
        );
        assert_eq!(output(Path::new("out/plume"), 5).unwrap(), dir("out/plume"));
        assert_eq!(
            output(Path::new("out/plume.d"), 1).unwrap(),
            dir("out/plume.d")
        );
        assert_eq!(
            output(Path::new("p.nii.gz"), 1).unwrap(),
            Output::File(PathBuf::from("p.nii.gz"))
        );
        assert_eq!(
            output(Path::new("p.vseq"), 3).unwrap(),
            Output::Packed(PathBuf::from("p.vseq"))
        );
        for (path, frames, expected) in [
            ("p.nrrd", 2, "directory"),
            ("p.vol", 1, "float format"),
            ("p.raw", 1, "float format"),
            ("", 3, "empty"),
        ] {
            let e = output(Path::new(path), frames).unwrap_err().to_string();
            assert!(e.contains(expected), "{path}: {e}");
        }
    }
}
