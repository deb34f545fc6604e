//! Writing a file so that it appears under its name only when complete: the
//! bytes go to a temporary file in the same directory (same file system, so
//! the final rename is atomic), which is synced and then renamed. Every
//! writer of the library (`.vol`, NRRD, NIfTI, raw) and the generator's
//! `.vol` writer go through here, so a reader never sees a partial file and
//! a failed write leaves nothing behind.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Runs `fill` on a buffered writer to a temporary file next to `path`, then
/// renames it to `path`. On any error the temporary file is removed and the
/// error names `path`.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    write_via_temporary(path, true, fill)
}

/// As [`write_atomically`] without syncing the data to the disk before the
/// rename: for files that a reader checks on its own and can rebuild (the
/// macrocell cache, whose checksum catches what a crash may leave), where
/// waiting for the disk would only slow the program down.
pub fn write_atomically_unsynced(
    path: &Path,
    fill: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    write_via_temporary(path, false, fill)
}

fn write_via_temporary(
    path: &Path,
    sync: bool,
    fill: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    let tmp = temp_path_for(path);
    let result = (|| {
        let f = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
        fill(&mut w)?;
        w.flush()?;
        if sync {
            w.get_ref().sync_data()?;
        }
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

/// The temporary name used while writing `path`: `.NAME.partial-PID` in the
/// same directory (hidden, and unique per process so that two programs
/// writing the same name do not share a temporary file).
fn temp_path_for(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.partial-{}", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_write_leaves_neither_file() {
        let dir = std::env::temp_dir().join(format!("rc-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("out.bin");
        let e = write_atomically(&path, |w| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(e.to_string().contains("out.bin"), "{e}");
        assert!(!path.exists() && !temp_path_for(&path).exists());
        write_atomically(&path, |w| w.write_all(b"whole")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"whole");
        assert!(!temp_path_for(&path).exists());
        std::fs::remove_dir_all(&dir).ok();
    }
}
