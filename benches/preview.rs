//! Criterion benchmark of the viewer's preview frame: the built-in demo
//! volume (and the chest CT of `volumes/fetch_ct_examples.sh`, when it has
//! been fetched) at 1280×800, rendered on the renderer front as the viewer
//! does, at the preview level the viewer's picker
//! ([`vol_app::viewer::progressive`]) chooses on this machine after a few
//! timed frames, and at the first refinement level (¼ resolution, full step).
//!
//! Run with `cargo bench --bench preview`. The same frames, with the
//! refinement to full resolution, are timed by
//! `vol_app render [FILE] --size 1280x800 --renderer tiles --progressive 30`
//! (see the README).

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use raycaster::format::{OpenOptions, open_file};
use raycaster::prelude::*;
use raycaster::render::{FrameRequest, FrontEvent, FrontOptions};
use vol_app::viewer::progressive::{Level, Progressive, REFINEMENT};

const SIZE: [u32; 2] = [1280, 800];

/// Renders `request` at `level` on `front` and waits for it.
fn render(front: &RendererFront, request: &FrameRequest, level: Level) -> Frame {
    let id = front.request(FrameRequest {
        quality: level.quality(),
        ..request.clone()
    });
    loop {
        match front.events().recv_timeout(Duration::from_secs(600)) {
            Ok(FrontEvent::Ready { id: done, .. }) if done == id => {
                if let Some((got, frame)) = front.take_frame()
                    && got == id
                {
                    return frame;
                }
            }
            Ok(FrontEvent::Failed { error, .. }) => panic!("render failed: {error}"),
            Ok(_) => {}
            Err(e) => panic!("no frame: {e}"),
        }
    }
}

fn bench_volume(c: &mut Criterion, name: &str, volume: AnyVolume, tf_preset: &str) {
    let scene = Arc::new(Scene::new(volume));
    let tf = TransferFunction::preset_for_data(
        tf_preset,
        scene.volume().sample_type(),
        scene.value_range(),
    )
    .expect("preset");
    // The viewer's defaults: tiles renderer on all cores, half the smallest
    // spacing, ERT, ESS and shading on, the framing camera.
    let renderer = RendererKind::Tiles.renderer(0).expect("renderer");
    let front = RendererFront::spawn(renderer, scene.clone(), FrontOptions::default())
        .expect("renderer front");
    let request = FrameRequest {
        camera: Camera::framing(&scene.grid().bounds(), SIZE[0], SIZE[1], 45.0),
        tf: Arc::new(tf),
        options: RenderOptions::default(),
        quality: Level::FULL.quality(),
    };
    // Let the viewer's picker learn this machine's speed, as during a drag.
    let mut progressive = Progressive::default();
    let mut level = Level::FULL;
    for _ in 0..8 {
        let planned = progressive.next(true, true, SIZE).expect("a preview");
        level = planned.level;
        progressive.sent(0);
        let f = render(&front, &request, level);
        progressive.arrived(0, level, SIZE, f.stats.time);
    }
    let mut group = c.benchmark_group(format!("viewer {name} {}x{}", SIZE[0], SIZE[1]));
    group.sample_size(20);
    // A fixed name, so that runs compare; the level depends on the machine.
    eprintln!("viewer {name}: the picker chose {}", level.label());
    group.bench_function("preview", |b| b.iter(|| render(&front, &request, level)));
    group.bench_function("refinement 1/4 res", |b| {
        b.iter(|| render(&front, &request, REFINEMENT[0]))
    });
    group.finish();
}

fn preview(c: &mut Criterion) {
    bench_volume(c, "demo 160^3", vol_app::demo::demo_volume(), "shapes");
    let ct = Path::new(env!("CARGO_MANIFEST_DIR")).join("volumes/ct/chest_ct.nii.gz");
    match open_file(&ct, &OpenOptions::default()) {
        Ok(o) => bench_volume(c, "chest CT 512x512x133", o.volume, "ct-bone"),
        Err(_) => eprintln!(
            "SKIPPED: {} is missing; run volumes/fetch_ct_examples.sh",
            ct.display()
        ),
    }
}

criterion_group!(benches, preview);
criterion_main!(benches);
