//! `vol_app convert IN OUT`: read any supported format, write the one OUT's
//! name says (the library's `format::save`).

use raycaster::format::save::{OutputFormat, SaveOptions, save};
use raycaster::format::vol::VolLayout;
use raycaster::format::{Endian, RawOptions};
use raycaster::storage::LoadMode;

use crate::anyhow_like::Error;
use crate::cli::{ConvertArgs, VolLayoutArg};

/// Runs the `convert` subcommand.
pub fn run(args: &ConvertArgs) -> Result<(), Error> {
    if args.output.exists() && !args.force {
        return Err(format!(
            "{}: already exists (use --force to replace it)",
            args.output.display()
        )
        .into());
    }
    let options = SaveOptions {
        vol_layout: Some(match args.layout {
            VolLayoutArg::Linear => VolLayout::Linear,
            VolLayoutArg::Bricked => VolLayout::Bricked {
                side: args.block_size,
            },
        }),
        gzip: args.gzip,
        window: args.window,
    };
    // Check the output name before reading a big input.
    raycaster::format::save::output_format(&args.output, &options)?;
    let opened = raycaster::format::open_file(&args.input, &args.raw.open_options(LoadMode::Map))?;
    let format = save(&args.output, &opened.volume, &options)?;
    let d = opened.info.dims;
    let what = match format {
        OutputFormat::Vol(layout) => format!(".vol ({}, u8)", layout_name(layout)),
        OutputFormat::Nrrd(e) => format!("NRRD ({}, {})", e.name(), opened.volume.sample_type()),
        OutputFormat::Nifti { gzip } => format!(
            "NIfTI-1{} ({})",
            if gzip { " gzip" } else { "" },
            opened.volume.sample_type()
        ),
        OutputFormat::Raw => format!(
            "raw x-fast little-endian {} (read it with --raw-dims {},{},{} --raw-type {})",
            opened.volume.sample_type(),
            d.x,
            d.y,
            d.z,
            RawOptions::type_name(opened.volume.sample_type(), Endian::Little)
        ),
    };
    eprintln!(
        "vol_app: wrote {} ({}x{}x{}, {what})",
        args.output.display(),
        d.x,
        d.y,
        d.z
    );
    Ok(())
}

fn layout_name(layout: VolLayout) -> String {
    match layout {
        VolLayout::Linear => "linear".into(),
        VolLayout::Bricked { side } => format!("bricked B = {side}"),
    }
}
