//! rollfuse edge-module firmware for the STM32H743ZI (see README.md).
//!
//! Camera (OV7725 over SCCB, DCMI + DMA snapshots) → the core's device pipeline → fused
//! tiles over USB (vendor interface, one protocol message per transfer), with commands
//! answered by the core's `device::Controller` — the same pipeline and controller the
//! host's virtual device runs. The roller's stepper follows the core's trapezoidal ramp
//! and triggers frames at equal belt spacing; three PWM LEDs; defmt-RTT logs; an
//! independent watchdog.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(target_os = "none")]
mod mcu;

/// On the host the firmware is an empty program: it exists only so that workspace-wide
/// `cargo clippy` and `cargo fmt` cover this crate.
#[cfg(not(target_os = "none"))]
fn main() {}
