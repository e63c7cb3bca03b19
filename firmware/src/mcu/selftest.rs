//! A fusion self-test at boot: a wrong build of the core shows here, on the MCU.

use rollfuse_core::fusion::{LlWeight, U8Pair, U8Work, fuse_scratch_words, fuse_u8};
use rollfuse_core::{Dims, FuseConfig};

/// Side of the self-test tiles.
const N: usize = 16;

/// Fuses a tile with an edge into a flat one on the integer path; returns the step kept
/// across the middle of the first row (160 in the edge tile, 0 in the flat one).
pub fn run() -> Result<u32, rollfuse_core::Error> {
    let dims = Dims::new(N, N)?;
    let mut edge: [u8; N * N] = core::array::from_fn(|i| if i % N < N / 2 { 40 } else { 200 });
    let flat = [120u8; N * N];
    let (mut a, mut b) = ([0i32; N * N], [0i32; N * N]);
    let mut scratch = [0i32; fuse_scratch_words(N, N)];
    let work = U8Work {
        a: &mut a,
        b: &mut b,
        scratch: &mut scratch,
    };
    fuse_u8(
        U8Pair::same(&mut edge, &flat, dims),
        &FuseConfig::default(),
        LlWeight::HALF,
        work,
    )?;
    // The fused tile replaced `edge`.
    Ok(u32::from(edge[N / 2].abs_diff(edge[N / 2 - 1])))
}
