//! The bench's camera frames: QVGA YUYV (the firmware's camera format) of a textured belt
//! that moves 16 camera pixels per frame, drawn by integer code so every run is the same.

use rollfuse_core::device::CAMERA;

/// Camera width, pixels.
pub const WIDTH: usize = CAMERA.width;
/// Camera height, pixels.
pub const HEIGHT: usize = CAMERA.height;
/// Belt travel per frame, camera pixels (the product's default).
pub const SPACING_PX: usize = 16;
/// Bytes of one YUYV frame.
pub const FRAME_BYTES: usize = CAMERA.frame_bytes();

/// Luma of belt point `(x, belt_row)`: a shading ramp, raised strokes (bars of dots, like
/// the dot and line matrices of the standard scenes) and a fine grain.
fn luma(x: usize, belt_row: usize) -> u8 {
    let ramp = 80 + x * 40 / WIDTH;
    let stroke = if (belt_row / 6).is_multiple_of(4) && !(x / 10).is_multiple_of(3) {
        70
    } else {
        0
    };
    let grain =
        ((x as u32).wrapping_mul(2_654_435_761) ^ (belt_row as u32).wrapping_mul(40_503)) >> 28;
    (ramp + stroke + grain as usize).min(255) as u8
}

/// Draws frame `k` into `out` (at least [`FRAME_BYTES`]).
pub fn draw(k: usize, out: &mut [u8]) {
    for (y, row) in out.chunks_exact_mut(WIDTH * 2).take(HEIGHT).enumerate() {
        let belt_row = y + k * SPACING_PX;
        for (x, px) in row.chunks_exact_mut(2).enumerate() {
            px[0] = luma(x, belt_row);
            // Chroma: neutral.
            px[1] = 128;
        }
    }
}
