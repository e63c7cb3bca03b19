//! The watchdog is fed only while every task comes round: each task's loop beats at least
//! every [`BEAT`] (waits are bounded by it), and the feeder pets the watchdog only when
//! every task has beaten since its last look. A task stuck anywhere — a capture that never
//! ends, a queue that never drains — starves the watchdog and the board restarts.

use core::pin::pin;
use core::sync::atomic::{AtomicU32, Ordering::Relaxed};
use embassy_futures::select::{Either, select};
use embassy_time::{Duration, Instant, TimeoutError, Timer};

/// The longest a task's loop may take between beats.
pub const BEAT: Duration = Duration::from_millis(200);

/// The tasks watched.
#[derive(Debug, Clone, Copy)]
pub enum Task {
    /// The USB link.
    Link,
    /// Capture and fusion.
    Pipeline,
    /// The roller's step generator.
    Motion,
    /// Commands' effects (LEDs, configuration, stream orders).
    Effects,
}

const TASKS: usize = 4;

static BEATS: [AtomicU32; TASKS] = [const { AtomicU32::new(0) }; TASKS];

/// Records that `task` came round its loop.
pub fn beat(task: Task) {
    BEATS[task as usize].fetch_add(1, Relaxed);
}

/// How often `task` has come round (for tests and diagnostics).
pub fn beats(task: Task) -> u32 {
    BEATS[task as usize].load(Relaxed)
}

/// Waits for `fut` at most `limit`, beating for `task` meanwhile: a bounded wait longer
/// than [`BEAT`] is progress, not a stuck task. `fut` is polled to its end or dropped once
/// (never restarted), so a USB write in flight is not cut and sent again.
pub async fn within<F: Future>(
    task: Task,
    limit: Duration,
    fut: F,
) -> Result<F::Output, TimeoutError> {
    let deadline = Instant::now() + limit;
    let mut fut = pin!(fut);
    loop {
        beat(task);
        let next = deadline.min(Instant::now() + BEAT);
        match select(fut.as_mut(), Timer::at(next)).await {
            Either::First(out) => return Ok(out),
            Either::Second(()) if Instant::now() >= deadline => return Err(TimeoutError),
            Either::Second(()) => {}
        }
    }
}

/// Waits for `fut` however long it takes, beating for `task` meanwhile: for a wait on
/// something that is alive and answers in its own time (a host yet to plug in, a queue
/// that a beating task drains), where giving up would lose what is waited for. A task
/// that stalls behind it still starves the watchdog by its own beats.
pub async fn waiting<F: Future>(task: Task, fut: F) -> F::Output {
    let mut fut = pin!(fut);
    loop {
        beat(task);
        if let Either::First(out) = select(fut.as_mut(), Timer::after(BEAT)).await {
            return out;
        }
    }
}

/// Whether every task has beaten since `seen` (which it updates).
pub fn all_alive(seen: &mut [u32; TASKS]) -> bool {
    let mut alive = true;
    for (last, beats) in seen.iter_mut().zip(&BEATS) {
        let now = beats.load(Relaxed);
        alive &= now != *last;
        *last = now;
    }
    alive
}
