//! The rollfuse host library: what the `rollfuse` tool does, callable from other programs
//! and from the end-to-end tests.
//!
//! The numeric core — integer and `f32` wavelet lifting, saliency, the fuse step and the
//! cyclic fuser — is the `no_std` crate [`rollfuse_core`], re-exported here as [`core`].
//! This crate adds what needs `std`:
//!
//! - [`files`]: outputs written whole or not at all.
//! - [`image`]: images as `f32` planes, PNG in and out.
//! - [`frames`]: a sequence of frames on disk, and where its motion record places them.
//! - [`sim`]: the tactile simulator (scenes, effects on demand, ground truth).
//! - [`fullres`]: full-resolution fusion of aligned frames into one mosaic.
//! - [`depth`]: photometric stereo, Poisson integration, light calibration.
//! - [`detect`]: fabric defect detection and classification with a neural network.
//! - [`eval`]: the paper's metrics.
//! - [`link`]: the device link — USB, the virtual device, recorded streams.
//! - [`pipeline_memory`]: the memory a device pipeline runs on (virtual device, trade-off
//!   study).
//! - [`strip_file`]: a strip written as it grows, in indexed PNG segments.
//! - [`session`]: a streaming session's options checked and its link opened.
//! - [`stream`]: a streaming session — tiles received, checked and stitched into a strip.
//! - [`tradeoff`]: what each device configuration buys in accuracy and costs in time.
//! - [`demo`]: the whole system end to end, and its HTML report.
//! - [`names`]: the names of settings' values, as the command line and Python take them.
//! - [`npy`]: NumPy array files.
//! - [`progress`]: how long work reports its progress ([`progress::Progress`]).
//! - [`records`]: what the commands put in the inspection records ([`rollfuse_records`]).

pub use rollfuse_core as core;
pub use rollfuse_depth as depth;
pub use rollfuse_detect as detect;
pub use rollfuse_fullres as fullres;
pub use rollfuse_fullres::strip_file;
pub use rollfuse_io::{files, font, image, npy, progress};
pub use rollfuse_link as link;
pub use rollfuse_link::pipeline_memory;
pub use rollfuse_sim as sim;

pub mod demo;
pub mod eval;
pub mod frames;
pub mod names;
pub mod records;
pub mod serve;
pub mod session;
pub mod stream;
pub mod tradeoff;
