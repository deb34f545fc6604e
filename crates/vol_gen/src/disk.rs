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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_current_directory_has_some_space() {
        assert!(available_bytes(Path::new(".")).is_some());
    }
}
