//! Helpers of the `vol_gen` integration tests: a temporary directory and
//! running the binary.

#![allow(dead_code)] // not every test binary uses every helper

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A directory removed when dropped.
pub struct TempDir(PathBuf);

impl TempDir {
    pub fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("vol_gen-test-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    pub fn path(&self, file: &str) -> PathBuf {
        self.0.join(file)
    }

    /// The names in the directory, sorted.
    pub fn entries(&self) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The `vol_gen` binary, with `RUST_BACKTRACE=1` as on the project's
/// machines (errors must stay one line even so).
pub fn vol_gen() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_vol_gen"));
    c.env("RUST_BACKTRACE", "1");
    c
}

/// `vol_gen ARGS`, whatever its exit code.
pub fn run(args: &[&str]) -> Output {
    vol_gen().args(args).output().unwrap()
}

/// `vol_gen ARGS`, expecting success.
pub fn run_ok(args: &[&str]) -> Output {
    let out = run(args);
    assert!(
        out.status.success(),
        "vol_gen {args:?} failed: {}",
        stderr(&out)
    );
    out
}

/// A command line written as text, around a path that may hold anything:
/// the words of `before`, `path`, the words of `after`.
pub fn args_around<'a>(before: &'a str, path: &'a Path, after: &'a str) -> Vec<&'a str> {
    let mut args: Vec<&str> = before.split_whitespace().collect();
    args.push(path.to_str().unwrap());
    args.extend(after.split_whitespace());
    args
}

/// What the run printed on stderr.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}
