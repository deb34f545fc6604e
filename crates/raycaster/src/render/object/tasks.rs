//! The frame's threads: render threads take (tile, brick) tasks from one
//! queue, integrate the brick's samples of the tile's rays, and pass the
//! tile on to its next brick or finish it (see the module docs of
//! [`object`](super)).

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use crossbeam_channel::{Receiver, Sender};
use parking_lot::Mutex;

use super::TaskOrder;
use super::bricks::sample_range;
use super::footprint::intersect;
use super::work::FrameWork;
use crate::integrator::{Integrator, RaySegment, Span};
use crate::render::driver::{FrameJob, render_tile};
use crate::render::film::{Film, RayCounts};
use crate::volume::Volume;

/// The rays of one tile, travelling with its tasks.
#[derive(Debug)]
struct TileBuf<I> {
    /// Per pixel (row-major in the tile) the ray, `None` when it misses the
    /// volume. Empty until the tile's first task.
    segs: Vec<Option<RaySegment>>,
    /// Per pixel the integration state.
    states: Vec<I>,
    /// Pixels whose ray hits the volume and is not finished.
    live: u32,
}

impl<I> Default for TileBuf<I> {
    fn default() -> Self {
        TileBuf {
            segs: Vec::new(),
            states: Vec::new(),
            live: 0,
        }
    }
}

/// A task: integrate brick `queue_of(tile)[next]` into the tile.
#[derive(Debug)]
struct Task<I> {
    tile: u32,
    next: u32,
    buf: TileBuf<I>,
}

/// State shared by the threads of one frame.
struct Shared<'a, V: Volume, I> {
    job: &'a FrameJob<'a, V>,
    film: &'a Film,
    work: &'a FrameWork,
    order: TaskOrder,
    /// One brick spans the volume and the integrator does not split rays:
    /// a tile is its rays integrated whole, by the shared tile loop.
    whole_rays: bool,
    /// Tiles not finished yet.
    remaining: AtomicUsize,
    /// Set when the frame stops early (cancelled, or a thread panicked).
    aborted: AtomicBool,
    /// Render threads also composite (no compositing threads running).
    inline: AtomicBool,
    tasks: (Sender<Task<I>>, Receiver<Task<I>>),
    done: (Sender<Task<I>>, Receiver<Task<I>>),
    /// Dropped (set to `None`) to wake every thread for the end of the frame.
    stop_tx: Mutex<Option<Sender<()>>>,
    stop_rx: Receiver<()>,
}

impl<V: Volume, I: Integrator> Shared<'_, V, I> {
    /// Ends the frame: every thread's wait returns.
    fn stop(&self) {
        self.stop_tx.lock().take();
    }

    fn abort(&self) {
        self.aborted.store(true, Ordering::Relaxed);
        self.stop();
    }

    /// Integrates the task's brick into its tile.
    fn render_task(&self, task: &mut Task<I>, samples: &mut u64) {
        let t = self.work.tiles[task.tile as usize];
        let tw = (t.x1 - t.x0) as usize;
        let buf = &mut task.buf;
        if buf.segs.is_empty() {
            let area = t.area() as usize;
            buf.segs.reserve_exact(area);
            for j in t.y0..t.y1 {
                for i in t.x0..t.x1 {
                    let seg = self.job.segment(i, j);
                    // A ray without samples (culled by the proxy depths,
                    // or clipped away) is never live.
                    buf.live += seg.is_some_and(|s| !s.is_empty()) as u32;
                    buf.segs.push(seg);
                }
            }
            buf.states = vec![I::default(); area];
        }
        let b = self.work.queue_of(task.tile)[task.next as usize];
        let brick = &self.work.bricks[b as usize];
        task.next += 1;
        let Some(r) = intersect(&brick.rect, &t) else {
            return;
        };
        for j in r.y0..r.y1 {
            // A task can take a while: look for cancellation per row.
            // The tile is left half-done, but a cancelled frame is dropped.
            if self.job.cancel.is_cancelled() {
                return;
            }
            let row = (j - t.y0) as usize * tw;
            for i in r.x0..r.x1 {
                let p = row + (i - t.x0) as usize;
                let Some(seg) = &buf.segs[p] else { continue };
                let state = &mut buf.states[p];
                if state.is_done() || seg.is_empty() {
                    continue;
                }
                let (k0, k1) = sample_range(seg, &brick.region);
                if k0 < k1 {
                    *samples += state.integrate(Span::new(&self.job.ctx, seg, k0, k1));
                    if state.is_done() {
                        buf.live -= 1;
                    }
                }
            }
        }
    }

    /// After a task: the tile's next task, or `None` when the tile is
    /// finished (then resolved into the film).
    fn composite(&self, task: Task<I>) -> Option<Task<I>> {
        let len = self.work.queue_of(task.tile).len() as u32;
        if task.next < len && task.buf.live > 0 {
            return Some(task);
        }
        self.finish(task.tile, &self.resolve(task.tile, &task.buf));
        None
    }

    /// Puts tile `tile`'s RGB bytes on the film; ends the frame after the
    /// last.
    fn finish(&self, tile: u32, rgb: &[u8]) {
        self.film.put_tile(&self.work.tiles[tile as usize], rgb);
        self.tile_done();
    }

    /// Counts a tile on the film; ends the frame after the last.
    fn tile_done(&self) {
        if self.remaining.fetch_sub(1, Ordering::AcqRel) == 1 {
            self.stop();
        }
    }

    /// The tile's RGB bytes.
    fn resolve(&self, tile: u32, buf: &TileBuf<I>) -> Vec<u8> {
        let t = self.work.tiles[tile as usize];
        let bg = self.film.background_rgb();
        let area = t.area() as usize;
        let mut rgb = Vec::with_capacity(3 * area);
        let mut counts = RayCounts::default();
        let mut scratch = I::Scratch::default();
        for (seg, state) in buf.segs.iter().zip(&buf.states) {
            if seg.is_some() {
                let c = state.resolve_in(&self.job.ctx, &mut scratch);
                counts.add(c);
                rgb.extend_from_slice(&self.film.composite(c));
            } else {
                rgb.extend_from_slice(&bg);
            }
        }
        self.film.add_counts(counts);
        rgb
    }

    fn stopped(&self) -> bool {
        self.aborted.load(Ordering::Relaxed) || self.job.cancel.is_cancelled()
    }

    /// A render thread: takes tasks until the frame ends. Never inlined:
    /// the calling thread and the spawned ones run it, and inlined into
    /// both callers it became two copies of the integrator's loop that the
    /// compiler optimised differently.
    #[inline(never)]
    fn render_loop(&self) -> u64 {
        self.worker_loop(&self.tasks.1, |mut task, samples| {
            if self.whole_rays {
                // The same rays, states and resolution as the tasks below
                // give, without keeping a tile's segments and states in
                // buffers between passes over it.
                let rect = &self.work.tiles[task.tile as usize];
                *samples += render_tile::<V, I>(self.job, self.film, rect);
                self.tile_done();
                return;
            }
            self.render_task(&mut task, samples);
            if !self.inline.load(Ordering::Relaxed) {
                let _ = self.done.0.send(task);
                return;
            }
            let keep = self.order == TaskOrder::TileFirst;
            while let Some(mut next) = self.composite(task) {
                if keep && !self.stopped() {
                    self.render_task(&mut next, samples);
                    task = next;
                    continue;
                }
                // The receiver lives in `self`: sending cannot fail.
                let _ = self.tasks.0.send(next);
                break;
            }
        })
    }

    /// A compositing thread: takes finished tasks until the frame ends.
    fn composite_loop(&self) -> u64 {
        self.worker_loop(&self.done.1, |task, _| {
            if let Some(next) = self.composite(task) {
                let _ = self.tasks.0.send(next);
            }
        })
    }

    /// Takes tasks from `queue` and hands them to `work` until the frame
    /// ends (or stops early, which ends it for every thread); returns the
    /// samples `work` counted.
    fn worker_loop(
        &self,
        queue: &Receiver<Task<I>>,
        mut work: impl FnMut(Task<I>, &mut u64),
    ) -> u64 {
        let _guard = AbortOnPanic(self);
        let mut samples = 0;
        loop {
            let task = crossbeam_channel::select! {
                recv(queue) -> t => t,
                recv(self.stop_rx) -> _ => break,
            };
            let Ok(task) = task else { break };
            if self.stopped() {
                self.abort();
                break;
            }
            work(task, &mut samples);
        }
        samples
    }
}

/// Ends the frame when a thread unwinds, so the others do not wait forever.
struct AbortOnPanic<'s, 'a, V: Volume, I: Integrator>(&'s Shared<'a, V, I>);

impl<V: Volume, I: Integrator> Drop for AbortOnPanic<'_, '_, V, I> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.abort();
        }
    }
}

/// Runs the frame's threads over `work`: `render_threads` render threads
/// (the calling thread is one of them) and `composite_threads` compositing
/// threads. `whole_rays`: the work is one brick spanning the volume, for
/// an integrator that does not split rays. The threads put the tiles on
/// `film` as they finish them. Returns the samples taken, `None` when the
/// frame was cancelled.
pub(super) fn run_frame<V: Volume, I: Integrator>(
    job: &FrameJob<'_, V>,
    film: &Film,
    work: &FrameWork,
    threads: (usize, usize),
    whole_rays: bool,
    order: TaskOrder,
) -> Option<u64> {
    let (render_threads, composite_threads) = threads;
    let (stop_tx, stop_rx) = crossbeam_channel::bounded(0);
    let shared = Shared::<V, I> {
        job,
        film,
        work,
        order,
        whole_rays,
        remaining: AtomicUsize::new(0),
        aborted: AtomicBool::new(false),
        inline: AtomicBool::new(true),
        tasks: crossbeam_channel::unbounded(),
        done: crossbeam_channel::unbounded(),
        stop_tx: Mutex::new(Some(stop_tx)),
        stop_rx,
    };
    // Tiles with nothing queued are background, which the film already
    // holds; the others start with the most work first, so the longest
    // chains of bricks do not trail.
    let mut started: Vec<(u64, u32)> = Vec::new();
    for (t, rect) in work.tiles.iter().enumerate() {
        let n = work.queue_of(t as u32).len() as u64;
        if n > 0 {
            started.push((n * rect.area(), t as u32));
        }
    }
    if started.is_empty() {
        return Some(0);
    }
    started.sort_unstable_by(|a, b| b.cmp(a));
    shared.remaining.store(started.len(), Ordering::Relaxed);
    for &(_, t) in &started {
        let _ = shared.tasks.0.send(Task {
            tile: t,
            next: 0,
            buf: TileBuf::default(),
        });
    }
    let outs = std::thread::scope(|s| {
        let shared = &shared;
        // Fewer threads than asked for still finish the frame.
        let spawn = |name: String, renders: bool| {
            std::thread::Builder::new()
                .name(name)
                .spawn_scoped(s, move || match renders {
                    true => shared.render_loop(),
                    false => shared.composite_loop(),
                })
                .ok()
        };
        let mut handles: Vec<_> = (0..composite_threads)
            .map_while(|i| spawn(format!("raycaster-composite-{i}"), false))
            .collect();
        shared.inline.store(handles.is_empty(), Ordering::Relaxed);
        handles.extend(
            (1..render_threads).map_while(|i| spawn(format!("raycaster-object-{i}"), true)),
        );
        let mine = shared.render_loop();
        let mut outs = vec![mine];
        for h in handles {
            match h.join() {
                Ok(o) => outs.push(o),
                Err(panic) => std::panic::resume_unwind(panic),
            }
        }
        outs
    });
    if shared.aborted.load(Ordering::Relaxed) || job.cancel.is_cancelled() {
        return None;
    }
    Some(outs.iter().sum())
}
