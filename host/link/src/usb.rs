//! The edge module over USB: a vendor-specific interface with one bulk OUT and one bulk IN
//! endpoint, one message per transfer (the device ends each with a short packet or a
//! zero-length packet).
//!
//! The firmware enumerates as [`VID`]:[`PID`] with interface [`INTERFACE`] and endpoints
//! [`EP_OUT`] and [`EP_IN`] (the core's `protocol::usb`, which the firmware builds its
//! descriptors from). libusb is built in (rusb's `vendored` feature): nothing needs
//! installing, but on Linux the user needs access to the device node (a udev rule, see
//! `firmware/README.md`).

use super::{Error, Received, Transport};
pub use rollfuse_core::protocol::usb::{EP_IN, EP_OUT, INTERFACE, PID, VID};
use rusb::UsbContext;
use std::time::Duration;

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
fn context() -> Result<rusb::Context, Error> {
    rusb::Context::new().map_err(Error::UsbUnavailable)
}

/// Lists the rollfuse devices on the bus; `Ok` with the number of other USB devices seen
/// when there are none of ours.
pub fn list() -> Result<(Vec<Found>, usize), Error> {
    let ctx = context()?;
    let devices = ctx.devices().map_err(Error::UsbList)?;
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
    reassembly: Reassembly,
}

/// How one bulk IN transfer ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Transfer {
    /// A short packet (or a zero-length one) ended it after this many bytes: a message.
    Done(usize),
    /// The timeout came first; this many bytes of a message had arrived.
    TimedOut(usize),
    /// The device sent more than the buffer holds.
    Overflow,
    /// The device is gone.
    Gone,
    /// Anything else libusb reported.
    Failed(String),
}

/// Bulk IN transfers that keep the bytes a timeout interrupts (rusb's `read_bulk` drops
/// them, tearing a message in flight).
pub trait BulkIn {
    /// One transfer into `buf`, ended by a short packet or `timeout`.
    fn transfer(&mut self, buf: &mut [u8], timeout: Duration) -> Transfer;
}

impl BulkIn for rusb::DeviceHandle<rusb::Context> {
    fn transfer(&mut self, buf: &mut [u8], timeout: Duration) -> Transfer {
        use rusb::constants::{
            LIBUSB_ERROR_NO_DEVICE, LIBUSB_ERROR_OVERFLOW, LIBUSB_ERROR_TIMEOUT, LIBUSB_SUCCESS,
        };
        let mut n: std::os::raw::c_int = 0;
        // libusb reads a timeout of 0 as "wait forever".
        let ms = timeout.as_millis().clamp(1, u128::from(u32::MAX)) as u32;
        let len = buf.len().min(i32::MAX as usize) as i32;
        // SAFETY: the handle is open for the call; `buf` holds `len` writable bytes and
        // `n` outlives the synchronous transfer.
        let rc = unsafe {
            rusb::ffi::libusb_bulk_transfer(self.as_raw(), EP_IN, buf.as_mut_ptr(), len, &mut n, ms)
        };
        let n = usize::try_from(n).unwrap_or(0).min(buf.len());
        match rc {
            LIBUSB_SUCCESS => Transfer::Done(n),
            LIBUSB_ERROR_TIMEOUT => Transfer::TimedOut(n),
            LIBUSB_ERROR_OVERFLOW => Transfer::Overflow,
            LIBUSB_ERROR_NO_DEVICE => Transfer::Gone,
            other => Transfer::Failed(format!("libusb error {other}")),
        }
    }
}

/// How long the IN endpoint must stay quiet for the stale bytes to be over.
const STALE_QUIET: Duration = Duration::from_millis(20);
/// At most this many transfers are drained: a device still streaming for a session whose
/// host is gone is not waited out.
const STALE_TRANSFERS: usize = 64;

/// Reads and drops what the IN endpoint holds from an earlier session, until it is quiet
/// for [`STALE_QUIET`] (at most [`STALE_TRANSFERS`] transfers); returns the bytes dropped.
pub fn drain_stale(io: &mut impl BulkIn) -> usize {
    let mut scratch = vec![0u8; 16 * 1024];
    let mut dropped = 0;
    for _ in 0..STALE_TRANSFERS {
        match io.transfer(&mut scratch, STALE_QUIET) {
            Transfer::Done(n) | Transfer::TimedOut(n) if n > 0 => dropped += n,
            Transfer::Overflow => dropped += scratch.len(),
            _ => break,
        }
    }
    dropped
}

/// A message whose transfer a timeout interrupted, completed by the next transfers.
#[derive(Debug, Default)]
pub struct Reassembly {
    partial: Vec<u8>,
}

impl Reassembly {
    /// Receives into `buf`: the bytes of an interrupted message first, then the next
    /// transfer's; a message is whole when a transfer ends with a short packet.
    pub fn receive(
        &mut self,
        io: &mut impl BulkIn,
        buf: &mut [u8],
        timeout: Duration,
    ) -> Result<Received, Error> {
        let have = self.partial.len();
        if have >= buf.len() {
            // Longer than any message: handed on whole to be refused as too long.
            buf.copy_from_slice(&self.partial[..buf.len()]);
            self.partial.clear();
            return Ok(Received::Message(buf.len()));
        }
        buf[..have].copy_from_slice(&self.partial);
        match io.transfer(&mut buf[have..], timeout) {
            Transfer::Done(n) => {
                self.partial.clear();
                Ok(Received::Message(have + n))
            }
            Transfer::TimedOut(n) => {
                self.partial.extend_from_slice(&buf[have..have + n]);
                Ok(Received::Timeout)
            }
            // More than the buffer holds: a full buffer is handed on, and refused by the
            // decoder as too long (and counted), like any other bad message.
            Transfer::Overflow => {
                self.partial.clear();
                Ok(Received::Message(buf.len()))
            }
            Transfer::Gone => Ok(Received::Closed),
            Transfer::Failed(error) => Err(Error::Transfer {
                what: "receive",
                error,
            }),
        }
    }
}

impl Usb {
    /// Opens the first rollfuse device and claims its interface.
    pub fn open() -> Result<Self, Error> {
        let (found, others) = list()?;
        if found.is_empty() {
            return Err(Error::NoDevice { others });
        }
        let ctx = context()?;
        let mut handle = ctx.open_device_with_vid_pid(VID, PID).ok_or(Error::Open)?;
        let _ = handle.set_auto_detach_kernel_driver(true);
        handle.claim_interface(INTERFACE).map_err(Error::Claim)?;
        // A host that died mid-message leaves the device's IN endpoint holding the rest of
        // it: clearing both endpoints resets their data toggles, and what is still queued
        // is read and dropped, so this session's first reply arrives alone.
        let _ = handle.clear_halt(EP_IN);
        let _ = handle.clear_halt(EP_OUT);
        drain_stale(&mut handle);
        Ok(Self {
            handle,
            reassembly: Reassembly::default(),
        })
    }
}

impl Transport for Usb {
    fn send(&mut self, message: &[u8]) -> Result<(), Error> {
        let n = self
            .handle
            .write_bulk(EP_OUT, message, Duration::from_secs(1))
            .map_err(|e| Error::Transfer {
                what: "send",
                error: e.to_string(),
            })?;
        if n != message.len() {
            return Err(Error::ShortSend {
                sent: n,
                len: message.len(),
            });
        }
        Ok(())
    }

    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> Result<Received, Error> {
        self.reassembly.receive(&mut self.handle, buf, timeout)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hands out scripted transfers, each as many bytes of `data` as it says.
    struct Script {
        data: Vec<u8>,
        steps: std::vec::IntoIter<Transfer>,
    }

    impl BulkIn for Script {
        fn transfer(&mut self, buf: &mut [u8], _: Duration) -> Transfer {
            let step = self.steps.next().unwrap_or(Transfer::Gone);
            let n = match step {
                Transfer::Done(n) | Transfer::TimedOut(n) => n,
                _ => 0,
            };
            buf[..n].copy_from_slice(&self.data[..n]);
            self.data.drain(..n);
            step
        }
    }

    #[test]
    fn what_an_earlier_session_left_is_dropped_before_this_one() {
        // The tail of a message a dead host stopped reading, then a quiet endpoint.
        let mut io = Script {
            data: vec![7; 100],
            steps: vec![
                Transfer::Done(64),
                Transfer::TimedOut(36),
                Transfer::TimedOut(0),
            ]
            .into_iter(),
        };
        assert_eq!(drain_stale(&mut io), 100);
        // This session's first reply then arrives alone.
        io.data = vec![1, 2, 3];
        io.steps = vec![Transfer::Done(3)].into_iter();
        let mut buf = vec![0u8; 64];
        match Reassembly::default()
            .receive(&mut io, &mut buf, Duration::from_millis(10))
            .unwrap()
        {
            Received::Message(n) => assert_eq!(&buf[..n], &[1, 2, 3]),
            other => panic!("{other:?}"),
        }
        // A device that never goes quiet is not waited out.
        let mut io = Script {
            data: vec![0; 64 * STALE_TRANSFERS + 64],
            steps: vec![Transfer::Done(64); STALE_TRANSFERS + 1].into_iter(),
        };
        assert_eq!(drain_stale(&mut io), 64 * STALE_TRANSFERS);
    }

    #[test]
    fn a_message_cut_by_timeouts_arrives_whole() {
        let message: Vec<u8> = (0..200u8).collect();
        let mut io = Script {
            data: message.clone(),
            steps: vec![
                Transfer::TimedOut(64),
                Transfer::TimedOut(0),
                Transfer::TimedOut(64),
                Transfer::Done(72),
            ]
            .into_iter(),
        };
        let mut r = Reassembly::default();
        let mut buf = vec![0u8; 512];
        let t = Duration::from_millis(10);
        for _ in 0..3 {
            assert!(matches!(
                r.receive(&mut io, &mut buf, t).unwrap(),
                Received::Timeout
            ));
        }
        match r.receive(&mut io, &mut buf, t).unwrap() {
            Received::Message(n) => assert_eq!(&buf[..n], &message[..]),
            other => panic!("{other:?}"),
        }
        // The next message starts afresh.
        io.data = vec![9; 10];
        io.steps = vec![Transfer::Done(10)].into_iter();
        assert!(matches!(
            r.receive(&mut io, &mut buf, t).unwrap(),
            Received::Message(10)
        ));
        assert!(matches!(
            r.receive(&mut io, &mut buf, t).unwrap(),
            Received::Closed
        ));
    }
}
