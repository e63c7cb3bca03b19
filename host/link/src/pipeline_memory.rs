//! The host's owner of a device pipeline's memory: the four buffers the core's
//! `PipelineBuffers` borrows, allocated at the sizes a `Memory` gives (the firmware's
//! `MCU_CAPACITY`, or what one configuration needs).

use rollfuse_core::device::{Memory, PipelineBuffers};

/// A device pipeline's memory, on the heap.
pub struct PipelineMemory {
    frame: Vec<u8>,
    tiles: Vec<u8>,
    work: Vec<i32>,
    profiles: Vec<i32>,
}

impl PipelineMemory {
    /// Zeroed buffers of the sizes `memory` gives.
    pub fn new(memory: &Memory) -> Self {
        Self {
            frame: vec![0; memory.frame_bytes],
            tiles: vec![0; memory.tile_bytes],
            work: vec![0; memory.work_words],
            profiles: vec![0; memory.profile_words],
        }
    }

    /// The buffers, for a `Pipeline` or a `Session`.
    pub fn buffers(&mut self) -> PipelineBuffers<'_> {
        PipelineBuffers {
            frame: &mut self.frame,
            tiles: &mut self.tiles,
            work: &mut self.work,
            profiles: &mut self.profiles,
        }
    }
}
