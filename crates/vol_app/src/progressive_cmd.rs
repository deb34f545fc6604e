//! `vol_app render --progressive N`: the viewer's frames, headlessly.
//!
//! Reproduces what the viewer renders while the camera is dragged and after
//! it stops, with the same code: the viewer's
//! [`Progressive`] state machine picks each frame's level from the frames
//! timed before it, and the frames render on the library's
//! [`RendererFront`] with that level as their [`Quality`](raycaster::render::Quality),
//! as in the viewer. The camera orbits the look-at point about the up
//! vector by [`ORBIT_DEGREES`] per frame (a steady drag) for N preview
//! frames, then stops: the refinement levels of the last view follow.

use std::sync::Arc;
use std::time::Duration;

use glam::Quat;
use raycaster::prelude::*;
use raycaster::render::{FrameRequest, FrontEvent, FrontOptions};
use serde::Serialize;
use vol_app::viewer::progressive::{Level, Progressive, Stage};

use crate::anyhow_like::Error;
use crate::stats::{median, peak_rss_mb};

/// How far the camera turns between two preview frames.
pub const ORBIT_DEGREES: f32 = 2.0;

/// How long to wait for one frame before giving up.
const FRAME_TIMEOUT: Duration = Duration::from_secs(600);

/// One frame of the sequence.
#[derive(Debug, Serialize)]
pub struct FrameRecord {
    /// `preview` or `refine`.
    pub stage: &'static str,
    /// Image size divisor.
    pub downscale: u32,
    /// Step multiplier.
    pub step_scale: u32,
    pub width: u32,
    pub height: u32,
    pub ms: f64,
    pub samples: u64,
}

/// The `--stats` object of `--progressive`.
#[derive(Debug, Serialize)]
pub struct ProgressiveStats {
    /// The full-quality size.
    pub width: u32,
    pub height: u32,
    pub renderer: String,
    pub threads: usize,
    /// Full-quality step in world units.
    pub step: f32,
    /// Median time of the preview frames after the first (which is rendered
    /// before anything has been timed).
    pub preview_ms_median: f64,
    /// Slowest of those.
    pub preview_ms_max: f64,
    /// Every frame in order: the previews, then the refinement.
    pub frames: Vec<FrameRecord>,
    pub load_ms: f64,
    pub peak_rss_mb: f64,
}

/// What the sequence renders.
pub struct Setup<'a> {
    pub renderer: AnyRenderer,
    pub scene: Arc<Scene>,
    pub camera: Camera,
    pub tf: TransferFunction,
    pub options: RenderOptions,
    pub previews: u32,
    pub load_ms: f64,
    pub out: Option<&'a std::path::Path>,
    pub stats: bool,
}

/// Renders the sequence; prints one line per frame (or the JSON object
/// with `stats`), and saves the final full-quality frame to `out`.
pub fn run(setup: Setup<'_>) -> Result<(), Error> {
    let name = setup.renderer.name();
    let threads = setup.renderer.threads();
    let step = setup.options.step_for(setup.scene.grid());
    let front = RendererFront::spawn(setup.renderer, setup.scene, FrontOptions::default())?;
    let tf = Arc::new(setup.tf);
    let full = [setup.camera.width, setup.camera.height];
    let axis = setup.camera.up.normalize_or_zero();
    let mut progressive = Progressive::default();
    let mut frames = Vec::new();
    let mut last = None;
    let mut camera = setup.camera;
    let render = |camera: &Camera, level: Level, p: &mut Progressive| {
        let id = front.request(FrameRequest {
            camera: *camera,
            tf: tf.clone(),
            options: setup.options.clone(),
            quality: level.quality(),
        });
        p.sent(id);
        let frame = wait_for(&front, id)?;
        p.arrived(id, level, full, frame.stats.time);
        Ok::<_, Error>(frame)
    };
    for k in 0..setup.previews {
        if k > 0 {
            let turn = Quat::from_axis_angle(axis, ORBIT_DEGREES.to_radians());
            camera.position = camera.target + turn * (camera.position - camera.target);
        }
        let planned = progressive
            .next(true, true, full)
            .ok_or("the viewer's picker planned no preview for a changed view")?;
        let frame = render(&camera, planned.level, &mut progressive)?;
        frames.push(record(planned.level, Stage::Preview, &frame));
        last = Some(frame);
    }
    while let Some(planned) = progressive.next(false, false, full) {
        let frame = render(&camera, planned.level, &mut progressive)?;
        frames.push(record(planned.level, planned.stage, &frame));
        last = Some(frame);
    }
    if let (Some(path), Some(frame)) = (setup.out, &last) {
        frame.save_png(path)?;
    }
    // The first preview is a guess made before any frame was timed.
    let timed: Vec<f64> = frames
        .iter()
        .filter(|f| f.stage == "preview")
        .skip(1)
        .map(|f| f.ms)
        .collect();
    if setup.stats {
        let stats = ProgressiveStats {
            width: full[0],
            height: full[1],
            renderer: name.to_string(),
            threads,
            step,
            preview_ms_median: median(&timed),
            preview_ms_max: timed.iter().copied().fold(0.0, f64::max),
            frames,
            load_ms: setup.load_ms,
            peak_rss_mb: peak_rss_mb(),
        };
        crate::stats::print_json(&stats)?;
    } else {
        for f in &frames {
            eprintln!(
                "{:7} {:>4}×{:<4} 1/{} res, step ×{}: {:8.2} ms, {} samples",
                f.stage, f.width, f.height, f.downscale, f.step_scale, f.ms, f.samples
            );
        }
        eprintln!(
            "vol_app: previews (after the first) median {:.2} ms, max {:.2} ms, at {}x{}, step {step}",
            median(&timed),
            timed.iter().copied().fold(0.0, f64::max),
            full[0],
            full[1]
        );
    }
    Ok(())
}

fn record(level: Level, stage: Stage, frame: &Frame) -> FrameRecord {
    FrameRecord {
        stage: match stage {
            Stage::Preview => "preview",
            Stage::Refine => "refine",
        },
        downscale: level.downscale,
        step_scale: level.step_scale,
        width: frame.width,
        height: frame.height,
        ms: (frame.stats.time.as_secs_f64() * 1e5).round() / 100.0,
        samples: frame.stats.samples,
    }
}

/// Waits for request `id`'s frame.
fn wait_for(front: &RendererFront, id: u64) -> Result<Frame, Error> {
    loop {
        match front.events().recv_timeout(FRAME_TIMEOUT) {
            Ok(FrontEvent::Ready { id: done, .. }) if done == id => {
                let (got, frame) = front
                    .take_frame()
                    .ok_or("the renderer front announced a frame it did not deliver")?;
                if got == id {
                    return Ok(frame);
                }
            }
            Ok(FrontEvent::Ready { .. }) => {}
            Ok(FrontEvent::Failed { id: failed, error }) if failed == id => {
                return Err(error.into());
            }
            Ok(FrontEvent::Failed { .. }) => {}
            Err(_) => return Err("no frame from the renderer front within 600 s".into()),
        }
    }
}
