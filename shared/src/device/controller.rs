//! The device's command handling: decode, validate, reply, and say what the hardware must
//! do. The firmware and the host's virtual device both run this, so a command is refused
//! for the same reason on both.

use super::pipeline::{Memory, PipelineConfig, Sensor};
use crate::motion::MotionConfig;
use crate::protocol::{
    self, Command, DecodeError, DeviceConfig, DeviceInfo, DeviceMessage, EncodeError, LedDuty,
    MAX_TILE_BYTES, NakReason, RollerCommand, StatusCounters,
};

/// The fastest belt speed the motion system is asked for, µm/s.
pub const MAX_SPEED_UM_S: u32 = 500_000;

/// The most raw frames one capture command may ask for.
pub const MAX_RAW_FRAMES: u8 = 8;

/// What the hardware must do after a command was accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Effect {
    /// Nothing beyond the reply.
    None,
    /// Rebuild the pipeline with this configuration.
    Configure(PipelineConfig),
    /// Set the LED duties.
    Leds(LedDuty),
    /// Move the roller.
    Roller(RollerCommand),
    /// Start streaming tiles.
    StreamStart,
    /// Flush the pipeline, stop streaming, send the status.
    StreamStop,
    /// Send this many raw frames.
    CaptureRaw(u8),
}

/// The device's side of the link: its configuration, counters and sequence numbers.
pub struct Controller {
    sensor: Sensor,
    firmware: [u8; 3],
    config: DeviceConfig,
    pipeline: PipelineConfig,
    counters: StatusCounters,
    seq: u32,
    /// The device's pipeline buffers, when it has fixed ones.
    capacity: Option<Memory>,
    /// The roller's mechanics, when the device has a roller.
    motion: Option<MotionConfig>,
}

impl Controller {
    /// A controller for `sensor` starting with `config` (refused if invalid for it).
    pub fn new(sensor: Sensor, firmware: [u8; 3], config: DeviceConfig) -> Result<Self, NakReason> {
        Ok(Self {
            sensor,
            firmware,
            pipeline: PipelineConfig::from_wire(&config, sensor)?,
            config,
            counters: StatusCounters::default(),
            seq: 0,
            capacity: None,
            motion: None,
        })
    }

    /// Refuses, from now on, configurations whose pipeline would not fit `capacity` (the
    /// firmware's static buffers); fails if the current one does not.
    pub fn with_capacity(mut self, capacity: Memory) -> Result<Self, NakReason> {
        if !self.pipeline.memory().fits(&capacity) {
            return Err(NakReason::Memory);
        }
        self.capacity = Some(capacity);
        Ok(self)
    }

    /// Refuses, from now on, roller speeds that `motion`'s ramp cannot run (below one step
    /// a second; [`MotionConfig::check_speed`]) as [`NakReason::Speed`], so that an `Ack`
    /// means the roller will turn.
    pub fn with_motion(mut self, motion: MotionConfig) -> Self {
        self.motion = Some(motion);
        self
    }

    /// The pipeline configuration in force.
    pub fn pipeline_config(&self) -> PipelineConfig {
        self.pipeline
    }

    /// The counters, for the tasks that count (frames, tiles, drops).
    pub fn counters_mut(&mut self) -> &mut StatusCounters {
        &mut self.counters
    }

    /// The counters.
    pub fn counters(&self) -> StatusCounters {
        self.counters
    }

    /// Handles one received command message: returns the reply and what to do.
    pub fn handle(&mut self, bytes: &[u8]) -> (DeviceMessage<'static>, Effect) {
        self.handle_when(bytes, true)
    }

    /// [`Self::handle`] for a device that can carry out an effect only when `room` (its
    /// effect queue has a free slot): a command that needs one is refused as
    /// [`NakReason::Busy`] and changes nothing, so an `Ack` always means the effect is on
    /// its way. Stopping the roller needs no room: it has a path of its own.
    pub fn handle_when(&mut self, bytes: &[u8], room: bool) -> (DeviceMessage<'static>, Effect) {
        let (seq, command) = match protocol::decode::<Command>(bytes) {
            Ok((h, c)) => (h.seq, c),
            Err(e) => {
                self.counters.bad_commands = self.counters.bad_commands.wrapping_add(1);
                // The sequence number of an undecodable command is unknown.
                let _: DecodeError = e;
                return (self.nak(u32::MAX, NakReason::BadMessage), Effect::None);
            }
        };
        if !room && needs_room(&command) {
            return (self.nak(seq, NakReason::Busy), Effect::None);
        }
        match self.apply(command) {
            Ok((reply, effect)) => (
                reply.unwrap_or(DeviceMessage::Ack { command_seq: seq }),
                effect,
            ),
            Err(reason) => (self.nak(seq, reason), Effect::None),
        }
    }

    /// Marks streaming and the roller stopped (the host is gone and the device stopped
    /// both on its own); returns whether either was running.
    pub fn host_lost(&mut self) -> bool {
        let running = self.counters.streaming || self.counters.roller_running;
        self.counters.streaming = false;
        self.counters.roller_running = false;
        running
    }

    fn nak(&self, command_seq: u32, reason: NakReason) -> DeviceMessage<'static> {
        DeviceMessage::Nak {
            command_seq,
            reason,
        }
    }

    /// Validates and applies a command: `Some(reply)` replaces the plain ack.
    fn apply(
        &mut self,
        command: Command,
    ) -> Result<(Option<DeviceMessage<'static>>, Effect), NakReason> {
        let streaming = self.counters.streaming;
        Ok(match command {
            Command::Hello => (Some(DeviceMessage::Info(self.info())), Effect::None),
            Command::Status => (Some(DeviceMessage::Status(self.counters)), Effect::None),
            Command::Configure(_) if streaming => return Err(NakReason::Busy),
            Command::Configure(cfg) => {
                let pipeline = PipelineConfig::from_wire(&cfg, self.sensor)?;
                if let Some(capacity) = &self.capacity
                    && !pipeline.memory().fits(capacity)
                {
                    return Err(NakReason::Memory);
                }
                self.config = cfg;
                self.pipeline = pipeline;
                (None, Effect::Configure(pipeline))
            }
            Command::Leds(d) => {
                if [d.red, d.green, d.blue].iter().any(|&v| v > LedDuty::FULL) {
                    return Err(NakReason::LedDuty);
                }
                (None, Effect::Leds(d))
            }
            Command::Roller(r) => {
                match r {
                    RollerCommand::Start { speed_um_s } | RollerCommand::Speed { speed_um_s } => {
                        let runs = |m: &MotionConfig| m.check_speed(speed_um_s).is_ok();
                        if speed_um_s == 0
                            || speed_um_s > MAX_SPEED_UM_S
                            || !self.motion.as_ref().is_none_or(runs)
                        {
                            return Err(NakReason::Speed);
                        }
                        self.counters.roller_running = true;
                    }
                    RollerCommand::Stop => self.counters.roller_running = false,
                }
                (None, Effect::Roller(r))
            }
            Command::StreamStart if streaming => return Err(NakReason::Busy),
            Command::StreamStart => {
                self.counters.streaming = true;
                (None, Effect::StreamStart)
            }
            Command::StreamStop => {
                self.counters.streaming = false;
                (None, Effect::StreamStop)
            }
            Command::CaptureRaw { frames } => {
                if frames == 0 || frames > MAX_RAW_FRAMES {
                    return Err(NakReason::RawFrames);
                }
                (None, Effect::CaptureRaw(frames))
            }
        })
    }

    /// What [`Command::Hello`] answers.
    pub fn info(&self) -> DeviceInfo {
        DeviceInfo {
            firmware: self.firmware,
            sensor_width: self.sensor.width as u16,
            sensor_height: self.sensor.height as u16,
            pixel_format: self.sensor.format,
            config: self.config,
            max_tile_bytes: MAX_TILE_BYTES as u32,
        }
    }

    /// Encodes a message to the host with the next sequence number, counting it.
    pub fn encode(
        &mut self,
        msg: &DeviceMessage<'_>,
        out: &mut [u8],
    ) -> Result<usize, EncodeError> {
        let n = protocol::encode(self.seq, msg, out)?;
        self.seq = self.seq.wrapping_add(1);
        self.counters.messages_sent = self.counters.messages_sent.wrapping_add(1);
        Ok(n)
    }
}

/// Whether `command` is carried out through the device's effect queue.
fn needs_room(command: &Command) -> bool {
    !matches!(
        command,
        Command::Hello | Command::Status | Command::Roller(RollerCommand::Stop)
    )
}
