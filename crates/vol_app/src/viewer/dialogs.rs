//! Native file dialogs (`rfd`, through the XDG desktop portal on Linux), run
//! on a thread of their own so the window keeps repainting while one is
//! open. One dialog at a time; the answer is polled by the UI.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, Sender};

use super::loading::VOLUME_EXTENSIONS;

/// What a dialog's answer is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Purpose {
    /// Pick a volume file to open.
    OpenVolume,
    /// Pick a directory (a DICOM series) to open.
    OpenFolder,
    /// Pick a TF JSON file to load.
    LoadTf,
    /// Choose where to save the TF as JSON.
    SaveTf,
    /// Choose where to save the current frame as PNG.
    SavePng,
    /// Choose the GIF a turntable export writes.
    ExportTurntable,
}

/// The dialog runner.
#[derive(Debug)]
pub struct Dialogs {
    tx: Sender<(Purpose, Option<PathBuf>)>,
    rx: Receiver<(Purpose, Option<PathBuf>)>,
    open: bool,
    opened_at: Option<Instant>,
}

/// A dialog answered faster than this without a file most likely never
/// appeared (no desktop portal).
const TOO_FAST: Duration = Duration::from_millis(400);

/// How a dialog ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Answer {
    /// The user chose a file.
    Chosen(PathBuf),
    /// The user cancelled.
    Cancelled,
    /// No dialog could be shown (it closed at once without a file).
    Unavailable,
}

impl Default for Dialogs {
    fn default() -> Self {
        let (tx, rx) = crossbeam_channel::unbounded();
        Dialogs {
            tx,
            rx,
            open: false,
            opened_at: None,
        }
    }
}

impl Dialogs {
    /// True while a dialog is showing.
    pub fn is_open(&self) -> bool {
        self.open
    }

    /// Shows a dialog for `purpose` starting in `dir`; `wake` is called when
    /// it closes. Does nothing while another dialog is open.
    pub fn show(
        &mut self,
        purpose: Purpose,
        dir: Option<PathBuf>,
        wake: impl Fn() + Send + 'static,
    ) {
        if self.open {
            return;
        }
        let tx = self.tx.clone();
        let spawned = std::thread::Builder::new()
            .name("vol_app-dialog".into())
            .spawn(move || {
                let mut d = rfd::FileDialog::new();
                if let Some(dir) = dir {
                    d = d.set_directory(dir);
                }
                let path = match purpose {
                    Purpose::OpenVolume => d
                        .set_title("Open volume")
                        .add_filter("Volumes", VOLUME_EXTENSIONS)
                        .add_filter("All files", &["*"])
                        .pick_file(),
                    Purpose::OpenFolder => d
                        .set_title(
                            "Open a DICOM series, a folder of frames or a folder holding one scan",
                        )
                        .pick_folder(),
                    Purpose::LoadTf => d
                        .set_title("Load transfer function")
                        .add_filter("Transfer function (JSON)", &["json"])
                        .pick_file(),
                    Purpose::SaveTf => d
                        .set_title("Save transfer function")
                        .add_filter("Transfer function (JSON)", &["json"])
                        .set_file_name("transfer_function.json")
                        .save_file(),
                    Purpose::SavePng => d
                        .set_title("Save frame")
                        .add_filter("PNG image", &["png"])
                        .set_file_name("frame.png")
                        .save_file(),
                    Purpose::ExportTurntable => d
                        .set_title("Export turntable")
                        .add_filter("Animated GIF", &["gif"])
                        .set_file_name("turntable.gif")
                        .save_file(),
                };
                let _ = tx.send((purpose, path));
                wake();
            });
        self.open = spawned.is_ok();
        self.opened_at = Some(Instant::now());
    }

    /// The answer of the dialog that closed, if one did.
    pub fn poll(&mut self) -> Option<(Purpose, Answer)> {
        let (purpose, path) = self.rx.try_recv().ok()?;
        self.open = false;
        let fast = self
            .opened_at
            .take()
            .is_some_and(|t| t.elapsed() < TOO_FAST);
        Some((
            purpose,
            match path {
                Some(p) => Answer::Chosen(p),
                None if fast => Answer::Unavailable,
                None => Answer::Cancelled,
            },
        ))
    }
}
