//! One device's stream, as the firmware and the host's virtual device both run it: the
//! pipeline for the configuration in force, frames fused while streaming, the tiles in
//! fusion flushed on a stop, raw frames cut into chunks, and all of it counted for the
//! status.
//!
//! The session neither waits nor queues: its caller captures the frames, carries out what
//! [`Session::order`] asks ([`Next`]) and gives it an [`Outlet`] — the firmware's outbox,
//! the virtual device's channel — for the tiles and the counts.
//!
//! ```
//! use rollfuse_core::device::{
//!     CAMERA, Capture, Event, Handed, ModuleBuffers, Next, Order, Outlet, PipelineConfig,
//!     Session,
//! };
//! use rollfuse_core::protocol::{DeviceConfig, Tile};
//!
//! /// Keeps the tile indices and counts fused frames.
//! #[derive(Default)]
//! struct Kept { tiles: Vec<u32>, fused: u32 }
//!
//! impl Outlet for Kept {
//!     fn tile(&mut self, tile: Tile<'_>) -> Handed {
//!         self.tiles.push(tile.index);
//!         Handed::Queued
//!     }
//!     fn count(&mut self, event: Event) {
//!         self.fused += u32::from(event == Event::FrameFused);
//!     }
//! }
//!
//! let config = PipelineConfig::from_wire(&DeviceConfig::default(), CAMERA).unwrap();
//! let mut memory = Box::new(ModuleBuffers::new());
//! let mut session = Session::new(config, memory.buffers()).unwrap();
//! let mut kept = Kept::default();
//! session.order(Order::Start, &mut kept).unwrap();
//! let frame = vec![128u8; CAMERA.frame_bytes()];
//! for k in 0..12 {
//!     if Capture::Done.delivered(&mut kept) {
//!         session.fuse(&frame, k * config.spacing_px() as u64, &mut kept);
//!     }
//! }
//! assert_eq!(session.order(Order::Stop, &mut kept), Ok(Next::SendStatus));
//! assert_eq!(kept.fused, 12);
//! assert!(kept.tiles.windows(2).all(|w| w[0] < w[1]));
//! ```

use super::controller::Effect;
use super::pipeline::{Pipeline, PipelineBuffers, PipelineConfig};
use crate::Error;
use crate::protocol::{MAX_CHUNK, RawChunk, StatusCounters, Tile};

/// What a device counts as it streams, as its status reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// The camera delivered a frame.
    FrameCaptured,
    /// A capture failed (a DMA or synchronization error), or a frame trigger was
    /// overwritten before the camera took it.
    CameraOverrun,
    /// A capture never completed.
    CameraTimeout,
    /// The pipeline fused a frame.
    FrameFused,
    /// The pipeline refused a frame (not one camera frame; the belt moved backwards).
    FrameRejected,
    /// A tile was completed.
    TileEmitted,
    /// A completed tile was dropped: the link had no room for it.
    TileDropped,
}

impl StatusCounters {
    /// Counts one `event` (wrapping, as every counter of the status does).
    pub fn count(&mut self, event: Event) {
        let counter = match event {
            Event::FrameCaptured => &mut self.frames_captured,
            Event::CameraOverrun => &mut self.camera_overruns,
            Event::CameraTimeout => &mut self.camera_timeouts,
            Event::FrameFused => &mut self.frames_fused,
            Event::FrameRejected => &mut self.frames_rejected,
            Event::TileEmitted => &mut self.tiles_emitted,
            Event::TileDropped => &mut self.tiles_dropped,
        };
        *counter = counter.wrapping_add(1);
    }
}

/// What became of a tile handed to the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Handed {
    /// It is on its way.
    Queued,
    /// No room: it is lost (the camera does not wait for the link), and counted.
    Dropped,
    /// The host is gone.
    LinkGone,
}

/// The device around a session: where its tiles go and where it counts.
pub trait Outlet {
    /// Takes a tile, copying it: it lives in the pipeline's memory.
    fn tile(&mut self, tile: Tile<'_>) -> Handed;
    /// Counts one event.
    fn count(&mut self, event: Event);
}

/// How one capture went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Capture {
    /// The frame is in the buffer.
    Done,
    /// DMA or synchronization error (an overrun).
    Failed,
    /// The frame never completed (no pixel clock, a short frame, a sensor that never
    /// started).
    TimedOut,
}

impl Capture {
    /// Counts the capture; `true` if it delivered a frame.
    pub fn delivered(self, outlet: &mut impl Outlet) -> bool {
        outlet.count(match self {
            Self::Done => Event::FrameCaptured,
            Self::Failed => Event::CameraOverrun,
            Self::TimedOut => Event::CameraTimeout,
        });
        self == Self::Done
    }
}

/// A session's part of accepted commands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Order {
    /// Fuse frames from now on.
    Start,
    /// Flush the tiles in fusion and stop.
    Stop,
    /// Serve this configuration (the controller accepts none while streaming).
    Configure(PipelineConfig),
    /// Send this many raw frames, captured now.
    CaptureRaw(u8),
}

impl Order {
    /// The session's part of an accepted command's effect, if it has one.
    pub fn of(effect: Effect) -> Option<Self> {
        match effect {
            Effect::StreamStart => Some(Self::Start),
            Effect::StreamStop => Some(Self::Stop),
            Effect::Configure(config) => Some(Self::Configure(config)),
            Effect::CaptureRaw(n) => Some(Self::CaptureRaw(n)),
            Effect::Leds(_) | Effect::Roller(_) | Effect::None => None,
        }
    }
}

/// What the caller does after an order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Next {
    /// Nothing more.
    Nothing,
    /// Send the final status, after the tiles the stop flushed.
    SendStatus,
    /// Capture this many frames and send them with [`raw_chunks`].
    CaptureRaw(u8),
}

/// One device's stream: its pipeline on the device's memory, and whether it is streaming.
pub struct Session<'b> {
    pipeline: Pipeline<'b>,
    streaming: bool,
}

impl<'b> Session<'b> {
    /// A session serving `config` on `buffers`, not streaming; fails if a buffer is
    /// smaller than the configuration needs.
    pub fn new(config: PipelineConfig, buffers: PipelineBuffers<'b>) -> Result<Self, Error> {
        Ok(Self {
            pipeline: Pipeline::new(config, buffers)?,
            streaming: false,
        })
    }

    /// Whether frames are being fused.
    pub fn streaming(&self) -> bool {
        self.streaming
    }

    /// The configuration in force.
    pub fn config(&self) -> &PipelineConfig {
        self.pipeline.config()
    }

    /// Carries out an order. Only [`Order::Configure`] can fail, when the device's memory
    /// cannot hold the configuration; the one in force stays.
    pub fn order(&mut self, order: Order, outlet: &mut impl Outlet) -> Result<Next, Error> {
        Ok(match order {
            Order::Start => {
                self.streaming = true;
                Next::Nothing
            }
            Order::Stop => {
                self.stop(outlet);
                Next::SendStatus
            }
            Order::Configure(config) => {
                self.pipeline.reconfigure(config)?;
                Next::Nothing
            }
            Order::CaptureRaw(n) => Next::CaptureRaw(n),
        })
    }

    /// Fuses a delivered camera frame, taken when the commanded belt position was
    /// `position_px` camera pixels from the start of the run, and hands the tiles it
    /// completes to `outlet`: [`Self::take`] then [`Self::fuse_taken`]. Does nothing
    /// unless streaming. `false` if the host is gone.
    pub fn fuse(&mut self, camera: &[u8], position_px: u64, outlet: &mut impl Outlet) -> bool {
        !self.take(camera, outlet) || self.fuse_taken(position_px, outlet)
    }

    /// The first half of [`Self::fuse`]: converts what the pipeline needs of a delivered
    /// camera frame into the session's memory, after which the camera's buffer is free
    /// for the next capture. Whether a frame is taken: not unless streaming, nor when it
    /// is refused (counted).
    pub fn take(&mut self, camera: &[u8], outlet: &mut impl Outlet) -> bool {
        if !self.streaming {
            return false;
        }
        let taken = self.pipeline.take_frame(camera).is_ok();
        if !taken {
            outlet.count(Event::FrameRejected);
        }
        taken
    }

    /// The second half of [`Self::fuse`]: fuses the frame [`Self::take`] took, at
    /// commanded belt position `position_px`, and hands the tiles it completes to
    /// `outlet`. `false` if the host is gone.
    pub fn fuse_taken(&mut self, position_px: u64, outlet: &mut impl Outlet) -> bool {
        let mut hand = Hand::new(outlet);
        let fused = self.pipeline.fuse_taken(position_px, |t| hand.tile(t));
        hand.outlet.count(match fused {
            Ok(_) => Event::FrameFused,
            Err(_) => Event::FrameRejected,
        });
        hand.alive
    }

    /// Flushes the tiles in fusion to `outlet` and stops streaming (the device's own stop,
    /// e.g. at the end of its frames; the caller sends the final status). `false` if the
    /// host is gone.
    pub fn stop(&mut self, outlet: &mut impl Outlet) -> bool {
        self.streaming = false;
        let mut hand = Hand::new(outlet);
        self.pipeline.finish(|t| hand.tile(t));
        hand.alive
    }
}

/// Tiles to an outlet, counted, remembering whether the host is still there.
struct Hand<'o, O> {
    outlet: &'o mut O,
    alive: bool,
}

impl<'o, O: Outlet> Hand<'o, O> {
    fn new(outlet: &'o mut O) -> Self {
        Self {
            outlet,
            alive: true,
        }
    }

    fn tile(&mut self, tile: Tile<'_>) {
        self.outlet.count(Event::TileEmitted);
        match self.outlet.tile(tile) {
            Handed::Queued => {}
            Handed::Dropped => self.outlet.count(Event::TileDropped),
            Handed::LinkGone => self.alive = false,
        }
    }
}

/// Raw frame `frame` of a capture, as the chunks the link sends, in order.
pub fn raw_chunks(frame: u8, bytes: &[u8]) -> impl Iterator<Item = RawChunk<'_>> {
    // A camera frame is far below 4 GB: the casts cannot truncate.
    let total = bytes.len() as u32;
    bytes
        .chunks(MAX_CHUNK)
        .enumerate()
        .map(move |(k, data)| RawChunk {
            frame,
            offset: (k * MAX_CHUNK) as u32,
            total,
            data,
        })
}
