//! The lengths a message may reach, and the check each message body makes of them.

/// The largest tile payload, in bytes (e.g. 640 columns × 25 rows).
pub const MAX_TILE_BYTES: usize = 16_000;

/// The largest raw-frame chunk payload, in bytes.
pub const MAX_CHUNK: usize = 4096;

/// The longest log line, in bytes of UTF-8.
pub const MAX_LOG: usize = 160;

/// Length limits a message body checks before it is sent and after it is received.
pub trait Limits {
    /// `Err(which field)` if a length is beyond its limit or inconsistent.
    fn check_limits(&self) -> Result<(), &'static str>;
}
