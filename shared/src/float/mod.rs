//! The `f32` path, for full-resolution work on the host.
//!
//! - [`fuse_pair`]: the fusion of the integer path — the same lifting steps, boundary rule,
//!   coefficient placement and weights — in exact `f32` arithmetic, on any size. The two
//!   paths differ only by the integer path's rounding.
//! - [`dwt2`], [`idwt2`]: the orthonormal Haar and db2 filter banks with periodic extension,
//!   reproducing PyWavelets' `dwt2(x, w, mode='periodization')` and `idwt2` (checked against
//!   committed vectors in `shared/tests/vectors/`). As in PyWavelets, a line of odd length
//!   is first extended by repeating its last sample. In the interior the lifting's
//!   coefficients are these, up to scale and a one-pixel shift of placement (test
//!   `lifting_interior_matches_the_pywavelets_filter_bank`).

mod dwt;
mod fuse;

pub use dwt::{dwt2, idwt2, level_scratch_len, subband_dims};
pub use fuse::{Float, MAX_SAMPLE_F32, fuse_pair, fuse_pair_with, fuse_scratch_len};
