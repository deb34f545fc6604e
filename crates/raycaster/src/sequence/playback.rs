//! Decoding frames ahead of a player, on a thread of its own.
//!
//! A [`Playback`] holds a window of frames: the one asked for last and the
//! `ahead − 1` after it (wrapping around the end when looping). Its worker
//! decodes the frames of the window that are not ready yet, in order, and
//! builds each one's [`Scene`] (its macrocell grid), so that the renderer
//! gets a frame it can draw at once while the next ones decode. Asking for
//! a frame outside the window (a seek) moves the window: decoded frames
//! that fall out of it are dropped, so memory stays bounded by `ahead`
//! frames plus the one being decoded, whose result is discarded if the
//! window has moved past it meanwhile.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use parking_lot::{Condvar, Mutex};

use super::Sequence;
use crate::error::{Error, Result};
use crate::scene::{Scene, SceneOptions};

/// A decoded frame, ready to render.
#[derive(Debug)]
pub struct PlaybackFrame {
    /// Its number in the sequence.
    pub index: u32,
    /// The volume and its macrocell grid.
    pub scene: Arc<Scene>,
    /// Time spent reading and decoding the frame.
    pub decode: Duration,
    /// Time spent building its macrocell grid.
    pub build: Duration,
}

/// Frames decoded ahead of a player (see the module documentation).
pub struct Playback {
    shared: Arc<Shared>,
    worker: Option<JoinHandle<()>>,
}

struct Shared {
    sequence: Arc<Sequence>,
    scene: SceneOptions,
    ahead: u32,
    looping: bool,
    state: Mutex<State>,
    changed: Condvar,
}

#[derive(Default)]
struct State {
    /// The frame asked for last: the window's start.
    position: u32,
    /// Decoded frames (or the error of decoding them) in the window.
    ready: BTreeMap<u32, Result<Arc<PlaybackFrame>>>,
    /// The frame the worker is decoding.
    busy: Option<u32>,
    stop: bool,
}

impl Shared {
    /// The window's frames in playing order.
    fn window(&self, position: u32) -> impl Iterator<Item = u32> + '_ {
        let n = self.sequence.frames();
        (0..self.ahead.min(n))
            .map(move |i| position as u64 + i as u64)
            .filter_map(move |f| {
                if f < n as u64 {
                    Some(f as u32)
                } else if self.looping {
                    Some((f % n as u64) as u32)
                } else {
                    None
                }
            })
    }

    fn in_window(&self, position: u32, f: u32) -> bool {
        self.window(position).any(|w| w == f)
    }
}

impl Playback {
    /// Starts decoding `sequence` from frame 0, keeping up to `ahead`
    /// frames (at least 1) ready; `looping` wraps the window around the
    /// end. Scenes are built with `scene` (the macrocell side).
    pub fn new(
        sequence: Arc<Sequence>,
        ahead: u32,
        looping: bool,
        scene: SceneOptions,
    ) -> Result<Playback> {
        let shared = Arc::new(Shared {
            sequence,
            scene,
            ahead: ahead.max(1),
            looping,
            state: Mutex::new(State::default()),
            changed: Condvar::new(),
        });
        let worker = {
            let shared = shared.clone();
            std::thread::Builder::new()
                .name("sequence decoder".into())
                .spawn(move || decode_loop(&shared))
                .map_err(|source| Error::Threads {
                    count: 1,
                    role: "sequence decoder",
                    source,
                })?
        };
        Ok(Playback {
            shared,
            worker: Some(worker),
        })
    }

    /// The sequence played.
    pub fn sequence(&self) -> &Arc<Sequence> {
        &self.shared.sequence
    }

    /// Moves the window to start at frame `k`.
    pub fn seek(&self, k: u32) {
        let mut state = self.shared.state.lock();
        self.move_window(&mut state, k);
    }

    fn move_window(&self, state: &mut State, k: u32) {
        if state.position == k && !state.ready.is_empty() {
            return;
        }
        state.position = k;
        let shared = &self.shared;
        state.ready.retain(|&f, _| shared.in_window(k, f));
        self.shared.changed.notify_all();
    }

    /// Frame `k` if it is decoded, without waiting (the window moves to
    /// `k` either way). An error is handed out once.
    pub fn try_get(&self, k: u32) -> Option<Result<Arc<PlaybackFrame>>> {
        if let Err(e) = self.check(k) {
            return Some(Err(e));
        }
        let mut state = self.shared.state.lock();
        self.move_window(&mut state, k);
        take(&mut state, k)
    }

    /// Frame `k`, waiting for it to be decoded.
    pub fn get(&self, k: u32) -> Result<Arc<PlaybackFrame>> {
        self.check(k)?;
        let mut state = self.shared.state.lock();
        self.move_window(&mut state, k);
        loop {
            if let Some(found) = take(&mut state, k) {
                return found;
            }
            self.shared.changed.wait(&mut state);
        }
    }

    /// An error for a frame past the end.
    fn check(&self, k: u32) -> Result<()> {
        let n = self.shared.sequence.frames();
        if k < n {
            Ok(())
        } else {
            Err(Error::option(
                "frame",
                format!("frame {k} asked for, but the sequence has {n} (numbered from 0)"),
            ))
        }
    }

    /// The frames decoded and waiting.
    pub fn ready(&self) -> Vec<u32> {
        self.shared.state.lock().ready.keys().copied().collect()
    }
}

/// Frame `k` from the ready set: a frame stays for another `get`, an
/// error is taken out.
fn take(state: &mut State, k: u32) -> Option<Result<Arc<PlaybackFrame>>> {
    match state.ready.get(&k)? {
        Ok(frame) => Some(Ok(frame.clone())),
        Err(_) => state.ready.remove(&k),
    }
}

impl Drop for Playback {
    fn drop(&mut self) {
        self.shared.state.lock().stop = true;
        self.shared.changed.notify_all();
        if let Some(worker) = self.worker.take() {
            let _ = worker.join();
        }
    }
}

/// The worker: decode the first frame of the window that is not ready,
/// until told to stop.
fn decode_loop(shared: &Shared) {
    let mut state = shared.state.lock();
    loop {
        if state.stop {
            return;
        }
        let next = shared
            .window(state.position)
            .find(|f| !state.ready.contains_key(f));
        let Some(f) = next else {
            shared.changed.wait(&mut state);
            continue;
        };
        state.busy = Some(f);
        drop(state);
        let result = decode(shared, f);
        state = shared.state.lock();
        state.busy = None;
        if shared.in_window(state.position, f) {
            state.ready.insert(f, result.map(Arc::new));
            shared.changed.notify_all();
        }
    }
}

fn decode(shared: &Shared, f: u32) -> Result<PlaybackFrame> {
    let start = Instant::now();
    let volume = shared.sequence.frame(f)?;
    let decoded = Instant::now();
    let scene = Scene::with_options(volume, &shared.scene);
    Ok(PlaybackFrame {
        index: f,
        scene: Arc::new(scene),
        decode: decoded - start,
        build: decoded.elapsed(),
    })
}
