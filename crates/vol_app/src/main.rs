//! `vol_app`: the volume viewer and its headless renderer.
//!
//! `vol_app render FILE ...` renders without a window (SPEC §6). `vol_app
//! [FILE]` without a subcommand opens the interactive viewer (the library's
//! [`vol_app::viewer`]).

mod cli;
mod convert_cmd;
mod info_cmd;
mod progress;
mod render_cmd;
mod stats;

use std::process::ExitCode;

use raycaster::transfer::{PRESET_NAMES, TransferFunction};
use vol_app::demo;
use vol_app::viewer::{self, StartOptions};

fn main() -> ExitCode {
    // A bug must still end in one line on stderr, never a backtrace dump.
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("vol_app: internal error: {msg}{at}");
    }));
    let cli = match cli::parse() {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    let result = match cli.command {
        Some(cli::Command::Render(args)) => render_cmd::run(&args),
        Some(cli::Command::Info(args)) => info_cmd::run(&args),
        Some(cli::Command::Convert(args)) => convert_cmd::run(&args),
        None => run_viewer(cli.viewer),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("vol_app: {}", one_line(&e));
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
    viewer::run(StartOptions {
        file: args.file,
        tf_preset: args.tf_preset,
        tf,
        raw,
    })?;
    Ok(())
}

/// The error and its causes on one line.
fn one_line(e: &anyhow_like::Error) -> String {
    e.to_string().replace('\n', " ")
}

/// A minimal boxed error for the command layer.
mod anyhow_like {
    /// Any error, displayed as its message.
    pub type Error = Box<dyn std::error::Error + Send + Sync>;
}
