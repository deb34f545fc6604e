//! `vol_app info FILE`: what a volume file holds, as text or JSON.

use raycaster::prelude::*;
use raycaster::sequence::{Sequence, frame_files};
use raycaster::storage::StorageKind;
use raycaster::units::{bytes, significant, value};

use crate::anyhow_like::Error;
use crate::cli::InfoArgs;

/// Runs the `info` subcommand.
pub fn run(args: &InfoArgs) -> Result<(), Error> {
    // The value range comes from the macrocell grid, so from its cache
    // when there is one: `info` on a huge volume reads no samples. A
    // directory of frame files is described by its first frame, after
    // every frame is checked against it.
    let open = args.raw.open_options(LoadMode::Map);
    let scene_options = crate::cli::scene_options(None, args.no_cache);
    let (info, scene) = if frame_files(&args.file).is_empty() {
        let opened = Scene::open(&args.file, &open, &scene_options)?;
        crate::cli::warn_all(&opened.cache.warnings);
        (opened.info, opened.scene)
    } else {
        let sequence = Sequence::open(&args.file, &open)?;
        sequence.check_all(crate::progress::bar("checking frames").as_ref())?;
        let scene = Scene::with_options(sequence.frame(0)?, &scene_options);
        (sequence.info().clone(), scene)
    };
    let info = &info;
    let volume = scene.volume();
    let in_memory = volume.sample_type();
    let storage = volume.storage_kind();
    let layout = volume.layout();
    let memory_bytes = volume.memory_bytes();
    let (lo, hi) = scene.value_range();
    let grid = *scene.grid();
    let extent = grid.extent();
    let storage_name = match storage {
        StorageKind::Mapped => "memory-mapped",
        StorageKind::Ram => "in RAM",
    };
    if args.json {
        let v = serde_json::json!({
            "file": args.file.display().to_string(),
            "format": info.format.name(),
            "dims": info.dims.to_array(),
            "spacing": info.spacing.to_array(),
            "extent": extent.to_array(),
            "stored_type": info.stored_type.name(),
            "byte_order": info.byte_order.map(|e| e.name()),
            "encoding": info.encoding,
            "rescale": info.rescale.map(|r| serde_json::json!({"slope": r.slope, "intercept": r.intercept})),
            "sample_type": in_memory.name(),
            "value_range": [lo, hi],
            "orientation": info.orientation,
            "notes": info.notes,
            "file_bytes": info.file_bytes,
            "memory_bytes": memory_bytes,
            "storage": storage_name,
            "layout": layout.to_string(),
            "frames": info.volumes,
        });
        return crate::stats::print_json(&v);
    }
    let d = info.dims;
    let s = info.spacing;
    let mut text = Vec::new();
    text.push(format!("file         {}", args.file.display()));
    text.push(format!("format       {}", info.format));
    text.push(format!("dimensions   {} x {} x {}", d.x, d.y, d.z));
    if info.volumes > 1 {
        text.push(format!(
            "frames       {} (values below are frame 0's)",
            info.volumes
        ));
    }
    text.push(format!("spacing      {}", triple(s)));
    text.push(format!("extent       {} (world units)", triple(extent)));
    let order = info
        .byte_order
        .map(|e| format!(", {}-endian", e.name()))
        .unwrap_or_default();
    text.push(format!(
        "stored as    {}{order}, {}",
        info.stored_type, info.encoding
    ));
    if let Some(r) = info.rescale {
        text.push(format!("rescale      value = {r} (held as {in_memory})"));
    }
    text.push(format!("values       {} .. {}", value(lo), value(hi)));
    text.push(format!(
        "orientation  {}",
        info.orientation
            .as_deref()
            .unwrap_or("none stored (not applied either way)")
    ));
    text.push(format!("on disk      {}", with_count(info.file_bytes)));
    text.push(format!(
        "in memory    {} ({storage_name}, {layout})",
        with_count(memory_bytes)
    ));
    for note in &info.notes {
        text.push(format!("note         {note}"));
    }
    crate::stats::print_text(&text.join("\n"))
}

/// `0.703125 x 0.703125 x 2.5`: at most 6 significant digits, so that the
/// float noise of a header (`3.0000002`) does not show.
fn triple(v: glam::Vec3) -> String {
    let [x, y, z] = v.to_array().map(|c| significant(c, 6));
    format!("{x} x {y} x {z}")
}

/// `1.2 MiB (1234567 bytes)`.
fn with_count(n: u64) -> String {
    if n < 1024 {
        bytes(n)
    } else {
        format!("{} ({n} bytes)", bytes(n))
    }
}
