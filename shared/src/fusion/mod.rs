//! Saliency-weighted wavelet fusion (paper eqs. 1–7) and its cyclic use over a sequence.
//!
//! One fuse step of images `A` and `B`, `levels` deep:
//!
//! - for each level `k`: saliency of both level inputs (the images, then their LL bands),
//!   weights `W₁, W₂` per coefficient ([`crate::saliency`]), one transform level of both,
//!   and each high band (HL, LH, HH) of the result set to `W₁·H_A + W₂·H_B`;
//! - the deepest LL band set to `(1 − w)·LL_A + w·LL_B` with `w = ½` (the paper's mean,
//!   eq. 2) or `w = 1/n` for an order-independent mean over `n` frames ([`LlWeighting`]);
//! - the inverse transform of the result (eq. 7).
//!
//! The same driver runs the integer path ([`integer`]: [`fuse_pair`], what the MCU runs)
//! and the float path ([`float`]); the crate-private `Arith` trait is the seam between
//! them.

mod config;
mod cyclic;
pub(crate) mod driver;
pub mod float;
pub(crate) mod integer;
mod lanes;

pub use crate::lifting::GUARD_BITS;
pub use config::{Ablation, FuseConfig, LlWeight, LlWeighting};
pub use cyclic::{CyclicBuffers, CyclicFuser};
pub(crate) use driver::ImagePair;
pub use driver::{Join, Sequential};
pub use integer::{U8Pair, U8Work, fuse_pair, fuse_scratch_len, fuse_scratch_words, fuse_u8};
