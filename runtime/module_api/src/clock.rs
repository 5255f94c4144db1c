//! The run clock: one time base for every module of a run, which can run faster than real time.
//!
//! `armor run` picks an epoch (a Unix time in nanoseconds) and a scale and passes both to every
//! module in `ARMOR_EPOCH_NS` and `ARMOR_TIME_SCALE`. Run time is `(now - epoch) × scale`, so all
//! modules agree on it and a ten-minute simulated mission can pass in seconds.

use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

pub const ENV_EPOCH: &str = "ARMOR_EPOCH_NS";
pub const ENV_TIME_SCALE: &str = "ARMOR_TIME_SCALE";

#[derive(Clone, Copy, Debug)]
pub struct Clock {
    /// The instant at which run time was zero, expressed on this process's monotonic clock.
    zero: Instant,
    /// Run time at `zero` is 0; when the epoch lies in the future `zero` is now and this is negative.
    offset_secs: f64,
    scale: f64,
}

impl Clock {
    /// A clock whose run time is zero at `epoch_unix_ns` and runs `scale` times real time.
    pub fn new(epoch_unix_ns: u64, scale: f64) -> Self {
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            1.0
        };
        let now_ns = unix_now_ns();
        let zero = Instant::now();
        let since_epoch_secs = (now_ns as f64 - epoch_unix_ns as f64) / 1e9;
        Self {
            zero,
            offset_secs: since_epoch_secs,
            scale,
        }
    }

    /// A clock starting now at real-time speed.
    pub fn real_time() -> Self {
        Self::new(unix_now_ns(), 1.0)
    }

    /// The clock of this run, from the environment `armor run` sets (real time from now if unset).
    pub fn from_env() -> Self {
        let epoch = std::env::var(ENV_EPOCH).ok().and_then(|v| v.parse().ok());
        let scale = std::env::var(ENV_TIME_SCALE)
            .ok()
            .and_then(|v| v.parse().ok());
        Self::new(epoch.unwrap_or_else(unix_now_ns), scale.unwrap_or(1.0))
    }

    /// Moves run time forward by `run_secs` (test benches only: real clocks never jump).
    pub(crate) fn advance(&mut self, run_secs: f64) {
        if run_secs.is_finite() && run_secs > 0.0 {
            self.offset_secs += run_secs / self.scale;
        }
    }

    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// Run time in seconds at the given instant.
    pub fn at(&self, instant: Instant) -> f64 {
        let real = match instant.checked_duration_since(self.zero) {
            Some(after) => after.as_secs_f64(),
            None => -self.zero.duration_since(instant).as_secs_f64(),
        };
        (self.offset_secs + real) * self.scale
    }

    /// Run time in seconds, now.
    pub fn now_secs(&self) -> f64 {
        self.at(Instant::now())
    }

    /// Run time in nanoseconds, now (0 before the epoch).
    pub fn now_ns(&self) -> u64 {
        let now = Instant::now();
        // At real-time speed, in integers: every sample is stamped, and on a VM the clock read
        // and the float conversions were a third of what publishing a small sample costs.
        if self.scale == 1.0
            && let Some(after) = now.checked_duration_since(self.zero)
        {
            let after_ns = i64::try_from(after.as_nanos()).unwrap_or(i64::MAX);
            return u64::try_from(self.offset_ns().saturating_add(after_ns)).unwrap_or(0);
        }
        (self.at(now) * 1e9).max(0.0) as u64
    }

    /// `offset_secs` in whole nanoseconds.
    fn offset_ns(&self) -> i64 {
        (self.offset_secs * 1e9) as i64
    }

    /// How long in real time a span of run time lasts.
    pub fn real_duration(&self, run_secs: f64) -> Duration {
        Duration::from_secs_f64((run_secs / self.scale).clamp(0.0, 1e9))
    }

    /// The real instant at which run time reaches `run_secs`.
    pub fn instant_at(&self, run_secs: f64) -> Instant {
        let now = Instant::now();
        let ahead = run_secs - self.at(now);
        if ahead > 0.0 {
            now + self.real_duration(ahead)
        } else {
            now
        }
    }
}

pub fn unix_now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |since| since.as_nanos() as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_clock_runs_faster_and_agrees_across_instances() {
        let epoch = unix_now_ns() - 2_000_000_000;
        let a = Clock::new(epoch, 10.0);
        let b = Clock::new(epoch, 10.0);
        let now = Instant::now();
        assert!((a.at(now) - 20.0).abs() < 0.5, "{}", a.at(now));
        assert!((a.at(now) - b.at(now)).abs() < 0.01);
        assert!((a.at(now + Duration::from_secs(1)) - a.at(now) - 10.0).abs() < 1e-9);
        assert_eq!(a.real_duration(5.0), Duration::from_millis(500));
    }

    #[test]
    fn stamps_at_real_speed_agree_with_run_time_and_never_go_back() {
        let epoch = unix_now_ns() - 3_000_000_000;
        for clock in [Clock::new(epoch, 1.0), Clock::new(epoch, 2.0)] {
            let before = clock.now_secs();
            let mut last = clock.now_ns();
            for _ in 0..1000 {
                let stamp = clock.now_ns();
                assert!(stamp >= last, "{stamp} after {last}");
                last = stamp;
            }
            let after = clock.now_secs();
            let stamp_secs = last as f64 / 1e9;
            assert!(
                stamp_secs >= before - 1e-6 && stamp_secs <= after + 1e-6,
                "{stamp_secs} outside {before}..{after}"
            );
        }
        // Before the epoch: 0, not a wrapped number.
        assert_eq!(Clock::new(unix_now_ns() + 60_000_000_000, 1.0).now_ns(), 0);
    }

    #[test]
    fn advancing_moves_run_time_in_run_seconds() {
        let mut clock = Clock::new(unix_now_ns(), 4.0);
        let now = Instant::now();
        let before = clock.at(now);
        clock.advance(10.0);
        assert!((clock.at(now) - before - 10.0).abs() < 1e-9);
        clock.advance(f64::NAN);
        clock.advance(-5.0);
        assert!((clock.at(now) - before - 10.0).abs() < 1e-9);
    }

    #[test]
    fn nonsense_scale_falls_back_to_real_time() {
        assert_eq!(Clock::new(0, f64::NAN).scale(), 1.0);
        assert_eq!(Clock::new(0, -3.0).scale(), 1.0);
    }
}
