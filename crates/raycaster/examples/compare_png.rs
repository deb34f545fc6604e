//! Compares two PNG images of the same size: prints the largest channel
//! difference, the PSNR and how many pixels differ, and exits 1 when the
//! PSNR is below `--min-psnr` (default 50 dB) or a channel differs by more
//! than `--max-diff` (default 255: no limit). `scripts/mpi_test.sh` uses it
//! to hold distributed renders to the single-process image.
//!
//! ```text
//! cargo run --release -p raycaster --example compare_png -- A.png B.png [--min-psnr DB] [--max-diff N]
//! ```

fn load(path: &str) -> Result<image::RgbImage, String> {
    image::open(path)
        .map(|i| i.to_rgb8())
        .map_err(|e| format!("{path}: {e}"))
}

fn run() -> Result<bool, String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: compare_png A.png B.png [--min-psnr DB] [--max-diff N]";
    if args.len() < 2 {
        return Err(usage.into());
    }
    let (mut min_psnr, mut max_diff) = (50.0f64, 255u8);
    let mut rest = args[2..].iter();
    while let Some(flag) = rest.next() {
        let value = rest.next().ok_or(usage)?;
        match flag.as_str() {
            "--min-psnr" => min_psnr = value.parse().map_err(|_| format!("--min-psnr {value}"))?,
            "--max-diff" => max_diff = value.parse().map_err(|_| format!("--max-diff {value}"))?,
            _ => return Err(usage.into()),
        }
    }
    let (a, b) = (load(&args[0])?, load(&args[1])?);
    if a.dimensions() != b.dimensions() {
        return Err(format!(
            "{} is {:?}, {} is {:?}",
            args[0],
            a.dimensions(),
            args[1],
            b.dimensions()
        ));
    }
    let (mut max, mut se, mut differing) = (0u8, 0f64, 0usize);
    for (p, q) in a.pixels().zip(b.pixels()) {
        let d =
            p.0.iter()
                .zip(q.0)
                .map(|(&x, y)| x.abs_diff(y))
                .max()
                .unwrap_or(0);
        max = max.max(d);
        differing += usize::from(d > 0);
        se +=
            p.0.iter()
                .zip(q.0)
                .map(|(&x, y)| f64::from(x.abs_diff(y)).powi(2))
                .sum::<f64>();
    }
    let mse = se / (3 * a.pixels().len()) as f64;
    let psnr = if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    };
    let ok = psnr >= min_psnr && max <= max_diff;
    println!(
        "{} vs {}: max diff {max}, PSNR {psnr:.1} dB, {differing} of {} pixels differ: {}",
        args[0],
        args[1],
        a.pixels().len(),
        if ok { "ok" } else { "FAILED" }
    );
    Ok(ok)
}

fn main() {
    match run() {
        Ok(true) => {}
        Ok(false) => std::process::exit(1),
        Err(e) => {
            eprintln!("compare_png: {e}");
            std::process::exit(2);
        }
    }
}
