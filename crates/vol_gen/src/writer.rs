//! Writing a volume: batches are computed on all cores while the previous
//! ones are written, in file order, in large sequential writes.
//!
//! The file goes through the library's [`write_atomically`]: it is written
//! under a temporary name in the same directory, synced, and renamed only when
//! complete. An I/O error, a panic or SIGINT/SIGTERM (checked between batches)
//! makes the write fail, and the temporary file is removed.
//!
//! After each batch the kernel is asked to start writing it to disk
//! (`sync_file_range` on Linux), so the disk works while later batches are
//! generated, the final sync has little left to do, and a 10 GB volume does
//! not fill the page cache with dirty pages.

use std::fs::File;
use std::io::{self, BufWriter, Seek, Write};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use raycaster::format::atomic::write_atomically;
use raycaster::format::vol::VolHeader;

use crate::error::{Error, Result};
use crate::generators::Field;
use crate::order::Plan;
use crate::progress::Progress;
use crate::signal;

/// Batches computed ahead of the one being written.
const AHEAD: usize = 2;

/// Writes the volume `field` to `path` with `header`, in the order of `plan`.
pub fn write_volume(
    path: &Path,
    header: &VolHeader,
    plan: &Plan,
    field: &dyn Field,
    progress: &Progress,
) -> Result<()> {
    let result = write_atomically(path, |w| {
        w.write_all(&header.to_bytes())?;
        progress.advance(header.to_bytes().len() as u64);
        // A panic while generating must not skip the temporary file's removal.
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            stream(w, plan, field, progress)
        }))
        .unwrap_or_else(|_| Err(io::Error::other("internal error while generating samples")))
    });
    match result {
        Ok(()) => Ok(()),
        Err(_) if signal::interrupted() => Err(Error::Interrupted),
        Err(e) => Err(e.into()),
    }
}

/// Computes the batches of `plan` on a producer thread (which spreads each
/// batch over rayon's pool) and writes them to `w` in order.
pub fn stream(
    w: &mut BufWriter<File>,
    plan: &Plan,
    field: &dyn Field,
    progress: &Progress,
) -> io::Result<()> {
    // Bytes already handed to the kernel (the header may still be buffered).
    let mut offset = 0u64;
    let batches = plan.batch_count();
    let stop = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let (full_tx, full_rx) = mpsc::sync_channel::<Vec<u8>>(AHEAD);
        let (empty_tx, empty_rx) = mpsc::channel::<Vec<u8>>();
        let stop = &stop;
        scope.spawn(move || {
            for b in 0..batches {
                if stop.load(Ordering::Relaxed) || signal::interrupted() {
                    break;
                }
                let mut buf = empty_rx.try_recv().unwrap_or_default();
                plan.fill_batch(b, field, &mut buf, &|| {
                    stop.load(Ordering::Relaxed) || signal::interrupted()
                });
                if full_tx.send(buf).is_err() {
                    break;
                }
            }
        });
        let result = (|| {
            for _ in 0..batches {
                // Wait for the next batch, watching for Ctrl-C meanwhile.
                let buf = loop {
                    if signal::interrupted() {
                        return Err(io::Error::new(io::ErrorKind::Interrupted, "interrupted"));
                    }
                    match full_rx.recv_timeout(Duration::from_millis(50)) {
                        // A batch finished after Ctrl-C may lack pieces: the
                        // check at the top of the loop refuses it.
                        Ok(buf) if signal::interrupted() => drop(buf),
                        Ok(buf) => break buf,
                        Err(mpsc::RecvTimeoutError::Timeout) => continue,
                        Err(mpsc::RecvTimeoutError::Disconnected) => {
                            return Err(io::Error::other("sample generation stopped early"));
                        }
                    }
                };
                if offset == 0 {
                    w.flush()?;
                    offset = w.get_ref().stream_position()?;
                }
                w.write_all(&buf)?;
                start_writeback(w.get_ref(), offset, buf.len() as u64);
                offset += buf.len() as u64;
                progress.advance(buf.len() as u64);
                // Recycle the buffer (the producer may already be gone).
                let _ = empty_tx.send(buf);
            }
            Ok(())
        })();
        // Unblock and stop the producer before the scope joins it.
        stop.store(true, Ordering::Relaxed);
        drop(full_rx);
        result
    })
}

/// Asks the kernel to start writing `len` bytes at `offset` to disk now, so
/// the final sync has little left to do and dirty pages do not pile up.
/// Only a hint: errors are ignored (the final sync reports real ones).
fn start_writeback(file: &File, offset: u64, len: u64) {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        // SAFETY: a plain system call on a file descriptor we own; it reads
        // no memory of ours.
        unsafe {
            libc::sync_file_range(
                file.as_raw_fd(),
                offset as libc::off64_t,
                len as libc::off64_t,
                libc::SYNC_FILE_RANGE_WRITE,
            );
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (file, offset, len);
}
