//! The interrupts the HAL's drivers take, bound to their handlers.

use super::frame_sync::FrameSync;
use embassy_stm32::{bind_interrupts, dcmi, dma, i2c, peripherals, usb};

bind_interrupts!(
    /// The interrupts the drivers of the USB, the camera's I2C and DCMI and their DMA take.
    pub struct Irqs {
    OTG_FS => usb::InterruptHandler<peripherals::USB_OTG_FS>;
    I2C1_EV => i2c::EventInterruptHandler<peripherals::I2C1>;
    I2C1_ER => i2c::ErrorInterruptHandler<peripherals::I2C1>;
    DCMI => FrameSync, dcmi::InterruptHandler<peripherals::DCMI>;
    DMA1_STREAM0 => dma::InterruptHandler<peripherals::DMA1_CH0>;
    DMA1_STREAM1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    DMA1_STREAM2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
});
