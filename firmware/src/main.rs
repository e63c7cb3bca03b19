//! rollfuse edge-module firmware for the STM32H743ZI.
//!
//! This build boots at 400 MHz, runs a self-test of the fusion core, and speaks the
//! product's protocol over USB (vendor interface, bulk OUT 0x01 / IN 0x81, 1209:0001):
//! every command is decoded, validated and answered by the core's `device::Controller`,
//! the same code the host's virtual device runs, and fused tiles queued by the pipeline
//! go out one message per transfer. It drives the three LEDs (PWM) and the roller's
//! stepper (the core's trapezoidal ramp, with frame triggers), logs over defmt-RTT, is
//! guarded by the independent watchdog, and blinks the board LED (PB0 on a NUCLEO-H743ZI).
//! The camera and pipeline tasks follow (see README.md).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(target_os = "none")]
mod mcu;

/// On the host the firmware is an empty program: it exists only so that workspace-wide
/// `cargo clippy` and `cargo fmt` cover this crate.
#[cfg(not(target_os = "none"))]
fn main() {}
