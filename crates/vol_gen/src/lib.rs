//! `vol_gen`: a fast, parallel generator of test volumes in the `.vol` format
//! (26-byte header, linear or bricked samples), with the command line the
//! README describes; and of signed distance fields of triangle meshes
//! (`--generator mesh`, f32 NRRD or NIfTI, see [`mesh`]); and of a synthetic
//! time series (`--generator plume --frames N`, a directory of f32 NRRD
//! frames, see [`plume`] and [`sequence`]).
//!
//! The design: a *sample generator*
//! gives any voxel its value ([`generators`]), an *order* decides the sequence
//! in which samples appear in the file ([`order`]), and the samples stream to
//! the file in that order ([`writer`]). Work is cut into batches of a few MB
//! that are filled on all cores while the previous batch is written, and
//! every value is a pure function of the voxel and the seed, so the output is
//! byte-identical whatever the thread count, and the linear and bricked files
//! of one seed hold the same voxels.
//!
//! | module | concept |
//! |---|---|
//! | [`cli`] | arguments, validation into a [`cli::Config`] |
//! | [`generators`] | the six voxel generators and spatial binning of objects |
//! | [`mesh`] | `--generator mesh`: mesh readers, BVH, signed distance field (f32, NRRD/NIfTI) |
//! | [`plume`] | `--generator plume`: an evolving jet, frame by frame (f32) |
//! | [`sequence`] | writing frames: a directory of NRRD files |
//! | [`order`] | file order: batches and parallel pieces, linear or bricked |
//! | [`writer`] | pipelined, atomic writing |
//! | [`progress`] | the progress bar |
//! | [`signal`] | Ctrl-C: stop cleanly, leave no file |
//! | [`disk`] | free-space check |
//!
//! The header and the atomic temporary-file-then-rename write come from the
//! `raycaster` library, so there is one implementation of the format.

pub mod cli;
pub mod disk;
pub mod error;
pub mod generators;
pub mod mesh;
pub mod order;
pub mod plume;
pub mod progress;
pub mod sequence;
pub mod signal;
pub mod writer;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use raycaster::format::vol::VolLayout;
use raycaster::units::bytes;

pub use error::{Error, Result};

use cli::{Cli, Config};
use generators::Field;
use order::Plan;
use progress::Progress;

/// A volume ready to be written: the output has been checked.
pub struct Job {
    config: Config,
    plan: Plan,
    field: Box<dyn Field>,
    file_len: u64,
}

/// What a finished run wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The file.
    pub path: PathBuf,
    /// Its length in bytes.
    pub bytes: u64,
    /// Wall time of generating and writing, in seconds.
    pub seconds: f64,
}

impl Job {
    /// Builds the generator and checks that the output can be written: it
    /// does not exist (unless `force`), its directory does, and the disk has
    /// room for it.
    pub fn prepare(config: Config) -> Result<Job> {
        let header = &config.header;
        let file_len = header
            .file_len()
            .map_err(|e| Error::Usage(format!("--dims: {e}")))?;
        let plan = Plan::new(header.dims, header.layout)
            .ok_or_else(|| Error::Usage("--dims: the volume is too large".into()))?;
        let field = generators::build(config.generator, &config.setup).map_err(Error::Usage)?;
        check_output(&config.output, config.force, file_len)?;
        Ok(Job {
            config,
            plan,
            field,
            file_len,
        })
    }

    /// The validated configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Length of the file to be written, in bytes.
    pub fn file_len(&self) -> u64 {
        self.file_len
    }

    /// Generates and writes the volume. SIGINT/SIGTERM stop it with
    /// [`Error::Interrupted`] and no file (this installs handlers for them
    /// that only raise a flag; see [`signal`]).
    pub fn run(&self, progress: &Progress) -> Result<Summary> {
        signal::install();
        let start = Instant::now();
        writer::write_volume(
            &self.config.output,
            &self.config.header,
            &self.plan,
            self.field.as_ref(),
            progress,
        )?;
        Ok(Summary {
            path: self.config.output.clone(),
            bytes: self.file_len,
            seconds: start.elapsed().as_secs_f64(),
        })
    }
}

/// Refuses an existing file (without `force`), a missing directory and a disk
/// with less than `need` bytes free.
pub(crate) fn check_output(path: &Path, force: bool, need: u64) -> Result<()> {
    if path.as_os_str().is_empty() {
        return Err(Error::Usage("--output-file is empty".into()));
    }
    let shown = path.display();
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => return Err(Error::Failed(format!("{shown} is a directory"))),
        Ok(_) if !force => {
            return Err(Error::Failed(format!(
                "{shown} already exists (pass --force to overwrite it)"
            )));
        }
        _ => {}
    }
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !dir.is_dir() {
        return Err(Error::Failed(format!(
            "directory {} does not exist",
            dir.display()
        )));
    }
    if let Some(free) = disk::available_bytes(dir)
        && free < need
    {
        return Err(Error::Failed(format!(
            "not enough free space in {}: {shown} needs {} ({need} bytes), {} available",
            dir.display(),
            bytes(need),
            bytes(free)
        )));
    }
    Ok(())
}

/// Runs the command line `cli`: prints the seed when it was random, a
/// progress bar and a summary (none of them with `--quiet`).
pub fn run(cli: Cli) -> Result<Summary> {
    let config = Config::from_cli(cli)?;
    if let Some(n) = config.threads {
        // Fails only if a pool exists already; then that one is used.
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global();
    }
    if config.generator == generators::GeneratorKind::Mesh {
        // f32 samples computed whole, then saved as NRRD/NIfTI: not the
        // streamed u8 `.vol` pipeline below.
        return mesh::field::run(&config);
    }
    if config.generator == generators::GeneratorKind::Plume {
        // A time series of f32 frames, each computed whole and saved.
        return sequence::run(&config);
    }
    let job = Job::prepare(config)?;
    let c = job.config();
    if c.seed_was_random && !c.quiet {
        eprintln!(
            "vol_gen: seed {} (pass --seed {} to repeat this volume)",
            c.setup.seed, c.setup.seed
        );
    }
    let progress = Progress::new(job.file_len(), !c.quiet);
    let result = job.run(&progress);
    progress.finish();
    let summary = result?;
    if !c.quiet {
        let d = c.header.dims;
        let layout = match c.header.layout {
            VolLayout::Linear => "linear".to_string(),
            VolLayout::Bricked { side } => format!("bricked B={side}"),
        };
        eprintln!(
            "vol_gen: wrote {} ({}x{}x{} {}, {}, {}) in {:.2} s, {}/s",
            summary.path.display(),
            d.x,
            d.y,
            d.z,
            c.generator.name(),
            layout,
            bytes(summary.bytes),
            summary.seconds,
            bytes((summary.bytes as f64 / summary.seconds.max(1e-9)) as u64)
        );
    }
    Ok(summary)
}

/// The program: parses `std::env::args`, runs, and turns any error into one
/// line on stderr and a non-zero exit code (2 for usage, 130 for Ctrl-C, 1
/// otherwise). Never shows a panic or a backtrace.
pub fn main_entry() -> ExitCode {
    raycaster::cli::one_line_panics("vol_gen");
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return raycaster::cli::parse_failure("vol_gen", &e),
    };
    match run(cli) {
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => {
            raycaster::cli::print_error("vol_gen", &e);
            ExitCode::from(e.exit_code())
        }
    }
}
