//! The CPU cost of sort-last compositing per pixel, one thread, no
//! network: the constants of the README's scaling model (section
//! "Distributed rendering (MPI)").
//!
//!   cargo run --release -p raycaster --example composite_cost [-- WIDTHxHEIGHT [REPEATS]]
//!
//! Times, for DVR fragments over a whole frame (default 1920x1080):
//! encoding a partial image for the wire and decoding it (per pixel),
//! merging one fragment into an accumulator (`Compositor::merge_over` with
//! two parts, per pixel and part), resolving a merged fragment to RGB8 over
//! the background (`resolve_rect`), and cropping (`PartialImage::crop`).
//! Prints the median of REPEATS (default 7) as ns per pixel.

use std::time::{Duration, Instant};

use glam::Vec3;
use raycaster::camera::PixelRect;
use raycaster::distributed::{Compositor, Fragment, PartialImage};
use raycaster::prelude::*;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (w, h) = args
        .get(1)
        .and_then(|s| s.split_once('x'))
        .map(|(a, b)| (a.parse().unwrap(), b.parse().unwrap()))
        .unwrap_or((1920u32, 1080u32));
    let repeats: usize = args.get(2).map_or(7, |s| s.parse().unwrap());
    let px = f64::from(w) * f64::from(h);
    let rect = PixelRect {
        x0: 0,
        y0: 0,
        x1: w,
        y1: h,
    };
    let mut rng = fastrand::Rng::with_seed(1);
    let image = |rng: &mut fastrand::Rng| PartialImage {
        width: w,
        height: h,
        rect,
        fragments: (0..px as usize)
            .map(|_| {
                let a = rng.f32() * 0.9;
                Fragment {
                    rgba: (Vec3::new(rng.f32(), rng.f32(), rng.f32()) * a).extend(a),
                    value: 0.0,
                    count: 0,
                }
            })
            .collect(),
        samples: 0,
        time: Duration::ZERO,
    };
    let (front, back) = (image(&mut rng), image(&mut rng));
    let compositor = Compositor {
        mode: RenderMode::Dvr,
        tf: TransferFunction::preset("ramp", raycaster::sample::SampleType::U8).unwrap(),
        ert: Some(0.99),
        avg_norm: 255.0,
        background: Vec3::splat(0.1),
    };
    let ns = |f: &mut dyn FnMut()| -> f64 {
        median(
            (0..repeats)
                .map(|_| {
                    let t = Instant::now();
                    f();
                    t.elapsed().as_secs_f64() * 1e9 / px
                })
                .collect(),
        )
    };
    let mut sink = 0usize;
    let encode = ns(&mut || sink += front.encode().len());
    let floats = front.encode();
    let decode = ns(&mut || sink += PartialImage::decode(&floats).unwrap().fragments.len());
    let crop_rect = PixelRect {
        x0: 1,
        y0: 1,
        x1: w - 1,
        y1: h - 1,
    };
    let crop = ns(&mut || sink += front.crop(&crop_rect).fragments.len());
    // Two parts merged: the first into empty fragments, the second with
    // "over"; per part.
    let merge = ns(&mut || {
        sink += compositor
            .merge_over(rect, w, h, [&front, &back])
            .unwrap()
            .fragments
            .len()
    }) / 2.0;
    let merged = compositor.merge_over(rect, w, h, [&front, &back]).unwrap();
    let resolve = ns(&mut || sink += compositor.resolve_rect(&merged, rect).len());
    println!(
        "{{\"width\":{w},\"height\":{h},\"repeats\":{repeats},\"ns_per_pixel\":{{\"encode\":{encode:.2},\"decode\":{decode:.2},\"crop\":{crop:.2},\"merge_per_part\":{merge:.2},\"resolve\":{resolve:.2}}},\"sink\":{sink}}}"
    );
}
