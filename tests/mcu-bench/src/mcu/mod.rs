//! The bench on the MCU: set up SysTick, run every measurement, print CSV over
//! semihosting, exit QEMU with the result.

mod clock;
mod frames;
mod lanes;
mod runs;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};

/// Version of the output format (the host's `rollfuse tradeoff` checks it).
const FORMAT: u32 = 2;

#[entry]
fn main() -> ! {
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        halt(false)
    };
    let clock = clock::Clock::start(peripherals.SYST);
    hprintln!("# rollfuse-mcu-bench format {}", FORMAT);
    hprintln!("# board: QEMU mps2-an500 (Cortex-M7), -icount shift=0, SysTick at 25 MHz");
    hprintln!("# {}", runs::HEADER);
    hprintln!(
        "calibration,instructions_per_tick,,,,,,1,{},{},,,",
        clock.per_tick(),
        clock.per_tick()
    );
    if !lanes::agree() {
        halt(false)
    }
    let mut print = |row: &runs::Row| hprintln!("{}", row);
    // Profiling (tests/mcu-bench/profile.sh) runs one configuration: its log stays small.
    let ok = if cfg!(feature = "profile") {
        match runs::profiled() {
            Some((setup, precision)) => runs::one(&clock, setup, precision, &mut print),
            None => {
                hprintln!("# ROLLFUSE_PROFILE names no configuration");
                false
            }
        }
    } else {
        runs::all(&clock, &mut print)
    };
    halt(ok)
}

/// Ends the QEMU run with the bench's result as its exit status.
fn halt(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    // Only reached off QEMU (no semihosting host): stop here.
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("# panic: {}", info);
    halt(false)
}
