//! A sensor that free-runs at 30 frames/s, as the OV7725 does: each frame is 30 ms of
//! pixels then 3.3 ms of vertical blanking, whose start raises the frame-sync edge the
//! board's DCMI interrupt gives `frame_clock`. A capture waits for the next whole frame and
//! draws it as the belt stands when that frame begins.

use embassy_time::{Instant, Timer};
use rollfuse_fw::pipeline::{Camera, FRAME_WORDS};
use rollfuse_fw::{frame_clock, roller};

/// A frame period, board microseconds.
const PERIOD_US: u64 = 33_333;
/// The part of it with pixels.
const ACTIVE_US: u64 = 30_000;

const WIDTH: usize = 320;

/// The mock sensor.
pub struct Sensor;

impl Camera for Sensor {
    async fn capture(&mut self, frame: &mut [u32; FRAME_WORDS]) -> bool {
        let now = Instant::now().as_micros();
        let n = now / PERIOD_US;
        let into = now % PERIOD_US;
        // Armed in the middle of a frame: the interface waits for its end.
        if into > 0 && into < ACTIVE_US {
            Timer::at(Instant::from_micros(n * PERIOD_US + ACTIVE_US)).await;
            frame_clock::frame_edge();
        }
        let start = if into == 0 { n } else { n + 1 } * PERIOD_US;
        Timer::at(Instant::from_micros(start)).await;
        draw(frame, roller::belt_px(roller::steps()));
        Timer::at(Instant::from_micros(start + ACTIVE_US)).await;
        frame_clock::frame_edge();
        true
    }

    fn reset(&mut self) {}
}

/// Draws the belt from row `top` on: luma textured along and across, chroma neutral, in
/// YUYV byte order (a word holds Y0 U Y1 V, little-endian).
fn draw(frame: &mut [u32; FRAME_WORDS], top: u64) {
    for (r, row) in frame.chunks_exact_mut(WIDTH / 2).enumerate() {
        let belt_row = (top + r as u64) as u32;
        for (c, word) in row.iter_mut().enumerate() {
            let y = ((belt_row.wrapping_mul(5) ^ (c as u32 >> 2)) & 0xFF) as u8;
            *word = u32::from_le_bytes([y, 128, y, 128]);
        }
    }
}
