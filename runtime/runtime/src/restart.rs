//! When a crashed module is started again: a pure policy that takes the time of each crash, so
//! that it is tested without processes or clocks.
//!
//! The wait doubles with each crash still in the last [`CRASH_WINDOW`], from [`FIRST_BACKOFF`]
//! up to [`MAX_BACKOFF`], so that a module that crashes now and then always comes back after
//! the first backoff; more than [`MAX_CRASHES`] crashes within the window and the module is
//! given up as failed.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// More crashes than this within [`CRASH_WINDOW`] and a module is given up as failed.
pub const MAX_CRASHES: usize = 5;
pub const CRASH_WINDOW: Duration = Duration::from_secs(10);
pub const FIRST_BACKOFF: Duration = Duration::from_millis(100);
pub const MAX_BACKOFF: Duration = Duration::from_secs(5);

/// What to do after a crash.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AfterCrash {
    /// Start the module again at this time (the crash's time plus the backoff).
    RestartAt(Instant, Duration),
    /// Too many crashes in the window: give up (`module.NAME.failed`).
    GiveUp { crashes: usize },
}

/// A module's recent crashes.
#[derive(Clone, Debug, Default)]
pub struct Backoff {
    crashes: VecDeque<Instant>,
}

impl Backoff {
    /// A crash at `now`: when to start again, or to give up.
    pub fn crashed(&mut self, now: Instant) -> AfterCrash {
        self.crashes.push_back(now);
        while self
            .crashes
            .front()
            .is_some_and(|&at| now.saturating_duration_since(at) > CRASH_WINDOW)
        {
            self.crashes.pop_front();
        }
        if self.crashes.len() > MAX_CRASHES {
            return AfterCrash::GiveUp {
                crashes: self.crashes.len(),
            };
        }
        let doublings = u32::try_from(self.crashes.len() - 1)
            .unwrap_or(u32::MAX)
            .min(16);
        let backoff = FIRST_BACKOFF
            .saturating_mul(1 << doublings)
            .min(MAX_BACKOFF);
        AfterCrash::RestartAt(now + backoff, backoff)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The waits after crashes at these offsets (milliseconds from the first), or `None` for
    /// giving up.
    fn check(crashes_ms: &[u64], expected: &[Option<u64>]) {
        let start = Instant::now();
        let mut backoff = Backoff::default();
        let got: Vec<Option<u64>> = crashes_ms
            .iter()
            .map(
                |&ms| match backoff.crashed(start + Duration::from_millis(ms)) {
                    AfterCrash::RestartAt(_, wait) => Some(wait.as_millis() as u64),
                    AfterCrash::GiveUp { .. } => None,
                },
            )
            .collect();
        assert_eq!(got, expected, "crashes at {crashes_ms:?}");
    }

    #[test]
    fn the_wait_doubles_within_the_window_and_gives_up_after_five() {
        check(
            &[0, 200, 500, 1000, 2000, 3000],
            &[Some(100), Some(200), Some(400), Some(800), Some(1600), None],
        );
    }

    #[test]
    fn a_module_that_crashes_now_and_then_comes_back_after_the_first_backoff() {
        check(&[0, 11_000, 22_000, 33_000], &[Some(100); 4]);
    }

    #[test]
    fn crashes_leave_the_window_one_by_one() {
        // At 10.5 s the first crash (at 0) has left the window; the other three stay.
        check(
            &[0, 1000, 2000, 3000, 10_500],
            &[Some(100), Some(200), Some(400), Some(800), Some(800)],
        );
    }
}
