//! The tactile simulator: renders what the sensor would see as the roller passes over an
//! object, computing only the effects a scene lists, and the ground truth beside it.
//!
//! - [`scene`]: the scene file (TOML) and its checks.
//! - [`built_in`]: the scenes compiled into the tool.
//! - [`object`]: the objects' height maps.
//! - [`textile`]: the detector's fabrics and their defects.
//! - [`render`]: the stages — contact, gel, shading, defocus, background, noise, jitter.
//! - [`output`]: frames, truth and manifest on disk.
//! - [`manifest`]: `manifest.json`, written and read by one type.
//!
//! Every fallible function returns [`Error`]: a scene or manifest that is not valid, a
//! file that could not be read, an output that could not be written.

pub mod built_in;
mod error;
pub mod manifest;
pub mod object;
pub mod output;
pub mod render;
pub mod scene;
pub mod textile;

pub use error::Error;
pub use manifest::Manifest;
pub use render::{Frame, Planes, Simulator, Strip};
pub use scene::{Effect, Scene};
