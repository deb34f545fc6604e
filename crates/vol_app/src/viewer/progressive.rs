//! Progressive refinement: which quality level the viewer asks for next.
//!
//! A full-quality frame of a large canvas takes far longer than an
//! interactive frame may, so the viewer renders in *levels* (a
//! [`Level`] divides the image size and multiplies the sampling step; the
//! renderer front delivers the smaller image and the canvas draws it
//! stretched with bilinear filtering):
//!
//! - **while something changes** (the camera moves, a slider or TF point is
//!   dragged, a setting is switched) every new view is first rendered at a
//!   *preview* level, the finest of [`PREVIEW_LADDER`] whose predicted time
//!   fits [`PREVIEW_BUDGET`];
//! - **once still**, the view is refined through [`REFINEMENT`] (¼ → ½ →
//!   full resolution at the full step), one request after the other, each
//!   sent when the previous one has arrived; only levels finer than the
//!   preview on screen are rendered. Any new change starts over with a
//!   preview and supersedes the refinement frame in progress (the front
//!   cancels it).
//!
//! The prediction is a [`CostModel`]: a running estimate of the time per
//! pixel·step (the frame time divided by the pixels rendered over the step
//! multiplier, i.e. a cost proportional to the samples a frame takes),
//! learned from the frames that arrive. It follows the view, the TF, the
//! renderer and whatever else the machine is doing, without being told.
//!
//! [`Progressive`] is the state machine; it knows nothing of egui, so that
//! the viewer and `vol_app render --progressive` (which reproduces the
//! viewer's frames headlessly) share it.

use std::time::Duration;

use raycaster::render::Quality;

/// The time a preview frame is aimed at: below the 40 ms an interactive
/// frame may take, leaving room for the estimate's error and for showing
/// the frame.
pub const PREVIEW_BUDGET: Duration = Duration::from_millis(30);

/// Going to a finer preview level than the last one needs its prediction
/// below this fraction of the budget, so that noise in the estimate does
/// not make the preview flip between two levels from frame to frame.
const FINER_MARGIN: f64 = 0.8;

/// Weight of the newest frame in the running estimate.
const EMA_WEIGHT: f64 = 0.5;

/// A preview image is kept at least this many pixels on its short side
/// (unless the full image is smaller).
const MIN_PREVIEW_SIDE: u32 = 24;

/// One quality level: the image size divided by `downscale`, the sampling
/// step multiplied by `step_scale`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Level {
    /// Divides width and height (1 = full resolution).
    pub downscale: u32,
    /// Multiplies the sampling step (1 = the full step).
    pub step_scale: u32,
}

impl Level {
    /// Full resolution at the full step.
    pub const FULL: Level = Level::new(1, 1);

    /// The level that divides the size by `downscale` and multiplies the step
    /// by `step_scale` (both at least 1).
    pub const fn new(downscale: u32, step_scale: u32) -> Self {
        Level {
            downscale: if downscale == 0 { 1 } else { downscale },
            step_scale: if step_scale == 0 { 1 } else { step_scale },
        }
    }

    /// The renderer front's description of this level.
    pub fn quality(self) -> Quality {
        Quality {
            step_scale: self.step_scale as f32,
            downscale: self.downscale,
        }
    }

    /// The image size at this level for a full size of `full` pixels (as the
    /// front computes it).
    pub fn size(self, full: [u32; 2]) -> [u32; 2] {
        full.map(|n| (n / self.downscale).max(1))
    }

    /// Cost units of a frame at this level: pixels over the step
    /// multiplier (proportional to the samples taken).
    fn work(self, full: [u32; 2]) -> f64 {
        let [w, h] = self.size(full);
        f64::from(w) * f64::from(h) / f64::from(self.step_scale)
    }

    /// Whether this level is a refinement of `other`: no coarser in
    /// resolution or step, and not the same.
    pub fn refines(self, other: Level) -> bool {
        self != other && self.downscale <= other.downscale && self.step_scale <= other.step_scale
    }

    /// `1/4 res, step ×2`-style label.
    pub fn label(self) -> String {
        let res = if self.downscale == 1 {
            "full res".to_string()
        } else {
            format!("1/{} res", self.downscale)
        };
        if self.step_scale == 1 {
            res
        } else {
            format!("{res}, step ×{}", self.step_scale)
        }
    }
}

/// The preview levels, finest first; each costs about half or less of the
/// one before. The step multiplier grows more slowly than the downscale: a
/// coarse step shows as banding, a low resolution only as blur.
pub const PREVIEW_LADDER: [Level; 9] = [
    Level::new(1, 1),
    Level::new(2, 1),
    Level::new(2, 2),
    Level::new(3, 2),
    Level::new(4, 2),
    Level::new(6, 2),
    Level::new(8, 3),
    Level::new(12, 4),
    Level::new(16, 4),
];

/// The level tried first, before any frame has been timed.
const FIRST_GUESS: Level = Level::new(4, 2);

/// The refinement once the view is still: ¼, ½ and full resolution at the
/// full step.
pub const REFINEMENT: [Level; 3] = [Level::new(4, 1), Level::new(2, 1), Level::FULL];

/// A running estimate of the time per cost unit (pixel·step) of frames.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CostModel {
    /// Nanoseconds per cost unit; `None` before the first frame.
    ns_per_unit: Option<f64>,
}

impl CostModel {
    /// Learns from a frame of `level` whose full size is `full` that took
    /// `time`.
    pub fn record(&mut self, level: Level, full: [u32; 2], time: Duration) {
        let rate = time.as_secs_f64() * 1e9 / level.work(full).max(1.0);
        if !rate.is_finite() {
            return;
        }
        self.ns_per_unit = Some(match self.ns_per_unit {
            Some(old) => old + EMA_WEIGHT * (rate - old),
            None => rate,
        });
    }

    /// The predicted time of a frame at `level` for a full size of `full`;
    /// `None` before the first frame.
    pub fn predict(&self, level: Level, full: [u32; 2]) -> Option<Duration> {
        self.ns_per_unit
            .map(|r| Duration::from_secs_f64(r * level.work(full) * 1e-9))
    }

    /// The preview level for a full size of `full`: the finest of
    /// [`PREVIEW_LADDER`] predicted to fit `budget`. `last` is the previous
    /// preview level: a finer one must fit with a margin. With nothing
    /// predicted to fit, the coarsest level that keeps a usable image.
    pub fn pick(&self, full: [u32; 2], budget: Duration, last: Option<Level>) -> Level {
        let short = full[0].min(full[1]);
        let usable = |l: &&Level| l.downscale == 1 || short / l.downscale >= MIN_PREVIEW_SIDE;
        let coarsest = PREVIEW_LADDER
            .iter()
            .rev()
            .find(usable)
            .copied()
            .unwrap_or(Level::FULL);
        if self.ns_per_unit.is_none() {
            return if FIRST_GUESS.refines(coarsest) || FIRST_GUESS == coarsest {
                FIRST_GUESS
            } else {
                coarsest
            };
        }
        let budget = budget.as_secs_f64();
        let last_work = last.map(|l| l.work(full));
        PREVIEW_LADDER
            .iter()
            .filter(usable)
            .find(|l| {
                let Some(t) = self.predict(**l, full) else {
                    return false;
                };
                let finer = last_work.is_some_and(|w| l.work(full) > w);
                let limit = if finer { budget * FINER_MARGIN } else { budget };
                t.as_secs_f64() <= limit
            })
            .copied()
            .unwrap_or(coarsest)
    }
}

/// What kind of frame a request is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// A preview: the first frame of a changed view, picked to be fast.
    Preview,
    /// A step of the refinement of a still view.
    Refine,
}

/// A frame to request: at which level, and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Planned {
    /// Size and step of the frame.
    pub level: Level,
    /// Preview or refinement.
    pub stage: Stage,
}

/// The progressive-refinement state machine (see the [module docs](self)).
///
/// Each UI frame the viewer calls [`Progressive::next`] with whether the
/// view changed and whether the user is still interacting; when it returns
/// a level, the viewer requests that frame and reports the request's id
/// with [`Progressive::sent`]. Each finished frame goes to
/// [`Progressive::arrived`].
#[derive(Debug, Clone)]
pub struct Progressive {
    /// The learned frame cost.
    pub cost: CostModel,
    budget: Duration,
    /// The level of the newest request, for the current view.
    current: Option<Level>,
    /// The id of the newest request, until its frame arrives.
    awaiting: Option<u64>,
    /// The last preview level chosen.
    last_preview: Option<Level>,
}

impl Default for Progressive {
    fn default() -> Self {
        Progressive::new(PREVIEW_BUDGET)
    }
}

impl Progressive {
    /// A state machine aiming previews at `budget`.
    pub fn new(budget: Duration) -> Self {
        Progressive {
            cost: CostModel::default(),
            budget,
            current: None,
            awaiting: None,
            last_preview: None,
        }
    }

    /// Aims previews at `budget` from now on.
    pub fn set_budget(&mut self, budget: Duration) {
        self.budget = budget;
    }

    /// Forgets the learned cost and the view (a new volume).
    pub fn reset(&mut self) {
        *self = Progressive::new(self.budget);
    }

    /// The frame to request now for a full image of `full` pixels, if any:
    /// a preview when the view `changed` (or nothing was requested yet);
    /// otherwise, when the user is not `interacting` and the previous frame
    /// of this view has arrived, the next refinement level finer than it.
    /// `None` when the frame on screen (or on its way) is the right one.
    pub fn next(&mut self, changed: bool, interacting: bool, full: [u32; 2]) -> Option<Planned> {
        if changed || self.current.is_none() {
            let level = self.cost.pick(full, self.budget, self.last_preview);
            self.last_preview = Some(level);
            self.current = Some(level);
            return Some(Planned {
                level,
                stage: Stage::Preview,
            });
        }
        if interacting || self.awaiting.is_some() {
            return None;
        }
        let shown = self.current?;
        let level = REFINEMENT.into_iter().find(|r| r.refines(shown))?;
        self.current = Some(level);
        Some(Planned {
            level,
            stage: Stage::Refine,
        })
    }

    /// The request for the level [`Progressive::next`] returned last has
    /// id `id`.
    pub fn sent(&mut self, id: u64) {
        self.awaiting = Some(id);
    }

    /// A frame of request `id` at `level` (full size `full`) arrived after
    /// rendering for `time`: learn its cost, and let the refinement go on
    /// when it is the newest request's.
    pub fn arrived(&mut self, id: u64, level: Level, full: [u32; 2], time: Duration) {
        self.cost.record(level, full, time);
        if self.awaiting == Some(id) {
            self.awaiting = None;
        }
    }

    /// The newest request failed: stop refining this view (the error is on
    /// screen; the next change starts over).
    pub fn failed(&mut self, id: u64) {
        if self.awaiting == Some(id) {
            self.awaiting = None;
            self.current = Some(Level::FULL);
        }
    }

    /// The frame on screen is final (progressive refinement is off): no
    /// refinement is due until the next change.
    pub fn settle(&mut self) {
        self.current = Some(Level::FULL);
        self.awaiting = None;
    }

    /// True while frames of the current view are still to come: the newest
    /// has not arrived, or a refinement level is left.
    pub fn is_refining(&self) -> bool {
        self.awaiting.is_some()
            || self
                .current
                .is_some_and(|c| REFINEMENT.iter().any(|r| r.refines(c)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HD: [u32; 2] = [1280, 800];

    fn ms(v: f64) -> Duration {
        Duration::from_secs_f64(v * 1e-3)
    }

    /// A model that has seen a full frame of `full_ms` at `full`.
    fn model(full_ms: f64, full: [u32; 2]) -> CostModel {
        let mut c = CostModel::default();
        c.record(Level::FULL, full, ms(full_ms));
        c
    }

    #[test]
    fn the_ladder_gets_cheaper_and_refinement_gets_finer() {
        let w: Vec<f64> = PREVIEW_LADDER.iter().map(|l| l.work(HD)).collect();
        assert!(w.windows(2).all(|p| p[1] < p[0] * 0.75), "{w:?}");
        assert!(REFINEMENT.windows(2).all(|p| p[1].refines(p[0])));
        assert_eq!(REFINEMENT.last(), Some(&Level::FULL));
        assert_eq!(Level::new(4, 2).size(HD), [320, 200]);
        assert_eq!(Level::new(0, 0), Level::FULL);
        let q = Level::new(3, 2).quality();
        assert_eq!((q.downscale, q.step_scale), (3, 2.0));
    }

    #[test]
    fn the_prediction_scales_with_pixels_and_step() {
        let c = model(640.0, HD);
        let p = |l| c.predict(l, HD).unwrap().as_secs_f64() * 1e3;
        assert!((p(Level::FULL) - 640.0).abs() < 1e-6);
        assert!((p(Level::new(2, 1)) - 160.0).abs() < 1e-6);
        assert!((p(Level::new(4, 2)) - 20.0).abs() < 1e-6);
        // Twice the pixels (a bigger window): twice the time.
        let p2 = c.predict(Level::FULL, [2560, 800]).unwrap().as_secs_f64() * 1e3;
        assert!((p2 - 1280.0).abs() < 1e-6);
        assert_eq!(CostModel::default().predict(Level::FULL, HD), None);
    }

    #[test]
    fn the_picker_takes_the_finest_level_within_the_budget() {
        let budget = ms(30.0);
        // A full frame of 10 ms: full quality is a fine preview.
        assert_eq!(model(10.0, HD).pick(HD, budget, None), Level::FULL);
        // 100 ms: 1/2 res costs 25 ms.
        assert_eq!(model(100.0, HD).pick(HD, budget, None), Level::new(2, 1));
        // 600 ms: 1/4 res at step ×2 costs 18.75 ms, 1/3 at ×2 33 ms.
        assert_eq!(model(600.0, HD).pick(HD, budget, None), Level::new(4, 2));
        // Hopelessly slow: the coarsest level that keeps 24 px.
        assert_eq!(model(1e7, HD).pick(HD, budget, None), Level::new(16, 4));
        assert_eq!(
            model(1e7, [200, 100]).pick([200, 100], budget, None),
            Level::new(4, 2)
        );
        // Nothing timed yet: a middle guess.
        assert_eq!(CostModel::default().pick(HD, budget, None), FIRST_GUESS);
        // Tiny images stay whole.
        assert_eq!(
            CostModel::default().pick([20, 20], budget, None),
            Level::FULL
        );
    }

    #[test]
    fn going_finer_needs_a_margin() {
        let budget = ms(30.0);
        // 1/2 res predicted at 28 ms: taken from scratch, but not when the
        // last preview was coarser (28 > 0.8 × 30).
        let c = model(112.0, HD);
        assert_eq!(c.pick(HD, budget, None), Level::new(2, 1));
        assert_eq!(c.pick(HD, budget, Some(Level::new(2, 2))), Level::new(2, 2));
        assert_eq!(c.pick(HD, budget, Some(Level::new(2, 1))), Level::new(2, 1));
    }

    #[test]
    fn the_estimate_follows_slower_frames() {
        let budget = ms(30.0);
        let mut c = model(100.0, HD);
        assert_eq!(c.pick(HD, budget, None), Level::new(2, 1));
        // The view gets 4× as expensive (zoomed in): the previews measured
        // at 1/2 res take 100 ms; within a few frames the picker backs off.
        for _ in 0..4 {
            c.record(Level::new(2, 1), HD, ms(100.0));
        }
        let l = c.pick(HD, budget, Some(Level::new(2, 1)));
        assert_eq!(l, Level::new(3, 2), "{c:?}");
        let t = c.predict(l, HD).unwrap();
        assert!(t <= budget, "{t:?}");
    }

    fn run(p: &mut Progressive, changed: bool, interacting: bool, id: &mut u64) -> Option<Level> {
        let planned = p.next(changed, interacting, HD)?;
        *id += 1;
        p.sent(*id);
        Some(planned.level)
    }

    #[test]
    fn moving_previews_then_still_refines_quarter_half_full() {
        let mut p = Progressive::new(ms(30.0));
        p.cost = model(600.0, HD);
        let mut id = 0;
        // Moving: each change gets a preview; nothing else while moving.
        let l = run(&mut p, true, true, &mut id).unwrap();
        assert_eq!(l, Level::new(4, 2));
        assert_eq!(p.next(false, true, HD), None);
        p.arrived(id, l, HD, ms(19.0));
        assert_eq!(p.next(false, true, HD), None, "no refinement while moving");
        // Still: ¼, ½, full, each after the previous one arrived.
        let mut seen = Vec::new();
        while let Some(l) = run(&mut p, false, false, &mut id) {
            assert_eq!(p.next(false, false, HD), None, "waits for the frame");
            seen.push(l);
            p.arrived(id, l, HD, ms(600.0 / (l.downscale * l.downscale) as f64));
        }
        assert_eq!(seen, REFINEMENT);
        assert!(!p.is_refining());
        assert_eq!(p.next(false, false, HD), None);
    }

    #[test]
    fn refinement_skips_levels_not_finer_than_the_preview() {
        let mut p = Progressive::new(ms(30.0));
        p.cost = model(100.0, HD);
        let mut id = 0;
        assert_eq!(run(&mut p, true, false, &mut id), Some(Level::new(2, 1)));
        p.arrived(id, Level::new(2, 1), HD, ms(25.0));
        assert_eq!(run(&mut p, false, false, &mut id), Some(Level::FULL));
        // A fast volume: the preview is full quality, nothing to refine.
        let mut p = Progressive::new(ms(30.0));
        p.cost = model(5.0, HD);
        assert_eq!(run(&mut p, true, false, &mut id), Some(Level::FULL));
        p.arrived(id, Level::FULL, HD, ms(5.0));
        assert_eq!(p.next(false, false, HD), None);
    }

    #[test]
    fn new_input_supersedes_the_refinement() {
        let mut p = Progressive::new(ms(30.0));
        p.cost = model(600.0, HD);
        let mut id = 0;
        let l = run(&mut p, true, false, &mut id).unwrap();
        p.arrived(id, l, HD, ms(20.0));
        assert_eq!(run(&mut p, false, false, &mut id), Some(REFINEMENT[0]));
        p.arrived(id, REFINEMENT[0], HD, ms(40.0));
        assert_eq!(run(&mut p, false, false, &mut id), Some(REFINEMENT[1]));
        let superseded = id;
        // The camera moves before the ½ frame arrives: a preview at once.
        let moved = run(&mut p, true, true, &mut id).unwrap();
        assert!(REFINEMENT[1].refines(moved), "{moved:?}");
        // The superseded frame arriving late does not advance anything.
        p.arrived(superseded, REFINEMENT[1], HD, ms(150.0));
        assert_eq!(
            p.next(false, false, HD),
            None,
            "still waiting for the preview"
        );
        p.arrived(id, moved, HD, ms(20.0));
        // Still again: the refinement starts over from ¼.
        assert_eq!(run(&mut p, false, false, &mut id), Some(REFINEMENT[0]));
    }

    #[test]
    fn a_failed_frame_ends_the_refinement_of_its_view() {
        let mut p = Progressive::new(ms(30.0));
        let mut id = 0;
        run(&mut p, true, false, &mut id).unwrap();
        p.failed(id);
        assert_eq!(p.next(false, false, HD), None);
        assert!(p.next(true, false, HD).is_some(), "a change tries again");
    }
}
