//! The firmware's tasks, written against small traits for their peripherals, so the same
//! code runs on the board (`src/mcu/` wires the STM32H743's peripherals in) and in host
//! tests with mock peripherals (`tests/tasks.rs`).
//!
//! - [`link`]: the USB link — commands to the core's `Controller`, messages out, the host's
//!   presence watched.
//! - [`pipeline`]: captures on frame triggers, the core's device pipeline, tiles to the
//!   [`outbox`].
//! - [`roller`]: the stepper's steps and frame triggers, and the stop path no queue holds.
//! - [`effects`]: accepted commands' effects to the LEDs, the roller and the pipeline.
//! - [`liveness`]: what the watchdog is fed on; [`counters`]: what `Status` reports;
//!   [`signals`]: the queues and signals between the tasks.
#![no_std]

pub mod log;

pub mod counters;
pub mod effects;
pub mod link;
pub mod liveness;
pub mod outbox;
pub mod pipeline;
pub mod roller;
pub mod signals;
