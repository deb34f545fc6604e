//! The `--stats` JSON object of `vol_app render`.

use serde::Serialize;

/// Timings and counters of a `vol_app render` run.
#[derive(Debug, Serialize)]
pub struct RenderStats {
    pub width: u32,
    pub height: u32,
    pub renderer: String,
    pub threads: usize,
    pub frame_ms_median: f64,
    pub frame_ms: Vec<f64>,
    pub load_ms: f64,
    pub rays: u64,
    /// Rays that met the volume's box.
    pub rays_in_volume: u64,
    /// Rays that ended with some opacity (iso: hit the surface).
    pub covered: u64,
    pub samples: u64,
    pub peak_rss_mb: f64,
    /// --mode metaballs only.
    #[serde(flatten)]
    pub metaballs: Option<MetaballJson>,
}

/// The `--stats` fields of `--mode metaballs`.
#[derive(Debug, Serialize)]
pub struct MetaballJson {
    /// Balls made from the volume or the points file.
    pub balls: usize,
    /// Making them (ms; part of `load_ms`).
    pub build_ms: f64,
    /// Building the tile candidate lists, per frame (ms, median; part of
    /// `frame_ms`).
    pub lists_ms_median: f64,
    /// Entries in all candidate lists (last frame).
    pub list_entries: u64,
    /// With `--shadows on`: binning the balls for the shadow rays, per
    /// frame (ms, median; part of `frame_ms`).
    pub shadow_grid_ms_median: f64,
}

/// Prints `value` as one JSON line on stdout; a closed pipe (`| head`) is
/// the reader's choice, not an error.
pub fn print_json<T: Serialize>(value: &T) -> Result<(), crate::anyhow_like::Error> {
    print_text(&serde_json::to_string(value)?)
}

/// Prints `text` and a newline on stdout; a closed pipe (`| head`) is the
/// reader's choice, not an error.
pub fn print_text(text: &str) -> Result<(), crate::anyhow_like::Error> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = writeln!(out, "{text}")
        && e.kind() != std::io::ErrorKind::BrokenPipe
    {
        return Err(e.into());
    }
    Ok(())
}

/// Timings and counters of a `vol_app render --frames` run: frames
/// decoded ahead on another thread while the renderer draws.
#[derive(Debug, Serialize)]
pub struct PlayStats {
    pub width: u32,
    pub height: u32,
    pub renderer: String,
    pub threads: usize,
    pub frames: u32,
    pub first_frame: u32,
    /// Frames per second over the whole run (decoding overlapped).
    pub fps: f64,
    /// Reading and decoding one frame (on the decoder thread).
    pub decode_ms_median: f64,
    /// Building a frame's macrocell grid (on the decoder thread).
    pub build_ms_median: f64,
    pub render_ms_median: f64,
    /// Time the renderer waited for a frame to be decoded.
    pub wait_ms_median: f64,
    pub decode_ms: Vec<f64>,
    pub render_ms: Vec<f64>,
    pub load_ms: f64,
    pub rays: u64,
    pub samples: u64,
    pub peak_rss_mb: f64,
}

/// The median of `v` (mean of the middle two for an even count, rounded
/// to three decimals: the values are milliseconds to 0.01, and the mean's
/// binary rounding would print as `1.2349999999999999`).
pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        ((s[n / 2 - 1] + s[n / 2]) * 500.0).round() / 1000.0
    }
}

/// Peak resident set size of this process in MB (Linux `VmHWM`), 0 elsewhere.
pub fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<f64>().ok())
        })
        .map_or(0.0, |kb| kb / 1024.0)
}

#[cfg(test)]
mod tests {
    #[test]
    fn median_of_odd_and_even() {
        assert_eq!(super::median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(super::median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        // Printed as written, not as the nearest binary mean.
        let m = super::median(&[1.23, 1.24]);
        assert_eq!(serde_json::to_string(&m).unwrap(), "1.235");
    }
}
