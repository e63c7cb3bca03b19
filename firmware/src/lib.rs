//! The firmware's tasks, written against small traits for their peripherals, so the same
//! code runs on the board (`src/mcu/` wires the STM32H743's peripherals in), in host tests
//! with mock peripherals (`tests/`) and on QEMU's Cortex-M7 board (`tests/firmware-qemu`).
//!
//! - [`link`]: the USB link — commands to the core's `Controller`, messages out, the host's
//!   presence watched.
//! - [`pipeline`]: captures on frame triggers, the core's device pipeline, tiles to the
//!   [`outbox`].
//! - [`roller`]: the stepper's steps and frame triggers, and the stop path no queue holds;
//!   [`frame_clock`]: the step count at which a captured frame began.
//! - [`effects`]: accepted commands' effects to the LEDs, the roller and the pipeline.
//! - [`liveness`]: what the watchdog is fed on; [`counters`] and [`cycles`]: what `Status`
//!   reports;
//!   [`signals`]: the queues and signals between the tasks.
//! - [`buffers`]: the large statics; `stack_guard` (MCU only): the MPU region below the
//!   stack.
#![no_std]

pub mod log;

pub mod buffers;
pub mod counters;
pub mod cycles;
pub mod effects;
pub mod frame_clock;
pub mod link;
pub mod liveness;
pub mod outbox;
pub mod pipeline;
pub mod roller;
pub mod sensor;
pub mod signals;
#[cfg(target_os = "none")]
pub mod stack_guard;

use rollfuse_core::device::{CAMERA, Controller, FIRMWARE_VERSION, MCU_CAPACITY};
use rollfuse_core::protocol::DeviceConfig;

/// The controller as the firmware serves it: the module's camera, the default
/// configuration, the pipeline's memory. `None` only if the default configuration did not
/// fit (a host test checks it does).
pub fn controller() -> Option<Controller> {
    Controller::new(CAMERA, FIRMWARE_VERSION, DeviceConfig::default())
        .and_then(|c| c.with_capacity(MCU_CAPACITY))
        .map(|c| c.with_motion(roller::MECHANICS))
        .ok()
}
