//! The progress bar: bytes written (voxels, frames), rate and ETA on stderr, hidden when stderr
//! is not a terminal or with `--quiet`.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Progress of one volume being written.
pub struct Progress {
    bar: ProgressBar,
}

impl Progress {
    /// A bar for `total` bytes; drawn only when `visible` and stderr is a terminal.
    pub fn new(total: u64, visible: bool) -> Self {
        Self::with_template(
            total,
            visible,
            "{spinner} [{elapsed_precise}] {wide_bar} {bytes}/{total_bytes} {bytes_per_sec} ETA {eta}",
        )
    }

    /// A bar for `total` voxels computed (the mesh SDF, which is computed
    /// before it is written).
    pub fn voxels(total: u64, visible: bool) -> Self {
        Self::with_template(
            total,
            visible,
            "{spinner} [{elapsed_precise}] {wide_bar} {human_pos}/{human_len} voxels {per_sec} ETA {eta}",
        )
    }

    /// A bar for `total` frames of a time series (`--generator plume`).
    pub fn frames(total: u64, visible: bool) -> Self {
        Self::with_template(
            total,
            visible,
            "{spinner} [{elapsed_precise}] {wide_bar} {human_pos}/{human_len} frames {per_sec} ETA {eta}",
        )
    }

    fn with_template(total: u64, visible: bool, template: &str) -> Self {
        let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::hidden());
        if visible && std::io::stderr().is_terminal() {
            bar.set_draw_target(ProgressDrawTarget::stderr());
            if let Ok(style) = ProgressStyle::with_template(template) {
                bar.set_style(style);
            }
        }
        Progress { bar }
    }

    /// A bar that never draws.
    pub fn hidden() -> Self {
        Progress::new(0, false)
    }

    /// Records `bytes` more written (voxels for [`Progress::voxels`]).
    pub fn advance(&self, bytes: u64) {
        self.bar.inc(bytes);
    }

    /// Removes the bar from the terminal.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
