//! The device link: the messages between host and device, and their framing.
//!
//! One message per USB bulk transfer (ended by a short packet or a zero-length packet):
//!
//! ```text
//! postcard(Header { version, seq }) ‖ postcard(body) ‖ CRC-32 (little-endian)
//! ```
//!
//! The body is a [`Command`] from host to device and a [`DeviceMessage`] from device to
//! host. The CRC (CRC-32/ISO-HDLC, as zlib and PNG use) covers everything before it.
//! [`decode`] checks, in order: the length limits, the CRC, the protocol version, the
//! body's encoding and every length inside it ([`Limits`]) — a message that fails any check
//! is refused whole, with the reason, and never partly used. Sequence numbers count up by
//! one per message in each direction; [`SeqTracker`] reports gaps, repeats and restarts.
//!
//! Every length has a limit ([`MAX_MESSAGE`], [`MAX_TILE_BYTES`], [`MAX_CHUNK`],
//! [`MAX_LOG`]), so both ends can size their buffers statically.

mod limits;
mod messages;
mod seq;
pub mod usb;

pub use limits::{Limits, MAX_CHUNK, MAX_LOG, MAX_TILE_BYTES};
pub use messages::{
    Command, DeviceConfig, DeviceInfo, DeviceMessage, LedDuty, NakReason, NormMode, PixelFormat,
    RawChunk, RollerCommand, StatusCounters, Tile, WaveletId,
};
pub use seq::{MAX_GAP, SeqEvent, SeqTracker};

use serde::{Deserialize, Serialize};

/// The protocol version this build speaks. A message with another version is refused.
pub const PROTOCOL_VERSION: u8 = 3;

/// The largest encoded message, in bytes: a largest tile, its fields and the framing.
pub const MAX_MESSAGE: usize = MAX_TILE_BYTES + 64;

/// The smallest encoded message: a one-byte version, a one-byte sequence number, a
/// one-byte body and the CRC.
pub const MIN_MESSAGE: usize = 3 + CRC_LEN;

const CRC_LEN: usize = 4;

/// CRC-32/ISO-HDLC: the CRC of zlib, PNG and Ethernet.
const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// What comes first in every message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// [`PROTOCOL_VERSION`] of the sender.
    pub version: u8,
    /// The sender's message counter: 0, 1, 2, … (wrapping).
    pub seq: u32,
}

/// Why a message could not be encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EncodeError {
    /// The output buffer is too small (size it [`MAX_MESSAGE`]).
    BufferTooSmall,
    /// A field is longer than its limit.
    Limit(&'static str),
}

/// Why a received message was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DecodeError {
    /// Fewer bytes than the smallest message: a truncated transfer.
    Truncated,
    /// More bytes than [`MAX_MESSAGE`].
    TooLong,
    /// The CRC does not match: corrupted in transit.
    BadCrc,
    /// Another protocol version (the sender's, as received).
    Version(u8),
    /// The CRC matches but the body does not decode as a message of this protocol.
    Malformed,
    /// A length inside the message breaks a limit (which one).
    Limit(&'static str),
}

impl core::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Truncated => write!(f, "truncated message"),
            Self::TooLong => write!(f, "message longer than {MAX_MESSAGE} bytes"),
            Self::BadCrc => write!(f, "bad CRC"),
            Self::Version(v) => {
                write!(
                    f,
                    "protocol version {v}, this build speaks {PROTOCOL_VERSION}"
                )
            }
            Self::Malformed => write!(f, "malformed message"),
            Self::Limit(what) => write!(f, "{what} beyond its limit"),
        }
    }
}

/// Encodes `body` with sequence number `seq` into `out`; returns the message length.
pub fn encode<T: Serialize + Limits>(
    seq: u32,
    body: &T,
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    body.check_limits().map_err(EncodeError::Limit)?;
    let header = Header {
        version: PROTOCOL_VERSION,
        seq,
    };
    let head_len = postcard::to_slice(&header, out)
        .map_err(|_| EncodeError::BufferTooSmall)?
        .len();
    let rest = out.get_mut(head_len..).ok_or(EncodeError::BufferTooSmall)?;
    let body_len = postcard::to_slice(body, rest)
        .map_err(|_| EncodeError::BufferTooSmall)?
        .len();
    let len = head_len + body_len;
    let crc = CRC.checksum(out.get(..len).ok_or(EncodeError::BufferTooSmall)?);
    out.get_mut(len..len + CRC_LEN)
        .ok_or(EncodeError::BufferTooSmall)?
        .copy_from_slice(&crc.to_le_bytes());
    Ok(len + CRC_LEN)
}

/// Decodes one message; the body borrows from `bytes`. Every check of the module's
/// documentation is made; a message failing one is refused whole.
///
/// ```
/// use rollfuse_core::protocol::{self, DecodeError, DeviceMessage, MAX_MESSAGE, Tile};
///
/// let pixels = [7u8; 8 * 2];
/// let tile = DeviceMessage::Tile(Tile {
///     index: 41,
///     width: 8,
///     height: 2,
///     observations: 4,
///     pixels: &pixels,
/// });
/// let mut buf = [0u8; MAX_MESSAGE];
/// let n = protocol::encode(9, &tile, &mut buf).unwrap();
///
/// let (header, message) = protocol::decode::<DeviceMessage>(&buf[..n]).unwrap();
/// assert_eq!(header.seq, 9);
/// assert_eq!(message, tile);
///
/// // One flipped bit, and nothing of the message is used.
/// buf[5] ^= 0x10;
/// assert_eq!(protocol::decode::<DeviceMessage>(&buf[..n]), Err(DecodeError::BadCrc));
/// ```
pub fn decode<'a, T: Deserialize<'a> + Limits>(
    bytes: &'a [u8],
) -> Result<(Header, T), DecodeError> {
    if bytes.len() < MIN_MESSAGE {
        return Err(DecodeError::Truncated);
    }
    if bytes.len() > MAX_MESSAGE {
        return Err(DecodeError::TooLong);
    }
    let (content, crc) = bytes.split_at(bytes.len() - CRC_LEN);
    let mut sent = [0u8; CRC_LEN];
    sent.copy_from_slice(crc);
    if CRC.checksum(content) != u32::from_le_bytes(sent) {
        return Err(DecodeError::BadCrc);
    }
    let (header, rest): (Header, _) =
        postcard::take_from_bytes(content).map_err(|_| DecodeError::Malformed)?;
    if header.version != PROTOCOL_VERSION {
        return Err(DecodeError::Version(header.version));
    }
    let (body, trailing): (T, _) =
        postcard::take_from_bytes(rest).map_err(|_| DecodeError::Malformed)?;
    if !trailing.is_empty() {
        return Err(DecodeError::Malformed);
    }
    body.check_limits().map_err(DecodeError::Limit)?;
    Ok((header, body))
}

#[cfg(test)]
mod tests;
