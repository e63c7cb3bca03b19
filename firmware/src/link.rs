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
use core::pin::pin;
use core::sync::atomic::Ordering;
use embassy_futures::select::{Either, Either3, select, select3};
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

/// An IN endpoint that can discard a packet it holds loaded for a host that never took
/// it. On the OTG core a write returns once its packet is in the FIFO with the endpoint
/// enabled; a send abandoned because the host stopped reading leaves that packet there,
/// and the next host's first read would get it glued before its own first reply.
pub trait DiscardLoaded {
    /// Drops a packet loaded but not taken, if there is one; the next write starts clean.
    fn discard_loaded(&mut self);
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

/// Answers to commands that completed while a message was being sent, held to follow it
/// in order. While it is full the host's further packets wait in its own queue.
const HELD_ANSWERS: usize = 4;

/// The host's side of the link: the command being assembled, when the last packet came,
/// and the answers held behind a message in flight.
struct Host {
    command: heapless::Vec<u8, MAX_COMMAND>,
    oversized: bool,
    last_command: Instant,
    silent: bool,
    answers: heapless::Deque<DeviceMessage<'static>, HELD_ANSWERS>,
}

impl Host {
    fn new() -> Self {
        Self {
            command: heapless::Vec::new(),
            oversized: false,
            last_command: Instant::now(),
            silent: false,
            answers: heapless::Deque::new(),
        }
    }

    /// Takes one packet; the last packet of a command carries the command out and gives
    /// its answer.
    fn take(
        &mut self,
        packet: &[u8],
        controller: &mut Controller,
    ) -> Option<DeviceMessage<'static>> {
        self.last_command = Instant::now();
        self.silent = false;
        if self.command.extend_from_slice(packet).is_err() {
            self.oversized = true;
        }
        if packet.len() == PACKET {
            return None;
        }
        let bytes: &[u8] = if self.oversized { &[] } else { &self.command };
        let answer = carry_out(controller, bytes);
        self.command.clear();
        self.oversized = false;
        Some(answer)
    }

    /// When a message sent now must have gone: a host that stopped reading is gone by the
    /// same rule as one that stopped talking.
    fn send_deadline(&self) -> Instant {
        self.last_command + HEARTBEAT
    }
}

/// Hands a command to the controller and starts its effect; the answer to send.
fn carry_out(controller: &mut Controller, bytes: &[u8]) -> DeviceMessage<'static> {
    COUNTERS.merge_into(controller.counters_mut());
    // An Ack means the effect is on its way: with the effect queue full, a command that
    // needs it is refused as busy instead.
    let (answer, effect) = controller.handle_when(bytes, !EFFECTS.is_full());
    match effect {
        // Stop never waits in a queue: the step generator sees it on its next step.
        Effect::Roller(RollerCommand::Stop) => roller::stop(),
        Effect::None => {}
        other => {
            // Room was checked before the command was accepted, and only this task sends
            // effects.
            if EFFECTS.try_send(Accepted::now(other)).is_err() {
                fw_warn!("effect queue full after all");
            }
        }
    }
    answer
}

/// Serves the link until the host goes away, then returns (the caller waits for it to
/// come back). Tiles are only sent while the host is there. `tx` is the encoding buffer
/// (static: a message is as large as a tile).
pub async fn serve(
    read: &mut impl EndpointOut,
    write: &mut (impl EndpointIn + DiscardLoaded),
    controller: &mut Controller,
    tx: &mut [u8; MAX_MESSAGE],
) {
    // No host may come for a long time (the board powered without its USB cable): the
    // link is alive meanwhile.
    liveness::waiting(liveness::Task::Link, read.wait_enabled()).await;
    fw_info!("USB host connected");
    // A new host must not get the last one's tiles.
    outbox::discard_ready();
    let mut host = Host::new();
    let mut link = Endpoints { read, write, tx };
    loop {
        liveness::beat(liveness::Task::Link);
        // A suspended or unconfigured bus stopped both already; the controller is told.
        if BUS_LOST.swap(false, Ordering::AcqRel) {
            host_gone(controller);
        }
        let result = if let Some(answer) = host.answers.pop_front() {
            link.send(&answer, &mut host, controller).await
        } else {
            link.next_event(&mut host, controller).await
        };
        if result.is_err() {
            fw_info!("USB host gone");
            // Losing the host stops the roller and streaming.
            host_gone(controller);
            return;
        }
    }
}

/// The endpoints and the encoding buffer.
struct Endpoints<'a, R, W> {
    read: &'a mut R,
    write: &'a mut W,
    tx: &'a mut [u8; MAX_MESSAGE],
}

impl<R: EndpointOut, W: EndpointIn + DiscardLoaded> Endpoints<'_, R, W> {
    /// Waits for a packet from the host, a message to send, or the next beat, and acts on it.
    async fn next_event(
        &mut self,
        host: &mut Host,
        controller: &mut Controller,
    ) -> Result<(), EndpointError> {
        let mut packet = [0u8; PACKET];
        // Wake for the next beat, or for the heartbeat's deadline if it comes first and
        // has not passed yet (a passed one would wake at once, again and again).
        let beat = Instant::now() + liveness::BEAT;
        let wake = if host.silent {
            beat
        } else {
            (host.last_command + HEARTBEAT).min(beat)
        };
        let event = select3(
            self.read.read(&mut packet),
            outbox::next_ready(),
            Timer::at(wake),
        )
        .await;
        match event {
            Either3::Third(()) => {
                if !host.silent && Instant::now() >= host.last_command + HEARTBEAT {
                    host.silent = true;
                    host_gone(controller);
                }
                Ok(())
            }
            Either3::First(Ok(n)) => match host.take(&packet[..n], controller) {
                Some(answer) => self.send(&answer, host, controller).await,
                None => Ok(()),
            },
            Either3::First(Err(e)) => Err(e),
            Either3::Second(sending) => {
                let msg = outgoing(sending.message(), controller);
                let sent = self.send(&msg, host, controller).await;
                sending.release();
                sent
            }
        }
    }

    /// Encodes a message with the controller's next sequence number and sends it, reading
    /// the host meanwhile: a command that completes during the send is carried out at
    /// once (a Stop halts the roller with a tile still in flight) and its answer held to
    /// follow. Gives up at the host's [`Host::send_deadline`] as at the start of the send.
    async fn send(
        &mut self,
        msg: &DeviceMessage<'_>,
        host: &mut Host,
        controller: &mut Controller,
    ) -> Result<(), EndpointError> {
        let Ok(n) = controller.encode(msg, self.tx) else {
            fw_warn!("message did not encode");
            return Ok(());
        };
        let left = host
            .send_deadline()
            .saturating_duration_since(Instant::now());
        // The link beats while it waits.
        let sending = liveness::within(liveness::Task::Link, left, send(self.write, &self.tx[..n]));
        let outcome = {
            let mut sending = pin!(sending);
            loop {
                let mut packet = [0u8; PACKET];
                let event = if host.answers.is_full() {
                    Either::First(sending.as_mut().await)
                } else {
                    select(sending.as_mut(), self.read.read(&mut packet)).await
                };
                match event {
                    Either::First(outcome) => break outcome,
                    Either::Second(Ok(n)) => {
                        if let Some(answer) = host.take(&packet[..n], controller) {
                            // Not full: checked above.
                            let _ = host.answers.push_back(answer);
                        }
                    }
                    Either::Second(Err(e)) => return Err(e),
                }
            }
        };
        outcome.unwrap_or_else(|_abandoned| {
            // The host stopped reading: what it never took must not reach the next host.
            self.write.discard_loaded();
            Err(EndpointError::Disabled)
        })
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
