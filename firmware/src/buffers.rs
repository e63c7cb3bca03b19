//! The firmware's large buffers: const-initialized statics, so taking them builds nothing
//! on the stack (built in place, a frame buffer alone would be 150 KB of stack). Each is
//! taken once, by whatever wires the tasks together (the board's `main`, or the QEMU run).

use crate::pipeline::FRAME_WORDS;
use rollfuse_core::device::ModuleBuffers;
use rollfuse_core::protocol::MAX_MESSAGE;
use static_cell::ConstStaticCell;

/// The camera's frame buffer. On the board all RAM is the AXI SRAM, which the DCMI's DMA
/// reaches.
pub static FRAME: ConstStaticCell<[u32; FRAME_WORDS]> = ConstStaticCell::new([0; FRAME_WORDS]);

/// The pipeline's buffers.
pub static PIPELINE: ConstStaticCell<ModuleBuffers> = ConstStaticCell::new(ModuleBuffers::new());

/// The link's encoding buffer (a message is as large as a tile).
pub static TX: ConstStaticCell<[u8; MAX_MESSAGE]> = ConstStaticCell::new([0; MAX_MESSAGE]);
