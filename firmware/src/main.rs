//! rollfuse edge-module firmware for the STM32H743ZI.
//!
//! This first cut boots, runs a self-test of the fusion core on the MCU, logs over
//! defmt-RTT and blinks the board LED (PB0 on a NUCLEO-H743ZI). The camera, pipeline,
//! motion and USB tasks follow; the numeric work they call lives in `rollfuse-core`.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(target_os = "none")]
mod mcu {
    use defmt::{error, info};
    use embassy_executor::Spawner;
    use embassy_stm32::gpio::{Level, Output, Speed};
    use embassy_time::{Instant, Timer};
    use rollfuse_core::fusion::{LlWeight, U8Work, fuse_scratch_words, fuse_u8};
    use rollfuse_core::{Dims, FuseConfig};
    use {defmt_rtt as _, panic_probe as _};

    /// Side of the self-test tiles.
    const N: usize = 16;

    /// Fuses a tile with a flat one on the integer path and checks the edge survives: a
    /// wrong build of the core (or a broken FPU-less path) shows here, at boot.
    fn self_test() -> Result<u32, rollfuse_core::Error> {
        let dims = Dims::new(N, N)?;
        let edge: [u8; N * N] = core::array::from_fn(|i| if i % N < N / 2 { 40 } else { 200 });
        let flat = [120u8; N * N];
        let (mut a, mut b) = ([0i32; N * N], [0i32; N * N]);
        let mut scratch = [0i32; fuse_scratch_words(N, N)];
        let work = U8Work {
            a: &mut a,
            b: &mut b,
            scratch: &mut scratch,
        };
        fuse_u8(
            (&edge, dims),
            (&flat, dims),
            &FuseConfig::default(),
            LlWeight::HALF,
            work,
        )?;
        // The step across the middle of the first row.
        Ok(a[N / 2].abs_diff(a[N / 2 - 1]))
    }

    #[embassy_executor::main]
    async fn main(_spawner: Spawner) {
        let p = embassy_stm32::init(Default::default());
        info!("rollfuse-fw {}", env!("CARGO_PKG_VERSION"));
        let t0 = Instant::now();
        match self_test() {
            Ok(step) => info!(
                "fusion self-test: edge step {} of 160 kept, {} us",
                step,
                t0.elapsed().as_micros()
            ),
            Err(_) => error!("fusion self-test failed"),
        }
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
