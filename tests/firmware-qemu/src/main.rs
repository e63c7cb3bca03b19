//! The firmware's tasks on QEMU's `mps2-an500` Cortex-M7 board with `-icount shift=0`, with
//! the firmware's statics, stack size and stack guard, against mock peripherals: a USB
//! host that streams, a camera that free-runs at the rate the firmware programs, the
//! stepper's pins, LEDs.
//! Prints over semihosting what `tests/firmware-qemu/run.sh` checks: the stack's
//! high-water mark and how late the roller's steps came while frames were fused.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(target_os = "none")]
mod mcu;

/// On the host this is an empty program: it exists only so that `cargo clippy` and
/// `cargo fmt` cover the crate.
#[cfg(not(target_os = "none"))]
fn main() {}
