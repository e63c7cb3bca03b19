//! The roller: step pulses from the core's trapezoidal ramp (`rollfuse_core::motion`),
//! timed against absolute deadlines of the 1 MHz time driver (TIM2), so intervals never
//! accumulate error; a frame trigger every `steps_per_frame` steps.
//!
//! The pins are the board's ([`StepPins`]; on the NUCLEO: STEP PF13, DIR PF12 fixed
//! forward, ENABLE PF14 low = driver on).

use crate::counters::COUNTERS;
use crate::liveness;
use crate::signals::{self, TRIGGERS, roller_stops_requested};
use crate::{fw_info, fw_warn};
use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use embassy_futures::select::{Either3, select3};
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Instant, Timer};
use rollfuse_core::motion::{MotionConfig, Ramp};
use rollfuse_core::protocol::RollerCommand;

/// The mechanics: a 24 mm roller driven by a 200-step motor at 16 microsteps
/// (75.4 mm / 3200 steps = 23.56 µm of belt per step), 100 mm/s² of acceleration.
pub const MECHANICS: MotionConfig = MotionConfig {
    nm_per_step: 23_562,
    accel_um_s2: 100_000,
    timer_hz: 1_000_000,
};

/// The optics: belt micrometres per camera pixel.
pub const UM_PER_PX: u32 = 50;

/// The belt's travel after `steps` steps, camera pixels (rounded down).
pub fn belt_px(steps: u64) -> u64 {
    steps * u64::from(MECHANICS.nm_per_step) / (u64::from(UM_PER_PX) * 1000)
}

/// What the motion task is told.
#[derive(Debug, Clone, Copy)]
pub enum Order {
    /// A roller command from the host, accepted after `stops` stops had been requested
    /// ([`roller_stops_requested`]). A Start or Speed that a later stop overtook is dropped: a
    /// stop is never queued, so it can reach the step generator before orders accepted
    /// ahead of it.
    Roller {
        /// The command.
        command: RollerCommand,
        /// [`roller_stops_requested`] when the command was accepted.
        stops: u32,
    },
    /// A new frame spacing, camera pixels.
    FrameSpacing(u16),
}

/// Orders for the motion task.
pub static ORDERS: Channel<CriticalSectionRawMutex, Order, 4> = Channel::new();

/// A stop requested and not yet taken up by the step generator. Set from anywhere, never
/// queued: no full queue can lose it.
static STOP: AtomicBool = AtomicBool::new(false);

/// Wakes the motion task when it waits for orders while stopped is requested.
static STOP_SIGNAL: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// Stops the roller (ramping down): the step generator sees it at once, and drops the
/// roller orders accepted before it that are still queued.
pub fn stop() {
    signals::count_roller_stop();
    STOP.store(true, Ordering::Release);
    STOP_SIGNAL.signal(());
}

/// Steps taken since start-up (a 64-bit count: no atomic of that width on the M7).
static STEPS: Mutex<CriticalSectionRawMutex, Cell<u64>> = Mutex::new(Cell::new(0));

/// Steps taken since start-up.
pub fn steps() -> u64 {
    STEPS.lock(Cell::get)
}

/// The latest any step came after its deadline since [`take_worst_lateness`] last looked,
/// microseconds.
static WORST_LATENESS_US: AtomicU32 = AtomicU32::new(0);

/// How late the latest step came since the last call (then starts afresh): the
/// step generator's jitter, for bring-up and the QEMU run.
pub fn take_worst_lateness() -> Duration {
    Duration::from_micros(u64::from(WORST_LATENESS_US.swap(0, Ordering::Relaxed)))
}

/// Whether a trigger was signalled and the camera has not taken it yet.
static TRIGGER_PENDING: AtomicBool = AtomicBool::new(false);

/// The camera took the last trigger.
pub fn trigger_taken() {
    TRIGGER_PENDING.store(false, Ordering::Release);
}

/// Takes a pending stop, if any.
fn stop_requested() -> bool {
    STOP.swap(false, Ordering::AcqRel)
}

/// The stepper driver's pins.
pub trait StepPins {
    /// Raises (`true`) or lowers the STEP line.
    fn step(&mut self, high: bool);
    /// Turns the driver on (`true`: ENABLE low) or off.
    fn enable(&mut self, on: bool);
}

/// Runs the roller forever. On the board it runs on the interrupt-priority executor, so
/// the pipeline's fusion (thread mode, milliseconds a frame) never delays a step.
pub async fn run(pins: &mut impl StepPins, spacing_px: u16) {
    let steps_per_frame = |px: u16| MECHANICS.steps_per_frame(u32::from(px) * UM_PER_PX);
    let Ok(mut ramp) = Ramp::new(MECHANICS, steps_per_frame(spacing_px)) else {
        fw_warn!("motion configuration refused; the roller stays off");
        return;
    };
    pins.enable(false);
    loop {
        // Stopped: wait for an order.
        if ramp.is_stopped() {
            pins.enable(false);
            // A stop while stopped has nothing to do; an order after it starts afresh.
            let _ = stop_requested();
            liveness::beat(liveness::Task::Motion);
            let wake = select3(
                ORDERS.receive(),
                STOP_SIGNAL.wait(),
                Timer::after(liveness::BEAT),
            );
            if let Either3::First(order) = wake.await {
                apply(&mut ramp, order, &steps_per_frame);
            }
            continue;
        }
        pins.enable(true);
        let mut deadline = Instant::now();
        while let Some(s) = ramp.next_step() {
            if stop_requested() {
                let _ = ramp.set_speed(0);
            }
            deadline += Duration::from_ticks(u64::from(s.interval));
            wait_for_step(&mut ramp, deadline, &steps_per_frame).await;
            let late = Instant::now().saturating_duration_since(deadline);
            let late_us = u32::try_from(late.as_micros()).unwrap_or(u32::MAX);
            WORST_LATENESS_US.fetch_max(late_us, Ordering::Relaxed);
            pins.step(true);
            STEPS.lock(|n| n.set(n.get() + 1));
            // The driver needs a pulse of at least a microsecond or two.
            Timer::after_micros(2).await;
            pins.step(false);
            if s.trigger {
                // A trigger the camera has not taken yet is overwritten: a lost frame.
                if TRIGGER_PENDING.swap(true, Ordering::AcqRel) {
                    COUNTERS.camera_overruns.fetch_add(1, Ordering::Relaxed);
                }
                TRIGGERS.signal(());
            }
        }
    }
}

/// Waits for the step due at `deadline`, beating at least every [`liveness::BEAT`] (a slow
/// belt steps once a second or less), applying orders as they arrive and a stop at once.
/// The step already due is still taken.
async fn wait_for_step(ramp: &mut Ramp, deadline: Instant, steps_per_frame: &impl Fn(u16) -> u32) {
    loop {
        liveness::beat(liveness::Task::Motion);
        let wake = deadline.min(Instant::now() + liveness::BEAT);
        match select3(Timer::at(wake), ORDERS.receive(), STOP_SIGNAL.wait()).await {
            Either3::First(()) if Instant::now() >= deadline => return,
            Either3::First(()) => {}
            Either3::Second(order) => apply(ramp, order, steps_per_frame),
            Either3::Third(()) => {
                if stop_requested() {
                    let _ = ramp.set_speed(0);
                }
            }
        }
    }
}

fn apply(ramp: &mut Ramp, order: Order, steps_per_frame: &impl Fn(u16) -> u32) {
    match order {
        Order::Roller {
            command: RollerCommand::Start { speed_um_s } | RollerCommand::Speed { speed_um_s },
            stops,
        } => {
            if stops != roller_stops_requested() {
                fw_info!("a roller order from before a stop dropped");
            } else if ramp.set_speed(speed_um_s).is_err() {
                fw_warn!("roller speed {} um/s refused", speed_um_s);
            }
        }
        Order::Roller {
            command: RollerCommand::Stop,
            ..
        } => {
            let _ = ramp.set_speed(0);
        }
        Order::FrameSpacing(px) => {
            ramp.set_steps_per_frame(steps_per_frame(px));
            fw_info!("frames every {} steps", steps_per_frame(px));
        }
    }
}
