//! The USB link: a vendor-specific interface with one bulk OUT and one bulk IN endpoint,
//! one protocol message per transfer.
//!
//! A transfer ends with a short packet: the host's message is assembled from 64-byte
//! packets until one is shorter, and every message sent is split into 64-byte packets
//! followed by a zero-length packet when its length is a multiple of 64. Commands go to the
//! core's [`Controller`]; its replies go back first, then queued tiles.

use super::{EFFECTS, TILES};
use defmt::{info, warn};
use embassy_futures::select::{Either, select};
use embassy_usb::driver::{EndpointError, EndpointIn, EndpointOut};
use rollfuse_core::device::{Controller, Effect};
use rollfuse_core::protocol::{DeviceMessage, MAX_MESSAGE};

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

/// Encodes and sends a controller reply.
async fn reply(
    ep: &mut impl EndpointIn,
    controller: &mut Controller,
    msg: &DeviceMessage<'_>,
) -> Result<(), EndpointError> {
    let mut buf = [0u8; 128];
    match controller.encode(msg, &mut buf) {
        Ok(n) => send(ep, &buf[..n]).await,
        // Replies are small; a failure to encode one is a bug, not a link fault.
        Err(_) => {
            warn!("reply did not encode");
            Ok(())
        }
    }
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
                reply(write, controller, &answer).await
            }
            Either::First(Err(e)) => Err(e),
            Either::Second(tile) => send(write, &tile).await,
        };
        if result.is_err() {
            info!("USB host gone");
            // Losing the host stops the roller.
            let _ = EFFECTS.try_send(Effect::Roller(rollfuse_core::protocol::RollerCommand::Stop));
            return;
        }
    }
}

/// A tile message ready to send.
pub type Message = heapless::Vec<u8, MAX_MESSAGE>;
