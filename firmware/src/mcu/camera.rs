//! The camera: an OV7725-class sensor configured over SCCB (I2C1) for QVGA YUYV, its pixel
//! clock from MCO1, frames captured by DCMI + DMA as single snapshots into a buffer in
//! D2 SRAM (`FRAME_WORDS` words, under the DMA's 65 535-word limit), with a timeout.
//!
//! The register values (`rollfuse_fw::sensor`, host-tested: byte order, window, 30
//! frames/s) are the OV7725 datasheet's QVGA settings; they are not yet tried on hardware
//! (firmware/README.md).

use super::irqs::Irqs;
use core::sync::atomic::Ordering::Relaxed;
use defmt::error;
use embassy_stm32::dcmi::{self, Dcmi};
use embassy_stm32::i2c::{I2c, Master};
use embassy_stm32::mode::Async;
use embassy_stm32::peripherals::DCMI;
use embassy_stm32::rcc::{Mco, Mco1Source, McoConfig, McoPrescaler};
use embassy_stm32::{Peri, peripherals};
use embassy_time::Timer;
use rollfuse_fw::counters::COUNTERS;
use rollfuse_fw::pipeline::{Camera, FRAME_WORDS};
use rollfuse_fw::sensor::{COM7_RESET, PID_OV77XX, Reg, SETUP};

/// SCCB address of the sensor (7-bit).
const ADDRESS: u8 = 0x21;

/// Why the camera could not be used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum CameraError {
    /// The sensor did not answer on SCCB.
    Sccb,
    /// The product ID is not an OV7725's (0x77xx).
    NotOv7725(u16),
}

/// Reads one register.
async fn read(i2c: &mut I2c<'static, Async, Master>, reg: Reg) -> Result<u8, CameraError> {
    let mut value = [0u8];
    i2c.write_read(ADDRESS, &[reg as u8], &mut value)
        .await
        .map_err(|_| CameraError::Sccb)?;
    Ok(value[0])
}

/// Writes one register.
async fn write(
    i2c: &mut I2c<'static, Async, Master>,
    reg: Reg,
    value: u8,
) -> Result<(), CameraError> {
    i2c.write(ADDRESS, &[reg as u8, value])
        .await
        .map_err(|_| CameraError::Sccb)
}

/// Resets and configures the sensor.
pub async fn setup(i2c: &mut I2c<'static, Async, Master>) -> Result<(), CameraError> {
    let pid = read(i2c, Reg::Pid).await?;
    let ver = read(i2c, Reg::Ver).await?;
    if pid != PID_OV77XX {
        return Err(CameraError::NotOv7725(u16::from_be_bytes([pid, ver])));
    }
    write(i2c, Reg::Com7, COM7_RESET).await?;
    // The datasheet's settling time after a register reset.
    Timer::after_millis(5).await;
    for &(reg, value) in SETUP {
        write(i2c, reg, value).await?;
    }
    Ok(())
}

/// What the camera is wired to: its clock (MCO1), SCCB (I2C1 with two DMA streams), the
/// DCMI with its DMA stream, and the DCMI's pins.
pub struct Wiring {
    /// The clock output that drives the sensor's XCLK.
    pub mco: Peri<'static, peripherals::MCO1>,
    /// XCLK.
    pub xclk: Peri<'static, peripherals::PA8>,
    /// SCCB.
    pub i2c: Peri<'static, peripherals::I2C1>,
    /// SCCB clock.
    pub scl: Peri<'static, peripherals::PB8>,
    /// SCCB data.
    pub sda: Peri<'static, peripherals::PB9>,
    /// SCCB's transmit DMA.
    pub i2c_tx_dma: Peri<'static, peripherals::DMA1_CH1>,
    /// SCCB's receive DMA.
    pub i2c_rx_dma: Peri<'static, peripherals::DMA1_CH2>,
    /// The camera interface.
    pub dcmi: Peri<'static, peripherals::DCMI>,
    /// Its DMA stream.
    pub dma: Peri<'static, peripherals::DMA1_CH0>,
    /// D0–D7.
    pub data: DataPins,
    /// Frame sync.
    pub vsync: Peri<'static, peripherals::PG9>,
    /// Line sync.
    pub hsync: Peri<'static, peripherals::PA4>,
    /// Pixel clock.
    pub pixclk: Peri<'static, peripherals::PA6>,
}

/// The DCMI's eight data pins, D0 first.
pub struct DataPins {
    /// D0.
    pub d0: Peri<'static, peripherals::PC6>,
    /// D1.
    pub d1: Peri<'static, peripherals::PC7>,
    /// D2.
    pub d2: Peri<'static, peripherals::PE0>,
    /// D3.
    pub d3: Peri<'static, peripherals::PC9>,
    /// D4.
    pub d4: Peri<'static, peripherals::PE4>,
    /// D5.
    pub d5: Peri<'static, peripherals::PD3>,
    /// D6.
    pub d6: Peri<'static, peripherals::PE5>,
    /// D7.
    pub d7: Peri<'static, peripherals::PE6>,
}

/// Starts the sensor's clock (HSI / 3 ≈ 21 MHz, `sensor::XCLK_HZ`), configures it over SCCB and brings up
/// the DCMI. A sensor refused at start-up is reported in every status (`camera_ready`
/// false); its captures then time out and are counted.
pub async fn start(w: Wiring) -> DcmiCamera {
    let mut mco_config = McoConfig::default();
    mco_config.prescaler = McoPrescaler::DIV3;
    // The clock runs from here on: the handle has nothing to undo when it goes.
    let _xclk = Mco::new(w.mco, w.xclk, Mco1Source::HSI, mco_config);
    let mut sccb = I2c::new(
        w.i2c,
        w.scl,
        w.sda,
        w.i2c_tx_dma,
        w.i2c_rx_dma,
        Irqs,
        Default::default(),
    );
    // The sensor needs its clock running before it answers on SCCB.
    Timer::after_millis(10).await;
    match setup(&mut sccb).await {
        Ok(()) => COUNTERS.camera_ready.store(true, Relaxed),
        Err(e) => error!("camera: {}", e),
    }
    let d = w.data;
    DcmiCamera(Dcmi::new_8bit(
        w.dcmi,
        w.dma,
        Irqs,
        d.d0,
        d.d1,
        d.d2,
        d.d3,
        d.d4,
        d.d5,
        d.d6,
        d.d7,
        w.vsync,
        w.hsync,
        w.pixclk,
        dcmi::Config::default(),
    ))
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
