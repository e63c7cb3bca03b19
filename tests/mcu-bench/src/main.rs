//! Instruction counts of the device pipeline and its kernels on a Cortex-M7, under QEMU's
//! `mps2-an500` board with `-icount shift=0` (one instruction per virtual nanosecond, so
//! the 25 MHz SysTick advances once every 40 instructions). Results go to the host over
//! semihosting as CSV; `tests/mcu-bench/run.sh` builds, runs and checks them.
//!
//! The frames are drawn by code in the binary (a textured belt moving 16 camera pixels per
//! frame), so every run of one build prints the same numbers.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(target_os = "none")]
mod mcu;

/// On the host the bench is an empty program: it exists only so that workspace-wide
/// `cargo clippy` and `cargo fmt` cover this crate.
#[cfg(not(target_os = "none"))]
fn main() {}
