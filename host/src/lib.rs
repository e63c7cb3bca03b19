//! The rollfuse host library: the parts of the `rollfuse` tool that other programs and the
//! end-to-end tests call directly.
//!
//! The numeric core (wavelets, saliency, fusion) is the `no_std` crate [`rollfuse_core`];
//! this crate adds owned images and everything that needs `std`.

pub mod image;
