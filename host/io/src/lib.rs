//! What every part of rollfuse reads and writes, and how long work tells its progress.
//!
//! - [`files`]: outputs written whole or not at all, and the rules on outputs and inputs.
//! - [`image`]: images as `f32` planes, PNG in and out, under a pixel limit.
//! - [`invalid`]: refusing input that cannot be used, with each crate's own error.
//! - [`npy`]: NumPy array files.
//! - [`font`]: the 5×7 font text is drawn in (the `letters` scene, picture labels).
//! - [`progress`]: how long work reports its progress ([`progress::Progress`]).

pub mod files;
pub mod font;
pub mod image;
pub mod invalid;
pub mod npy;
pub mod progress;
