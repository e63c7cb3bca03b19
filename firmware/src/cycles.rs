//! What a frame's fusion costs in processor cycles, measured on the device: the board
//! counts with the DWT's cycle counter, and `Status` reports the worst and the mean since
//! start-up. Without a counter (the host's tests) nothing is timed and both read 0.

use core::cell::Cell;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use rollfuse_core::protocol::StatusCounters;

/// A free-running 32-bit cycle count. It wraps (10.7 s at 400 MHz), far above a fusion.
pub type CycleCounter = fn() -> u32;

#[derive(Clone, Copy)]
struct Tally {
    worst: u32,
    total: u64,
    fusions: u32,
}

static COUNTER: Mutex<CriticalSectionRawMutex, Cell<Option<CycleCounter>>> =
    Mutex::new(Cell::new(None));
static TALLY: Mutex<CriticalSectionRawMutex, Cell<Tally>> = Mutex::new(Cell::new(Tally {
    worst: 0,
    total: 0,
    fusions: 0,
}));

/// Times fusions with `counter` from now on.
pub fn count_with(counter: CycleCounter) {
    COUNTER.lock(|c| c.set(Some(counter)));
}

/// Runs one fusion, timed when there is a counter.
pub fn timed<R>(fusion: impl FnOnce() -> R) -> R {
    let Some(counter) = COUNTER.lock(Cell::get) else {
        return fusion();
    };
    let start = counter();
    let out = fusion();
    let cycles = counter().wrapping_sub(start);
    TALLY.lock(|t| {
        let mut tally = t.get();
        tally.worst = tally.worst.max(cycles);
        tally.total += u64::from(cycles);
        tally.fusions = tally.fusions.saturating_add(1);
        t.set(tally);
    });
    out
}

/// Copies the worst and mean cycles a fusion took into the status.
pub fn merge_into(status: &mut StatusCounters) {
    let tally = TALLY.lock(Cell::get);
    status.fusion_cycles_worst = tally.worst;
    status.fusion_cycles_mean = tally
        .total
        .checked_div(u64::from(tally.fusions))
        .map_or(0, |mean| u32::try_from(mean).unwrap_or(u32::MAX));
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::sync::atomic::{AtomicU32, Ordering::Relaxed};

    static NOW: AtomicU32 = AtomicU32::new(u32::MAX - 500);

    /// A counter that advances by a set amount between reads, wrapping.
    fn counter() -> u32 {
        NOW.load(Relaxed)
    }

    #[test]
    fn fusions_are_timed_across_the_counters_wrap_and_reported_worst_and_mean() {
        let mut status = StatusCounters::default();
        // Not timed without a counter.
        timed(|| NOW.load(Relaxed));
        merge_into(&mut status);
        assert_eq!(
            (status.fusion_cycles_worst, status.fusion_cycles_mean),
            (0, 0)
        );
        count_with(counter);
        // 1 000 cycles across the wrap, then 3 000.
        timed(|| NOW.fetch_add(1_000, Relaxed));
        timed(|| NOW.fetch_add(3_000, Relaxed));
        merge_into(&mut status);
        assert_eq!(status.fusion_cycles_worst, 3_000);
        assert_eq!(status.fusion_cycles_mean, 2_000);
    }
}
