//! The host's end of the device link: one [`Transport`] trait and its three
//! implementations.
//!
//! - [`usb`]: the edge module over USB (rusb, with libusb built in).
//! - [`sim`]: the virtual device — the core's device pipeline and command handling on
//!   simulated frames, in a thread, behind the same message bytes.
//! - [`replay`]: a recorded stream, message by message ([`replay::Recorder`] writes one).
//! - [`pipeline_memory`]: the memory a device pipeline runs on (the virtual device, the
//!   trade-off study).
//!
//! A transport moves whole messages: one per bulk transfer, as the protocol defines
//! (`rollfuse_core::protocol`). It does not decode them.

pub mod pipeline_memory;
pub mod replay;
pub mod sim;
pub mod usb;

use std::path::PathBuf;
use std::time::Duration;

/// Why the link failed: the bus or the device ([`Error::UsbUnavailable`] …
/// [`Error::ShortSend`]), a recording's file ([`Error::File`], [`Error::Write`]) or its
/// content ([`Error::NotARecording`]), the virtual device ([`Error::VirtualConfig`] …
/// [`Error::Scene`]), or another transport's own ([`Error::Other`]).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// libusb could not start.
    #[error(
        "cannot use USB: libusb failed to start ({0}); on Linux, is /dev/bus/usb there and readable?"
    )]
    UsbUnavailable(rusb::Error),
    /// The bus could not be listed.
    #[error("cannot list USB devices: {0}")]
    UsbList(rusb::Error),
    /// No rollfuse device is on the bus.
    #[error(
        "no rollfuse device ({:04x}:{:04x}) on USB ({others} other devices seen); is it plugged \
         in and flashed? `rollfuse devices` lists what is seen",
        usb::VID,
        usb::PID
    )]
    NoDevice {
        /// Other USB devices seen.
        others: usize,
    },
    /// The device is there but could not be opened.
    #[error("the rollfuse device could not be opened: permissions? (see firmware/README.md)")]
    Open,
    /// Another program holds the device's interface.
    #[error("cannot claim the device's interface: {0}")]
    Claim(rusb::Error),
    /// A transfer failed mid-session.
    #[error("USB {what} failed: {error}")]
    Transfer {
        /// "send" or "receive".
        what: &'static str,
        /// What libusb said.
        error: String,
    },
    /// The device took only part of a message.
    #[error("USB send cut short: {sent} of {len} bytes")]
    ShortSend {
        /// Bytes taken.
        sent: usize,
        /// The message's length.
        len: usize,
    },
    /// A recording could not be opened, read or started: the file system's fault.
    #[error("cannot {doing} recording {}", path.display())]
    File {
        /// "open", "read" or "create".
        doing: &'static str,
        /// The recording.
        path: PathBuf,
        /// What went wrong underneath.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A recording could not be written or put in place.
    #[error(transparent)]
    Write(#[from] rollfuse_io::files::WriteError),
    /// The file is not a stream recording.
    #[error("{} is not a rollfuse stream recording", path.display())]
    NotARecording {
        /// The file.
        path: PathBuf,
    },
    /// The virtual device's default configuration does not fit the scene's camera.
    #[error(
        "the virtual device's default configuration does not fit a {}×{} camera: {reason}",
        camera[0],
        camera[1]
    )]
    VirtualConfig {
        /// The camera's width and height.
        camera: [usize; 2],
        /// Why, as the core says it.
        reason: String,
    },
    /// The virtual device's thread could not start.
    #[error("cannot start the virtual device's thread")]
    VirtualThread(#[source] std::io::Error),
    /// The virtual device is no longer running.
    #[error("the virtual device has stopped")]
    VirtualStopped,
    /// The scene cannot be simulated.
    #[error(transparent)]
    Scene(rollfuse_sim::Error),
    /// Another transport's error.
    #[error(transparent)]
    Other(Box<dyn std::error::Error + Send + Sync>),
}

/// What a receive gave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Received {
    /// A message of this many bytes is at the start of the buffer.
    Message(usize),
    /// Nothing arrived in time.
    Timeout,
    /// The other end is gone (device unplugged, virtual device finished, end of file).
    Closed,
}

/// A link that moves whole messages.
pub trait Transport: Send {
    /// Sends one message (one bulk OUT transfer).
    fn send(&mut self, message: &[u8]) -> Result<(), Error>;
    /// Receives one message (one bulk IN transfer) into `buf`, waiting at most `timeout`.
    /// A transfer longer than `buf` fills it (and is then refused as too long).
    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> Result<Received, Error>;
    /// Whether commands reach a device (false for a replay, which only plays back).
    fn is_live(&self) -> bool {
        true
    }
    /// What was stepped over to go on, in a line (a damaged recording), if anything.
    fn damage(&self) -> Option<String> {
        None
    }
}
