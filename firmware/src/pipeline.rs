//! The stream on the MCU: on every frame trigger while streaming, one snapshot through
//! the core's `device::Session` — the same session the host's virtual device runs — and
//! each completed tile queued for the USB link, or dropped and counted when the queue is
//! full.

use crate::counters::COUNTERS;
use crate::outbox::{self, Kind};
use crate::signals::{self, STOP_STREAM, STREAM, StreamOrder, TRIGGERS};
use crate::{cycles, frame_clock, fw_info, fw_warn, liveness, roller};
use embassy_futures::join::join;
use embassy_futures::select::{Either4, select4};
use embassy_time::{Duration, Timer, with_timeout};
use rollfuse_core::device::{
    CAMERA, Capture, Event, Handed, Next, Order, Outlet, PipelineBuffers, PipelineConfig, Session,
    raw_chunks,
};
use rollfuse_core::protocol::Tile;

/// Words of one camera frame (under the DMA's 65 535-word limit).
pub const FRAME_WORDS: usize = CAMERA.frame_bytes() / 4;

/// The longest a snapshot may take: waiting for the next frame start, then one frame
/// (33 ms at 30 frames/s), with room for a slower sensor clock.
pub const CAPTURE_TIMEOUT: Duration = Duration::from_millis(150);

/// The camera, as the pipeline uses it.
pub trait Camera {
    /// Captures one frame into `frame`; `false` on a DMA or synchronization error. The
    /// capture is armed when the future is first polled.
    fn capture(&mut self, frame: &mut [u32; FRAME_WORDS]) -> impl Future<Output = bool>;
    /// Makes the interface ready for the next capture after one was abandoned.
    fn reset(&mut self);
}

/// One snapshot, abandoned (and the interface reset) after [`CAPTURE_TIMEOUT`].
async fn snapshot(camera: &mut impl Camera, frame: &mut [u32; FRAME_WORDS]) -> Capture {
    match with_timeout(CAPTURE_TIMEOUT, camera.capture(frame)).await {
        Ok(true) => Capture::Done,
        Ok(false) => Capture::Failed,
        Err(_) => {
            camera.reset();
            Capture::TimedOut
        }
    }
}

/// The camera's two frame buffers: the next capture fills one while the window of the
/// last is taken out of the other, so the next capture can be armed as soon as a frame
/// ends — before the take, which need not fit before the sensor's next VSYNC.
pub struct Frames {
    /// Where the next capture writes.
    filling: &'static mut [u32; FRAME_WORDS],
    /// The last capture's frame.
    filled: &'static mut [u32; FRAME_WORDS],
}

impl Frames {
    /// Two buffers, each of one frame.
    pub fn new(a: &'static mut [u32; FRAME_WORDS], b: &'static mut [u32; FRAME_WORDS]) -> Self {
        Self {
            filling: a,
            filled: b,
        }
    }

    /// The buffer just filled becomes the last capture's.
    fn swap(&mut self) {
        core::mem::swap(&mut self.filling, &mut self.filled);
    }
}

/// The frame's bytes (YUYV) as the pipeline reads them: the DMA wrote them in memory
/// order, and the little-endian words hold them as they came.
fn frame_bytes(frame: &[u32; FRAME_WORDS]) -> &[u8] {
    bytemuck::cast_slice(frame.as_slice())
}

/// The session's outlet: tiles into free outbox slots (dropped, and counted, when none is
/// free: the camera does not wait for the link), counts into [`COUNTERS`].
struct Outbox;

impl Outlet for Outbox {
    fn tile(&mut self, tile: Tile<'_>) -> Handed {
        let Some(mut claim) = outbox::try_claim() else {
            return Handed::Dropped;
        };
        let m = claim.message();
        let Some(room) = m.bytes.get_mut(..tile.pixels.len()) else {
            return Handed::Dropped;
        };
        room.copy_from_slice(tile.pixels);
        m.len = tile.pixels.len();
        m.kind = Kind::Tile {
            index: tile.index,
            width: tile.width,
            height: tile.height,
            observations: tile.observations,
        };
        claim.send();
        Handed::Queued
    }

    fn count(&mut self, event: Event) {
        COUNTERS.count(event);
    }
}

/// Captures `n` frames now and queues them raw, in chunks; waits for room in the outbox
/// rather than drop any (a raw capture is an explicit request).
async fn send_raw(camera: &mut impl Camera, frame: &mut [u32; FRAME_WORDS], n: u8) {
    for k in 0..n {
        if !snapshot(camera, frame).await.delivered(&mut Outbox) {
            continue;
        }
        for chunk in raw_chunks(k, frame_bytes(frame)) {
            let Some(mut claim) = slot_within(SLOT_WAIT).await else {
                fw_warn!("raw capture abandoned: the link took nothing for a while");
                return;
            };
            let m = claim.message();
            m.bytes[..chunk.data.len()].copy_from_slice(chunk.data);
            m.len = chunk.data.len();
            m.kind = Kind::Raw {
                frame: chunk.frame,
                offset: chunk.offset,
                total: chunk.total,
            };
            claim.send();
        }
    }
}

/// Queues the marker after which the link sends the final status (once the flushed
/// tiles are out); it waits for the link to free a slot rather than be dropped.
async fn send_status() {
    if let Some(mut claim) = slot_within(SLOT_WAIT).await {
        claim.message().kind = Kind::StreamEnded;
        claim.message().len = 0;
        claim.send();
    } else {
        fw_warn!("no link to send the final status to");
    }
}

/// The longest the pipeline waits for the link to free an outbox slot (it beats
/// meanwhile, so the watchdog waits too).
const SLOT_WAIT: Duration = Duration::from_secs(2);

/// A free outbox slot, waiting at most `limit` for the link to free one.
async fn slot_within(limit: Duration) -> Option<outbox::Claim> {
    liveness::within(liveness::Task::Pipeline, limit, outbox::claim())
        .await
        .ok()
}

/// What woke the pipeline.
enum Wake {
    /// A frame trigger.
    Trigger,
    /// An order.
    Order(StreamOrder),
}

/// The next thing to do: an order, a frame trigger, or nothing yet (a beat passed).
/// `streaming`: a stream runs that a stop signalled now would end.
async fn wake(streaming: bool) -> Option<Wake> {
    liveness::beat(liveness::Task::Pipeline);
    // Orders first: with captures of up to 150 ms and triggers every few tens of ms, a
    // trigger is nearly always pending, and orders behind it would starve (and the
    // effects task with them, waiting to queue one).
    let wake = select4(
        STREAM.receive(),
        STOP_STREAM.wait(),
        TRIGGERS.wait(),
        Timer::after(liveness::BEAT),
    );
    match wake.await {
        Either4::First(order) => Some(Wake::Order(order)),
        // The host is gone: stop as if it had asked.
        Either4::Second(()) if streaming => Some(Wake::Order(StreamOrder {
            order: Order::Stop,
            stops: signals::stream_stops_requested(),
        })),
        Either4::Third(()) => Some(Wake::Trigger),
        Either4::Second(()) | Either4::Fourth(()) => None,
    }
}

/// On a frame trigger while streaming: one snapshot, fused at the belt position of its
/// first row. When the next trigger is already waiting (and no order is), its capture is
/// armed into the other buffer as soon as this frame ends, before this frame's window is
/// taken and fused: neither has to fit in the sensor's time to its next VSYNC.
async fn on_trigger(session: &mut Session<'_>, camera: &mut impl Camera, frames: &mut Frames) {
    roller::trigger_taken();
    if !session.streaming() {
        return;
    }
    let mut armed = frame_clock::arm();
    let mut capture = snapshot(camera, frames.filling).await;
    while capture.delivered(&mut Outbox) {
        frames.swap();
        let position_px = roller::belt_px(armed.frame_start());
        if !next_capture_waits() {
            take_and_fuse(session, frames.filled, position_px);
            return;
        }
        liveness::beat(liveness::Task::Pipeline);
        armed = frame_clock::arm();
        // The capture is armed when first polled, which `join` does before the take.
        let Frames { filling, filled } = frames;
        let work = async { take_and_fuse(session, filled, position_px) };
        let fused;
        (capture, fused) = join(snapshot(camera, filling), work).await;
        if !fused {
            // The frame was refused; the capture armed beside it is counted, not fused.
            let _ = capture.delivered(&mut Outbox);
            return;
        }
    }
}

/// Takes a frame's window and fuses it at `position_px`; false if the frame was refused.
fn take_and_fuse(session: &mut Session<'_>, frame: &[u32; FRAME_WORDS], position_px: u64) -> bool {
    if !session.take(frame_bytes(frame), &mut Outbox) {
        return false;
    }
    cycles::timed(|| session.fuse_taken(position_px, &mut Outbox));
    true
}

/// Whether a frame trigger is waiting and no order is; if so, the trigger is taken.
fn next_capture_waits() -> bool {
    let waits = STREAM.is_empty() && !STOP_STREAM.signaled() && TRIGGERS.try_take().is_some();
    if waits {
        roller::trigger_taken();
    }
    waits
}

/// Runs the stream forever on the camera's frames, starting with `initial`.
pub async fn run(
    camera: &mut impl Camera,
    mut frames: Frames,
    buffers: PipelineBuffers<'static>,
    initial: PipelineConfig,
) {
    let Ok(mut session) = Session::new(initial, buffers) else {
        fw_warn!("pipeline buffers too small for the configuration");
        return;
    };
    // The stream stops requested when the running stream's start was accepted: a stop
    // signalled since ends it, one from before does not.
    let mut started_after = 0;
    loop {
        let live = session.streaming() && started_after != signals::stream_stops_requested();
        let Some(woken) = wake(live).await else {
            continue;
        };
        let order = match woken {
            Wake::Trigger => {
                on_trigger(&mut session, camera, &mut frames).await;
                continue;
            }
            Wake::Order(StreamOrder { order, stops }) => {
                if matches!(order, Order::Start) {
                    if stops != signals::stream_stops_requested() {
                        fw_info!("a stream start from before a stop dropped");
                        continue;
                    }
                    started_after = stops;
                }
                order
            }
        };
        match session.order(order, &mut Outbox) {
            Ok(Next::Nothing) => {}
            Ok(Next::SendStatus) => send_status().await,
            Ok(Next::CaptureRaw(n)) => send_raw(camera, frames.filling, n).await,
            // The controller checked the configuration against this memory.
            Err(_) => fw_warn!("configuration refused: pipeline buffers too small"),
        }
    }
}
