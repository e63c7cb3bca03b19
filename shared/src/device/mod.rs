//! The device pipeline: what the edge module runs on every camera frame, and its command
//! handling. The firmware calls it on the MCU; the host's virtual device calls the same
//! code on simulated frames.
//!
//! - [`downsample`]: camera frames (8-bit gray, RGB565, YUYV) to downsampled 8-bit luma.
//! - [`refine`]: the belt shift between frames, refined by a 1-D correlation.
//! - [`pipeline`]: the streaming tile model — tiles fused from the frames that see them
//!   near the roller's apex and emitted once complete, in fixed, caller-owned memory.
//! - [`session`]: one stream — the pipeline driven by the accepted commands, tiles handed
//!   to the link, everything counted for the status. The firmware and the virtual device
//!   both run their streams through it.
//! - [`controller`]: commands decoded, validated and answered.
//! - [`module`]: the module as built — firmware version, camera, the firmware's memory.
//! - [`leds`]: LED duties to PWM compare values.

pub mod controller;
pub mod downsample;
pub mod leds;
pub mod module;
pub mod pipeline;
pub mod refine;
pub mod session;

pub use controller::{Controller, Effect};
pub use module::{CAMERA, FIRMWARE_VERSION, MCU_CAPACITY, ModuleBuffers, ModuleFrame, ModuleWork};
pub use pipeline::{
    FrameError, FrameReport, Memory, Pipeline, PipelineBuffers, PipelineConfig, Precision,
    Schedule, Sensor,
};
pub use session::{Capture, Event, Handed, Next, Order, Outlet, Session, raw_chunks};
