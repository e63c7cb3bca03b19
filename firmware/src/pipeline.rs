//! The device pipeline on the MCU: on every frame trigger while streaming, one snapshot
//! through `rollfuse_core::device::Pipeline` — the same type the host's virtual device
//! runs — and each completed tile queued for the USB link, or dropped and counted when the
//! queue is full.

use crate::counters::COUNTERS;
use crate::outbox::{self, Kind};
use crate::signals::{STOP_STREAM, STREAM, StreamOrder, TRIGGERS};
use crate::{frame_clock, fw_warn, liveness, roller};
use core::sync::atomic::Ordering::Relaxed;
use embassy_futures::select::{Either4, select4};
use embassy_time::{Duration, Timer, with_timeout};
use rollfuse_core::device::{MCU_CAPACITY, Memory, Pipeline, PipelineBuffers, PipelineConfig};
use rollfuse_core::protocol::{MAX_CHUNK, Tile};

/// Words of one QVGA YUYV frame (under the DMA's 65 535-word limit).
pub const FRAME_WORDS: usize = 320 * 240 * 2 / 4;

/// The longest a snapshot may take: waiting for the next frame start, then one frame
/// (33 ms at 30 frames/s), with room for a slower sensor clock.
pub const CAPTURE_TIMEOUT: Duration = Duration::from_millis(150);

/// How a snapshot went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Capture {
    /// The frame is in the buffer.
    Done,
    /// DMA or synchronization error (an overrun).
    Failed,
    /// Nothing within [`CAPTURE_TIMEOUT`] (no pixel clock, a short frame, a sensor that
    /// never started); the interface was reset.
    TimedOut,
}

/// The camera, as the pipeline uses it.
pub trait Camera {
    /// Captures one frame into `frame`; `false` on a DMA or synchronization error.
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

/// Counts a capture that did not deliver a frame; `true` if it did.
fn counted(outcome: Capture) -> bool {
    match outcome {
        Capture::Done => {
            COUNTERS.frames_captured.fetch_add(1, Relaxed);
            true
        }
        Capture::Failed => {
            COUNTERS.camera_overruns.fetch_add(1, Relaxed);
            false
        }
        Capture::TimedOut => {
            COUNTERS.camera_timeouts.fetch_add(1, Relaxed);
            false
        }
    }
}

/// The frame's bytes (YUYV) as the pipeline reads them: the DMA wrote them in memory
/// order, and the little-endian words hold them as they came.
fn frame_bytes(frame: &[u32; FRAME_WORDS]) -> &[u8] {
    bytemuck::cast_slice(frame.as_slice())
}

/// The pipeline memory the firmware has (see `MCU_CAPACITY`: the controller refuses
/// configurations that need more).
pub const CAPACITY: Memory = MCU_CAPACITY;

/// The pipeline's static buffers.
pub struct Buffers {
    /// The downsampled frame.
    pub frame: [u8; CAPACITY.frame_bytes],
    /// Tiles in fusion.
    pub tiles: [u8; CAPACITY.tile_bytes],
    /// The fuse step's work space.
    pub work: [i32; CAPACITY.work_words],
    /// Row profiles for the offset refinement.
    pub profiles: [i32; CAPACITY.profile_words],
}

impl Default for Buffers {
    fn default() -> Self {
        Self::new()
    }
}

impl Buffers {
    /// All zero.
    pub const fn new() -> Self {
        Self {
            frame: [0; CAPACITY.frame_bytes],
            tiles: [0; CAPACITY.tile_bytes],
            work: [0; CAPACITY.work_words],
            profiles: [0; CAPACITY.profile_words],
        }
    }
}

/// Queues a tile for the link, copied into a free slot of the outbox; with no slot free
/// the tile is dropped and counted (the camera does not wait for the link).
fn queue(tile: Tile<'_>) {
    COUNTERS.tiles_emitted.fetch_add(1, Relaxed);
    let Some(mut claim) = outbox::try_claim() else {
        COUNTERS.tiles_dropped.fetch_add(1, Relaxed);
        return;
    };
    let m = claim.message();
    let Some(room) = m.bytes.get_mut(..tile.pixels.len()) else {
        COUNTERS.tiles_dropped.fetch_add(1, Relaxed);
        return;
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
}

/// Captures `n` frames now and queues them raw, in chunks; waits for room in the outbox
/// rather than drop any (a raw capture is an explicit request).
async fn send_raw(camera: &mut impl Camera, frame: &mut [u32; FRAME_WORDS], n: u8) {
    for k in 0..n {
        if !counted(snapshot(camera, frame).await) {
            continue;
        }
        let bytes = frame_bytes(frame);
        for (i, piece) in bytes.chunks(MAX_CHUNK).enumerate() {
            let Some(mut claim) = slot_within(SLOT_WAIT).await else {
                fw_warn!("raw capture abandoned: the link took nothing for a while");
                return;
            };
            let m = claim.message();
            m.bytes[..piece.len()].copy_from_slice(piece);
            m.len = piece.len();
            m.kind = Kind::Raw {
                frame: k,
                offset: (i * MAX_CHUNK) as u32,
                total: bytes.len() as u32,
            };
            claim.send();
        }
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

/// Runs the pipeline forever on the camera's frames.
pub async fn run(
    camera: &mut impl Camera,
    frame: &'static mut [u32; FRAME_WORDS],
    buffers: &'static mut Buffers,
    initial: PipelineConfig,
) {
    let mut bufs = PipelineBuffers {
        frame: &mut buffers.frame,
        tiles: &mut buffers.tiles,
        work: &mut buffers.work,
        profiles: &mut buffers.profiles,
    };
    let mut config = initial;
    let mut streaming = false;
    loop {
        let Ok(mut pipeline) = Pipeline::new(config, bufs) else {
            fw_warn!("pipeline buffers too small for the configuration");
            return;
        };
        // Serve this configuration until the host sends another.
        let next = loop {
            liveness::beat(liveness::Task::Pipeline);
            // Orders first: with captures of up to 150 ms and triggers every few tens of
            // ms, a trigger is nearly always pending, and orders behind it would starve
            // (and the effects task with them, waiting to queue one).
            let wake = select4(
                STREAM.receive(),
                STOP_STREAM.wait(),
                TRIGGERS.wait(),
                Timer::after(liveness::BEAT),
            );
            let woken = match wake.await {
                Either4::First(order) => Wake::Order(order),
                // The host is gone: stop as if it had asked.
                Either4::Second(()) if streaming => Wake::Order(StreamOrder::Stop),
                Either4::Third(()) => Wake::Trigger,
                Either4::Second(()) | Either4::Fourth(()) => continue,
            };
            match woken {
                Wake::Trigger => {
                    roller::trigger_taken();
                    if !streaming {
                        continue;
                    }
                    let armed = frame_clock::arm();
                    if !counted(snapshot(camera, frame).await) {
                        continue;
                    }
                    let position_px = roller::belt_px(armed.frame_start());
                    match pipeline.push_frame(frame_bytes(frame), position_px, queue) {
                        Ok(_) => COUNTERS.frames_fused.fetch_add(1, Relaxed),
                        Err(_) => COUNTERS.frames_rejected.fetch_add(1, Relaxed),
                    };
                }
                Wake::Order(StreamOrder::Start) => streaming = true,
                Wake::Order(StreamOrder::Stop) => {
                    streaming = false;
                    pipeline.finish(queue);
                    // The link sends the final status once the flushed tiles are out; the
                    // marker waits for the link to free a slot rather than be dropped.
                    if let Some(mut claim) = slot_within(SLOT_WAIT).await {
                        claim.message().kind = Kind::StreamEnded;
                        claim.message().len = 0;
                        claim.send();
                    } else {
                        fw_warn!("no link to send the final status to");
                    }
                }
                Wake::Order(StreamOrder::Configure(c)) => break c,
                Wake::Order(StreamOrder::CaptureRaw(n)) => send_raw(camera, frame, n).await,
            }
        };
        bufs = pipeline.into_buffers();
        config = next;
    }
}
