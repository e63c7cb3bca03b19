//! Messages for the USB link, built in place in a static pool and handed over by slot
//! index, so no tile-sized value is ever moved through a channel or built on the stack.
//!
//! Each slot index is owned by exactly one side at a time: the free list, the producer
//! (the pipeline) while it fills the slot, the ready queue, or the link while it sends it.
//! The slots' mutexes are therefore never contended; they make the ownership checkable
//! without `unsafe`. The ready queue has room for every index, so handing a filled slot
//! over never fails.

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::mutex::{Mutex, MutexGuard};
use rollfuse_core::protocol::MAX_TILE_BYTES;

/// Slots in the pool: tiles and raw chunks waiting for the link.
pub const SLOTS: usize = 4;

// A raw chunk fits a slot.
const _: () = assert!(rollfuse_core::protocol::MAX_CHUNK <= MAX_TILE_BYTES);

/// What a slot holds. The variant without data comes first, so an empty pool is all
/// zeros and lives in `.bss`, not as a 64 KB image in flash.
#[derive(Clone, Copy)]
pub enum Kind {
    /// Streaming stopped and every tile before it is queued: send the final status.
    StreamEnded,
    /// A fused tile.
    Tile {
        /// Belt index.
        index: u32,
        /// Columns.
        width: u16,
        /// Rows.
        height: u16,
        /// Frames fused into it.
        observations: u8,
    },
    /// A piece of a raw camera frame.
    Raw {
        /// Which frame of the capture.
        frame: u8,
        /// Byte offset in the frame.
        offset: u32,
        /// The frame's size in bytes.
        total: u32,
    },
}

/// One message's contents.
pub struct Message {
    /// What it is.
    pub kind: Kind,
    /// Bytes used in `bytes`.
    pub len: usize,
    /// Pixels or raw bytes.
    pub bytes: [u8; MAX_TILE_BYTES],
}

impl Message {
    /// The bytes in use.
    pub fn payload(&self) -> &[u8] {
        &self.bytes[..self.len.min(MAX_TILE_BYTES)]
    }
}

type Slot = Mutex<CriticalSectionRawMutex, Message>;

static POOL: [Slot; SLOTS] = [const {
    Mutex::new(Message {
        kind: Kind::StreamEnded,
        len: 0,
        bytes: [0; MAX_TILE_BYTES],
    })
}; SLOTS];

static FREE: Channel<CriticalSectionRawMutex, u8, SLOTS> = Channel::new();

/// Filled slots, in the order the link must send them.
static READY: Channel<CriticalSectionRawMutex, u8, SLOTS> = Channel::new();

/// Puts every slot on the free list; call once before any other function here.
pub fn init() {
    for i in 0..SLOTS as u8 {
        let _ = FREE.try_send(i);
    }
}

/// A slot being filled.
pub struct Claim {
    index: u8,
    slot: MutexGuard<'static, CriticalSectionRawMutex, Message>,
}

impl Claim {
    /// The slot's message, to fill in place.
    pub fn message(&mut self) -> &mut Message {
        &mut self.slot
    }

    /// Hands the filled slot to the link.
    pub fn send(self) {
        let index = self.index;
        drop(self.slot);
        // The ready queue has room for every index: this cannot fail.
        let _ = READY.try_send(index);
    }
}

fn claim_index(index: u8) -> Option<Claim> {
    let slot = POOL.get(usize::from(index))?.try_lock().ok()?;
    Some(Claim { index, slot })
}

/// A free slot now, if there is one.
pub fn try_claim() -> Option<Claim> {
    claim_index(FREE.try_receive().ok()?)
}

/// A free slot, waiting for the link to free one.
pub async fn claim() -> Claim {
    loop {
        if let Some(c) = claim_index(FREE.receive().await) {
            return c;
        }
    }
}

/// Frees every filled slot not sent yet (a new host must not get the last one's tiles).
pub fn discard_ready() {
    while let Ok(index) = READY.try_receive() {
        let _ = FREE.try_send(index);
    }
}

/// The next filled slot, for the link; [`Sending::release`] returns it to the free list.
pub async fn next_ready() -> Sending {
    loop {
        let index = READY.receive().await;
        if let Some(slot) = POOL.get(usize::from(index)).and_then(|s| s.try_lock().ok()) {
            return Sending { index, slot };
        }
    }
}

/// A filled slot the link is sending.
pub struct Sending {
    index: u8,
    slot: MutexGuard<'static, CriticalSectionRawMutex, Message>,
}

impl Sending {
    /// The message.
    pub fn message(&self) -> &Message {
        &self.slot
    }

    /// Returns the slot to the free list.
    pub fn release(self) {
        let index = self.index;
        drop(self.slot);
        let _ = FREE.try_send(index);
    }
}
