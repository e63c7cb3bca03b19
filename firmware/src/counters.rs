//! What the tasks count, for the status the controller reports.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering::Relaxed};
use rollfuse_core::device::Event;
use rollfuse_core::protocol::StatusCounters;

/// Counters shared by the camera, pipeline and link.
pub struct Counters {
    /// Frames the camera delivered.
    pub frames_captured: AtomicU32,
    /// Captures that failed, and triggers overwritten before the camera took them.
    pub camera_overruns: AtomicU32,
    /// Captures that never completed.
    pub camera_timeouts: AtomicU32,
    /// Whether the camera took its set-up at start-up.
    pub camera_ready: AtomicBool,
    /// Frames the pipeline fused.
    pub frames_fused: AtomicU32,
    /// Frames the pipeline refused.
    pub frames_rejected: AtomicU32,
    /// Tiles completed.
    pub tiles_emitted: AtomicU32,
    /// Tiles completed but dropped: no outbox slot free.
    pub tiles_dropped: AtomicU32,
}

/// The firmware's counters.
pub static COUNTERS: Counters = Counters {
    frames_captured: AtomicU32::new(0),
    camera_overruns: AtomicU32::new(0),
    camera_timeouts: AtomicU32::new(0),
    camera_ready: AtomicBool::new(false),
    frames_fused: AtomicU32::new(0),
    frames_rejected: AtomicU32::new(0),
    tiles_emitted: AtomicU32::new(0),
    tiles_dropped: AtomicU32::new(0),
};

impl Counters {
    /// Counts one event of the stream.
    pub fn count(&self, event: Event) {
        let counter = match event {
            Event::FrameCaptured => &self.frames_captured,
            Event::CameraOverrun => &self.camera_overruns,
            Event::CameraTimeout => &self.camera_timeouts,
            Event::FrameFused => &self.frames_fused,
            Event::FrameRejected => &self.frames_rejected,
            Event::TileEmitted => &self.tiles_emitted,
            Event::TileDropped => &self.tiles_dropped,
        };
        counter.fetch_add(1, Relaxed);
    }

    /// Copies the tasks' counts into the controller's status (its own fields — messages
    /// sent, bad commands, streaming — it keeps itself).
    pub fn merge_into(&self, status: &mut StatusCounters) {
        status.frames_captured = self.frames_captured.load(Relaxed);
        status.camera_overruns = self.camera_overruns.load(Relaxed);
        status.camera_timeouts = self.camera_timeouts.load(Relaxed);
        status.camera_ready = self.camera_ready.load(Relaxed);
        status.frames_fused = self.frames_fused.load(Relaxed);
        status.frames_rejected = self.frames_rejected.load(Relaxed);
        status.tiles_emitted = self.tiles_emitted.load(Relaxed);
        status.tiles_dropped = self.tiles_dropped.load(Relaxed);
        crate::cycles::merge_into(status);
    }
}
