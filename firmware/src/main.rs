//! rollfuse edge-module firmware for the STM32H743ZI.
//!
//! This first cut boots, logs over defmt-RTT and blinks the board LED (PB0 on a
//! NUCLEO-H743ZI). The camera, pipeline, motion and USB tasks are described in
//! `firmware/README.md`; the numeric work they call lives in `rollfuse-core`.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(target_os = "none")]
mod mcu {
    use defmt::info;
    use embassy_executor::Spawner;
    use embassy_stm32::gpio::{Level, Output, Speed};
    use embassy_time::Timer;
    use {defmt_rtt as _, panic_probe as _};

    #[embassy_executor::main]
    async fn main(_spawner: Spawner) {
        let p = embassy_stm32::init(Default::default());
        info!(
            "rollfuse-fw {} (core wavelets: haar, db2)",
            env!("CARGO_PKG_VERSION")
        );
        let mut led = Output::new(p.PB0, Level::High, Speed::Low);
        loop {
            led.toggle();
            Timer::after_millis(500).await;
        }
    }
}

/// On the host the firmware is an empty program: it exists only so that workspace-wide
/// `cargo clippy` and `cargo fmt` cover this crate.
#[cfg(not(target_os = "none"))]
fn main() {}
