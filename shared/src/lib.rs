//! `rollfuse-core`: the numeric core of rollfuse, shared by the firmware and the host.
//!
//! It implements the cyclic wavelet fusion of tactile images from a rolling, curved
//! elastomer sensor: each frame sees the object at a different contact depth, and fusing
//! the frames' wavelet subbands — low band averaged, high bands weighted by a Laplacian
//! saliency — keeps the deepest, sharpest contact of every frame.
//!
//! `#![no_std]`, no allocation, and no panics on any input: bad sizes and parameters come
//! back as [`Error`] values. Buffers are the caller's. No `unsafe` either, but for two
//! units: on x86-64 hosts a hot loop's AVX2 or AVX-512 copy, run where the CPU has that
//! unit (`simd`); on Arm cores with the DSP extension the one-instruction operations on
//! two 16-bit lanes (`lanes`). Every other target forbids `unsafe`.
//!
//! # Layers
//!
//! - [`geometry`]: validated sizes and strides ([`Dims`]), the in-place subband layout.
//! - [`lifting`]: reversible integer Haar and db2 lifting, 1-D and 2-D, with proven
//!   coefficient bounds per level ([`lifting::bounds`]).
//! - [`saliency`]: the integer Laplacian saliency map and the `exp(x/255) − 1` table.
//! - [`fusion`]: the pairwise fuse step, the ablations, and [`fusion::CyclicFuser`], on
//!   the integer path the MCU runs.
//! - [`float`] (also [`fusion::float`]): the same algorithm in `f32` for full-resolution
//!   work on the host.
//! - [`device`]: the device pipeline (downsampling, belt offsets, the streaming tile
//!   model) and the device's command handling.
//! - [`protocol`]: the messages of the USB link, their framing, CRC and limits.
//! - [`motion`]: the roller's trapezoidal step profile and frame triggers.
//! - `lanes` (crate-private; public with the `internals` feature): two 16-bit samples a
//!   word and the Cortex-M7's DSP instructions on them.
//! - `simd` (likewise): the run-time choice between baseline, AVX2 and AVX-512 copies of
//!   the hot loops.
#![no_std]
#![cfg_attr(not(any(target_arch = "x86_64", rollfuse_dsp)), forbid(unsafe_code))]
#![cfg_attr(any(target_arch = "x86_64", rollfuse_dsp), deny(unsafe_code))]
// The core must never panic: public entry points validate sizes and return `Error`s.
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)
)]

pub mod device;
pub mod error;
pub mod fusion;
pub mod geometry;
// The lane and vector-unit machinery is the core's own; `internals` shows it to the
// Cortex-M7 bench and the kernel benchmarks, which use items the core does not.
#[cfg(feature = "internals")]
pub mod lanes;
#[cfg(not(feature = "internals"))]
#[allow(dead_code)]
pub(crate) mod lanes;
pub mod lifting;
mod limits;
pub mod motion;
mod packed;
pub mod protocol;
pub mod saliency;
#[cfg(feature = "internals")]
pub mod simd;
#[cfg(not(feature = "internals"))]
#[allow(dead_code)]
pub(crate) mod simd;

pub use error::Error;
/// The float fusion paths, where the host has always found them.
pub use fusion::float;
pub use fusion::{Ablation, CyclicFuser, FuseConfig, LlWeighting};
pub use geometry::Dims;
pub use lifting::Wavelet;
pub use limits::{MAX_DIMENSION, MAX_LEVELS};
pub use saliency::SaliencyNorm;

/// A deterministic byte generator for tests: a linear congruential generator seeded with
/// `seed`, each call the next byte (bits 16–23 of the state).
#[cfg(test)]
pub(crate) fn test_bytes(mut seed: u32) -> impl FnMut() -> u8 {
    move || {
        seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        (seed >> 16) as u8
    }
}

/// `w × h` images of 0 and 255 that give the largest coefficients 8-bit samples can, for
/// tests: a checkerboard, column stripes, row stripes, a checkerboard of 2 × 1 cells, then
/// `noise` images of binary noise from [`test_bytes`]`(seed)`.
#[cfg(test)]
pub(crate) fn extreme_tiles(w: usize, h: usize, noise: usize, seed: u32) -> TestImages {
    let patterns: [fn(usize, usize) -> bool; 4] = [
        |x, y| (x + y) % 2 == 0,
        |x, _| x % 2 == 0,
        |_, y| y % 2 == 0,
        |x, y| (x / 2 + y) % 2 == 0,
    ];
    let mut bytes = test_bytes(seed);
    let mut images: TestImages = patterns
        .iter()
        .map(|p| {
            (0..w * h)
                .map(|i| [0, 255][usize::from(p(i % w, i / w))])
                .collect()
        })
        .collect();
    for _ in 0..noise {
        images.push(
            (0..w * h)
                .map(|_| [0, 255][usize::from(bytes() > 127)])
                .collect(),
        );
    }
    images
}

/// `img` (`w` bytes a row) in rows of `stride` bytes, the bytes between them `fill`.
#[cfg(test)]
pub(crate) fn padded_rows(img: &[u8], w: usize, stride: usize, fill: u8) -> std::vec::Vec<u8> {
    let mut padded = std::vec![fill; stride * img.len().div_ceil(w.max(1))];
    for (dst, src) in padded.chunks_mut(stride).zip(img.chunks(w)) {
        dst[..w].copy_from_slice(src);
    }
    padded
}

/// Images of bytes, for tests.
#[cfg(test)]
type TestImages = std::vec::Vec<std::vec::Vec<u8>>;

#[cfg(test)]
extern crate std;
