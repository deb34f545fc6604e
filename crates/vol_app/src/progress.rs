//! A progress bar on stderr for the parts of opening that take time
//! (decoding a gzip NRRD or NIfTI or a DICOM series, building the macrocell
//! grid of a volume without its cache), drawn only when stderr is a
//! terminal.

use std::io::IsTerminal;
use std::sync::Arc;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use raycaster::format::Progress;

/// Steps of the bar.
const STEPS: u64 = 1000;

/// The library's progress callback driving a terminal bar labelled
/// `label`, or `None` when stderr is not a terminal (scripts, `--stats`
/// pipelines). The bar stays hidden for work that finishes within
/// indicatif's first redraw.
pub fn bar(label: &str) -> Option<Progress> {
    if !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = ProgressBar::with_draw_target(Some(STEPS), ProgressDrawTarget::stderr());
    let template = format!("{label} {{wide_bar}} {{percent}}% ETA {{eta}}");
    if let Ok(style) = ProgressStyle::with_template(&template) {
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
