//! The `f32` path: the same fusion as the integer path, for full-resolution work on the host.
//!
//! The transforms are the orthonormal Haar and db2 filter banks with periodic extension,
//! and reproduce PyWavelets' `dwt2(x, w, mode='periodization')` and `idwt2` (checked against
//! committed vectors in `shared/tests/vectors/`). As in PyWavelets, a line of odd length is
//! first extended by repeating its last sample.
//!
//! Multi-level fusion needs an even size at every level, so [`fuse_pair`] works on a
//! region whose sides are multiples of `2^levels`: a [`Padded`] frame holds the image with
//! reflected margins, and the caller reads the fused image back from inside it.

mod dwt;
mod fuse;

pub use dwt::{dwt2, idwt2, level_scratch_len, subband_dims};
pub use fuse::{MAX_SAMPLE_F32, Padded, fuse_pair, fuse_scratch_len};
