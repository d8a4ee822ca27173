//! Progressive refinement: which quality level to render next. While the user drags, the
//! coarsest level keeps up with the input; once idle, each finished level asks for the next
//! finer one until the full-quality frame, the same render `caustica render` makes.

use std::time::{Duration, Instant};

/// One quality level: image scale and sample-distance multiplier against the full render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    pub name: &'static str,
    /// Fraction of the viewport's width and height rendered.
    pub scale: f32,
    /// Factor on the scene's sample distance (fewer planes).
    pub step_factor: f32,
}

/// Coarse to fine; the last is the full-quality frame.
pub const LEVELS: [Level; 3] = [
    Level {
        name: "interactive",
        // 128×96 at a 1024×768 viewport: about a second per frame on lavapipe with 2 cores.
        scale: 0.125,
        step_factor: 4.0,
    },
    Level {
        name: "preview",
        scale: 0.5,
        step_factor: 2.0,
    },
    Level {
        name: "full",
        scale: 1.0,
        step_factor: 1.0,
    },
];

pub const FULL: usize = LEVELS.len() - 1;

/// How long after the last change the view counts as idle, so refinement may start.
pub const IDLE_AFTER: Duration = Duration::from_millis(200);

impl Level {
    /// The render size for a viewport (at least 1×1).
    pub fn size(&self, width: u32, height: u32) -> (u32, u32) {
        let s = |v: u32| ((v as f32 * self.scale).round() as u32).max(1);
        (s(width), s(height))
    }
}

/// A render to start: the view version it shows and the level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Job {
    pub version: u64,
    pub level: usize,
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
}

impl Progressive {
    pub fn new(now: Instant) -> Self {
        Progressive {
            version: 1,
            last_change: now.checked_sub(IDLE_AFTER).unwrap_or(now),
            in_flight: None,
            done: None,
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
        self.in_flight.is_some_and(|j| j.level > 0)
    }

    pub fn is_idle(&self, now: Instant) -> bool {
        now.duration_since(self.last_change) >= IDLE_AFTER
    }

    /// The full-quality frame of the current view is on screen and nothing is pending.
    pub fn settled(&self) -> bool {
        self.done == Some(FULL) && self.in_flight.is_none()
    }

    /// The next render to start, if any (None while one is in flight or all is done).
    pub fn next(&mut self, now: Instant) -> Option<Job> {
        if self.in_flight.is_some() {
            return None;
        }
        let level = match self.done {
            None => 0,
            Some(l) if l < FULL && self.is_idle(now) => l + 1,
            Some(_) => return None,
        };
        let job = Job {
            version: self.version,
            level,
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
            return true;
        }
        // An outdated coarse frame is still better than nothing while dragging.
        ok && job.level == 0
    }

    /// When the caller should look again even without input (idle refinement).
    pub fn wake_at(&self) -> Option<Instant> {
        (self.in_flight.is_none() && !self.settled()).then(|| self.last_change + IDLE_AFTER)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert_eq!(seen, vec![0, 1, 2]);
        assert!(p.settled());
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
    fn level_sizes() {
        assert_eq!(LEVELS[0].size(1024, 768), (128, 96));
        assert_eq!(LEVELS[FULL].size(1024, 768), (1024, 768));
        assert_eq!(LEVELS[0].size(2, 2), (1, 1));
        assert_eq!(LEVELS[FULL].step_factor, 1.0);
    }
}
