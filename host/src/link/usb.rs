//! The edge module over USB: a vendor-specific interface with one bulk OUT and one bulk IN
//! endpoint, one message per transfer (the device ends each with a short packet or a
//! zero-length packet).
//!
//! The firmware enumerates as [`VID`]:[`PID`] (pid.codes' open-source VID with its test
//! PID, until the product has its own), interface [`INTERFACE`], endpoints
//! [`EP_OUT`] and [`EP_IN`]. libusb is built in (rusb's `vendored` feature): nothing needs
//! installing, but on Linux the user needs access to the device node (a udev rule, see
//! `firmware/README.md`).

use super::{Received, Transport};
use anyhow::{Context, bail};
use rusb::UsbContext;
use std::time::Duration;

/// USB vendor ID (pid.codes).
pub const VID: u16 = 0x1209;
/// USB product ID (pid.codes test PID).
pub const PID: u16 = 0x0001;
/// The vendor-specific interface.
pub const INTERFACE: u8 = 0;
/// Bulk OUT endpoint (host → device).
pub const EP_OUT: u8 = 0x01;
/// Bulk IN endpoint (device → host).
pub const EP_IN: u8 = 0x81;

/// One rollfuse device seen on the bus.
#[derive(Debug, Clone)]
pub struct Found {
    /// Bus number.
    pub bus: u8,
    /// Address on the bus.
    pub address: u8,
    /// Serial number, if it could be read.
    pub serial: Option<String>,
}

/// Opens libusb, with a message that says what to do when it cannot.
fn context() -> anyhow::Result<rusb::Context> {
    rusb::Context::new().map_err(|e| {
        anyhow::anyhow!(
            "cannot use USB: libusb failed to start ({e}); on Linux, is /dev/bus/usb there and readable?"
        )
    })
}

/// Lists the rollfuse devices on the bus; `Ok` with the number of other USB devices seen
/// when there are none of ours.
pub fn list() -> anyhow::Result<(Vec<Found>, usize)> {
    let ctx = context()?;
    let devices = ctx
        .devices()
        .map_err(|e| anyhow::anyhow!("cannot list USB devices: {e}"))?;
    let mut found = Vec::new();
    let mut others = 0;
    for dev in devices.iter() {
        let Ok(desc) = dev.device_descriptor() else {
            others += 1;
            continue;
        };
        if (desc.vendor_id(), desc.product_id()) != (VID, PID) {
            others += 1;
            continue;
        }
        let serial = dev
            .open()
            .ok()
            .and_then(|h| h.read_serial_number_string_ascii(&desc).ok());
        found.push(Found {
            bus: dev.bus_number(),
            address: dev.address(),
            serial,
        });
    }
    Ok((found, others))
}

/// An opened device.
pub struct Usb {
    handle: rusb::DeviceHandle<rusb::Context>,
}

impl Usb {
    /// Opens the first rollfuse device and claims its interface.
    pub fn open() -> anyhow::Result<Self> {
        let (found, others) = list()?;
        if found.is_empty() {
            bail!(
                "no rollfuse device ({VID:04x}:{PID:04x}) on USB ({others} other devices seen); \
                 is it plugged in and flashed? `rollfuse devices` lists what is seen"
            );
        }
        let ctx = context()?;
        let handle = ctx.open_device_with_vid_pid(VID, PID).context(
            "the rollfuse device could not be opened: permissions? (see firmware/README.md)",
        )?;
        let _ = handle.set_auto_detach_kernel_driver(true);
        handle
            .claim_interface(INTERFACE)
            .map_err(|e| anyhow::anyhow!("cannot claim the device's interface: {e}"))?;
        Ok(Self { handle })
    }
}

impl Transport for Usb {
    fn send(&mut self, message: &[u8]) -> anyhow::Result<()> {
        let n = self
            .handle
            .write_bulk(EP_OUT, message, Duration::from_secs(1))
            .map_err(|e| anyhow::anyhow!("USB send failed: {e}"))?;
        if n != message.len() {
            bail!("USB send cut short: {n} of {} bytes", message.len());
        }
        Ok(())
    }

    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> anyhow::Result<Received> {
        match self.handle.read_bulk(EP_IN, buf, timeout) {
            Ok(n) => Ok(Received::Message(n)),
            Err(rusb::Error::Timeout) => Ok(Received::Timeout),
            Err(rusb::Error::NoDevice) => Ok(Received::Closed),
            // More than the buffer holds: a full buffer is handed on, and refused by the
            // decoder as too long (and counted), like any other bad message.
            Err(rusb::Error::Overflow) => Ok(Received::Message(buf.len())),
            Err(e) => bail!("USB receive failed: {e}"),
        }
    }
}
