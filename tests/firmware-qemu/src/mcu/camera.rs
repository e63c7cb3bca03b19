//! A sensor that free-runs as the firmware's register writes program the OV7725
//! (`rollfuse_fw::sensor::timing` of its `SETUP` at its XCLK: 29.97 frames/s, 7.5 ms of
//! vertical blanking): each frame is its lines of pixels then the blanking, whose start
//! raises the frame-sync edge the board's DCMI interrupt gives `frame_clock`. A capture
//! waits for the next whole frame and draws it as the belt stands when that frame begins.

use embassy_time::{Instant, Timer};
use rollfuse_fw::pipeline::{Camera, FRAME_WORDS};
use rollfuse_fw::sensor::{SETUP, XCLK_HZ, timing};
use rollfuse_fw::{frame_clock, roller};

/// A frame period and the part of it with pixels, board microseconds.
fn frame_us() -> (u64, u64) {
    let t = timing(SETUP, XCLK_HZ);
    let period = 1e6 / t.frames_per_s;
    (period as u64, (period - 1e6 * t.blanking_s) as u64)
}

const WIDTH: usize = 320;

/// The mock sensor.
pub struct Sensor;

impl Camera for Sensor {
    async fn capture(&mut self, frame: &mut [u32; FRAME_WORDS]) -> bool {
        let (period, active) = frame_us();
        let now = Instant::now().as_micros();
        let n = now / period;
        let into = now % period;
        // Armed in the middle of a frame: the interface waits for its end.
        if into > 0 && into < active {
            Timer::at(Instant::from_micros(n * period + active)).await;
            frame_clock::frame_edge();
        }
        let start = if into == 0 { n } else { n + 1 } * period;
        Timer::at(Instant::from_micros(start)).await;
        draw(frame, roller::belt_px(roller::steps()));
        Timer::at(Instant::from_micros(start + active)).await;
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
