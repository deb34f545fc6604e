//! `vol_app`: the volume viewer and its headless renderer.
//!
//! `vol_app render FILE ...` renders without a window. `vol_app
//! [FILE]` without a subcommand opens the interactive viewer (the library's
//! [`vol_app::viewer`]).

mod cli;
mod convert_cmd;
mod distributed_cmd;
mod info_cmd;
mod metaballs_cmd;
mod pack_cmd;
mod progress;
mod progressive_cmd;
mod render_cmd;
mod stats;

use std::process::ExitCode;

use raycaster::transfer::{PRESET_NAMES, TransferFunction};
use vol_app::demo;
use vol_app::viewer::{self, StartOptions};

fn main() -> ExitCode {
    raycaster::cli::one_line_panics("vol_app");
    let cli = match cli::parse() {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    let result = match cli.command {
        Some(cli::Command::Render(args)) => render_cmd::run(&args),
        Some(cli::Command::Info(args)) => info_cmd::run(&args),
        Some(cli::Command::Convert(args)) => convert_cmd::run(&args),
        Some(cli::Command::Pack(args)) => pack_cmd::run(&args),
        None => run_viewer(cli.viewer),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            raycaster::cli::print_error("vol_app", e);
            ExitCode::FAILURE
        }
    }
}

/// Checks the viewer's arguments, then opens its window.
fn run_viewer(args: cli::ViewerArgs) -> Result<(), anyhow_like::Error> {
    if let Some(name) = &args.tf_preset
        && !PRESET_NAMES.contains(&name.as_str())
    {
        return Err(format!(
            "unknown transfer function preset '{name}' (known: {})",
            PRESET_NAMES.join(", ")
        )
        .into());
    }
    let tf = match &args.tf {
        Some(path) => Some(TransferFunction::from_json_file(path)?),
        None => None,
    };
    let raw = args.raw.open_options(raycaster::storage::LoadMode::Map).raw;
    // A file that cannot be opened is reported as such, before the window
    // (or the lack of a display) comes into it.
    if let Some(file) = &args.file {
        check_readable(file, raw.is_some())?;
    }
    viewer::run(StartOptions {
        file: args.file,
        tf_preset: args.tf_preset,
        tf,
        raw,
        no_cache: args.no_cache,
        max_memory: args
            .max_memory
            .map(|gib| (gib * (1u64 << 30) as f64) as u64),
        layout: args.layout,
        frame: args.frame,
    })?;
    Ok(())
}

/// Checks that `file` exists and, unless it is raw (described by the
/// `--raw-*` options), that its format is recognised: reads its first
/// bytes, not the samples.
fn check_readable(file: &std::path::Path, raw: bool) -> Result<(), anyhow_like::Error> {
    if raw {
        std::fs::metadata(file).map_err(|e| format!("{}: {e}", file.display()))?;
    } else {
        raycaster::format::detect(file)?;
    }
    Ok(())
}

/// A minimal boxed error for the command layer.
mod anyhow_like {
    /// Any error, displayed as its message.
    pub type Error = Box<dyn std::error::Error + Send + Sync>;
}
