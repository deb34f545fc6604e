//! Replays the fuzz targets' inputs through the fuzz harness itself
//! (`fuzz/src/harness.rs`, compiled here too) on stable, in the normal
//! suite: every seed of `fuzz/seeds/<target>/` must open and render, and
//! every input kept in `fuzz/regressions/<target>/` (a crash, hang or
//! runaway allocation that fuzzing found, minimised, and since fixed) must
//! be handled — opened or refused — within a deadline, without a panic.

#[path = "../fuzz/src/harness.rs"]
#[allow(dead_code)]
mod harness;

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use harness::Target;

/// Far longer than any input takes; the hangs fuzzing found never ended.
const DEADLINE: Duration = Duration::from_secs(60);

fn inputs(kind: &str, target: Target) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz")
        .join(kind)
        .join(target.name());
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    files.retain(|p| p.is_file() && p.file_name().is_none_or(|n| n != "README.md"));
    files.sort();
    files
}

/// Runs `path` through `target` on a thread; `Err` on a panic or a
/// missed deadline, else whether it opened.
fn replay(target: Target, path: &Path) -> Result<bool, String> {
    let data = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let outcome = std::panic::catch_unwind(|| harness::run(target, &data));
        let _ = tx.send(outcome);
    });
    match rx.recv_timeout(DEADLINE) {
        Ok(Ok(opened)) => Ok(opened),
        Ok(Err(_)) => Err(format!("{}: panicked", path.display())),
        Err(_) => Err(format!("{}: not done in {DEADLINE:?}", path.display())),
    }
}

#[test]
fn every_seed_opens_and_renders() {
    let mut failures = Vec::new();
    for target in Target::ALL {
        let seeds = inputs("seeds", target);
        if seeds.is_empty() {
            failures.push(format!("{}: no seeds", target.name()));
        }
        for path in seeds {
            match replay(target, &path) {
                Ok(true) => {}
                Ok(false) => failures.push(format!("{}: refused", path.display())),
                Err(e) => failures.push(e),
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn every_fuzz_finding_is_handled() {
    let mut failures = Vec::new();
    for target in Target::ALL {
        for path in inputs("regressions", target) {
            if let Err(e) = replay(target, &path) {
                failures.push(e);
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
