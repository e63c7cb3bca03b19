//! The virtual device: the core's device pipeline and command handling (the code the
//! firmware runs) on simulated camera frames, in a thread, speaking the protocol's bytes.
//!
//! Gray scenes give an 8-bit gray camera, RGB scenes an RGB565 one (so the luma path is
//! exercised). Frames are rendered on demand, one per trigger, at the scene's commanded
//! belt positions. The virtual device runs in virtual time: when the host is slow to read,
//! it waits instead of dropping tiles, so its streams are reproducible; its send queue
//! holds [`QUEUE`] messages.
//!
//! Paced ([`SimDevice::start_paced`], `rollfuse stream --frame-rate`), it captures at most
//! so many frames a second in real time, as the camera would, for live views and demos;
//! the frames and tiles are the same, only later.
//!
//! Its stream is the core's `device::Session`, the one the firmware runs, on the
//! firmware's memory by default ([`DeviceMemory`]): it refuses what the module refuses.

use super::{Error, Received, Transport};
use crate::pipeline_memory::PipelineMemory;
use rollfuse_core::device::{
    Capture, Controller, Event, FIRMWARE_VERSION, Handed, MCU_CAPACITY, Memory, Next, Order,
    Outlet, Sensor, Session, raw_chunks,
};
use rollfuse_core::protocol::{DeviceConfig, DeviceMessage, MAX_MESSAGE, PixelFormat, Tile};
use rollfuse_io::image::Planes;
use rollfuse_sim::{Scene, Simulator};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TryRecvError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Messages the virtual device may have in flight to the host.
pub const QUEUE: usize = 64;

/// The pipeline memory a virtual device has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DeviceMemory {
    /// The firmware's ([`MCU_CAPACITY`]): it refuses, as the module does, configurations
    /// that do not fit.
    #[default]
    Firmware,
    /// As much as each configuration needs: for host-only studies of configurations the
    /// module cannot run.
    Unbounded,
}

/// A virtual device running in a thread.
pub struct SimDevice {
    default_config: DeviceConfig,
    to_device: Option<SyncSender<Vec<u8>>>,
    from_device: Receiver<Vec<u8>>,
    thread: Option<JoinHandle<()>>,
}

/// The camera the virtual device has for `scene`, and its default configuration (the
/// product defaults with the scene's frame spacing).
pub fn sensor_for(scene: &Scene, sim: &Simulator) -> (Sensor, DeviceConfig) {
    let format = if scene.has(rollfuse_sim::Effect::Rgb) {
        PixelFormat::Rgb565
    } else {
        PixelFormat::Gray8
    };
    let sensor = Sensor {
        width: scene.sensor.width_px,
        height: scene.sensor.height_px,
        format,
    };
    let spacing = sim.strip_row_of_top(scene.sensor.frame_spacing_mm) - sim.strip_row_of_top(0.0);
    let config = DeviceConfig {
        frame_spacing_px: spacing.round().clamp(1.0, f64::from(u16::MAX)) as u16,
        ..DeviceConfig::default()
    };
    (sensor, config)
}

impl SimDevice {
    /// Starts a virtual device on `scene` with the firmware's memory. Fails if the
    /// product's default configuration does not fit the scene's camera (the host may
    /// configure another once connected).
    pub fn start(scene: &Scene) -> Result<Self, Error> {
        Self::start_with(scene, DeviceMemory::Firmware)
    }

    /// [`Self::start`] with the given pipeline memory.
    pub fn start_with(scene: &Scene, memory: DeviceMemory) -> Result<Self, Error> {
        Self::start_paced(scene, memory, None)
    }

    /// [`Self::start_with`], capturing a frame at most every `frame_period` of real time
    /// (none: in virtual time, as fast as the host reads).
    pub fn start_paced(
        scene: &Scene,
        memory: DeviceMemory,
        frame_period: Option<Duration>,
    ) -> Result<Self, Error> {
        let sim = Simulator::new(scene).map_err(Error::Scene)?;
        let (sensor, config) = sensor_for(scene, &sim);
        let refused = |reason| Error::VirtualConfig {
            camera: [sensor.width, sensor.height],
            reason: format!("{reason:?}"),
        };
        let mut controller = Controller::new(sensor, FIRMWARE_VERSION, config).map_err(refused)?;
        let capacity = match memory {
            DeviceMemory::Firmware => Some(MCU_CAPACITY),
            DeviceMemory::Unbounded => None,
        };
        if let Some(capacity) = capacity {
            controller = controller.with_capacity(capacity).map_err(refused)?;
        }
        // The simulated camera is always there.
        controller.counters_mut().camera_ready = true;
        let (to_device, commands) = mpsc::sync_channel::<Vec<u8>>(QUEUE);
        let (out, from_device) = mpsc::sync_channel::<Vec<u8>>(QUEUE);
        let thread = std::thread::Builder::new()
            .name("virtual-device".into())
            .spawn(move || {
                let mut dev = Device {
                    sim,
                    link: Wire { controller, out },
                    commands,
                    capacity,
                    next_frame: 0,
                    origin_px: None,
                    pace: frame_period.map(|period| Pace {
                        period,
                        due: Instant::now(),
                    }),
                };
                dev.run();
            })
            .map_err(Error::VirtualThread)?;
        Ok(Self {
            default_config: config,
            to_device: Some(to_device),
            from_device,
            thread: Some(thread),
        })
    }

    /// The configuration the device starts with: the product defaults with the scene's
    /// frame spacing.
    pub fn default_config(&self) -> DeviceConfig {
        self.default_config
    }
}

impl Drop for SimDevice {
    fn drop(&mut self) {
        // Closing the command channel ends the device loop.
        self.to_device = None;
        while self.from_device.try_recv().is_ok() {}
        if let Some(t) = self.thread.take() {
            // Unblock a device waiting to send.
            drop(std::mem::replace(
                &mut self.from_device,
                mpsc::sync_channel(1).1,
            ));
            let _ = t.join();
        }
    }
}

impl Transport for SimDevice {
    fn send(&mut self, message: &[u8]) -> Result<(), Error> {
        self.to_device
            .as_ref()
            .and_then(|tx| tx.send(message.to_vec()).ok())
            .ok_or(Error::VirtualStopped)
    }

    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> Result<Received, Error> {
        match self.from_device.recv_timeout(timeout) {
            Ok(msg) => {
                let n = msg.len().min(buf.len());
                buf[..n].copy_from_slice(&msg[..n]);
                Ok(Received::Message(n))
            }
            Err(RecvTimeoutError::Timeout) => Ok(Received::Timeout),
            Err(RecvTimeoutError::Disconnected) => Ok(Received::Closed),
        }
    }
}

/// The device's side of the channel: messages encoded with the controller's sequence
/// numbers, counts into its status. In virtual time a tile is never dropped: the device
/// waits for the host to read.
struct Wire {
    controller: Controller,
    out: SyncSender<Vec<u8>>,
}

impl Wire {
    /// Sends a message; `false` if the host is gone.
    fn send(&mut self, msg: &DeviceMessage) -> bool {
        let mut buf = vec![0u8; MAX_MESSAGE];
        match self.controller.encode(msg, &mut buf) {
            Ok(n) => {
                buf.truncate(n);
                self.out.send(buf).is_ok()
            }
            // Only an oversized message fails to encode; it is not sent.
            Err(_) => true,
        }
    }

    /// Sends the status, as a stream's last message.
    fn send_status(&mut self) -> bool {
        let status = DeviceMessage::Status(self.controller.counters());
        self.send(&status)
    }
}

impl Outlet for Wire {
    fn tile(&mut self, tile: Tile<'_>) -> Handed {
        if self.send(&DeviceMessage::Tile(tile)) {
            Handed::Queued
        } else {
            Handed::LinkGone
        }
    }

    fn count(&mut self, event: Event) {
        self.controller.counters_mut().count(event);
    }
}

/// The device thread's state.
struct Device {
    sim: Simulator,
    link: Wire,
    commands: Receiver<Vec<u8>>,
    /// The pipeline memory, if bounded.
    capacity: Option<Memory>,
    next_frame: usize,
    /// Commanded position of the first streamed frame's top row, camera pixels.
    origin_px: Option<f64>,
    /// Real-time pacing of the frames, if any.
    pace: Option<Pace>,
}

/// A frame rate held in real time.
struct Pace {
    period: Duration,
    /// When the next frame may be captured.
    due: Instant,
}

/// Why the device loop on one session ended.
enum Ended {
    /// The configuration in force needs more memory than the session's (unbounded
    /// memory only: the controller refuses it otherwise).
    Grow,
    /// The host is gone.
    Exit,
}

impl Device {
    fn run(&mut self) {
        loop {
            let config = self.link.controller.pipeline_config();
            let mut memory = PipelineMemory::new(&self.capacity.unwrap_or(config.memory()));
            let Ok(mut session) = Session::new(config, memory.buffers()) else {
                return;
            };
            match self.serve(&mut session) {
                Ended::Grow => continue,
                Ended::Exit => return,
            }
        }
    }

    /// Serves commands and streams frames until the host goes or the memory must grow.
    fn serve(&mut self, session: &mut Session) -> Ended {
        loop {
            let command = if session.streaming() {
                match self.command_before_next_frame() {
                    Ok(c) => c,
                    Err(ended) => return ended,
                }
            } else {
                match self.commands.recv() {
                    Ok(c) => Some(c),
                    Err(_) => return Ended::Exit,
                }
            };
            let served = match command {
                Some(bytes) => self.command(session, &bytes),
                None => self.stream_one(session),
            };
            if let Err(ended) = served {
                return ended;
            }
        }
    }

    /// A command from the host, if one comes before the next frame is due: at once in
    /// virtual time, within the frame period when paced (commands are never held up).
    fn command_before_next_frame(&mut self) -> Result<Option<Vec<u8>>, Ended> {
        let Some(pace) = &self.pace else {
            return match self.commands.try_recv() {
                Ok(c) => Ok(Some(c)),
                Err(TryRecvError::Empty) => Ok(None),
                Err(TryRecvError::Disconnected) => Err(Ended::Exit),
            };
        };
        let wait = pace.due.saturating_duration_since(Instant::now());
        match self.commands.recv_timeout(wait) {
            Ok(c) => Ok(Some(c)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(Ended::Exit),
        }
    }

    /// Answers one command and carries out the session's part of it.
    fn command(&mut self, session: &mut Session, bytes: &[u8]) -> Result<(), Ended> {
        let (reply, effect) = self.link.controller.handle(bytes);
        alive(self.link.send(&reply))?;
        let Some(order) = Order::of(effect) else {
            return Ok(());
        };
        match session.order(order, &mut self.link) {
            Ok(Next::Nothing) => Ok(()),
            Ok(Next::SendStatus) => alive(self.link.send_status()),
            Ok(Next::CaptureRaw(n)) => alive(self.capture_raw(n)),
            Err(_) => Err(Ended::Grow),
        }
    }

    /// The camera bytes of frame `k` and its commanded position, camera pixels.
    fn camera_frame(&self, k: usize) -> (Vec<u8>, f64) {
        let frame = self.sim.frame(k);
        let position = self.sim.strip_row_of_top(frame.offset_mm);
        (camera_bytes(&frame.image), position)
    }

    /// Captures, fuses and sends the next frame; at the end of the scene, ends the stream.
    fn stream_one(&mut self, session: &mut Session) -> Result<(), Ended> {
        if self.next_frame >= self.sim.frames() {
            return self.end_of_scene(session);
        }
        let (bytes, position) = self.camera_frame(self.next_frame);
        self.next_frame += 1;
        if let Some(pace) = &mut self.pace {
            // Behind (a slow host): the next frame at once, not a burst to catch up.
            pace.due = (pace.due + pace.period).max(Instant::now());
        }
        let origin = *self.origin_px.get_or_insert(position);
        let position_px = (position - origin).round().max(0.0) as u64;
        // The simulated camera always delivers.
        Capture::Done.delivered(&mut self.link);
        alive(session.fuse(&bytes, position_px, &mut self.link))
    }

    /// The scene has no more frames: the device stops streaming on its own, says why,
    /// and sends the status.
    fn end_of_scene(&mut self, session: &mut Session) -> Result<(), Ended> {
        let note = format!("scene ended after {} frames", self.next_frame);
        let flushed = session.stop(&mut self.link);
        self.link.controller.counters_mut().streaming = false;
        let told = self.link.send(&DeviceMessage::Log(&note));
        alive(flushed && told && self.link.send_status())
    }

    /// Sends the next `n` frames raw, in chunks (they are not fused).
    fn capture_raw(&mut self, n: u8) -> bool {
        for frame in 0..n {
            if self.next_frame >= self.sim.frames() {
                break;
            }
            let (bytes, _) = self.camera_frame(self.next_frame);
            self.next_frame += 1;
            Capture::Done.delivered(&mut self.link);
            for chunk in raw_chunks(frame, &bytes) {
                if !self.link.send(&DeviceMessage::RawChunk(chunk)) {
                    return false;
                }
            }
        }
        true
    }
}

/// `Err(Exit)` if the host is gone.
fn alive(host_there: bool) -> Result<(), Ended> {
    if host_there { Ok(()) } else { Err(Ended::Exit) }
}

/// A rendered frame as the camera would deliver it: 8-bit gray, or RGB565 little-endian.
pub fn camera_bytes(image: &Planes) -> Vec<u8> {
    let bytes = image.to_u8();
    if !image.is_rgb() {
        return bytes;
    }
    bytes
        .chunks_exact(3)
        .flat_map(|p| {
            let v =
                (u16::from(p[0]) >> 3) << 11 | (u16::from(p[1]) >> 2) << 5 | u16::from(p[2]) >> 3;
            v.to_le_bytes()
        })
        .collect()
}
