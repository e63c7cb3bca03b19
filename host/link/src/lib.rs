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

use std::time::Duration;

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
    fn send(&mut self, message: &[u8]) -> anyhow::Result<()>;
    /// Receives one message (one bulk IN transfer) into `buf`, waiting at most `timeout`.
    /// A transfer longer than `buf` fills it (and is then refused as too long).
    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> anyhow::Result<Received>;
    /// Whether commands reach a device (false for a replay, which only plays back).
    fn is_live(&self) -> bool {
        true
    }
    /// What was stepped over to go on, in a line (a damaged recording), if anything.
    fn damage(&self) -> Option<String> {
        None
    }
}
