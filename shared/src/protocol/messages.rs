//! The message bodies: commands (host → device) and device messages (device → host).

use super::limits::{Limits, MAX_CHUNK, MAX_LOG, MAX_TILE_BYTES};
use serde::{Deserialize, Serialize};

/// The wavelet, on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum WaveletId {
    /// Haar (integer S-transform).
    Haar,
    /// Daubechies-4 by integer lifting.
    Db2,
}

/// How the device normalizes saliency when it fuses a tile.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum NormMode {
    /// By the tile's own Laplacian maximum.
    PerTile,
    /// By the maximum over the rows of the (downsampled) frame its tiles come from (the
    /// tiles it observes), so every tile of a frame is judged on one scale.
    PerFrame,
}

/// The camera's pixel format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum PixelFormat {
    /// One byte per pixel.
    Gray8,
    /// Two bytes per pixel, RGB565 little-endian; luma is computed.
    Rgb565,
    /// YUV 4:2:2 as Y0 U Y1 V; luma is the Y bytes.
    Yuyv,
}

impl PixelFormat {
    /// Bytes per pixel.
    pub const fn bytes_per_pixel(self) -> usize {
        match self {
            Self::Gray8 => 1,
            Self::Rgb565 | Self::Yuyv => 2,
        }
    }
}

/// How the device fuses: everything the host may configure. Validated on the device
/// ([`crate::device::PipelineConfig::from_wire`]); out-of-range values get a
/// [`NakReason`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeviceConfig {
    /// Wavelet.
    pub wavelet: WaveletId,
    /// Decomposition levels, 1..=4 (the tile must be large enough).
    pub levels: u8,
    /// Box downsampling of camera frames: 1, 2 or 4.
    pub downsample: u8,
    /// Tile height along the belt, in downsampled rows.
    pub tile_rows: u16,
    /// Observations fused into each tile (frames around the roller's apex).
    pub frames_per_tile: u8,
    /// Belt travel between frame triggers, in camera pixels.
    pub frame_spacing_px: u16,
    /// Offset refinement search: ± this many downsampled rows around the commanded shift
    /// (0 = trust the motion).
    pub refine_rows: u8,
    /// Saliency normalization.
    pub norm: NormMode,
}

impl Default for DeviceConfig {
    /// db2, 1 level, the camera's full resolution (no downsampling), 16-row tiles, 4
    /// frames per tile, 16 camera pixels between frames, ±2 rows of refinement, per-frame
    /// normalization.
    fn default() -> Self {
        Self {
            wavelet: WaveletId::Db2,
            levels: 1,
            downsample: 1,
            tile_rows: 16,
            frames_per_tile: 4,
            frame_spacing_px: 16,
            refine_rows: 3,
            norm: NormMode::PerFrame,
        }
    }
}

/// LED duty cycles, 0..=1000 (per mille).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct LedDuty {
    /// Red LED.
    pub red: u16,
    /// Green LED.
    pub green: u16,
    /// Blue LED.
    pub blue: u16,
}

impl LedDuty {
    /// Full duty.
    pub const FULL: u16 = 1000;
    /// All three LEDs fully on (RGB photometric frames).
    pub const ALL_ON: Self = Self {
        red: Self::FULL,
        green: Self::FULL,
        blue: Self::FULL,
    };
}

/// Roller motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RollerCommand {
    /// Ramp up to this belt speed, µm/s.
    Start {
        /// Target belt speed, µm/s.
        speed_um_s: u32,
    },
    /// Change the target speed while running, µm/s.
    Speed {
        /// Target belt speed, µm/s.
        speed_um_s: u32,
    },
    /// Ramp down and stop.
    Stop,
}

/// Host → device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Command {
    /// Asks for [`DeviceMessage::Info`].
    Hello,
    /// Sets the fusion configuration (refused while streaming).
    Configure(DeviceConfig),
    /// Sets the LEDs.
    Leds(LedDuty),
    /// Moves the roller.
    Roller(RollerCommand),
    /// Starts streaming fused tiles.
    StreamStart,
    /// Stops streaming; tiles still in fusion are flushed first.
    StreamStop,
    /// Sends this many raw camera frames, in [`RawChunk`]s.
    CaptureRaw {
        /// Frames to send, 1..=8.
        frames: u8,
    },
    /// Asks for [`DeviceMessage::Status`].
    Status,
}

impl Limits for Command {
    fn check_limits(&self) -> Result<(), &'static str> {
        Ok(())
    }
}

/// Why the device refused a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum NakReason {
    /// The message did not decode (bad CRC, version, malformed).
    BadMessage,
    /// `levels` is 0, above 4, or too deep for the tile.
    Levels,
    /// `downsample` is not 1, 2 or 4.
    Downsample,
    /// `tile_rows` is 0, larger than the downsampled frame, or the tile is larger than
    /// the largest tile message.
    TileRows,
    /// `frames_per_tile` is 0, above the device's maximum, the observation window does
    /// not fit in the frame, or it would hold more tiles than the device keeps in fusion.
    FramesPerTile,
    /// `frame_spacing_px` is 0 or larger than the frame.
    FrameSpacing,
    /// `refine_rows` is above the limit.
    RefineRows,
    /// An LED duty above 1000.
    LedDuty,
    /// A roller speed of 0 or above the motion system's maximum.
    Speed,
    /// `frames` of a raw capture is 0 or above 8.
    RawFrames,
    /// Not allowed now (e.g. configuring while streaming).
    Busy,
    /// The configuration needs more pipeline memory than the device has.
    Memory,
}

/// What the device is and how it is set up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeviceInfo {
    /// Firmware version: major, minor, patch.
    pub firmware: [u8; 3],
    /// Camera frame width, pixels.
    pub sensor_width: u16,
    /// Camera frame height, pixels.
    pub sensor_height: u16,
    /// Camera pixel format.
    pub pixel_format: PixelFormat,
    /// The configuration in force.
    pub config: DeviceConfig,
    /// The largest tile payload this device sends.
    pub max_tile_bytes: u32,
}

/// The device's counters since power-up: what it saw, made and lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct StatusCounters {
    /// Frames the camera delivered.
    pub frames_captured: u32,
    /// Frames the camera lost (DMA overrun, missed trigger).
    pub camera_overruns: u32,
    /// Captures that did not complete within a few frame periods (no pixel clock, a short
    /// frame, a camera that did not start); the camera interface is reset after each.
    pub camera_timeouts: u32,
    /// Whether the camera answered and took its configuration at start-up.
    pub camera_ready: bool,
    /// Frames the pipeline fused.
    pub frames_fused: u32,
    /// Frames the pipeline refused (belt moved backwards, wrong size).
    pub frames_rejected: u32,
    /// Tiles completed by the pipeline.
    pub tiles_emitted: u32,
    /// Tiles completed but not sent because the send queue was full.
    pub tiles_dropped: u32,
    /// Messages sent to the host.
    pub messages_sent: u32,
    /// Commands that failed to decode.
    pub bad_commands: u32,
    /// Whether tiles are streaming.
    pub streaming: bool,
    /// Whether the roller is turning.
    pub roller_running: bool,
    /// The most processor cycles one frame's fusion took; 0 where fusions are not timed
    /// (the virtual device).
    pub fusion_cycles_worst: u32,
    /// The mean processor cycles a frame's fusion took; 0 where fusions are not timed.
    pub fusion_cycles_mean: u32,
}

/// One fused tile: a band of the belt, across its whole width.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Tile<'a> {
    /// Belt index: the tile covers downsampled belt rows `index·height ..`.
    pub index: u32,
    /// Columns.
    pub width: u16,
    /// Rows.
    pub height: u16,
    /// Frames fused into it (fewer at the start and end of a run).
    pub observations: u8,
    /// 8-bit gray, row-major, `width × height` bytes.
    pub pixels: &'a [u8],
}

/// A piece of a raw camera frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RawChunk<'a> {
    /// Which captured frame (counting from 0 in this capture).
    pub frame: u8,
    /// Byte offset of this chunk in the frame.
    pub offset: u32,
    /// The frame's total size in bytes.
    pub total: u32,
    /// The bytes.
    pub data: &'a [u8],
}

/// Device → host.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum DeviceMessage<'a> {
    /// Reply to [`Command::Hello`].
    Info(DeviceInfo),
    /// A command was carried out.
    Ack {
        /// Sequence number of the command.
        command_seq: u32,
    },
    /// A command was refused.
    Nak {
        /// Sequence number of the command.
        command_seq: u32,
        /// Why.
        reason: NakReason,
    },
    /// Reply to [`Command::Status`], and sent when streaming stops.
    Status(StatusCounters),
    /// A fused tile.
    #[serde(borrow)]
    Tile(Tile<'a>),
    /// A piece of a raw frame.
    #[serde(borrow)]
    RawChunk(RawChunk<'a>),
    /// A line of the device's log.
    Log(&'a str),
}

impl Limits for DeviceMessage<'_> {
    fn check_limits(&self) -> Result<(), &'static str> {
        match self {
            Self::Tile(t) => {
                let n = usize::from(t.width) * usize::from(t.height);
                if t.pixels.len() > MAX_TILE_BYTES {
                    Err("tile size")
                } else if t.pixels.len() != n {
                    Err("tile pixel count")
                } else if n == 0 {
                    // No pipeline makes an empty tile; a strip cannot take one.
                    Err("empty tile")
                } else {
                    Ok(())
                }
            }
            Self::RawChunk(c) => {
                let end = u64::from(c.offset) + c.data.len() as u64;
                if c.data.len() > MAX_CHUNK {
                    Err("raw chunk size")
                } else if end > u64::from(c.total) {
                    Err("raw chunk offset")
                } else {
                    Ok(())
                }
            }
            Self::Log(line) if line.len() > MAX_LOG => Err("log line length"),
            _ => Ok(()),
        }
    }
}
