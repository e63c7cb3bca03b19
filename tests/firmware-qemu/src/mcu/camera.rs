//! A sensor that free-runs as the firmware's register writes program the OV7725
//! (`rollfuse_fw::sensor::timing` of its `SETUP` at its XCLK: 29.97 frames/s, 7.5 ms of
//! vertical blanking): each frame is its lines of pixels then the blanking, whose start
//! raises the frame-sync edge the board's DCMI interrupt gives `frame_clock`. A capture
//! draws a whole frame as the belt stands when that frame begins — the frame after the
//! next VSYNC, as the DCMI in snapshot mode starts only on VSYNC: the sensor's VSYNC comes
//! [`VSYNC_LINES`] line times into the blanking, so a capture armed later than that misses
//! the next frame and takes the one after.

use core::sync::atomic::{AtomicU32, Ordering::Relaxed};
use embassy_time::{Instant, Timer};
use rollfuse_fw::pipeline::{Camera, FRAME_WORDS};
use rollfuse_fw::sensor::{SETUP, XCLK_HZ, timing};
use rollfuse_fw::{frame_clock, roller};

/// Line times from the last line of a frame to the VSYNC that starts the next capture
/// (the issue of the board review: about 4).
pub const VSYNC_LINES: f64 = 4.0;

/// A frame period, the part of it with pixels, and when in it VSYNC comes, board
/// microseconds.
fn frame_us() -> (u64, u64, u64) {
    let t = timing(SETUP, XCLK_HZ);
    let period = 1e6 / t.frames_per_s;
    let active = period - 1e6 * t.blanking_s;
    let vsync = active + 1e6 * VSYNC_LINES * t.line_s;
    (period as u64, active as u64, vsync as u64)
}

const WIDTH: usize = 320;

/// The latest a capture was armed after the one before it ended (its frame's last line),
/// when armed in that frame's blanking — the pipeline's turnaround — board microseconds.
pub static LATEST_REARM_US: AtomicU32 = AtomicU32::new(0);
/// Captures re-armed in that blanking but after VSYNC: each lost a frame.
pub static REARMED_LATE: AtomicU32 = AtomicU32::new(0);
/// When the last capture ended, board microseconds.
static LAST_END_US: AtomicU32 = AtomicU32::new(0);

/// VSYNC's time after a frame's last line, board microseconds.
pub fn vsync_after_frame_us() -> u64 {
    let (_, active, vsync) = frame_us();
    vsync - active
}

/// The mock sensor.
pub struct Sensor;

impl Camera for Sensor {
    async fn capture(&mut self, frame: &mut [u32; FRAME_WORDS]) -> bool {
        let (period, active, vsync) = frame_us();
        let now = Instant::now().as_micros();
        let n = now / period;
        let into = now % period;
        // The frame after the next VSYNC: the next one if armed before this frame's
        // VSYNC, else the one after it.
        let mut next = if into == 0 { n } else { n + 1 };
        if into > vsync {
            next += 1;
        }
        // Re-armed in the blanking of the frame the last capture ended with.
        let since_end = now.saturating_sub(u64::from(LAST_END_US.load(Relaxed)));
        if into >= active && since_end <= into - active {
            LATEST_REARM_US.fetch_max(since_end as u32, Relaxed);
            if into > vsync {
                REARMED_LATE.fetch_add(1, Relaxed);
            }
        }
        // The frame-sync edges of the frames the interface waits through.
        let mut edge = n * period + active;
        if edge <= now {
            edge += period;
        }
        while edge < next * period {
            Timer::at(Instant::from_micros(edge)).await;
            frame_clock::frame_edge();
            edge += period;
        }
        let start = next * period;
        Timer::at(Instant::from_micros(start)).await;
        draw(frame, roller::belt_px(roller::steps()));
        Timer::at(Instant::from_micros(start + active)).await;
        frame_clock::frame_edge();
        LAST_END_US.store((start + active) as u32, Relaxed);
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
