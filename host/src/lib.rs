//! The rollfuse host library: what the `rollfuse` tool does, callable from other programs
//! and from the end-to-end tests.
//!
//! The numeric core — integer and `f32` wavelet lifting, saliency, the fuse step and the
//! cyclic fuser — is the `no_std` crate [`rollfuse_core`], re-exported here as [`core`].
//! This crate will add what needs `std`: image files, the simulator, the device link,
//! depth and evaluation (see the README's roadmap).

pub use rollfuse_core as core;
