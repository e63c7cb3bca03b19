//! The edge module as built: its firmware version, its camera and the pipeline memory its
//! firmware reserves. The firmware is built from these values; the host's virtual device
//! reports the same version and, by default, refuses what does not fit the same memory.

use super::pipeline::{Memory, PipelineBuffers, Sensor};
use super::refine::profile_len;
use crate::protocol::PixelFormat;

/// The firmware version `Info` reports, on the module and on the virtual device.
pub const FIRMWARE_VERSION: [u8; 3] = [0, 1, 0];

/// The module's camera: an OV7725-class sensor at QVGA, YUYV.
pub const CAMERA: Sensor = Sensor {
    width: 320,
    height: 240,
    format: PixelFormat::Yuyv,
};

/// The pipeline buffers the firmware reserves ([`ModuleFrame`] and [`ModuleWork`]): the
/// camera's whole frame at full resolution (so every downsampling factor, 1× included),
/// 48 KiB of tiles, 16 Ki words of work area, the row profiles of a full-resolution frame.
/// Tiles, work and profiles are sized to fit the H743's 128 KiB DTCM together (the
/// firmware's `memory.x`). The controller refuses configurations that need more
/// (`Controller::with_capacity`).
pub const MCU_CAPACITY: Memory = Memory {
    frame_bytes: CAMERA.width * CAMERA.height,
    tile_bytes: 48 * 1024,
    work_words: 16 * 1024,
    profile_words: 2 * profile_len(CAMERA.height),
};

/// The downsampled observation window at [`MCU_CAPACITY`]: written once per frame and
/// read by the kernels that follow, so the firmware may place it apart from the fusion's
/// work ([`ModuleWork`]).
pub type ModuleFrame = [u8; MCU_CAPACITY.frame_bytes];

/// The fusion's memory at [`MCU_CAPACITY`] — tiles, work area and row profiles — as
/// fixed arrays: const-initialized, so a `static` of it is placed by the linker and costs
/// no stack. Every fused tile reads and writes it many times over.
pub struct ModuleWork {
    tiles: [u8; MCU_CAPACITY.tile_bytes],
    work: [i32; MCU_CAPACITY.work_words],
    profiles: [i32; MCU_CAPACITY.profile_words],
}

impl Default for ModuleWork {
    fn default() -> Self {
        Self::new()
    }
}

impl ModuleWork {
    /// All zero.
    pub const fn new() -> Self {
        Self {
            tiles: [0; MCU_CAPACITY.tile_bytes],
            work: [0; MCU_CAPACITY.work_words],
            profiles: [0; MCU_CAPACITY.profile_words],
        }
    }

    /// The pipeline's buffers: `frame` for the window, the rest from here.
    pub fn buffers<'a>(&'a mut self, frame: &'a mut ModuleFrame) -> PipelineBuffers<'a> {
        PipelineBuffers {
            frame,
            tiles: &mut self.tiles,
            work: &mut self.work,
            profiles: &mut self.profiles,
        }
    }
}

/// The pipeline's buffers at [`MCU_CAPACITY`] in one value, for the host's virtual device
/// and tests (the firmware keeps [`ModuleFrame`] and [`ModuleWork`] in different RAMs).
pub struct ModuleBuffers {
    frame: ModuleFrame,
    work: ModuleWork,
}

impl Default for ModuleBuffers {
    fn default() -> Self {
        Self::new()
    }
}

impl ModuleBuffers {
    /// All zero.
    pub const fn new() -> Self {
        Self {
            frame: [0; MCU_CAPACITY.frame_bytes],
            work: ModuleWork::new(),
        }
    }

    /// The buffers, for a [`super::Pipeline`] or a [`super::Session`].
    pub fn buffers(&mut self) -> PipelineBuffers<'_> {
        self.work.buffers(&mut self.frame)
    }
}
