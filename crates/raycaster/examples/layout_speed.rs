//! Measures whether a volume in RAM renders faster bricked than in its
//! file's linear order: opens a file, makes a bricked copy (B = 16) in RAM,
//! renders both with the serial and the object renderer from three
//! directions and prints the median frame times.
//!
//! ```text
//! cargo run --release -p raycaster --example layout_speed -- VOLUME [TF_PRESET] [REPEAT]
//! ```

use std::time::Instant;

use glam::Vec3;
use raycaster::prelude::*;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        eprintln!("usage: layout_speed VOLUME [TF_PRESET] [REPEAT]");
        std::process::exit(2);
    };
    let preset = args.get(1).map_or("mr-default", String::as_str);
    let repeat: usize = args.get(2).and_then(|r| r.parse().ok()).unwrap_or(5);
    if let Err(e) = run(path, preset, repeat) {
        eprintln!("layout_speed: {e}");
        std::process::exit(1);
    }
}

fn run(path: &str, preset: &str, repeat: usize) -> Result<(), raycaster::Error> {
    let options = raycaster::format::OpenOptions {
        mode: LoadMode::Ram,
        ..Default::default()
    };
    let linear = raycaster::format::open_file(path.as_ref(), &options)?.volume;
    let bricked = linear.with_layout(Layout::Bricked { side: 16 })?;
    let t = linear.sample_type();
    for (name, volume) in [("linear", linear), ("bricked16", bricked)] {
        let scene = Scene::new(volume);
        let tf =
            TransferFunction::preset_for_data(preset, t, scene.value_range()).ok_or_else(|| {
                raycaster::Error::option("tf-preset", format!("unknown preset {preset}"))
            })?;
        let bounds = scene.grid().bounds();
        let c = bounds.center();
        let r = (bounds.max - bounds.min).length() * 1.2;
        for (view, dir) in [
            ("x", Vec3::X),
            ("y", Vec3::Y),
            ("diag", Vec3::ONE.normalize()),
        ] {
            let mut camera = Camera::framing(&bounds, 512, 512, 45.0);
            camera.position = c + dir * r;
            camera.target = c;
            camera.up = if view == "y" { Vec3::Z } else { Vec3::Y };
            for kind in [RendererKind::Serial, RendererKind::Object] {
                let mut renderer = kind.renderer(0)?;
                let opts = RenderOptions::default();
                renderer.render(&scene, &camera, &tf, &opts)?;
                let mut ms: Vec<f64> = (0..repeat)
                    .map(|_| {
                        let t0 = Instant::now();
                        let _ = renderer.render(&scene, &camera, &tf, &opts);
                        t0.elapsed().as_secs_f64() * 1e3
                    })
                    .collect();
                ms.sort_by(f64::total_cmp);
                println!(
                    "{name:10} {view:5} {:7} {:8.1} ms",
                    format!("{kind:?}"),
                    ms[ms.len() / 2]
                );
            }
        }
    }
    Ok(())
}
