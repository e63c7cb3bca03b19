//! The USB device: full speed on the OTG_FS peripheral, enumerating as the core's
//! `protocol::usb` says (VID:PID, one vendor-specific interface with a bulk OUT and a bulk
//! IN endpoint at the addresses the host opens); a suspended or unconfigured bus stops the
//! roller and streaming.

use super::irqs::Irqs;
use core::sync::atomic::Ordering;
use defmt::warn;
use embassy_stm32::peripherals::{PA11, PA12, USB_OTG_FS};
use embassy_stm32::{Peri, usb};
use embassy_usb::driver::{Endpoint, EndpointError, EndpointIn, EndpointInfo};
use embassy_usb::{UsbDevice, msos};
use rollfuse_core::protocol::usb as wire;
use rollfuse_fw::link::DiscardLoaded;
use rollfuse_fw::roller;
use rollfuse_fw::signals::{self, BUS_LOST};
use static_cell::ConstStaticCell;

/// The USB peripheral's driver.
pub type Bus = usb::Driver<'static, USB_OTG_FS>;
/// The bulk OUT endpoint (commands).
pub type CommandEndpoint = <Bus as embassy_usb::driver::Driver<'static>>::EndpointOut;
/// The driver's bulk IN endpoint.
type DriverIn = <Bus as embassy_usb::driver::Driver<'static>>::EndpointIn;

/// The bulk IN endpoint (messages to the host): the driver's, able to discard a packet a
/// host never took.
pub struct MessageEndpoint(DriverIn);

impl Endpoint for MessageEndpoint {
    fn info(&self) -> &EndpointInfo {
        self.0.info()
    }

    async fn wait_enabled(&mut self) {
        self.0.wait_enabled().await
    }
}

impl EndpointIn for MessageEndpoint {
    async fn write(&mut self, buf: &[u8]) -> Result<(), EndpointError> {
        self.0.write(buf).await
    }
}

/// Polls of a register the endpoint's discard waits on at most (a few µs each way at
/// 400 MHz; the core answers within a USB frame, so a miss means something else is wrong).
const DISCARD_POLLS: u32 = 100_000;

/// Waits for `done`, at most [`DISCARD_POLLS`] reads; whether it came.
fn poll_until(done: impl Fn() -> bool) -> bool {
    (0..DISCARD_POLLS).any(|_| done())
}

impl DiscardLoaded for MessageEndpoint {
    /// RM0433's IN endpoint disable on OTG_FS: NAK the endpoint, disable it, then flush
    /// its transmit FIFO. The next write enables it again (CNAK, EPENA).
    fn discard_loaded(&mut self) {
        let otg = embassy_stm32::pac::USB_OTG_FS;
        let n = self.info().addr.index();
        if !otg.diepctl(n).read().epena() {
            return;
        }
        otg.diepctl(n).modify(|w| w.set_snak(true));
        let nak = poll_until(|| otg.diepint(n).read().inepne());
        otg.diepctl(n).modify(|w| {
            w.set_snak(true);
            w.set_epdis(true);
        });
        let disabled = poll_until(|| otg.diepint(n).read().epdisd());
        otg.diepint(n).write(|w| {
            w.set_inepne(true);
            w.set_epdisd(true);
        });
        otg.grstctl().modify(|w| {
            w.set_txfnum(n as u8);
            w.set_txfflsh(true);
        });
        let flushed = poll_until(|| !otg.grstctl().read().txfflsh());
        if !(nak && disabled && flushed) {
            warn!(
                "IN endpoint discard: NAK {}, disabled {}, flushed {}",
                nak, disabled, flushed
            );
        }
    }
}

/// Bus events: a suspended or unconfigured bus means the host is gone.
struct BusEvents;

impl embassy_usb::Handler for BusEvents {
    fn suspended(&mut self, suspended: bool) {
        if suspended {
            bus_lost();
        }
    }

    fn configured(&mut self, configured: bool) {
        if !configured {
            bus_lost();
        }
    }
}

/// Stops the roller and streaming at once, and tells the link (which keeps the
/// controller's state) that the host is gone.
fn bus_lost() {
    roller::stop();
    signals::stop_stream();
    BUS_LOST.store(true, Ordering::Release);
}

/// The stack's buffers: the OUT endpoints' packet memory, the descriptors, control
/// transfers.
struct Memory {
    ep_out: [u8; 256],
    config_descriptor: [u8; 256],
    bos_descriptor: [u8; 256],
    msos_descriptor: [u8; 256],
    control: [u8; 64],
    events: BusEvents,
}

static MEMORY: ConstStaticCell<Memory> = ConstStaticCell::new(Memory {
    ep_out: [0; 256],
    config_descriptor: [0; 256],
    bos_descriptor: [0; 256],
    msos_descriptor: [0; 256],
    control: [0; 64],
    events: BusEvents,
});

/// The vendor request Windows sends to read the MS OS 2.0 descriptor set (the link itself
/// uses no control requests, so any code is free).
const MSOS_VENDOR_CODE: u8 = 0x01;
/// The device interface GUID Windows registers for the module's WinUSB interface (made
/// once for rollfuse; libusb finds WinUSB devices without it, other WinUSB clients by it).
const DEVICE_INTERFACE_GUIDS: &[&str] = &["{ABC3F981-75DF-49CA-A97F-20FF5AB2FDA3}"];

/// Builds the device and its two endpoints (call once: it takes the buffers).
pub fn start(
    otg: Peri<'static, USB_OTG_FS>,
    dp: Peri<'static, PA12>,
    dm: Peri<'static, PA11>,
) -> (UsbDevice<'static, Bus>, CommandEndpoint, MessageEndpoint) {
    let m = MEMORY.take();
    let mut usb_config = usb::Config::default();
    // VBUS on PA9 (the NUCLEO's USB connector wires it there): pulling the cable is seen
    // at once, not only as a suspended bus.
    usb_config.vbus_detection = true;
    let driver = usb::Driver::new_fs(otg, Irqs, dp, dm, &mut m.ep_out, usb_config);
    let mut config = embassy_usb::Config::new(wire::VID, wire::PID);
    config.manufacturer = Some(wire::MANUFACTURER);
    config.product = Some(wire::PRODUCT);
    // The chip's 96-bit unique ID in hexadecimal: two modules on one host are told apart.
    config.serial_number = Some(embassy_stm32::uid::uid_hex());
    config.max_power = 100;
    config.max_packet_size_0 = wire::PACKET as u8;
    let mut builder = embassy_usb::Builder::new(
        driver,
        config,
        &mut m.config_descriptor,
        &mut m.bos_descriptor,
        &mut m.msos_descriptor,
        &mut m.control,
    );
    builder.handler(&mut m.events);
    // Microsoft OS 2.0 descriptors: Windows (8.1 and later) binds its own WinUSB driver to
    // the module on first plug-in, so rusb/libusb reach it with no INF file or Zadig.
    builder.msos_descriptor(msos::windows_version::WIN8_1, MSOS_VENDOR_CODE);
    builder.msos_feature(msos::CompatibleIdFeatureDescriptor::new("WINUSB", ""));
    builder.msos_feature(msos::RegistryPropertyFeatureDescriptor::new(
        "DeviceInterfaceGUIDs",
        msos::PropertyData::RegMultiSz(DEVICE_INTERFACE_GUIDS),
    ));
    let mut function = builder.function(wire::VENDOR_CLASS, 0, 0);
    let mut interface = function.interface();
    let mut alt = interface.alt_setting(wire::VENDOR_CLASS, 0, 0, None);
    // The addresses the host opens, asked for by number rather than left to the order of
    // allocation.
    let packet = wire::PACKET as u16;
    let read = alt.endpoint_bulk_out(Some(wire::EP_OUT.into()), packet);
    let write = alt.endpoint_bulk_in(Some(wire::EP_IN.into()), packet);
    drop(function);
    (builder.build(), read, MessageEndpoint(write))
}
