//! Progressive refinement: which quality level to render next. While the user drags, the
//! coarsest level keeps up with the input; once idle, each finished level asks for the next
//! finer one until the full-quality frame, the same render `caustica render` makes. While the
//! view stays idle after that, further full-quality passes with their planes and light grid
//! moved are averaged into it ([`ACCUMULATE`], as `caustica render --accumulate`).

use std::time::{Duration, Instant};

use crate::render::RenderedImage;

/// One quality level: image size, sample-distance multiplier and light grid against the full
/// render, and the volume's resolution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    pub name: &'static str,
    /// Fraction of the viewport's width and height rendered (at most, with `pixels`).
    pub scale: f32,
    /// Pixels rendered, whatever the viewport's size: the scale that gives at least this
    /// many, unless `scale` is smaller (0: `scale` alone). A level that keeps up with a drag
    /// costs the same in any window.
    pub pixels: u32,
    /// Factor on the scene's sample distance (fewer planes).
    pub step_factor: f32,
    /// Factor on the scene's beams per texel (a coarser light grid; at least
    /// `MIN_BEAMS_PER_TEXEL`).
    pub beams_factor: f32,
    /// `quality.volume_level` at least: 1 samples the volume at half resolution.
    pub volume_level: u32,
}

/// The interactive level's pixels: those of 160×120.
pub const INTERACTIVE_PIXELS: u32 = 160 * 120;

/// Coarse to fine; the last is the full-quality frame.
pub const LEVELS: [Level; 4] = [
    Level {
        name: "interactive",
        // 160×120 pixels' worth in any viewport (127×152 in the portrait viewport of a
        // 1024×768 window with the panel), planes 6 voxels apart to start with (then as far
        // apart as the frame budget needs: `Pace`), a beam per 4 pixels and
        // axis, from the half-resolution volume: 125–145 ms per frame on the CT head with
        // every effect on lavapipe with 2 cores. Its pixels and planes are several voxels
        // apart; at full resolution every trilinear fetch of the volumes lands on memory no
        // neighbouring sample touched (30 % more time for a less smooth image).
        scale: 0.25,
        pixels: INTERACTIVE_PIXELS,
        step_factor: 6.0,
        beams_factor: 0.25,
        volume_level: 1,
    },
    Level {
        name: "draft",
        // Three times the interactive level's pixels with planes 4 voxels apart, a beam per
        // 2 pixels: a sharper image within about a second of letting go, while the preview
        // takes several on real CT (the CT head's at 322×384: 2.8–3.0 s on lavapipe).
        scale: 0.5,
        pixels: 3 * INTERACTIVE_PIXELS,
        step_factor: 4.0,
        beams_factor: 0.5,
        volume_level: 1,
    },
    Level {
        name: "preview",
        scale: 0.5,
        pixels: 0,
        step_factor: 2.0,
        // Beams are asked per plane-0 pixel, which in perspective are smaller than pixels at
        // the volume: at 1 the CT head's preview (322×384) traced 474×520 beams, two thirds of
        // its 3.0–3.3 s. At 0.75 (355×389 beams, 2.2–2.3 s) it is as close to the full frame
        // (relative L1 of the full frame box-filtered to its size: 0.0592 at 1 and at 0.75,
        // 0.0609 at 0.5).
        beams_factor: 0.75,
        volume_level: 0,
    },
    Level {
        name: "full",
        scale: 1.0,
        pixels: 0,
        step_factor: 1.0,
        beams_factor: 1.0,
        volume_level: 0,
    },
];

pub const FULL: usize = LEVELS.len() - 1;

/// The spacings of the interactive level's planes [`Pace`] chooses from (factors on the
/// scene's sample distance), finest first; it starts at `LEVELS[0].step_factor`. Finer than
/// the draft's 4 would be wasted on the interactive level's few pixels; 16 is where the sample
/// distance is capped.
pub const INTERACTIVE_STEPS: [f32; 7] = [4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 16.0];

/// The time an interactive frame may take by default (`view --frame-budget`): with a fifth of
/// headroom below the 150 ms within which a drag still feels direct.
pub const FRAME_BUDGET_MS: f64 = 120.0;

/// The latest interactive frames at one spacing whose median [`Pace`] goes by.
const PACE_FRAMES: usize = 3;

/// [`Pace`] moves to a finer spacing only where its frames, by the planes, would take at most
/// this part of the budget: frames that fit it well do not flip between two spacings.
const FINER_MARGIN: f64 = 0.8;

/// The interactive level's plane spacing, kept to what the machine renders within a frame
/// budget: the same 160×120 pixels' worth on any device, with planes further apart on a slow
/// one and closer on a fast one, as a drag needs frames that keep up with the hand more than
/// it needs their detail. After each interactive frame ([`Pace::record`]) the median of the
/// latest ones at the current spacing decides: over the budget, the planes move apart as far
/// as a frame's time, taken as proportional to the square root of its planes, says is needed;
/// well within it, one spacing closer. Time falls more slowly than the planes: part of a
/// frame does not depend on them, and a plane costs more where they are further apart (not for
/// the view passes' span: passes over fewer planes counted the same instructions). The CT
/// head's interactive frames on lavapipe took 177 ms of GPU time with 66 planes, 150–176 ms
/// with 36 and 79–103 ms with 21.
#[derive(Clone, Debug, PartialEq)]
pub struct Pace {
    /// The budget (ms); 0 keeps the level's own spacing.
    budget_ms: f64,
    /// Index into [`INTERACTIVE_STEPS`].
    index: usize,
    /// The latest frames' times at this spacing.
    times: Vec<f64>,
}

impl Pace {
    pub fn new(budget_ms: f64) -> Pace {
        let index = INTERACTIVE_STEPS
            .iter()
            .position(|&s| s == LEVELS[0].step_factor)
            .unwrap_or(0);
        Pace {
            budget_ms: if budget_ms.is_finite() { budget_ms.max(0.0) } else { 0.0 },
            index,
            times: Vec::new(),
        }
    }

    /// The interactive level's factor on the scene's sample distance.
    pub fn step_factor(&self) -> f32 {
        INTERACTIVE_STEPS[self.index]
    }

    /// An interactive frame at the current spacing took `ms` (frames that also made or copied
    /// scene textures are left out by the caller: they are not what the next ones cost).
    /// Returns whether the spacing changed.
    pub fn record(&mut self, ms: f64) -> bool {
        if self.budget_ms <= 0.0 || !ms.is_finite() || ms < 0.0 {
            return false;
        }
        self.times.push(ms);
        if self.times.len() > PACE_FRAMES {
            self.times.remove(0);
        }
        if self.times.len() < 2 {
            return false;
        }
        let median = crate::bench::median(&mut self.times.clone());
        let step = INTERACTIVE_STEPS[self.index] as f64;
        let at = |i: usize| median * (step / INTERACTIVE_STEPS[i] as f64).sqrt();
        let mut next = self.index;
        if median > self.budget_ms {
            while next + 1 < INTERACTIVE_STEPS.len() && at(next) > self.budget_ms {
                next += 1;
            }
        } else if self.index > 0 && at(self.index - 1) <= FINER_MARGIN * self.budget_ms {
            next = self.index - 1;
        }
        if next == self.index {
            return false;
        }
        self.index = next;
        self.times.clear();
        true
    }
}

/// Full-quality passes averaged while the view stays idle (the first is the full frame): the
/// planes and the light grid move between them (`render::jitter_sequence`), so banding that
/// follows where the samples fall averages out.
pub const ACCUMULATE: u32 = 8;

/// How long after the last change the view counts as idle, so refinement may start.
pub const IDLE_AFTER: Duration = Duration::from_millis(200);

impl Level {
    /// The render size for a viewport (at least 1×1).
    pub fn size(&self, width: u32, height: u32) -> (u32, u32) {
        let area = width as f64 * height as f64;
        let mut scale = self.scale as f64;
        if self.pixels > 0 && area > 0.0 {
            // Rounded up, so that the product is not short of `pixels` by a rounding.
            let (w, h) = (width as f64, height as f64);
            let fit = (self.pixels as f64 / area).sqrt();
            let mut s = fit;
            while s < scale && (w * s).round() * (h * s).round() < self.pixels as f64 {
                s += 0.25 / w.max(h);
            }
            scale = scale.min(s);
        }
        let s = |v: u32| ((v as f64 * scale).round() as u32).max(1);
        (s(width), s(height))
    }
}

/// A render to start: the view version it shows, the level and, at the full level, the
/// accumulation pass (0: the full frame itself).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Job {
    pub version: u64,
    pub level: usize,
    pub pass: u32,
}

/// The scheduler. The caller bumps [`Progressive::changed`] on every edit and asks
/// [`Progressive::next`] whenever nothing is in flight; one render runs at a time.
#[derive(Debug)]
pub struct Progressive {
    version: u64,
    last_change: Instant,
    in_flight: Option<Job>,
    /// The best level finished for the current version.
    done: Option<usize>,
    /// Full-quality passes finished for the current version.
    passes: u32,
}

impl Progressive {
    pub fn new(now: Instant) -> Self {
        Progressive {
            version: 1,
            last_change: now.checked_sub(IDLE_AFTER).unwrap_or(now),
            in_flight: None,
            done: None,
            passes: 0,
        }
    }

    pub fn version(&self) -> u64 {
        self.version
    }

    /// Something that changes the image was edited. Returns true when the render in flight
    /// should be cancelled: a refinement of an outdated view is wasted work, while a coarse
    /// frame is let finish so a continuous drag still shows frames.
    pub fn changed(&mut self, now: Instant) -> bool {
        self.version += 1;
        self.last_change = now;
        self.done = None;
        self.passes = 0;
        self.in_flight.is_some_and(|j| j.level > 0)
    }

    pub fn is_idle(&self, now: Instant) -> bool {
        now.duration_since(self.last_change) >= IDLE_AFTER
    }

    /// The full-quality frame of the current view is on screen and nothing but accumulation
    /// passes is pending.
    pub fn settled(&self) -> bool {
        self.done == Some(FULL) && self.in_flight.is_none_or(|j| j.pass > 0)
    }

    /// Every accumulation pass of the current view is on screen.
    pub fn accumulated(&self) -> bool {
        self.settled() && self.passes >= ACCUMULATE
    }

    /// The next render to start, if any (None while one is in flight or all is done).
    pub fn next(&mut self, now: Instant) -> Option<Job> {
        if self.in_flight.is_some() {
            return None;
        }
        let (level, pass) = match self.done {
            None => (0, 0),
            Some(l) if l < FULL && self.is_idle(now) => (l + 1, 0),
            Some(FULL) if self.passes < ACCUMULATE && self.is_idle(now) => (FULL, self.passes),
            Some(_) => return None,
        };
        let job = Job {
            version: self.version,
            level,
            pass,
        };
        self.in_flight = Some(job);
        Some(job)
    }

    /// The render of `job` ended (finished, failed or cancelled). Returns true when its image
    /// shows the current view and should replace what is on screen.
    pub fn finished(&mut self, job: Job, ok: bool) -> bool {
        if self.in_flight == Some(job) {
            self.in_flight = None;
        }
        if ok && job.version == self.version {
            self.done = Some(self.done.map_or(job.level, |d| d.max(job.level)));
            if job.level == FULL {
                self.passes = self.passes.max(job.pass + 1);
            }
            return true;
        }
        // An outdated coarse frame is still better than nothing while dragging.
        ok && job.level == 0
    }

    /// When the caller should look again even without input (idle refinement).
    pub fn wake_at(&self) -> Option<Instant> {
        (self.in_flight.is_none() && !self.accumulated()).then(|| self.last_change + IDLE_AFTER)
    }
}

/// How long a frame renders before the window's title shows how far it has got, and how often
/// it is brought up to date then: the coarse levels, a tenth of a second each, leave it alone.
/// (The title, not the panel: repainting the window takes 40–50 ms of a CPU's time on a
/// software surface, which a frame rendered on the same CPU would lose.)
pub const TITLE_AFTER: Duration = Duration::from_secs(1);
pub const TITLE_EVERY: Duration = Duration::from_millis(500);

/// A frame being rendered, as the title names it: its level, its size, which of the
/// full-quality passes it is (after the first, of `ACCUMULATE`), and the steps of its
/// sweep done of all (0 of 0 while the scene is set up).
#[derive(Clone, Copy, Debug)]
pub struct InFlight<'a> {
    pub name: &'a str,
    pub size: (u32, u32),
    pub pass: u32,
    pub done: u32,
    pub total: u32,
}

/// The window's title while `frame` renders, `elapsed` after it was asked for: what it is and
/// how far it has got; just the program's name before `TITLE_AFTER` and without a frame.
pub fn progress_title(frame: Option<InFlight>, elapsed: Duration) -> String {
    let Some(f) = frame.filter(|_| elapsed >= TITLE_AFTER) else {
        return "caustica".into();
    };
    let (name, (w, h), secs) = (f.name, f.size, elapsed.as_secs_f64());
    let pass = if f.pass > 0 {
        format!(", pass {} of {ACCUMULATE}", f.pass + 1)
    } else {
        String::new()
    };
    if f.total == 0 {
        return format!("caustica · {name} {w}×{h}{pass} · setting up · {secs:.0} s");
    }
    let percent = (100 * f.done as u64 / f.total as u64).min(100);
    format!(
        "caustica · {name} {w}×{h}{pass} · {percent} % of {} planes · {secs:.0} s",
        f.total
    )
}

/// The image to show for a finished frame: at the full level the mean of its passes so far
/// (`sum` holds their sum and count; pass 0 starts it), coarser levels as they are.
pub fn accumulate(sum: &mut Option<(RenderedImage, u32)>, job: Job, image: RenderedImage) -> RenderedImage {
    if job.level != FULL {
        *sum = None;
        return image;
    }
    match sum {
        Some((s, n)) if job.pass > 0 && (s.width, s.height) == (image.width, image.height) => {
            s.add(&image);
            *n += 1;
            s.scaled(1.0 / *n as f32)
        }
        _ => {
            *sum = Some((image.clone(), 1));
            image
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(v: f32) -> RenderedImage {
        RenderedImage {
            width: 2,
            height: 1,
            pixels: vec![[v; 4]; 2],
        }
    }

    #[test]
    fn full_passes_are_averaged_and_a_new_full_frame_starts_over() {
        let mut sum = None;
        let job = |level, pass| Job {
            version: 1,
            level,
            pass,
        };
        assert_eq!(accumulate(&mut sum, job(FULL, 0), flat(1.0)).pixels[0][0], 1.0);
        assert_eq!(accumulate(&mut sum, job(FULL, 1), flat(2.0)).pixels[0][0], 1.5);
        assert_eq!(accumulate(&mut sum, job(FULL, 2), flat(6.0)).pixels[1][3], 3.0);
        // The next view's full frame replaces the sum; a coarse frame drops it.
        assert_eq!(accumulate(&mut sum, job(FULL, 0), flat(4.0)).pixels[0][0], 4.0);
        assert_eq!(accumulate(&mut sum, job(0, 0), flat(8.0)).pixels[0][0], 8.0);
        assert!(sum.is_none());
        assert_eq!(accumulate(&mut sum, job(FULL, 3), flat(5.0)).pixels[0][0], 5.0);
    }

    /// The title names a long frame and how far its sweep has got, and stays the program's
    /// name for short ones and between frames.
    #[test]
    fn the_title_shows_a_long_frames_progress() {
        let frame = |done, total| {
            Some(InFlight {
                name: "full",
                size: (644, 768),
                pass: 0,
                done,
                total,
            })
        };
        let s = |ms| Duration::from_millis(ms);
        assert_eq!(progress_title(frame(10, 342), s(400)), "caustica");
        assert_eq!(progress_title(None, s(5000)), "caustica");
        assert_eq!(
            progress_title(frame(0, 0), s(1200)),
            "caustica · full 644×768 · setting up · 1 s"
        );
        assert_eq!(
            progress_title(frame(171, 342), s(4600)),
            "caustica · full 644×768 · 50 % of 342 planes · 5 s"
        );
        assert_eq!(
            progress_title(frame(342, 342), s(10_400)),
            "caustica · full 644×768 · 100 % of 342 planes · 10 s"
        );
        // The passes averaged into the full frame say which they are.
        let second = frame(34, 342).map(|f| InFlight { pass: 1, ..f });
        assert_eq!(
            progress_title(second, s(2000)),
            format!("caustica · full 644×768, pass 2 of {ACCUMULATE} · 9 % of 342 planes · 2 s")
        );
    }

    #[test]
    fn refines_to_full_when_idle() {
        let t0 = Instant::now();
        let mut p = Progressive::new(t0);
        let mut seen = Vec::new();
        while let Some(job) = p.next(t0) {
            seen.push(job.level);
            assert!(p.next(t0).is_none(), "one render at a time");
            assert!(p.finished(job, true));
        }
        let passes: Vec<u32> = (1..ACCUMULATE).collect();
        assert_eq!(seen[..=FULL], [0, 1, 2, 3]);
        assert!(seen[FULL..].iter().all(|&l| l == FULL), "{seen:?}");
        assert_eq!(seen.len(), FULL + ACCUMULATE as usize, "{seen:?} (passes {passes:?})");
        assert!(p.settled() && p.accumulated());
        assert_eq!(p.wake_at(), None, "nothing left to do");
    }

    #[test]
    fn accumulation_passes_follow_the_full_frame_and_an_edit_cancels_them() {
        let t0 = Instant::now();
        let mut p = Progressive::new(t0);
        for _ in 0..=FULL {
            let j = p.next(t0).unwrap();
            assert_eq!(j.pass, 0);
            p.finished(j, true);
        }
        assert!(p.settled() && !p.accumulated());
        let first = p.next(t0).unwrap();
        assert_eq!((first.level, first.pass), (FULL, 1));
        assert!(p.settled(), "an accumulation pass in flight leaves the view settled");
        assert!(p.finished(first, true));
        let second = p.next(t0).unwrap();
        assert_eq!(second.pass, 2);
        // An edit during a pass cancels it, and the view starts over from the coarse level.
        let t1 = t0 + Duration::from_millis(10);
        assert!(p.changed(t1));
        assert!(!p.finished(second, false));
        assert!(!p.settled());
        let coarse = p.next(t1).unwrap();
        assert_eq!((coarse.level, coarse.pass), (0, 0));
    }

    #[test]
    fn dragging_stays_coarse_and_cancels_refinement() {
        let t0 = Instant::now();
        let mut p = Progressive::new(t0);
        let j = p.next(t0).unwrap();
        p.finished(j, true);
        let refine = p.next(t0).unwrap();
        assert_eq!(refine.level, 1);
        // An edit while refining: cancel it.
        let t1 = t0 + Duration::from_millis(10);
        assert!(p.changed(t1));
        assert!(!p.finished(refine, false));
        let coarse = p.next(t1).unwrap();
        assert_eq!(coarse.level, 0);
        // Edits during a coarse render let it finish; its outdated frame is still shown.
        assert!(!p.changed(t1));
        assert!(p.finished(coarse, true));
        // Not idle yet: the next render is coarse again, not a refinement.
        let again = p.next(t1).unwrap();
        assert_eq!(again.level, 0);
        assert!(p.finished(again, true));
        assert!(p.next(t1).is_none(), "no refinement before the view is idle");
        assert_eq!(p.wake_at(), Some(t1 + IDLE_AFTER));
        let idle = t1 + IDLE_AFTER;
        assert_eq!(p.next(idle).map(|j| j.level), Some(1));
    }

    #[test]
    fn pace_moves_planes_apart_as_far_as_slow_frames_need() {
        let mut p = Pace::new(120.0);
        assert_eq!(p.step_factor(), 6.0, "starts at the level's own spacing");
        // One frame is not enough to go by.
        assert!(!p.record(160.0));
        assert_eq!(p.step_factor(), 6.0);
        // A median of 162.5 ms at 6: 12 voxels apart would take 162.5 × √(6/12) = 114.9 ms,
        // 10 apart 125.9.
        assert!(p.record(165.0));
        assert_eq!(p.step_factor(), 12.0);
        // Within the budget, but not well enough for 10 (100 × √(12/10) = 109.5 > 96): kept.
        for _ in 0..5 {
            assert!(!p.record(100.0));
        }
        assert_eq!(p.step_factor(), 12.0);
        // Far beyond any spacing's reach: the widest.
        p.record(5000.0);
        p.record(5000.0);
        assert_eq!(p.step_factor(), 16.0);
    }

    #[test]
    fn pace_moves_planes_closer_one_spacing_at_a_time_when_frames_fit_well() {
        let mut p = Pace::new(120.0);
        p.record(30.0);
        assert!(p.record(30.0));
        assert_eq!(p.step_factor(), 5.0);
        p.record(30.0);
        assert!(p.record(30.0));
        assert_eq!(p.step_factor(), 4.0);
        // The finest: no further.
        for _ in 0..4 {
            assert!(!p.record(1.0));
        }
        assert_eq!(p.step_factor(), 4.0);
    }

    #[test]
    fn pace_goes_by_the_median_not_one_slow_frame() {
        let mut p = Pace::new(120.0);
        p.record(100.0);
        p.record(110.0);
        // One frame stalled (another process, a page fault): the median of three is 110.
        assert!(!p.record(900.0));
        assert_eq!(p.step_factor(), 6.0);
    }

    #[test]
    fn pace_without_a_budget_keeps_the_levels_spacing() {
        for budget in [0.0, -5.0, f64::NAN] {
            let mut p = Pace::new(budget);
            for ms in [5000.0, 5000.0, 1.0, 1.0, 1.0] {
                assert!(!p.record(ms));
            }
            assert_eq!(p.step_factor(), LEVELS[0].step_factor);
        }
        let mut p = Pace::new(120.0);
        assert!(!p.record(f64::NAN) && !p.record(f64::INFINITY));
        assert_eq!(p.step_factor(), LEVELS[0].step_factor, "no time to go by");
    }

    #[test]
    fn level_sizes() {
        // The interactive level renders 160×120 pixels' worth in any viewport, the draft three
        // times as many, at most a quarter and a half of the viewport per axis.
        assert_eq!(LEVELS[0].size(1024, 768), (160, 120));
        // Rounded to whole pixels, the size may exceed the pixels asked for by about a row or
        // a column (152 or 127 pixels here: bounds of 400 and, at three times the pixels, 700)
        // and change the aspect by about a pixel in 127 (0.01).
        let (w, h) = LEVELS[0].size(644, 768);
        assert!(
            w * h >= INTERACTIVE_PIXELS && w * h < INTERACTIVE_PIXELS + 400,
            "{w}×{h}"
        );
        assert!(
            (w as f32 / h as f32 - 644.0 / 768.0).abs() < 0.01,
            "{w}×{h} keeps the viewport's shape"
        );
        let (w, h) = LEVELS[1].size(644, 768);
        assert!(
            w * h >= 3 * INTERACTIVE_PIXELS && w * h < 3 * INTERACTIVE_PIXELS + 700,
            "{w}×{h}"
        );
        assert_eq!(LEVELS[0].size(320, 240), (80, 60), "at most a quarter per axis");
        assert_eq!(LEVELS[1].size(320, 240), (160, 120), "at most half per axis");
        // Each level is at least as fine as the one before.
        for w in LEVELS.windows(2) {
            assert!(
                w[1].scale >= w[0].scale && w[1].step_factor <= w[0].step_factor,
                "{w:?}"
            );
        }
        assert_eq!(LEVELS[FULL].size(1024, 768), (1024, 768));
        assert_eq!(LEVELS[0].size(2, 2), (1, 1));
        assert_eq!(LEVELS[FULL].step_factor, 1.0);
        assert_eq!(LEVELS[FULL].beams_factor, 1.0);
    }
}
