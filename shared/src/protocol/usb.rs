//! How the module appears on USB: the numbers the firmware enumerates with and the host
//! looks for. Full speed, one vendor-specific interface with one bulk OUT and one bulk IN
//! endpoint, one protocol message per transfer (ended by a short or zero-length packet).

/// USB vendor ID: pid.codes, the open-source hardware vendor.
pub const VID: u16 = 0x1209;

/// USB product ID: pid.codes' test PID, until the module has its own.
pub const PID: u16 = 0x0001;

/// The class, subclass and protocol of the interface: vendor-specific.
pub const VENDOR_CLASS: u8 = 0xFF;

/// The vendor-specific interface's number.
pub const INTERFACE: u8 = 0;

/// The bulk OUT endpoint (host → device: commands).
pub const EP_OUT: u8 = 0x01;

/// The bulk IN endpoint (device → host: replies, tiles, raw frames, logs).
pub const EP_IN: u8 = 0x81;

/// Full-speed bulk packet size, bytes.
pub const PACKET: usize = 64;

/// The manufacturer string descriptor.
pub const MANUFACTURER: &str = "rollfuse";

/// The product string descriptor.
pub const PRODUCT: &str = "rollfuse tactile module";
