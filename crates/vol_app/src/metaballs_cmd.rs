//! `vol_app render --mode metaballs`: balls from a volume or a points file,
//! rendered by the library's `MetaballRenderer`.

use std::time::Instant;

use raycaster::metaballs::{Balls, Extraction, MetaballOptions, MetaballRenderer};
use raycaster::prelude::*;
use raycaster::transfer::PRESET_NAMES;

use crate::anyhow_like::Error;
use crate::cli::RenderArgs;
use crate::render_cmd::{camera_for, ms};
use crate::stats::{MetaballJson, RenderStats, median, peak_rss_mb, print_json};

/// Runs `vol_app render --mode metaballs`.
pub fn run(args: &RenderArgs) -> Result<(), Error> {
    if args.progressive.is_some() {
        return Err("--progressive is not available with --mode metaballs".into());
    }
    if !(args.field_threshold.is_finite() && args.field_threshold > 0.0) {
        return Err(format!(
            "--field-threshold {} must be a finite number greater than 0",
            args.field_threshold
        )
        .into());
    }
    if let Some(r) = args.ball_radius
        && !(r.is_finite() && r > 0.0)
    {
        return Err(format!("--ball-radius {r} must be a finite number greater than 0").into());
    }
    if args.background.min_element() < 0.0 || args.background.max_element() > 1.0 {
        return Err("--background channels must be in 0..1".into());
    }
    let cap = (args.max_balls > 0).then_some(args.max_balls);

    let load_start = Instant::now();
    let points = args.file.as_deref().filter(|p| Balls::is_points_file(p));
    // The balls, the box the default camera frames, the data's sample type
    // and value range (for TF presets).
    let (balls, bounds, sample_type, range, build_ms) = match points {
        Some(path) => {
            let start = Instant::now();
            let balls = Balls::read_points(path, args.ball_radius, cap)?;
            let build_ms = ms(start.elapsed());
            let bounds = balls
                .bounds()
                .ok_or_else(|| format!("{}: no balls in the file", path.display()))?;
            let range = balls
                .as_slice()
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), b| {
                    (lo.min(b.value), hi.max(b.value))
                });
            (balls, bounds, SampleType::F32, range, build_ms)
        }
        None => {
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
            let (lo, hi) = scene.value_range();
            let ex = Extraction {
                threshold: args.ball_threshold.unwrap_or(lo + 0.3 * (hi - lo)),
                stride: args.ball_stride,
                radius: args.ball_radius,
                max_balls: cap,
            };
            let start = Instant::now();
            let balls = Balls::from_volume(scene.volume(), &ex)?;
            let build_ms = ms(start.elapsed());
            let bounds = scene.grid().bounds();
            (
                balls,
                bounds,
                scene.volume().sample_type(),
                (lo, hi),
                build_ms,
            )
        }
    };
    let load_ms = ms(load_start.elapsed());

    let tf = match (&args.tf, &args.tf_preset) {
        (Some(path), _) => Some(TransferFunction::from_json_file(path)?),
        (None, Some(name)) => Some(
            TransferFunction::preset_for_data(name, sample_type, range).ok_or_else(|| {
                format!(
                    "unknown transfer function preset '{name}' (known: {})",
                    PRESET_NAMES.join(", ")
                )
            })?,
        ),
        (None, None) => None,
    };
    let camera = camera_for(args, &bounds)?;
    let options = MetaballOptions {
        kernel: args.kernel,
        field_threshold: args.field_threshold,
        shading: args.shading.on(),
        phong: None,
        lights: args.lights.clone(),
        background: args.background,
        shadows: args.shadows.on(),
    };
    let mut renderer = MetaballRenderer::new(args.renderer, args.threads as usize)?;
    let mut last = renderer.render(&balls, &camera, tf.as_ref(), &options)?;
    let mut times = vec![ms(last.0.stats.time)];
    let mut lists = vec![ms(last.1.lists)];
    let mut grids = vec![ms(last.1.shadow_grid)];
    if args.repeat > 1 {
        times.clear();
        lists.clear();
        grids.clear();
        for _ in 0..args.repeat {
            last = renderer.render(&balls, &camera, tf.as_ref(), &options)?;
            times.push(ms(last.0.stats.time));
            lists.push(ms(last.1.lists));
            grids.push(ms(last.1.shadow_grid));
        }
    }
    let (frame, mstats) = last;

    let out = match (&args.out, args.stats) {
        (Some(p), _) => Some(p.clone()),
        (None, false) => Some("out.png".into()),
        (None, true) => None,
    };
    if let Some(path) = &out {
        frame.save_png(path)?;
    }
    if args.stats {
        print_json(&RenderStats {
            width: frame.width,
            height: frame.height,
            renderer: renderer.name().to_string(),
            threads: renderer.threads(),
            frame_ms_median: median(&times),
            frame_ms: times,
            load_ms,
            rays: frame.stats.rays,
            rays_in_volume: frame.stats.rays_in_volume,
            covered: frame.stats.covered,
            samples: frame.stats.samples,
            peak_rss_mb: peak_rss_mb(),
            metaballs: Some(MetaballJson {
                balls: balls.len(),
                build_ms,
                lists_ms_median: median(&lists),
                list_entries: mstats.list_entries,
                shadow_grid_ms_median: median(&grids),
            }),
        })?;
    } else if let Some(path) = &out {
        eprintln!(
            "vol_app: wrote {} ({}x{}, {} balls, {:.1} ms)",
            path.display(),
            frame.width,
            frame.height,
            balls.len(),
            ms(frame.stats.time),
        );
    }
    Ok(())
}
