//! The camera: an OV7725-class sensor configured over SCCB (I2C1) for QVGA YUYV, its pixel
//! clock from MCO1, frames captured by DCMI + DMA as single snapshots into a buffer in
//! AXI SRAM (38 400 words, under the DMA's 65 535-word limit), with a timeout.
//!
//! The register values are the OV7725 datasheet's QVGA settings; they are not yet tried on
//! hardware (firmware/README.md).

use embassy_stm32::dcmi::Dcmi;
use embassy_stm32::i2c::{I2c, Master};
use embassy_stm32::interrupt::typelevel::{self, Handler};
use embassy_stm32::mode::Async;
use embassy_stm32::peripherals::DCMI;
use embassy_time::Timer;
use rollfuse_fw::frame_clock;
use rollfuse_fw::pipeline::{Camera, FRAME_WORDS};

/// SCCB address of the sensor (7-bit).
const ADDRESS: u8 = 0x21;

/// Register, value: reset first, then QVGA, YUV output, the 320×240 window.
const SETUP: &[(u8, u8)] = &[
    (0x12, 0x40), // COM7: QVGA, YUV
    (0x11, 0x01), // CLKRC: internal clock = input / 2
    (0x67, 0x00), // DSP_Ctrl4: YUV output from the DSP
    (0x0C, 0x18), // COM3: bytes Y U Y V (bit 3; clear, the reset state, gives U Y V Y);
    //               bit 4 as at reset
    (0x17, 0x3F), // HSTART
    (0x18, 0x50), // HSIZE: 320 / 4
    (0x19, 0x03), // VSTART
    (0x1A, 0x78), // VSIZE: 240 / 2
    (0x32, 0x00), // HREF
    (0x29, 0x50), // HOutSize: 320 / 4
    (0x2C, 0x78), // VOutSize: 240 / 2
    (0x2A, 0x00), // EXHCH
];

/// Why the camera could not be used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum CameraError {
    /// The sensor did not answer on SCCB.
    Sccb,
    /// The product ID is not an OV7725's (0x77xx).
    NotOv7725(u16),
}

/// Resets and configures the sensor.
pub async fn setup(i2c: &mut I2c<'static, Async, Master>) -> Result<(), CameraError> {
    let mut id = [0u8; 2];
    i2c.write_read(ADDRESS, &[0x0A], &mut id[..1])
        .await
        .map_err(|_| CameraError::Sccb)?;
    i2c.write_read(ADDRESS, &[0x0B], &mut id[1..])
        .await
        .map_err(|_| CameraError::Sccb)?;
    let pid = u16::from_be_bytes(id);
    if pid >> 8 != 0x77 {
        return Err(CameraError::NotOv7725(pid));
    }
    i2c.write(ADDRESS, &[0x12, 0x80])
        .await
        .map_err(|_| CameraError::Sccb)?;
    Timer::after_millis(5).await;
    for &(reg, value) in SETUP {
        i2c.write(ADDRESS, &[reg, value])
            .await
            .map_err(|_| CameraError::Sccb)?;
    }
    Ok(())
}

/// The DCMI with its DMA stream, as the pipeline's camera.
pub struct DcmiCamera(pub Dcmi<'static, DCMI>);

impl Camera for DcmiCamera {
    async fn capture(&mut self, frame: &mut [u32; FRAME_WORDS]) -> bool {
        // Frame-sync edges while the capture is armed give the frame's start
        // (`FrameSync`); the HAL leaves this enable alone.
        embassy_stm32::pac::DCMI
            .ier()
            .modify(|r| r.set_vsync_ie(true));
        self.0.capture(frame.as_mut_slice()).await.is_ok()
    }

    fn reset(&mut self) {
        // Dropping the capture stopped its DMA transfer; the interface is still waiting
        // for a frame: disable it, so the next capture starts clean.
        embassy_stm32::pac::DCMI.cr().modify(|r| {
            r.set_capture(false);
            r.set_enable(false);
        });
    }
}

/// The DCMI's frame-sync interrupt, bound before the HAL's handler: at each VSYNC edge
/// into blanking (a frame's end) the roller's step count is latched for
/// `frame_clock`, before the HAL wakes the capture that the same edge completes.
pub struct FrameSync;

impl Handler<typelevel::DCMI> for FrameSync {
    unsafe fn on_interrupt() {
        let dcmi = embassy_stm32::pac::DCMI;
        if dcmi.ris().read().vsync_ris() {
            dcmi.icr().write(|r| r.set_vsync_isc(true));
            frame_clock::frame_edge();
        }
    }
}
