//! `vol_app render`: open, render, time, save.

use std::time::Instant;

use raycaster::camera::{Camera, Projection};
use raycaster::prelude::*;
use raycaster::transfer::PRESET_NAMES;

use crate::anyhow_like::Error;
use crate::cli::RenderArgs;
use crate::stats::{RenderStats, median, peak_rss_mb, print_json};

/// Runs the `render` subcommand.
pub fn run(args: &RenderArgs) -> Result<(), Error> {
    if args.mode == RenderMode::Metaballs {
        return crate::metaballs_cmd::run(args);
    }
    let load_start = Instant::now();
    let mode = if args.in_ram {
        LoadMode::Ram
    } else {
        LoadMode::Map
    };
    let scene_options = crate::cli::scene_options(args.macrocell, args.no_cache);
    let scene = match &args.file {
        Some(path) => {
            let opened = Scene::open(path, &args.raw.open_options(mode), &scene_options)?;
            crate::cli::warn_all(&opened.cache.warnings);
            opened.scene
        }
        None => Scene::with_options(crate::demo::demo_volume(), &scene_options),
    };
    let sample_type = scene.volume().sample_type();
    let load_ms = ms(load_start.elapsed());

    let tf = match (&args.tf, &args.tf_preset) {
        (Some(path), _) => TransferFunction::from_json_file(path)?,
        (None, Some(name)) => {
            TransferFunction::preset_for_data(name, sample_type, scene.value_range()).ok_or_else(
                || {
                    format!(
                        "unknown transfer function preset '{name}' (known: {})",
                        PRESET_NAMES.join(", ")
                    )
                },
            )?
        }
        (None, None) => {
            let name = if args.file.is_some() {
                "ramp"
            } else {
                crate::demo::DEMO_TF
            };
            TransferFunction::preset(name, sample_type).ok_or("built-in preset missing")?
        }
    };

    let (width, height) = args.size;
    let camera = camera_for(args, &scene.grid().bounds())?;

    let (lo, hi) = scene.value_range();
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
        iso_normals: args.normals,
        background: args.background,
    };
    if let Some(s) = args.step
        && !(s.is_finite() && s > 0.0)
    {
        return Err(format!("--step {s} must be a finite number greater than 0").into());
    }
    if args.background.min_element() < 0.0 || args.background.max_element() > 1.0 {
        return Err("--background channels must be in 0..1".into());
    }

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
    if let Some(previews) = args.progressive {
        return crate::progressive_cmd::run(crate::progressive_cmd::Setup {
            renderer,
            scene: std::sync::Arc::new(scene),
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
