//! The USB link: a vendor-specific interface with one bulk OUT and one bulk IN endpoint,
//! one protocol message per transfer.
//!
//! A transfer ends with a short packet: the host's message is assembled from 64-byte
//! packets until one is shorter, and every message sent is split into 64-byte packets
//! followed by a zero-length packet when its length is a multiple of 64. Commands go to the
//! core's [`Controller`]; its replies go back first, then queued tiles.

use crate::counters::COUNTERS;
use crate::outbox::{self, Kind};
use crate::signals::{self, Accepted, BUS_LOST, EFFECTS};
use crate::{fw_info, fw_warn, liveness, roller};
use core::sync::atomic::Ordering;
use embassy_futures::select::{Either3, select3};
use embassy_time::{Duration, Instant, Timer};
use embassy_usb_driver::{EndpointError, EndpointIn, EndpointOut};
use rollfuse_core::device::{Controller, Effect};
use rollfuse_core::protocol::{DeviceMessage, MAX_MESSAGE, RawChunk, RollerCommand, Tile};

/// Full-speed bulk packet size.
pub use rollfuse_core::protocol::usb::PACKET;

/// The largest command accepted; longer transfers are dropped whole and answered with a
/// bad-message refusal.
const MAX_COMMAND: usize = 256;

/// A host that sends no command for this long is taken as gone: the roller stops and
/// streaming ends. The host sends a status request every second while a session runs.
pub const HEARTBEAT: Duration = Duration::from_secs(3);

/// Stops the roller and streaming, and clears the controller's flags, once.
fn host_gone(controller: &mut Controller) {
    roller::stop();
    signals::stop_stream();
    if controller.host_lost() {
        fw_warn!("host gone: roller and streaming stopped");
    }
}

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
/// come back). Tiles are only sent while the host is there. `tx` is the encoding buffer
/// (static: a message is as large as a tile).
pub async fn serve(
    read: &mut impl EndpointOut,
    write: &mut impl EndpointIn,
    controller: &mut Controller,
    tx: &mut [u8; MAX_MESSAGE],
) {
    // No host may come for a long time (the board powered without its USB cable): the
    // link is alive meanwhile.
    liveness::waiting(liveness::Task::Link, read.wait_enabled()).await;
    fw_info!("USB host connected");
    // A new host must not get the last one's tiles.
    outbox::discard_ready();
    let mut last_command = Instant::now();
    let mut silent = false;
    let mut command = heapless::Vec::<u8, MAX_COMMAND>::new();
    let mut oversized = false;
    loop {
        let mut packet = [0u8; PACKET];
        liveness::beat(liveness::Task::Link);
        // A suspended or unconfigured bus stopped both already; the controller is told.
        if BUS_LOST.swap(false, Ordering::AcqRel) {
            host_gone(controller);
        }
        // Wake for the next beat, or for the heartbeat's deadline if it comes first and
        // has not passed yet (a passed one would wake at once, again and again).
        let beat = Instant::now() + liveness::BEAT;
        let wake = if silent {
            beat
        } else {
            (last_command + HEARTBEAT).min(beat)
        };
        let event = select3(
            read.read(&mut packet),
            outbox::next_ready(),
            Timer::at(wake),
        )
        .await;
        let result = match event {
            Either3::Third(()) => {
                if !silent && Instant::now() >= last_command + HEARTBEAT {
                    silent = true;
                    host_gone(controller);
                }
                continue;
            }
            Either3::First(Ok(n)) => {
                last_command = Instant::now();
                silent = false;
                if command.extend_from_slice(&packet[..n]).is_err() {
                    oversized = true;
                }
                if n == PACKET {
                    continue;
                }
                let bytes: &[u8] = if oversized { &[] } else { &command };
                COUNTERS.merge_into(controller.counters_mut());
                // An Ack means the effect is on its way: with the effect queue full, a
                // command that needs it is refused as busy instead.
                let (answer, effect) = controller.handle_when(bytes, !EFFECTS.is_full());
                command.clear();
                oversized = false;
                match effect {
                    // Stop never waits in a queue: the step generator sees it on its next
                    // step.
                    Effect::Roller(RollerCommand::Stop) => roller::stop(),
                    Effect::None => {}
                    other => {
                        // Room was checked before the command was accepted, and only this
                        // task sends effects.
                        if EFFECTS.try_send(Accepted::now(other)).is_err() {
                            fw_warn!("effect queue full after all");
                        }
                    }
                }
                encode_and_send(write, controller, &answer, tx, last_command).await
            }
            Either3::First(Err(e)) => Err(e),
            Either3::Second(sending) => {
                let m = sending.message();
                let msg = outgoing(m, controller);
                let sent = encode_and_send(write, controller, &msg, tx, last_command).await;
                sending.release();
                sent
            }
        };
        if result.is_err() {
            fw_info!("USB host gone");
            // Losing the host stops the roller and streaming.
            host_gone(controller);
            return;
        }
    }
}

/// The protocol message for an outbox slot; the final status takes the tasks' counters.
fn outgoing<'a>(m: &'a outbox::Message, controller: &mut Controller) -> DeviceMessage<'a> {
    match m.kind {
        Kind::Tile {
            index,
            width,
            height,
            observations,
        } => DeviceMessage::Tile(Tile {
            index,
            width,
            height,
            observations,
            pixels: m.payload(),
        }),
        Kind::Raw {
            frame,
            offset,
            total,
        } => DeviceMessage::RawChunk(RawChunk {
            frame,
            offset,
            total,
            data: m.payload(),
        }),
        Kind::StreamEnded => {
            COUNTERS.merge_into(controller.counters_mut());
            DeviceMessage::Status(controller.counters())
        }
    }
}

/// Encodes a message with the controller's next sequence number and sends it, giving up
/// when the host's heartbeat runs out (`last_command` + [`HEARTBEAT`]): a host that stopped
/// reading is gone by the same rule as one that stopped talking, the same bus error.
async fn encode_and_send(
    ep: &mut impl EndpointIn,
    controller: &mut Controller,
    msg: &DeviceMessage<'_>,
    buf: &mut [u8; MAX_MESSAGE],
    last_command: Instant,
) -> Result<(), EndpointError> {
    let Ok(n) = controller.encode(msg, buf) else {
        fw_warn!("message did not encode");
        return Ok(());
    };
    let left = (last_command + HEARTBEAT).saturating_duration_since(Instant::now());
    // The link beats while it waits.
    match liveness::within(liveness::Task::Link, left, send(ep, &buf[..n])).await {
        Ok(sent) => sent,
        Err(_) => Err(EndpointError::Disabled),
    }
}
