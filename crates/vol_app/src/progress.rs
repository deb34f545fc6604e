//! A progress bar on stderr for decodes that take time (a gzip NRRD or
//! NIfTI, a DICOM series), drawn only when stderr is a terminal.

use std::io::IsTerminal;
use std::sync::Arc;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use raycaster::format::Progress;

/// Percent steps of the decode.
const STEPS: u64 = 1000;

/// The library's progress callback driving a terminal bar, or `None` when
/// stderr is not a terminal (scripts, `--stats` pipelines). The bar stays
/// hidden for decodes that finish within indicatif's first redraw.
pub fn decode_bar() -> Option<Progress> {
    if !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = ProgressBar::with_draw_target(Some(STEPS), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template("decoding {wide_bar} {percent}% ETA {eta}") {
        bar.set_style(style);
    }
    let bar = Arc::new(bar);
    Some(Progress::new(move |f| {
        bar.set_position((f * STEPS as f32) as u64);
        if f >= 1.0 {
            bar.finish_and_clear();
        }
    }))
}
