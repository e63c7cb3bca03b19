//! The roller's motion: a trapezoidal speed profile as step intervals for a hardware timer,
//! and frame triggers equally spaced in belt distance.
//!
//! Accelerating from rest at `a` steps/s², step `n` is reached at `t(n) = √(2n/a)`; the
//! interval before step `n + 1` is `t(n+1) − t(n)`, in timer ticks computed exactly from
//! the integer square root of `2n·f²/a` (no accumulated rounding: each step's time is
//! rounded on its own). At the target speed `v` the interval is `f/v`; slowing down walks
//! the same ramp back. [`Ramp::next_step`] gives the interval before each step and whether that
//! step triggers a frame (every `steps_per_frame` steps).

/// How the belt and the stepper relate, and the timer's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MotionConfig {
    /// Belt travel per motor step, nanometres.
    pub nm_per_step: u32,
    /// Acceleration, µm/s².
    pub accel_um_s2: u32,
    /// Step timer clock, Hz.
    pub timer_hz: u32,
}

/// The fastest step timer a ramp takes, Hz.
pub const MAX_TIMER_HZ: u32 = 100_000_000;

/// Why a motion request was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionError {
    /// A zero or absurd configuration value.
    Config,
    /// A speed of zero or beyond one step per timer tick.
    Speed,
}

impl MotionConfig {
    fn check(&self) -> Result<(), MotionError> {
        // The ramp squares the timer's rate in 64 bits (`Ramp::new`): 2·f² must fit.
        if self.nm_per_step == 0
            || self.accel_um_s2 == 0
            || !(1000..=MAX_TIMER_HZ).contains(&self.timer_hz)
        {
            return Err(MotionError::Config);
        }
        Ok(())
    }

    /// Whether the ramp can run the belt at `speed_um_s` (> 0): at least one step a second
    /// and at most one a timer tick; else [`MotionError::Speed`]. A device refuses such a
    /// speed before it acknowledges it ([`crate::device::Controller::with_motion`]).
    pub fn check_speed(&self, speed_um_s: u32) -> Result<(), MotionError> {
        let v = self.steps_per_s(speed_um_s);
        if v == 0 || v > u64::from(self.timer_hz) {
            return Err(MotionError::Speed);
        }
        Ok(())
    }

    /// Speed in steps/s for a belt speed in µm/s.
    fn steps_per_s(&self, speed_um_s: u32) -> u64 {
        u64::from(speed_um_s) * 1000 / u64::from(self.nm_per_step)
    }

    /// Acceleration in steps/s² (at least 1).
    fn accel_steps(&self) -> u64 {
        (u64::from(self.accel_um_s2) * 1000 / u64::from(self.nm_per_step)).max(1)
    }

    /// Motor steps between frames `spacing_um` apart on the belt (at least 1).
    pub fn steps_per_frame(&self, spacing_um: u32) -> u32 {
        let nm = u64::from(spacing_um) * 1000;
        let n = (nm + u64::from(self.nm_per_step) / 2) / u64::from(self.nm_per_step);
        n.clamp(1, u64::from(u32::MAX)) as u32
    }
}

/// One step: how long to wait before it (timer ticks), and whether it triggers a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Step {
    /// Ticks since the previous step.
    pub interval: u32,
    /// Take a frame at this step.
    pub trigger: bool,
}

/// A step generator: ramps to a target speed, holds it, ramps down to stop.
#[derive(Debug, Clone)]
pub struct Ramp {
    cfg: MotionConfig,
    /// `2·f²/a`: step `n` of the ramp is at `√(n·k)` ticks.
    ramp_k: u64,
    /// Ramp position: the current speed is that of step `n` of the ramp.
    n: u64,
    /// Ramp position of the target speed (0 = stop).
    target_n: u64,
    /// Interval at the target speed, ticks.
    cruise: u64,
    steps_per_frame: u32,
    steps: u64,
}

impl Ramp {
    /// A stopped ramp; frames every `steps_per_frame` steps (0 = no frames).
    pub fn new(cfg: MotionConfig, steps_per_frame: u32) -> Result<Self, MotionError> {
        cfg.check()?;
        let f = u64::from(cfg.timer_hz);
        Ok(Self {
            cfg,
            ramp_k: 2 * f * f / cfg.accel_steps(),
            n: 0,
            target_n: 0,
            cruise: 0,
            steps_per_frame,
            steps: 0,
        })
    }

    /// Sets the target belt speed (0 = ramp down and stop).
    pub fn set_speed(&mut self, speed_um_s: u32) -> Result<(), MotionError> {
        if speed_um_s == 0 {
            self.target_n = 0;
            return Ok(());
        }
        self.cfg.check_speed(speed_um_s)?;
        let v = self.cfg.steps_per_s(speed_um_s);
        let f = u64::from(self.cfg.timer_hz);
        // v² = 2·a·n.
        self.target_n = (v * v / (2 * self.cfg.accel_steps())).max(1);
        self.cruise = f / v;
        Ok(())
    }

    /// Ticks from rest to step `n` of the ramp.
    fn at(&self, n: u64) -> u64 {
        (n.saturating_mul(self.ramp_k)).isqrt()
    }

    /// Whether the roller is stopped (and will stay so until a new speed is set).
    pub fn is_stopped(&self) -> bool {
        self.n == 0 && self.target_n == 0
    }

    /// Frames every `n` steps from now on (0 = no frames).
    pub fn set_steps_per_frame(&mut self, n: u32) {
        self.steps_per_frame = n;
    }

    /// Steps taken since creation.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The next step, or `None` when stopped.
    pub fn next_step(&mut self) -> Option<Step> {
        let interval = if self.n < self.target_n {
            let i = self.at(self.n + 1) - self.at(self.n);
            self.n += 1;
            i
        } else if self.n > self.target_n {
            // Walking the ramp back; its last step brings the roller to rest.
            let i = self.at(self.n) - self.at(self.n - 1);
            self.n -= 1;
            i
        } else if self.n == 0 {
            return None;
        } else {
            self.cruise
        };
        self.steps += 1;
        let trigger =
            self.steps_per_frame > 0 && self.steps.is_multiple_of(u64::from(self.steps_per_frame));
        Some(Step {
            interval: interval.clamp(1, u64::from(u32::MAX)) as u32,
            trigger,
        })
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    const CFG: MotionConfig = MotionConfig {
        nm_per_step: 5_000, // 5 µm of belt per step
        accel_um_s2: 200_000,
        timer_hz: 1_000_000,
    };

    /// Ideal time (s) of step `k` of a move: accelerate at `a` to `v`, cruise; steps/s.
    fn ideal(k: f64, a: f64, v: f64) -> f64 {
        let n_ramp = v * v / (2.0 * a);
        if k <= n_ramp {
            (2.0 * k / a).sqrt()
        } else {
            v / a + (k - n_ramp) / v
        }
    }

    #[test]
    fn steps_follow_the_ideal_trapezoid_within_one_percent() {
        let mut r = Ramp::new(CFG, 0).unwrap();
        r.set_speed(20_000).unwrap(); // 20 mm/s = 4000 steps/s
        let (a, v) = (40_000.0, 4_000.0); // steps/s², steps/s
        let mut t = 0u64;
        for k in 1..=2000u64 {
            t += u64::from(r.next_step().unwrap().interval);
            let got = t as f64 / 1e6;
            let want = ideal(k as f64, a, v);
            assert!(
                (got - want).abs() <= 0.01 * want + 2e-6,
                "step {k}: {got} s, ideal {want} s"
            );
        }
        // Stop: the ramp down mirrors the ramp up and ends at rest.
        r.set_speed(0).unwrap();
        let down: Vec<u32> = core::iter::from_fn(|| r.next_step().map(|s| s.interval)).collect();
        assert_eq!(down.len() as u64, 4_000 * 4_000 / (2 * 40_000));
        // Slowing down, up to one tick of rounding per step.
        assert!(down.windows(2).all(|w| w[1] + 1 >= w[0]), "slowing down");
        assert!(r.is_stopped());
        assert_eq!(r.next_step(), None);
    }

    #[test]
    fn frames_trigger_at_the_configured_spacing() {
        // 100 µm between frames = 20 steps.
        let n = CFG.steps_per_frame(100);
        assert_eq!(n, 20);
        let mut r = Ramp::new(CFG, n).unwrap();
        r.set_speed(10_000).unwrap();
        let triggers: Vec<u64> = (1..=1000u64)
            .filter(|_| r.next_step().unwrap().trigger)
            .collect();
        assert_eq!(triggers.len(), 50);
        assert_eq!(CFG.steps_per_frame(1), 1, "never zero");
        r.set_steps_per_frame(0);
        assert!((0..100).all(|_| !r.next_step().unwrap().trigger));
    }

    #[test]
    fn bad_requests_are_refused() {
        assert_eq!(
            Ramp::new(
                MotionConfig {
                    nm_per_step: 0,
                    ..CFG
                },
                1
            )
            .err(),
            Some(MotionError::Config)
        );
        // A timer whose rate the ramp could not square in 64 bits.
        for timer_hz in [999, MAX_TIMER_HZ + 1, u32::MAX] {
            let cfg = MotionConfig { timer_hz, ..CFG };
            assert_eq!(
                Ramp::new(cfg, 1).err(),
                Some(MotionError::Config),
                "{timer_hz}"
            );
        }
        assert!(
            Ramp::new(
                MotionConfig {
                    timer_hz: MAX_TIMER_HZ,
                    ..CFG
                },
                1
            )
            .is_ok()
        );
        let mut r = Ramp::new(CFG, 1).unwrap();
        // Faster than one step per tick, slower than one a second (5 µm a step).
        assert_eq!(r.set_speed(u32::MAX), Err(MotionError::Speed));
        assert_eq!(r.set_speed(4), Err(MotionError::Speed));
        assert_eq!(r.next_step(), None, "still stopped");
        assert_eq!(r.set_speed(5), Ok(()), "one step a second");
    }
}
