//! `vol_app`: the volume viewer and its headless renderer.
//!
//! `vol_app render FILE ...` renders without a window (SPEC §6). `vol_app`
//! without a subcommand will open the interactive viewer; until it exists it
//! says so and points to `vol_app render`.

mod cli;
mod demo;
mod render_cmd;
mod stats;

use std::process::ExitCode;

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
        None => {
            eprintln!(
                "vol_app: the interactive viewer is not built yet; render headlessly with `vol_app render FILE --out image.png` (see `vol_app render --help`)"
            );
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("vol_app: {}", one_line(&e));
            ExitCode::FAILURE
        }
    }
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
