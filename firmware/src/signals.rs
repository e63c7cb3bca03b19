//! How the tasks reach each other: queues for orders that may wait, signals for what must
//! never be lost or delayed behind them.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use rollfuse_core::device::{Effect, Order};

/// The pipeline's orders: the stream's part of accepted commands.
pub static STREAM: Channel<CriticalSectionRawMutex, StreamOrder, 4> = Channel::new();

/// A stream order, with the stream stops requested when its command was accepted
/// ([`stream_stops_requested`]).
#[derive(Debug, Clone, Copy)]
pub struct StreamOrder {
    /// The order.
    pub order: Order,
    /// Stream stops requested before its command was accepted.
    pub stops: u32,
}

/// Wakes the pipeline when the host is gone ([`stop_stream`]).
pub static STOP_STREAM: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// Stream stops requested since start-up (wrapping).
static STREAM_STOPS: AtomicU32 = AtomicU32::new(0);

/// Roller stops requested since start-up (wrapping).
static ROLLER_STOPS: AtomicU32 = AtomicU32::new(0);

/// Counts a roller stop ([`crate::roller::stop`] requests it).
pub fn count_roller_stop() {
    ROLLER_STOPS.fetch_add(1, Ordering::AcqRel);
}

/// Roller stops requested since start-up (wrapping): what an order accepted now is tagged
/// with.
pub fn roller_stops_requested() -> u32 {
    ROLLER_STOPS.load(Ordering::Acquire)
}

/// The host is gone: streaming ends. Counted and signalled, never queued, so no full queue
/// can lose it. The counts keep it to the stream it was meant for: a stream started by a
/// command accepted before it is not started when its order comes, and one started by a
/// command accepted after it is not ended by it.
pub fn stop_stream() {
    STREAM_STOPS.fetch_add(1, Ordering::AcqRel);
    STOP_STREAM.signal(());
}

/// Stream stops requested since start-up (wrapping): what an order accepted now is tagged
/// with.
pub fn stream_stops_requested() -> u32 {
    STREAM_STOPS.load(Ordering::Acquire)
}

/// The bus was suspended or unconfigured (set by the USB stack's events, which stop the
/// roller and streaming at once): the link takes it to mark the host gone in the
/// controller too, so a host that comes back is told the truth.
pub static BUS_LOST: AtomicBool = AtomicBool::new(false);

/// Accepted commands' effects, for the task that carries them out ([`crate::effects`]).
/// The link checks for room before accepting a command that needs it.
pub static EFFECTS: Channel<CriticalSectionRawMutex, Accepted, 8> = Channel::new();

/// An accepted command's effect, with the roller and stream stops requested when it was
/// accepted ([`roller_stops_requested`], [`stream_stops_requested`]): an order that
/// a later stop overtook in the queues is dropped, not carried out after it.
#[derive(Debug, Clone, Copy)]
pub struct Accepted {
    /// What the command does.
    pub effect: Effect,
    /// Roller stops requested before the command was accepted.
    pub stops: u32,
    /// Stream stops requested before the command was accepted.
    pub stream_stops: u32,
}

impl Accepted {
    /// `effect`, accepted now.
    pub fn now(effect: Effect) -> Self {
        Self {
            effect,
            stops: roller_stops_requested(),
            stream_stops: stream_stops_requested(),
        }
    }
}

/// Frame triggers from the roller. A trigger the camera has not taken when the next
/// arrives is overwritten, and counted as an overrun. The frame's position is not the
/// trigger's but its start's ([`crate::frame_clock`]).
pub static TRIGGERS: Signal<CriticalSectionRawMutex, ()> = Signal::new();
