//! Measures how long a `.vseq` file takes to decode, frame by frame: every
//! frame in order (what playback does), then the same frames in a shuffled
//! order (random access: a difference frame then decodes from its key
//! frame), printing the median and the slowest time of each, and the size
//! of a frame in memory.
//!
//! ```text
//! cargo run --release -p raycaster --example vseq_decode -- FILE.vseq [ROUNDS]
//! ```

use std::time::Instant;

use raycaster::format::vseq::VseqFile;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        eprintln!("usage: vseq_decode FILE.vseq [ROUNDS]");
        std::process::exit(2);
    };
    let rounds: usize = args.get(1).and_then(|r| r.parse().ok()).unwrap_or(2);
    if let Err(e) = run(path, rounds) {
        eprintln!("vseq_decode: {e}");
        std::process::exit(1);
    }
}

fn run(path: &str, rounds: usize) -> Result<(), raycaster::Error> {
    let mut rng = fastrand::Rng::with_seed(1);
    let mut sequential = Vec::new();
    let mut random = Vec::new();
    let mut bytes = 0;
    for _ in 0..rounds {
        // A fresh file each round: no frame kept from the last round.
        let file = VseqFile::open(path.as_ref())?;
        let n = file.frames();
        for k in 0..n {
            let t = Instant::now();
            let v = file.frame(k)?;
            sequential.push(t.elapsed().as_secs_f64() * 1e3);
            bytes = v.memory_bytes();
        }
        let file = VseqFile::open(path.as_ref())?;
        let mut order: Vec<u32> = (0..n).collect();
        rng.shuffle(&mut order);
        for k in order {
            let t = Instant::now();
            file.frame(k)?;
            random.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    let h = VseqFile::open(path.as_ref())?;
    let h = h.header();
    println!(
        "{{\"file\":\"{path}\",\"codec\":\"{}\",\"f16\":{},\"key_interval\":{},\"frame_bytes\":{bytes},\"threads\":{},\"sequential_ms_median\":{:.3},\"sequential_ms_max\":{:.3},\"random_ms_median\":{:.3},\"random_ms_max\":{:.3}}}",
        h.codec,
        h.stored == raycaster::format::vseq::StoredAs::F16,
        h.key_interval,
        rayon::current_num_threads(),
        median(&mut sequential),
        max(&sequential),
        median(&mut random),
        max(&random),
    );
    Ok(())
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}
