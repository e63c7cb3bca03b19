//! The edge module as built: its firmware version, its camera and the pipeline memory its
//! firmware reserves. The firmware is built from these values; the host's virtual device
//! reports the same version and, by default, refuses what does not fit the same memory.

use super::pipeline::{Memory, PipelineBuffers, Sensor};
use crate::protocol::PixelFormat;

/// The firmware version `Info` reports, on the module and on the virtual device.
pub const FIRMWARE_VERSION: [u8; 3] = [0, 1, 0];

/// The module's camera: an OV7725-class sensor at QVGA, YUYV.
pub const CAMERA: Sensor = Sensor {
    width: 320,
    height: 240,
    format: PixelFormat::Yuyv,
};

/// The pipeline buffers the firmware reserves ([`ModuleBuffers`]): the camera's frame
/// downsampled at least 2×, 48 KiB of tiles, 16 Ki words of work area, the row profiles
/// of a 2×-downsampled frame. The controller refuses configurations that need more
/// (`Controller::with_capacity`).
pub const MCU_CAPACITY: Memory = Memory {
    frame_bytes: (CAMERA.width / 2) * (CAMERA.height / 2),
    tile_bytes: 48 * 1024,
    work_words: 16 * 1024,
    profile_words: 2 * (CAMERA.height / 2 - 1),
};

/// The pipeline's buffers at [`MCU_CAPACITY`], as fixed arrays: const-initialized, so a
/// `static` of them is placed by the linker and costs no stack.
pub struct ModuleBuffers {
    frame: [u8; MCU_CAPACITY.frame_bytes],
    tiles: [u8; MCU_CAPACITY.tile_bytes],
    work: [i32; MCU_CAPACITY.work_words],
    profiles: [i32; MCU_CAPACITY.profile_words],
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
            tiles: [0; MCU_CAPACITY.tile_bytes],
            work: [0; MCU_CAPACITY.work_words],
            profiles: [0; MCU_CAPACITY.profile_words],
        }
    }

    /// The buffers, for a [`super::Pipeline`] or a [`super::Session`].
    pub fn buffers(&mut self) -> PipelineBuffers<'_> {
        PipelineBuffers {
            frame: &mut self.frame,
            tiles: &mut self.tiles,
            work: &mut self.work,
            profiles: &mut self.profiles,
        }
    }
}
