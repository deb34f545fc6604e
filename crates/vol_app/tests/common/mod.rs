//! Helpers shared by the `vol_app` integration tests: temporary
//! directories, test volumes, running the binary and checking its errors.

#![allow(dead_code)] // each test binary uses its own part

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use glam::{UVec3, Vec3};
use raycaster::format::vol::{self, VolLayout};
use raycaster::volume::{AnyVolume, Grid};

/// A temporary directory, removed at the end of the test. Named after the
/// test binary, the tag and the process, so tests running at the same time
/// never share one.
pub struct TempDir(PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> Self {
        let p = std::env::temp_dir().join(format!(
            "vol_app_{}_{tag}_{}",
            env!("CARGO_CRATE_NAME"),
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Writes `bytes` to the file `name` in the directory; its path.
    pub fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.path(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Writes a `.vol` file `name` in `dir` of `dims` voxels (unit spacing),
/// each voxel's value given by its distance from the volume's centre.
pub fn radial_vol_file(
    dir: &TempDir,
    name: &str,
    dims: UVec3,
    layout: VolLayout,
    value_at: impl Fn(f32) -> u8,
) -> PathBuf {
    let c = (dims.as_vec3() - 1.0) * 0.5;
    let v = AnyVolume::from_fn(Grid::new(dims, Vec3::ONE), |p| {
        value_at((p.as_vec3() - c).length())
    });
    let path = dir.path(name);
    vol::write(&path, &v, layout).unwrap();
    path
}

/// The `vol_app` binary, with `RUST_BACKTRACE=1` as on the project's
/// machines (errors must stay one line even so).
pub fn vol_app() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_vol_app"));
    c.env("RUST_BACKTRACE", "1");
    c
}

/// `vol_app SUBCOMMAND FILE`, more arguments to be added.
pub fn vol_app_on(subcommand: &str, file: &Path) -> Command {
    let mut c = vol_app();
    c.arg(subcommand).arg(file);
    c
}

/// Runs `cmd` and returns what it printed, whatever its exit code.
pub fn output(cmd: &mut Command) -> Output {
    cmd.output().unwrap()
}

/// Runs `cmd`, expecting it to succeed.
pub fn run_ok(cmd: &mut Command) -> Output {
    let out = output(cmd);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The run failed with one line on stderr, `vol_app: error: ...`, no panic
/// or backtrace, holding `needle`.
pub fn assert_one_line_error(out: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure, stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    assert!(
        err.starts_with("vol_app: error: "),
        "not an error line: {err}"
    );
    assert!(!err.contains("panicked"), "panic: {err}");
    assert!(!err.contains("stack backtrace"), "backtrace: {err}");
    assert!(err.contains(needle), "'{needle}' not in: {err}");
}
