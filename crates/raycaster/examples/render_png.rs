//! Opens a volume file and writes a PNG: the smallest complete program.
//!
//! ```text
//! cargo run --release -p raycaster --example render_png -- VOLUME.vol out.png [TF_PRESET]
//! ```

use raycaster::prelude::*;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: render_png VOLUME.vol OUT.png [shapes|skull|ramp|...]");
        std::process::exit(2);
    }
    if let Err(e) = run(
        &args[0],
        &args[1],
        args.get(2).map_or("ramp", String::as_str),
    ) {
        eprintln!("render_png: {e}");
        std::process::exit(1);
    }
}

fn run(input: &str, output: &str, preset: &str) -> Result<(), raycaster::Error> {
    // Map the file (no copy); build the empty-space-skipping data once, or
    // read it from the file's macrocell cache when an earlier run wrote one.
    let opened = Scene::open(input.as_ref(), &Default::default(), &Default::default())?;
    for warning in &opened.cache.warnings {
        eprintln!("render_png: warning: {warning}");
    }
    let scene = opened.scene;
    let tf = TransferFunction::preset(preset, scene.volume().sample_type())
        .ok_or_else(|| raycaster::Error::option("tf-preset", format!("unknown preset {preset}")))?;
    // A camera that frames the whole volume from the +z side.
    let camera = Camera::framing(&scene.grid().bounds(), 512, 512, 45.0);
    // All cores, 16-pixel tiles.
    let mut renderer = TiledRenderer::new(0, 16)?;
    let frame = renderer.render(&scene, &camera, &tf, &RenderOptions::default())?;
    frame.save_png(output.as_ref())?;
    println!(
        "{output}: {} rays, {} samples, {:.1} ms",
        frame.stats.rays,
        frame.stats.samples,
        frame.stats.time.as_secs_f64() * 1e3
    );
    Ok(())
}
