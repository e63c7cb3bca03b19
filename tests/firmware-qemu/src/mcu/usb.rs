//! The USB link's endpoints, with the host at their other end: commands arrive as 64-byte
//! packets, and what the device writes is taken at full speed's bulk rate, reassembled
//! into messages and tallied as the host tool would see them.

use core::cell::RefCell;
use core::sync::atomic::{AtomicBool, Ordering::Relaxed};
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::{CriticalSectionRawMutex, ThreadModeRawMutex};
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Timer};
use embassy_usb_driver::{
    Direction, Endpoint, EndpointAddress, EndpointError, EndpointIn, EndpointInfo, EndpointOut,
    EndpointType,
};
use rollfuse_core::protocol::{self, Command, DeviceMessage, MAX_MESSAGE, StatusCounters};
use rollfuse_fw::link::PACKET;

/// One bulk packet.
type Packet = ([u8; PACKET], usize);

/// Packets from the host.
static OUT: Channel<CriticalSectionRawMutex, Packet, 8> = Channel::new();

/// Whether the host takes what the device writes.
pub static HOST_READS: AtomicBool = AtomicBool::new(true);

/// A 64-byte bulk packet's share of a full-speed frame (19 a millisecond at most).
const PACKET_TIME: Duration = Duration::from_micros(52);

/// What the host has seen.
#[derive(Clone, Copy)]
pub struct Seen {
    /// Tiles received.
    pub tiles: u32,
    /// Bytes of the tile messages received, as they crossed the bus.
    pub tile_bytes: u32,
    /// Commands acknowledged.
    pub acks: u32,
    /// Commands refused.
    pub naks: u32,
    /// Messages that did not decode.
    pub bad: u32,
    /// Answers to Hello.
    pub infos: u32,
    /// Status reports, and the last.
    pub statuses: u32,
    /// The last status.
    pub status: Option<StatusCounters>,
}

struct Host {
    seen: Seen,
    message: [u8; MAX_MESSAGE],
    len: usize,
}

/// Thread mode only (the link and the session): decoding a tile takes thousands of
/// instructions, which a critical section would add to the roller's latency. Outside the
/// device's 512 KiB (`memory.x`): the host's memory is not the device's.
#[unsafe(link_section = ".host")]
static HOST: Mutex<ThreadModeRawMutex, RefCell<Host>> = Mutex::new(RefCell::new(Host {
    seen: Seen {
        tiles: 0,
        tile_bytes: 0,
        acks: 0,
        naks: 0,
        bad: 0,
        infos: 0,
        statuses: 0,
        status: None,
    },
    message: [0; MAX_MESSAGE],
    len: 0,
}));

/// What the host has seen so far.
pub fn seen() -> Seen {
    HOST.lock(|h| h.borrow().seen)
}

/// The packet loaded in the IN endpoint and not yet taken, as the OTG core holds it: a
/// write loads its packet first and the host takes it when it reads, so a write
/// abandoned while the host does not read leaves it there.
static LOADED: Mutex<ThreadModeRawMutex, RefCell<Option<Packet>>> = Mutex::new(RefCell::new(None));

/// Another host process opens the device (no bus reset): it reads, and holds no part of
/// the last one's message.
pub fn new_host() {
    HOST.lock(|h| h.borrow_mut().len = 0);
    HOST_READS.store(true, Relaxed);
}

/// Sends a command as the host tool does: one transfer of 64-byte packets ending short.
pub async fn send(seq: u32, command: &Command) {
    let mut buf = [0u8; 256];
    let Ok(n) = protocol::encode(seq, command, &mut buf) else {
        return;
    };
    for piece in buf[..n].chunks(PACKET) {
        let mut packet = [0u8; PACKET];
        packet[..piece.len()].copy_from_slice(piece);
        OUT.send((packet, piece.len())).await;
    }
    if n % PACKET == 0 {
        OUT.send(([0; PACKET], 0)).await;
    }
}

fn info(dir: Direction) -> EndpointInfo {
    EndpointInfo {
        addr: EndpointAddress::from_parts(1, dir),
        ep_type: EndpointType::Bulk,
        max_packet_size: PACKET as u16,
        interval_ms: 0,
    }
}

/// The bulk OUT endpoint.
pub struct Out(EndpointInfo);

impl Out {
    /// Endpoint 0x01.
    pub fn new() -> Self {
        Self(info(Direction::Out))
    }
}

impl Endpoint for Out {
    fn info(&self) -> &EndpointInfo {
        &self.0
    }
    async fn wait_enabled(&mut self) {}
}

impl EndpointOut for Out {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, EndpointError> {
        let (packet, n) = OUT.receive().await;
        buf[..n].copy_from_slice(&packet[..n]);
        Ok(n)
    }
}

/// The bulk IN endpoint.
pub struct In(EndpointInfo);

impl In {
    /// Endpoint 0x81.
    pub fn new() -> Self {
        Self(info(Direction::In))
    }
}

impl Endpoint for In {
    fn info(&self) -> &EndpointInfo {
        &self.0
    }
    async fn wait_enabled(&mut self) {}
}

impl EndpointIn for In {
    async fn write(&mut self, buf: &[u8]) -> Result<(), EndpointError> {
        // A packet an abandoned write left loaded goes out first, as the core's FIFO
        // would send it.
        if LOADED.lock(|l| l.borrow().is_some()) {
            deliver_loaded().await;
        }
        let mut packet = [0u8; PACKET];
        packet[..buf.len()].copy_from_slice(buf);
        LOADED.lock(|l| *l.borrow_mut() = Some((packet, buf.len())));
        deliver_loaded().await;
        Ok(())
    }
}

/// Waits until the host reads, then hands it the loaded packet at the bus's pace.
async fn deliver_loaded() {
    // A host that stopped reading never takes the packet.
    while !HOST_READS.load(Relaxed) {
        Timer::after_millis(1).await;
    }
    Timer::after(PACKET_TIME).await;
    if let Some((packet, n)) = LOADED.lock(|l| l.borrow_mut().take()) {
        HOST.lock(|h| h.borrow_mut().take(&packet[..n]));
    }
}

impl rollfuse_fw::link::DiscardLoaded for In {
    fn discard_loaded(&mut self) {
        LOADED.lock(|l| l.borrow_mut().take());
    }
}

impl Host {
    /// Adds a packet; a short one ends the message.
    fn take(&mut self, packet: &[u8]) {
        let end = self.len + packet.len();
        if let Some(room) = self.message.get_mut(self.len..end) {
            room.copy_from_slice(packet);
            self.len = end;
        }
        if packet.len() < PACKET {
            let n = core::mem::take(&mut self.len);
            self.tally(n);
        }
    }

    fn tally(&mut self, n: usize) {
        let seen = &mut self.seen;
        match protocol::decode::<DeviceMessage>(&self.message[..n]) {
            Ok((_, DeviceMessage::Tile(_))) => {
                seen.tiles += 1;
                seen.tile_bytes += n as u32;
            }
            Ok((_, DeviceMessage::Ack { .. })) => seen.acks += 1,
            Ok((_, DeviceMessage::Nak { .. })) => seen.naks += 1,
            Ok((_, DeviceMessage::Info(_))) => seen.infos += 1,
            Ok((_, DeviceMessage::Status(s))) => {
                seen.statuses += 1;
                seen.status = Some(s);
            }
            Ok(_) => {}
            Err(_) => seen.bad += 1,
        }
    }
}
