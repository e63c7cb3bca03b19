//! The DCMI's frame-sync interrupt handler.

use embassy_stm32::interrupt::typelevel::{self, Handler};
use rollfuse_fw::frame_clock;

/// The DCMI's frame-sync interrupt, bound before the HAL's handler: at each VSYNC edge
/// into blanking (a frame's end) the roller's step count is latched for
/// `frame_clock`, before the HAL wakes the capture that the same edge completes.
pub struct FrameSync;

impl Handler<typelevel::DCMI> for FrameSync {
    unsafe fn on_interrupt() {
        let dcmi = embassy_stm32::pac::DCMI;
        if dcmi.ris().read().vsync_ris() {
            dcmi.icr().write(|r| r.set_vsync_isc(true));
            frame_clock::frame_edge();
        }
    }
}
