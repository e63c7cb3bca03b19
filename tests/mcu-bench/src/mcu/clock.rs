//! Counting instructions with SysTick.

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;

/// SysTick's 24-bit counter range.
const RELOAD: u32 = 0x00FF_FFFF;

/// SysTick free-running from the core clock. A measured section must stay below 2²⁴ ticks
/// (about 670 M instructions); the largest here is a few million.
pub struct Clock {
    /// Instructions per tick, measured by [`Clock::calibrate`] (40 at 25 MHz).
    per_tick: u32,
}

impl Clock {
    /// Starts the counter.
    pub fn start(mut syst: SYST) -> Self {
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(RELOAD);
        syst.clear_current();
        syst.enable_counter();
        let mut clock = Self { per_tick: 1 };
        clock.per_tick = clock.calibrate();
        clock
    }

    /// Ticks `f` takes.
    pub fn ticks<R>(&self, f: impl FnOnce() -> R) -> (R, u32) {
        section_marker();
        let start = SYST::get_current();
        let out = f();
        let end = SYST::get_current();
        section_marker();
        // A down-counter: elapsed ticks modulo its range.
        (out, start.wrapping_sub(end) & RELOAD)
    }

    /// Instructions `f` takes, to the nearest tick.
    pub fn instructions<R>(&self, f: impl FnOnce() -> R) -> (R, u64) {
        let (out, ticks) = self.ticks(f);
        (out, u64::from(ticks) * u64::from(self.per_tick))
    }

    /// Instructions per tick, from a loop of known length: `2 · LOOPS` instructions
    /// (`subs` and `bne` per turn).
    pub fn calibrate(&self) -> u32 {
        const LOOPS: u32 = 1_000_000;
        let (_, ticks) = self.ticks(|| {
            let mut n = LOOPS;
            // SAFETY: a register-only countdown loop.
            unsafe {
                core::arch::asm!(
                    "1:",
                    "subs {n}, {n}, #1",
                    "bne 1b",
                    n = inout(reg) n,
                    options(nomem, nostack),
                );
            }
            n
        });
        (2 * LOOPS + ticks / 2) / ticks.max(1)
    }

    /// The calibrated instructions per tick.
    pub fn per_tick(&self) -> u32 {
        self.per_tick
    }
}

/// Called before and after every timed section when profiling (feature `profile`): the
/// profiler (`tests/mcu-bench/profile.py`) counts the instructions QEMU executes between
/// two calls, by function. Out of line so that it shows in the log; a no-op otherwise.
#[cfg(feature = "profile")]
#[inline(never)]
fn section_marker() {
    cortex_m::asm::nop();
}

#[cfg(not(feature = "profile"))]
#[inline(always)]
fn section_marker() {}
