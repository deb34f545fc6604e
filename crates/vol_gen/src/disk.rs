//! Free disk space, checked before writing so a run that cannot finish does
//! not start.

use std::path::Path;

/// Bytes available to an unprivileged user on the file system holding `dir`,
/// or `None` when the system cannot tell.
pub fn available_bytes(dir: &Path) -> Option<u64> {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let c_path = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
        // SAFETY: `statvfs` writes into the zero-initialised struct we own and
        // reads the NUL-terminated path that lives until the call returns.
        let stats = unsafe {
            let mut stats: libc::statvfs = std::mem::zeroed();
            if libc::statvfs(c_path.as_ptr(), &mut stats) != 0 {
                return None;
            }
            stats
        };
        #[allow(clippy::unnecessary_cast)] // the field types differ between platforms
        Some((stats.f_bavail as u64).saturating_mul(stats.f_frsize as u64))
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        None
    }
}

/// `bytes` in decimal units with one decimal (`9.8 GB`), as disk sizes are sold.
pub fn human(bytes: u64) -> String {
    const UNITS: [&str; 6] = ["B", "kB", "MB", "GB", "TB", "PB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1000.0 && unit + 1 < UNITS.len() {
        value /= 1000.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn human_sizes() {
        assert_eq!(human(26), "26 B");
        assert_eq!(human(9_800_000_000), "9.8 GB");
        assert_eq!(human(512_000_026), "512.0 MB");
    }

    #[test]
    fn the_current_directory_has_some_space() {
        assert!(available_bytes(Path::new(".")).is_some());
    }
}
