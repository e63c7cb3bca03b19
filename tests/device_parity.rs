//! The virtual device is the module: over the protocol's bytes, it accepts and refuses
//! the configurations the firmware's controller accepts and refuses — memory included —
//! unless a host-only study lifts its memory explicitly.

use rollfuse::link::sim::{DeviceMemory, SimDevice};
use rollfuse::link::{Received, Transport};
use rollfuse::sim::Scene;
use rollfuse_core::protocol::{
    self, Command, DeviceConfig, DeviceMessage, MAX_MESSAGE, NakReason, WaveletId,
};
use std::path::Path;
use std::time::Duration;

fn letters() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../host/scenes/letters.toml");
    let mut scene = Scene::load(&path).unwrap();
    scene.sensor.frames = 14;
    scene
}

/// Configurations around the module's limits: every downsampling factor, tiles from a
/// few rows to most of a frame, short and long observation windows, 1 to 3 levels.
fn configurations(spacing: u16) -> Vec<DeviceConfig> {
    let mut all = Vec::new();
    for downsample in [1, 2, 4] {
        for tile_rows in [4, 16, 32, 60] {
            for frames_per_tile in [1, 3, 6] {
                for levels in [1, 2, 3] {
                    all.push(DeviceConfig {
                        wavelet: WaveletId::Db2,
                        levels,
                        downsample,
                        tile_rows,
                        frames_per_tile,
                        frame_spacing_px: spacing,
                        ..DeviceConfig::default()
                    });
                }
            }
        }
    }
    all
}

/// The reply to a command: `Ok` for an ack, the reason for a refusal.
type Reply = Result<(), NakReason>;

fn reply_of(bytes: &[u8]) -> Reply {
    match protocol::decode::<DeviceMessage>(bytes).unwrap().1 {
        DeviceMessage::Ack { .. } => Ok(()),
        DeviceMessage::Nak { reason, .. } => Err(reason),
        other => panic!("not a reply: {other:?}"),
    }
}

/// Sends `command` to the virtual device and returns its reply.
fn ask(device: &mut SimDevice, seq: u32, command: &Command) -> Reply {
    let mut buf = vec![0u8; MAX_MESSAGE];
    let n = protocol::encode(seq, command, &mut buf).unwrap();
    device.send(&buf[..n]).unwrap();
    match device.receive(&mut buf, Duration::from_secs(10)).unwrap() {
        Received::Message(n) => reply_of(&buf[..n]),
        other => panic!("no reply from the virtual device: {other:?}"),
    }
}

/// The firmware controller's reply to `command`.
fn firmware_reply(
    controller: &mut rollfuse_core::device::Controller,
    seq: u32,
    command: &Command,
) -> Reply {
    let mut buf = vec![0u8; MAX_MESSAGE];
    let n = protocol::encode(seq, command, &mut buf).unwrap();
    let (reply, _) = controller.handle(&buf[..n]);
    let n = controller.encode(&reply, &mut buf).unwrap();
    reply_of(&buf[..n])
}

#[test]
fn the_virtual_device_refuses_what_the_firmware_refuses() {
    let mut firmware = rollfuse_fw::controller().unwrap();
    let mut device = SimDevice::start(&letters()).unwrap();
    let spacing = device.default_config().frame_spacing_px;
    let (mut accepted, mut for_memory) = (0, 0);
    for (seq, config) in (0..).zip(configurations(spacing)) {
        let command = Command::Configure(config);
        let expected = firmware_reply(&mut firmware, seq, &command);
        assert_eq!(ask(&mut device, seq, &command), expected, "{config:?}");
        accepted += usize::from(expected.is_ok());
        for_memory += usize::from(expected == Err(NakReason::Memory));
    }
    // The grid reaches both sides of the memory limit, and past it.
    assert!(
        accepted > 0 && for_memory > 0,
        "{accepted} accepted, {for_memory} refused for memory"
    );
}

#[test]
fn lifted_memory_accepts_what_the_firmware_cannot_hold() {
    let scene = letters();
    let mut bounded = SimDevice::start(&scene).unwrap();
    let mut unbounded = SimDevice::start_with(&scene, DeviceMemory::Unbounded).unwrap();
    // Full resolution in 48-row tiles: two work images of 48 × 320 words, more than the
    // module's 16 Ki.
    let full_resolution = Command::Configure(DeviceConfig {
        downsample: 1,
        tile_rows: 48,
        ..bounded.default_config()
    });
    assert_eq!(
        ask(&mut bounded, 0, &full_resolution),
        Err(NakReason::Memory)
    );
    assert_eq!(ask(&mut unbounded, 0, &full_resolution), Ok(()));
    // And it streams at full resolution: tiles as wide as the camera, then the status.
    assert_eq!(ask(&mut unbounded, 1, &Command::StreamStart), Ok(()));
    let mut buf = vec![0u8; MAX_MESSAGE];
    let mut widths = Vec::new();
    loop {
        let Received::Message(n) = unbounded
            .receive(&mut buf, Duration::from_secs(30))
            .unwrap()
        else {
            panic!("the stream stopped before its status");
        };
        match protocol::decode::<DeviceMessage>(&buf[..n]).unwrap().1 {
            DeviceMessage::Tile(tile) => widths.push(tile.width),
            DeviceMessage::Status(status) => {
                assert_eq!(status.tiles_emitted as usize, widths.len());
                break;
            }
            _ => {}
        }
    }
    assert!(!widths.is_empty());
    assert!(
        widths
            .iter()
            .all(|&w| usize::from(w) == scene.sensor.width_px)
    );
}
