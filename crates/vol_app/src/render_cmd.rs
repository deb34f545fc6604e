//! `vol_app render`: open, render, time, save.

use std::sync::Arc;
use std::time::Instant;

use raycaster::camera::{Camera, Projection};
use raycaster::prelude::*;
use raycaster::scene::SceneOptions;
use raycaster::sequence::{Playback, Sequence, frame_files};
use raycaster::transfer::PRESET_NAMES;

use crate::anyhow_like::Error;
use crate::cli::{FrameRange, RenderArgs};
use crate::stats::{PlayStats, RenderStats, median, peak_rss_mb, print_json};

/// Frames `--frames` keeps decoded ahead of the renderer.
const PLAYBACK_AHEAD: u32 = 3;

/// Runs the `render` subcommand.
pub fn run(args: &RenderArgs) -> Result<(), Error> {
    if args.distributed {
        return crate::distributed_cmd::run(args);
    }
    if args.mode == RenderMode::Metaballs {
        if args.turntable.is_some() {
            return Err(
                "--turntable renders volumes; it does not work with --mode metaballs".into(),
            );
        }
        return crate::metaballs_cmd::run(args);
    }
    let load_start = Instant::now();
    let mode = if args.in_ram {
        LoadMode::Ram
    } else {
        LoadMode::Map
    };
    let scene_options = crate::cli::scene_options(args.macrocell, args.no_cache);
    let open = || args.raw.open_options(mode);
    // `--frames` plays a sequence; a directory of frame files is a
    // sequence whatever is asked; other files open their volume `--frame`
    // as a scene (with the macrocell cache where the file has one volume).
    let mut playback = None;
    let scene: Arc<Scene> = match &args.file {
        Some(path) if args.frames.is_some() => {
            let sequence = Arc::new(Sequence::open(path, &open())?);
            let frames = args.frames.unwrap_or(FrameRange {
                start: 0,
                end: None,
            });
            let end = frames.end.unwrap_or(sequence.frames());
            if frames.start >= sequence.frames() || end > sequence.frames() {
                return Err(format!(
                    "--frames {}..{end}: {} has {} frames (numbered from 0)",
                    frames.start,
                    path.display(),
                    sequence.frames()
                )
                .into());
            }
            let options = SceneOptions {
                progress: None,
                ..scene_options.clone()
            };
            let p = Playback::new(sequence, PLAYBACK_AHEAD, false, options)?;
            let first = p.get(frames.start)?.scene.clone();
            playback = Some((p, frames.start..end));
            first
        }
        Some(path) if !frame_files(path).is_empty() => {
            let sequence = Sequence::open(path, &open())?;
            Arc::new(Scene::with_options(
                sequence.frame(args.frame)?,
                &scene_options,
            ))
        }
        Some(path) => {
            let options = raycaster::format::OpenOptions {
                volume: u64::from(args.frame),
                ..open()
            };
            let opened = Scene::open(path, &options, &scene_options)?;
            crate::cli::warn_all(&opened.cache.warnings);
            Arc::new(opened.scene)
        }
        None if args.frame > 0 => {
            return Err("--frame needs a sequence FILE (the demo volume has one frame)".into());
        }
        None => Arc::new(Scene::with_options(
            crate::demo::demo_volume(),
            &scene_options,
        )),
    };
    let sample_type = scene.volume().sample_type();
    let load_ms = ms(load_start.elapsed());

    let tf = transfer_function(args, sample_type, scene.value_range())?;
    let (width, height) = args.size;
    let camera = camera_for(args, &scene.grid().bounds())?;
    let options = render_options(args, scene.value_range())?;

    let mut renderer: AnyRenderer = match args.renderer {
        RendererKind::Serial => Box::new(SerialRenderer::new()),
        RendererKind::Tiles => Box::new(TiledRenderer::new(
            args.threads as usize,
            args.tile.unwrap_or(TiledRenderer::DEFAULT_TILE),
        )?),
        RendererKind::Object => {
            // The library's defaults, `--threads 0` resolved to the cores.
            let defaults = ObjectConfig::with_threads(args.threads as usize);
            let total = defaults.render_threads;
            let composite = args.composite_threads as usize;
            if composite >= total {
                return Err(format!(
                    "--composite-threads {composite} leaves no render thread of --threads {total}"
                )
                .into());
            }
            Box::new(ObjectRenderer::with_config(ObjectConfig {
                render_threads: total - composite,
                composite_threads: composite,
                tile: args.tile.unwrap_or(defaults.tile),
                brick: args.brick.unwrap_or(defaults.brick),
                order: args.task_order,
            })?)
        }
    };
    if let Some(frames) = args.turntable {
        return turntable(
            args,
            renderer.as_mut(),
            &scene,
            camera,
            &tf,
            &options,
            frames,
        );
    }
    if let Some((playback, range)) = playback {
        return play(
            args,
            renderer.as_mut(),
            &playback,
            range,
            &camera,
            &tf,
            &options,
            load_ms,
        );
    }
    if let Some(previews) = args.progressive {
        return crate::progressive_cmd::run(crate::progressive_cmd::Setup {
            renderer,
            scene,
            camera,
            tf,
            options,
            previews,
            load_ms,
            out: args.out.as_deref(),
            stats: args.stats,
        });
    }
    let (last, times) = render_repeated(
        renderer.as_mut(),
        &scene,
        &camera,
        &tf,
        &options,
        args.repeat,
    )?;
    let (name, threads) = (renderer.name(), renderer.threads());

    let out = match (&args.out, args.stats) {
        (Some(p), _) => Some(p.clone()),
        (None, false) => Some("out.png".into()),
        (None, true) => None,
    };
    if let Some(path) = &out {
        last.save_png(path)?;
    }
    if args.stats {
        let stats = RenderStats {
            width,
            height,
            renderer: name.to_string(),
            threads,
            frame_ms_median: median(&times),
            frame_ms: times,
            load_ms,
            rays: last.stats.rays,
            rays_in_volume: last.stats.rays_in_volume,
            covered: last.stats.covered,
            samples: last.stats.samples,
            peak_rss_mb: peak_rss_mb(),
            metaballs: None,
        };
        print_json(&stats)?;
    } else if let Some(path) = &out {
        eprintln!(
            "vol_app: wrote {} ({}x{}, {:.1} ms, {} samples)",
            path.display(),
            width,
            height,
            ms(last.stats.time),
            last.stats.samples
        );
    }
    Ok(())
}

/// `--turntable N`: N frames orbiting the volume's centre into `--out`
/// (a directory or a GIF), with a progress bar.
fn turntable(
    args: &RenderArgs,
    renderer: &mut dyn Renderer,
    scene: &Scene,
    camera: Camera,
    tf: &TransferFunction,
    options: &RenderOptions,
    frames: u32,
) -> Result<(), Error> {
    use vol_app::turntable::{Outcome, Output, Turntable};
    let path = args
        .out
        .as_deref()
        .ok_or("--turntable needs --out DIR/ (one PNG a frame) or --out FILE.gif")?;
    let out = Output::from_path(path, args.fps)?;
    let job = Turntable {
        scene,
        camera,
        center: scene.grid().bounds().center(),
        axis: args.axis,
        frames,
        tf,
        options,
    };
    let progress = crate::progress::bar("turntable");
    let start = Instant::now();
    let never = std::sync::atomic::AtomicBool::new(false);
    let outcome = vol_app::turntable::render(&job, renderer, &out, &never, |done, n| {
        if let Some(p) = &progress {
            p.report(done as f32 / n as f32);
        }
    })?;
    debug_assert_eq!(outcome, Outcome::Done);
    let seconds = start.elapsed().as_secs_f64();
    let (width, height) = args.size;
    eprintln!(
        "vol_app: wrote a {frames}-frame turntable to {} ({width}x{height}, {:.1} frames/s)",
        path.display(),
        f64::from(frames) / seconds.max(1e-9)
    );
    Ok(())
}

/// Renders the frames `range` of `playback` (`--frames`), writing one PNG
/// per frame into `--out DIR` and, with `--stats`, the timings as JSON.
#[allow(clippy::too_many_arguments)]
fn play(
    args: &RenderArgs,
    renderer: &mut dyn Renderer,
    playback: &Playback,
    range: std::ops::Range<u32>,
    camera: &Camera,
    tf: &TransferFunction,
    options: &RenderOptions,
    load_ms: f64,
) -> Result<(), Error> {
    let dir = match (&args.out, args.stats) {
        // A path that names an image is a slip for a directory: refused,
        // rather than made a directory with that name.
        (Some(d), _)
            if !d.is_dir()
                && d.extension().is_some_and(|e| {
                    ["png", "gif", "jpg", "jpeg"]
                        .contains(&e.to_string_lossy().to_lowercase().as_str())
                }) =>
        {
            return Err(format!(
                "--out {}: --frames writes one PNG a frame into a directory (e.g. --out frames/)",
                d.display()
            )
            .into());
        }
        (Some(d), _) => Some(d.clone()),
        (None, false) => Some(std::path::PathBuf::from("frames")),
        (None, true) => None,
    };
    if let Some(d) = &dir {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    let n = range.len();
    let progress = (!args.stats)
        .then(|| crate::progress::bar("rendering"))
        .flatten();
    let (mut decode, mut build, mut render, mut wait) = (vec![], vec![], vec![], vec![]);
    let (mut rays, mut samples) = (0, 0);
    let start = Instant::now();
    for (i, k) in range.clone().enumerate() {
        let asked = Instant::now();
        let frame = playback.get(k)?;
        wait.push(ms(asked.elapsed()));
        let image = renderer.render(&frame.scene, camera, tf, options)?;
        decode.push(ms(frame.decode));
        build.push(ms(frame.build));
        render.push(ms(image.stats.time));
        rays += image.stats.rays;
        samples += image.stats.samples;
        if let Some(d) = &dir {
            image.save_png(&d.join(format!("frame_{k:04}.png")))?;
        }
        if let Some(p) = &progress {
            p.report((i + 1) as f32 / n as f32);
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    let (width, height) = args.size;
    if args.stats {
        let stats = PlayStats {
            width,
            height,
            renderer: renderer.name().to_string(),
            threads: renderer.threads(),
            frames: n as u32,
            first_frame: range.start,
            fps: n as f64 / seconds.max(1e-9),
            decode_ms_median: median(&decode),
            build_ms_median: median(&build),
            render_ms_median: median(&render),
            wait_ms_median: median(&wait),
            decode_ms: decode,
            render_ms: render,
            load_ms,
            rays,
            samples,
            peak_rss_mb: peak_rss_mb(),
        };
        print_json(&stats)?;
    } else if let Some(d) = &dir {
        eprintln!(
            "vol_app: wrote {n} frames to {} ({width}x{height}, {:.1} frames/s)",
            d.display(),
            n as f64 / seconds.max(1e-9)
        );
    }
    Ok(())
}

/// The transfer function of the command line for data of `sample_type`
/// with values in `value_range` (`--tf`, `--tf-preset`, else `ramp`, or the
/// demo's for the demo volume).
pub fn transfer_function(
    args: &RenderArgs,
    sample_type: SampleType,
    value_range: (f32, f32),
) -> Result<TransferFunction, Error> {
    Ok(match (&args.tf, &args.tf_preset) {
        (Some(path), _) => TransferFunction::from_json_file(path)?,
        (None, Some(name)) => TransferFunction::preset_for_data(name, sample_type, value_range)
            .ok_or_else(|| {
                format!(
                    "unknown transfer function preset '{name}' (known: {})",
                    PRESET_NAMES.join(", ")
                )
            })?,
        (None, None) => {
            let name = if args.file.is_some() {
                "ramp"
            } else {
                crate::demo::DEMO_TF
            };
            TransferFunction::preset(name, sample_type).ok_or("built-in preset missing")?
        }
    })
}

/// The render options of the command line, checked, for data with values
/// in `(lo, hi)` (the default iso value is their middle).
pub fn render_options(args: &RenderArgs, (lo, hi): (f32, f32)) -> Result<RenderOptions, Error> {
    let options = RenderOptions {
        mode: args.mode,
        step: args.step,
        ert: args.ert.on(),
        ert_threshold: args.ert_threshold,
        ess: args.ess.on(),
        shading: args.shading.on(),
        phong: None,
        iso_value: args.iso.unwrap_or(0.5 * (lo + hi)),
        lights: args.lights.clone(),
        shadows: args.shadows.on(),
        reflection: args.reflection,
        iso_normals: args.normals,
        background: args.background,
        clip: raycaster::clip::Clip {
            clip_box: args.clip_box,
            planes: args.clip_planes.clone(),
        },
        gradient_opacity: args
            .gradient_opacity
            .map(|(g0, g1)| raycaster::integrator::GradientOpacity { g0, g1 }),
        jitter: args.jitter.on(),
        seed: args.seed,
    };
    if args.gradient_opacity.is_some() && args.mode != RenderMode::Dvr {
        // It scales opacity per unit length, which only DVR composites.
        return Err(format!(
            "--gradient-opacity applies to --mode dvr only, not {}",
            format!("{:?}", args.mode).to_lowercase()
        )
        .into());
    }
    if args.clip_planes.len() > raycaster::clip::MAX_CLIP_PLANES {
        return Err(format!(
            "--clip-plane given {} times, at most {}",
            args.clip_planes.len(),
            raycaster::clip::MAX_CLIP_PLANES
        )
        .into());
    }
    if let Some(s) = args.step
        && !(s.is_finite() && s > 0.0)
    {
        return Err(format!("--step {s} must be a finite number greater than 0").into());
    }
    if args.background.min_element() < 0.0 || args.background.max_element() > 1.0 {
        return Err("--background channels must be in 0..1".into());
    }
    Ok(options)
}

/// The camera of the command line, framing `bounds` by default.
pub fn camera_for(args: &RenderArgs, bounds: &raycaster::geometry::Aabb) -> Result<Camera, Error> {
    let (width, height) = args.size;
    let mut camera = Camera::framing(bounds, width, height, args.fov);
    if let Some(p) = args.camera_pos {
        camera.position = p;
    }
    camera.target = args.look_at.unwrap_or(bounds.center());
    camera.up = args.up;
    camera.fov_y_deg = args.fov;
    if args.ortho {
        camera.projection = Projection::Orthographic;
    }
    if camera.frame().is_none() {
        return Err(format!(
            "camera is degenerate: position {} and look-at {} must differ, up {} must not be parallel to the view, fov {} must be in (0, 180)",
            camera.position, camera.target, camera.up, camera.fov_y_deg
        )
        .into());
    }
    Ok(camera)
}

/// One warm-up frame when repeating, then `repeat` timed frames.
fn render_repeated(
    r: &mut dyn Renderer,
    scene: &Scene,
    camera: &Camera,
    tf: &TransferFunction,
    options: &RenderOptions,
    repeat: u32,
) -> Result<(Frame, Vec<f64>), Error> {
    let mut last = r.render(scene, camera, tf, options)?;
    if repeat == 1 {
        let t = ms(last.stats.time);
        return Ok((last, vec![t]));
    }
    let mut times = Vec::with_capacity(repeat as usize);
    for _ in 0..repeat {
        last = r.render(scene, camera, tf, options)?;
        times.push(ms(last.stats.time));
    }
    Ok((last, times))
}

pub fn ms(d: std::time::Duration) -> f64 {
    (d.as_secs_f64() * 1e5).round() / 100.0
}
