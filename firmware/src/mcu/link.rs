//! The USB link: a vendor-specific interface with one bulk OUT and one bulk IN endpoint,
//! one protocol message per transfer.
//!
//! A transfer ends with a short packet: the host's message is assembled from 64-byte
//! packets until one is shorter, and every message sent is split into 64-byte packets
//! followed by a zero-length packet when its length is a multiple of 64. Commands go to the
//! core's [`Controller`]; its replies go back first, then queued tiles.

use super::counters::COUNTERS;
use super::{EFFECTS, TILES};
use defmt::{info, warn};
use embassy_futures::select::{Either, select};
use embassy_usb::driver::{EndpointError, EndpointIn, EndpointOut};
use rollfuse_core::device::{Controller, Effect};
use rollfuse_core::protocol::{
    DeviceMessage, MAX_CHUNK, MAX_MESSAGE, MAX_TILE_BYTES, RawChunk, Tile,
};

/// Full-speed bulk packet size.
pub const PACKET: usize = 64;

/// The largest command accepted; longer transfers are dropped whole and answered with a
/// bad-message refusal.
const MAX_COMMAND: usize = 256;

/// Sends one message as one transfer.
async fn send(ep: &mut impl EndpointIn, message: &[u8]) -> Result<(), EndpointError> {
    for packet in message.chunks(PACKET) {
        ep.write(packet).await?;
    }
    if message.len().is_multiple_of(PACKET) {
        ep.write(&[]).await?;
    }
    Ok(())
}

/// Serves the link until the host goes away, then returns (the caller waits for it to
/// come back). Tiles are only sent while the host is there.
pub async fn serve(
    read: &mut impl EndpointOut,
    write: &mut impl EndpointIn,
    controller: &mut Controller,
) {
    read.wait_enabled().await;
    info!("USB host connected");
    let mut command = heapless::Vec::<u8, MAX_COMMAND>::new();
    let mut oversized = false;
    loop {
        let mut packet = [0u8; PACKET];
        let event = select(read.read(&mut packet), TILES.receive()).await;
        let result = match event {
            Either::First(Ok(n)) => {
                if command.extend_from_slice(&packet[..n]).is_err() {
                    oversized = true;
                }
                if n == PACKET {
                    continue;
                }
                let bytes: &[u8] = if oversized { &[] } else { &command };
                COUNTERS.merge_into(controller.counters_mut());
                let (answer, effect) = controller.handle(bytes);
                command.clear();
                oversized = false;
                if effect != Effect::None {
                    // A full queue means the tasks are behind; the command was still
                    // accepted, and the next one of its kind will get through.
                    if EFFECTS.try_send(effect).is_err() {
                        warn!("effect queue full");
                    }
                }
                encode_and_send(write, controller, &answer).await
            }
            Either::First(Err(e)) => Err(e),
            Either::Second(Outgoing::Tile(t)) => {
                let tile = Tile {
                    index: t.index,
                    width: t.width,
                    height: t.height,
                    observations: t.observations,
                    pixels: &t.pixels,
                };
                encode_and_send(write, controller, &DeviceMessage::Tile(tile)).await
            }
            Either::Second(Outgoing::Raw(r)) => {
                let chunk = RawChunk {
                    frame: r.frame,
                    offset: r.offset,
                    total: r.total,
                    data: &r.data,
                };
                encode_and_send(write, controller, &DeviceMessage::RawChunk(chunk)).await
            }
            Either::Second(Outgoing::StreamEnded) => {
                COUNTERS.merge_into(controller.counters_mut());
                let status = DeviceMessage::Status(controller.counters());
                encode_and_send(write, controller, &status).await
            }
        };
        if result.is_err() {
            info!("USB host gone");
            // Losing the host stops the roller.
            let _ = EFFECTS.try_send(Effect::Roller(rollfuse_core::protocol::RollerCommand::Stop));
            return;
        }
    }
}

/// A completed tile, as the pipeline hands it to the link (which numbers and encodes it).
pub struct TileOut {
    /// Belt index.
    pub index: u32,
    /// Columns.
    pub width: u16,
    /// Rows.
    pub height: u16,
    /// Frames fused into it.
    pub observations: u8,
    /// The pixels.
    pub pixels: heapless::Vec<u8, MAX_TILE_BYTES>,
}

/// What the pipeline queues for the link. Tiles travel inline (there is no allocator), so
/// the queue's slots are tile-sized on purpose.
#[allow(clippy::large_enum_variant)]
pub enum Outgoing {
    /// A tile.
    Tile(TileOut),
    /// A piece of a raw frame (on request).
    Raw(RawOut),
    /// Streaming stopped and the last tiles are queued: send the final status.
    StreamEnded,
}

/// A piece of a raw camera frame, as the pipeline hands it to the link.
pub struct RawOut {
    /// Which frame of the capture.
    pub frame: u8,
    /// Byte offset in the frame.
    pub offset: u32,
    /// The frame's size in bytes.
    pub total: u32,
    /// The bytes.
    pub data: heapless::Vec<u8, MAX_CHUNK>,
}

/// Encodes a message with the controller's next sequence number and sends it.
async fn encode_and_send(
    ep: &mut impl EndpointIn,
    controller: &mut Controller,
    msg: &DeviceMessage<'_>,
) -> Result<(), EndpointError> {
    let mut buf = [0u8; MAX_MESSAGE];
    match controller.encode(msg, &mut buf) {
        Ok(n) => send(ep, &buf[..n]).await,
        Err(_) => {
            warn!("message did not encode");
            Ok(())
        }
    }
}
