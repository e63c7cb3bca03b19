//! The virtual device: the core's device pipeline and command handling (the code the
//! firmware runs) on simulated camera frames, in a thread, speaking the protocol's bytes.
//!
//! Gray scenes give an 8-bit gray camera, RGB scenes an RGB565 one (so the luma path is
//! exercised). Frames are rendered on demand, one per trigger, at the scene's commanded
//! belt positions. The virtual device runs in virtual time: when the host is slow to read,
//! it waits instead of dropping tiles, so its streams are reproducible; its send queue
//! holds [`QUEUE`] messages.

use super::{Received, Transport};
use crate::image::Planes;
use crate::sim::{Scene, Simulator};
use anyhow::Context;
use rollfuse_core::device::{
    Controller, Effect, Pipeline, PipelineBuffers, PipelineConfig, Sensor,
};
use rollfuse_core::protocol::{
    DeviceConfig, DeviceMessage, MAX_CHUNK, MAX_MESSAGE, PixelFormat, RawChunk,
};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TryRecvError};
use std::thread::JoinHandle;
use std::time::Duration;

/// Messages the virtual device may have in flight to the host.
pub const QUEUE: usize = 64;

/// The firmware version the virtual device reports.
const FIRMWARE: [u8; 3] = [0, 1, 0];

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
    let format = if scene.has(crate::sim::Effect::Rgb) {
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
    /// Starts a virtual device on `scene`. Fails if the product's default configuration
    /// does not fit the scene's camera (the host may configure another once connected).
    pub fn start(scene: &Scene) -> anyhow::Result<Self> {
        let sim = Simulator::new(scene)?;
        let (sensor, config) = sensor_for(scene, &sim);
        let mut controller = Controller::new(sensor, FIRMWARE, config).map_err(|reason| {
            anyhow::anyhow!(
                "the virtual device's default configuration does not fit a {}×{} camera: {reason:?}",
                sensor.width,
                sensor.height
            )
        })?;
        // The simulated camera is always there.
        controller.counters_mut().camera_ready = true;
        let (to_device, commands) = mpsc::sync_channel::<Vec<u8>>(QUEUE);
        let (out, from_device) = mpsc::sync_channel::<Vec<u8>>(QUEUE);
        let thread = std::thread::Builder::new()
            .name("virtual-device".into())
            .spawn(move || {
                let mut dev = Device {
                    sim,
                    controller,
                    commands,
                    out,
                    next_frame: 0,
                    origin_px: None,
                };
                dev.run();
            })
            .context("cannot start the virtual device's thread")?;
        Ok(Self {
            default_config: config,
            to_device: Some(to_device),
            from_device,
            thread: Some(thread),
        })
    }
}

impl SimDevice {
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
    fn send(&mut self, message: &[u8]) -> anyhow::Result<()> {
        self.to_device
            .as_ref()
            .and_then(|tx| tx.send(message.to_vec()).ok())
            .context("the virtual device has stopped")
    }

    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> anyhow::Result<Received> {
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

/// The device thread's state.
struct Device {
    sim: Simulator,
    controller: Controller,
    commands: Receiver<Vec<u8>>,
    out: SyncSender<Vec<u8>>,
    next_frame: usize,
    /// Commanded position of the first streamed frame's top row, camera pixels.
    origin_px: Option<f64>,
}

/// Why the device loop on one configuration ended.
enum Next {
    Reconfigure,
    Exit,
}

/// The pipeline's memory, allocated per configuration as the formula says.
struct Storage {
    frame: Vec<u8>,
    tiles: Vec<u8>,
    work: Vec<i32>,
    profiles: Vec<i32>,
}

impl Storage {
    fn new(cfg: &PipelineConfig) -> Self {
        let m = cfg.memory();
        Self {
            frame: vec![0; m.frame_bytes],
            tiles: vec![0; m.tile_bytes],
            work: vec![0; m.work_words],
            profiles: vec![0; m.profile_words],
        }
    }
}

impl Device {
    fn run(&mut self) {
        loop {
            let cfg = self.controller.pipeline_config();
            let mut storage = Storage::new(&cfg);
            let bufs = PipelineBuffers {
                frame: &mut storage.frame,
                tiles: &mut storage.tiles,
                work: &mut storage.work,
                profiles: &mut storage.profiles,
            };
            let Ok(mut pipeline) = Pipeline::new(cfg, bufs) else {
                return;
            };
            match self.run_with(&mut pipeline) {
                Next::Reconfigure => continue,
                Next::Exit => return,
            }
        }
    }

    /// Sends a message; `false` if the host is gone.
    fn send(controller: &mut Controller, out: &SyncSender<Vec<u8>>, msg: &DeviceMessage) -> bool {
        let mut buf = vec![0u8; MAX_MESSAGE];
        match controller.encode(msg, &mut buf) {
            Ok(n) => {
                buf.truncate(n);
                out.send(buf).is_ok()
            }
            // Only an oversized message fails to encode; it is not sent.
            Err(_) => true,
        }
    }

    fn run_with(&mut self, pipeline: &mut Pipeline) -> Next {
        loop {
            let streaming = self.controller.counters().streaming;
            let command = if streaming {
                match self.commands.try_recv() {
                    Ok(c) => Some(c),
                    Err(TryRecvError::Empty) => None,
                    Err(TryRecvError::Disconnected) => return Next::Exit,
                }
            } else {
                match self.commands.recv() {
                    Ok(c) => Some(c),
                    Err(_) => return Next::Exit,
                }
            };
            if let Some(bytes) = command {
                let (reply, effect) = self.controller.handle(&bytes);
                if !Self::send(&mut self.controller, &self.out, &reply) {
                    return Next::Exit;
                }
                match effect {
                    Effect::Configure(_) => return Next::Reconfigure,
                    Effect::StreamStop => {
                        if !self.end_stream(pipeline, None) {
                            return Next::Exit;
                        }
                    }
                    Effect::CaptureRaw(n) => {
                        if !self.capture_raw(n) {
                            return Next::Exit;
                        }
                    }
                    Effect::StreamStart | Effect::Leds(_) | Effect::Roller(_) | Effect::None => {}
                }
                continue;
            }
            if !self.stream_one(pipeline) {
                return Next::Exit;
            }
        }
    }

    /// The camera bytes of frame `k` and its commanded position, camera pixels.
    fn camera_frame(&self, k: usize) -> (Vec<u8>, f64) {
        let frame = self.sim.frame(k);
        let position = self.sim.strip_row_of_top(frame.offset_mm);
        (camera_bytes(&frame.image), position)
    }

    /// Captures, fuses and sends the next frame; at the end of the scene, ends the stream.
    fn stream_one(&mut self, pipeline: &mut Pipeline) -> bool {
        if self.next_frame >= self.sim.frames() {
            let note = format!("scene ended after {} frames", self.next_frame);
            return self.end_stream(pipeline, Some(&note));
        }
        let (bytes, position) = self.camera_frame(self.next_frame);
        self.next_frame += 1;
        let origin = *self.origin_px.get_or_insert(position);
        let position_px = (position - origin).round().max(0.0) as u64;
        let Device {
            controller, out, ..
        } = self;
        controller.counters_mut().frames_captured += 1;
        let mut alive = true;
        let mut emitted = 0;
        let result = pipeline.push_frame(&bytes, position_px, |tile| {
            emitted += 1;
            alive &= Self::send(controller, out, &DeviceMessage::Tile(tile));
        });
        let c = controller.counters_mut();
        c.tiles_emitted += emitted;
        match result {
            Ok(_) => c.frames_fused += 1,
            Err(_) => c.frames_rejected += 1,
        }
        alive
    }

    /// Flushes the pipeline, stops streaming and sends the status (and `note`).
    fn end_stream(&mut self, pipeline: &mut Pipeline, note: Option<&str>) -> bool {
        let Device {
            controller, out, ..
        } = self;
        let mut alive = true;
        let mut emitted = 0;
        pipeline.finish(|tile| {
            emitted += 1;
            alive &= Self::send(controller, out, &DeviceMessage::Tile(tile));
        });
        let c = controller.counters_mut();
        c.tiles_emitted += emitted;
        c.streaming = false;
        if let Some(note) = note {
            alive &= Self::send(controller, out, &DeviceMessage::Log(note));
        }
        let status = DeviceMessage::Status(controller.counters());
        alive && Self::send(controller, out, &status)
    }

    /// Sends the next `n` frames raw, in chunks (they are not fused).
    fn capture_raw(&mut self, n: u8) -> bool {
        for frame in 0..n {
            if self.next_frame >= self.sim.frames() {
                break;
            }
            let (bytes, _) = self.camera_frame(self.next_frame);
            self.next_frame += 1;
            for (k, data) in bytes.chunks(MAX_CHUNK).enumerate() {
                let chunk = RawChunk {
                    frame,
                    offset: (k * MAX_CHUNK) as u32,
                    total: bytes.len() as u32,
                    data,
                };
                if !Self::send(
                    &mut self.controller,
                    &self.out,
                    &DeviceMessage::RawChunk(chunk),
                ) {
                    return false;
                }
            }
        }
        true
    }
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
