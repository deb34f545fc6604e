//! `vol_app pack INPUT -o OUT.vseq`: a sequence packed into this project's
//! container.

use raycaster::format::vseq::{PackOptions, pack};
use raycaster::prelude::*;
use raycaster::sequence::Sequence;
use raycaster::units::bytes;

use crate::anyhow_like::Error;
use crate::cli::PackArgs;

/// Runs the `pack` subcommand.
pub fn run(args: &PackArgs) -> Result<(), Error> {
    if args.output.exists() && !args.force {
        return Err(format!(
            "{}: already exists (use --force to replace it)",
            args.output.display()
        )
        .into());
    }
    let open = raycaster::format::OpenOptions {
        mode: LoadMode::Map,
        ..Default::default()
    };
    let sequence = Sequence::open(&args.input, &open)?;
    let options = PackOptions {
        codec: args.codec,
        level: args.level,
        f16: args.f16,
        key_interval: args.key_interval,
        chunk_bytes: args.chunk_kib as usize * 1024,
        shuffle: !args.no_shuffle,
        delta: args.delta,
    };
    let progress = crate::progress::bar("packing");
    let report = pack(
        &args.output,
        sequence.frames(),
        |k| sequence.frame(k),
        &options,
        progress.as_ref(),
    )?;
    if args.json {
        let v = serde_json::json!({
            "input": args.input.display().to_string(),
            "output": args.output.display().to_string(),
            "frames": report.frames,
            "codec": args.codec.name(),
            "f16": args.f16,
            "key_interval": args.key_interval,
            "raw_bytes": report.raw_bytes,
            "file_bytes": report.file_bytes,
            "percent": report.percent(),
            "seconds": report.seconds,
        });
        crate::stats::print_json(&v)?;
    } else {
        eprintln!(
            "vol_app: wrote {} ({} frames, {} of {} samples = {:.2} %, {:.1} s)",
            args.output.display(),
            report.frames,
            bytes(report.file_bytes),
            bytes(report.raw_bytes),
            report.percent(),
            report.seconds
        );
    }
    Ok(())
}
