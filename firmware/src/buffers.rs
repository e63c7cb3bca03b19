//! The firmware's large buffers: const-initialized statics, so taking them builds nothing
//! on the stack (built in place, a frame buffer alone would be 150 KB of stack). Each is
//! taken once, by whatever wires the tasks together (the board's `main`, or the QEMU run).
//!
//! Where each lives on the STM32H743 (`memory.x`; docs/device.md, "Memory map"):
//! - the camera's two frames, one in D2 SRAM1–3 (`.sram_d2`) and one in the AXI SRAM
//!   (`.bss`; both frames do not fit in the D2 SRAM): the DCMI's DMA (DMA1) writes them
//!   and reaches both, but not the DTCM;
//! - the fusion's tiles, work area and row profiles in the DTCM (`.dtcm`): zero wait
//!   states, no cache needed, and every fused tile goes over them many times;
//! - the downsampled window, the link's encoding buffer and the outbox in the AXI SRAM
//!   (`.bss`, the RAM cortex-m-rt initializes): each is written and read once per frame or
//!   message, and the USB core (no DMA here) reads nothing of them itself — the CPU copies
//!   messages into its FIFO.
//!
//! cortex-m-rt zeroes only `.bss` and copies only `.data`, both in the AXI SRAM. The DTCM
//! and D2 sections are `NOLOAD`: their statics are all-zero when built (arrays of zeros,
//! and `ConstStaticCell`'s flag, which is false as a zero byte), and [`zero_placed`] writes
//! those zeros at boot, before anything takes them.

use crate::pipeline::{FRAME_WORDS, Frames};
use rollfuse_core::device::{MCU_CAPACITY, ModuleFrame, ModuleWork, PipelineBuffers};
use rollfuse_core::protocol::MAX_MESSAGE;
use static_cell::ConstStaticCell;

/// One of the camera's frame buffers, where the DCMI's DMA writes (D2 SRAM).
#[cfg_attr(target_os = "none", unsafe(link_section = ".sram_d2"))]
pub static FRAME_D2: ConstStaticCell<[u32; FRAME_WORDS]> = ConstStaticCell::new([0; FRAME_WORDS]);

/// The camera's other frame buffer (AXI SRAM, which DMA1 reaches through the bus matrix).
pub static FRAME_AXI: ConstStaticCell<[u32; FRAME_WORDS]> = ConstStaticCell::new([0; FRAME_WORDS]);

/// The camera's two frame buffers, each taken once.
pub fn frames() -> Frames {
    Frames::new(FRAME_D2.take(), FRAME_AXI.take())
}

/// The downsampled observation window (AXI SRAM: 75 KiB at 1×, which the DTCM's other
/// tenants leave no room for; each pixel is written once and read a few times a frame).
pub static WINDOW: ConstStaticCell<ModuleFrame> =
    ConstStaticCell::new([0; MCU_CAPACITY.frame_bytes]);

/// The fusion's tiles, work area and row profiles: the pipeline's hot memory (DTCM).
#[cfg_attr(target_os = "none", unsafe(link_section = ".dtcm"))]
pub static FUSION: ConstStaticCell<ModuleWork> = ConstStaticCell::new(ModuleWork::new());

/// The link's encoding buffer (a message is as large as a tile; AXI SRAM).
pub static TX: ConstStaticCell<[u8; MAX_MESSAGE]> = ConstStaticCell::new([0; MAX_MESSAGE]);

/// The pipeline's buffers: the window and the fusion's memory, each taken once.
pub fn pipeline() -> PipelineBuffers<'static> {
    FUSION.take().buffers(WINDOW.take())
}

#[cfg(target_os = "none")]
unsafe extern "C" {
    /// Bounds of the `NOLOAD` sections outside the RAM cortex-m-rt initializes
    /// (`memory.x`).
    static mut __sdtcm: u32;
    static mut __edtcm: u32;
    static mut __ssram_d2: u32;
    static mut __esram_d2: u32;
}

/// Writes zeros over the DTCM and D2 SRAM sections: the values their statics were built
/// with, which cortex-m-rt does not write there.
///
/// # Safety
/// Call once at boot, before anything reads or takes a static of those sections
/// ([`FRAME_D2`], [`FUSION`]).
#[cfg(target_os = "none")]
pub unsafe fn zero_placed() {
    // SAFETY: the linker script bounds each section with these symbols, word-aligned; no
    // reference into them exists yet (the caller's promise).
    unsafe {
        for (start, end) in [
            (&raw mut __sdtcm, &raw mut __edtcm),
            (&raw mut __ssram_d2, &raw mut __esram_d2),
        ] {
            let words = (end as usize - start as usize) / 4;
            core::ptr::write_bytes(start, 0, words);
        }
    }
}
