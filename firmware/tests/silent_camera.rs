//! A camera that never answers: every capture is abandoned and counted, and meanwhile LED
//! and roller orders are carried out and every task keeps coming round (the watchdog
//! would be fed).

mod common;

use common::*;
use embassy_futures::join::join;
use embassy_futures::select::{Either4, select, select4};
use embassy_time::Duration;
use rollfuse_core::device::{CAMERA, Effect, MCU_CAPACITY, ModuleBuffers, Order, PipelineConfig};
use rollfuse_core::protocol::{DeviceConfig, LedDuty, RollerCommand};
use rollfuse_fw::counters::COUNTERS;
use rollfuse_fw::effects::{self, Leds};
use rollfuse_fw::pipeline::{self, Camera, FRAME_WORDS};
use rollfuse_fw::signals::{self, Accepted, EFFECTS, STREAM, StreamOrder};
use rollfuse_fw::{liveness, outbox, roller};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

/// A camera with no pixel clock: a capture never ends.
struct Silent;

static RESETS: AtomicU32 = AtomicU32::new(0);

impl Camera for Silent {
    async fn capture(&mut self, _: &mut [u32; FRAME_WORDS]) -> bool {
        std::future::pending().await
    }
    fn reset(&mut self) {
        RESETS.fetch_add(1, Relaxed);
    }
}

static LED: Mutex<Option<LedDuty>> = Mutex::new(None);

struct MockLeds;

impl Leds for MockLeds {
    fn set(&mut self, duty: LedDuty) {
        *LED.lock().unwrap() = Some(duty);
    }
}

#[test]
fn a_silent_camera_blocks_no_order_and_is_reported() {
    outbox::init();
    let config = PipelineConfig::from_wire(&DeviceConfig::default(), CAMERA).unwrap();
    assert!(config.memory().fits(&MCU_CAPACITY));
    let frames = pipeline::Frames::new(
        Box::leak(Box::new([0u32; FRAME_WORDS])),
        Box::leak(Box::new([0u32; FRAME_WORDS])),
    );
    let buffers = Box::leak(Box::new(ModuleBuffers::new())).buffers();
    let (mut camera, mut leds, mut pins) = (Silent, MockLeds, Pins);
    let test = async {
        STREAM
            .send(StreamOrder {
                order: Order::Start,
                stops: signals::stream_stops_requested(),
            })
            .await;
        EFFECTS
            .send(Accepted::now(Effect::Roller(RollerCommand::Start {
                speed_um_s: 20_000,
            })))
            .await;
        // Frames are triggered; their captures time out one after another.
        assert!(
            until(Duration::from_secs(2), || COUNTERS
                .camera_timeouts
                .load(Relaxed)
                >= 3)
            .await
        );
        assert_eq!(COUNTERS.frames_captured.load(Relaxed), 0);
        assert!(RESETS.load(Relaxed) >= 3, "the interface was not reset");
        // More pipeline orders than its queue holds, then an LED order: the pipeline
        // takes its orders between abandoned captures, so the LED order gets through.
        for _ in 0..6 {
            EFFECTS.send(Accepted::now(Effect::StreamStart)).await;
        }
        let duty = LedDuty {
            red: 100,
            green: 200,
            blue: 300,
        };
        EFFECTS.send(Accepted::now(Effect::Leds(duty))).await;
        let lit = until(Duration::from_secs(2), || {
            *LED.lock().unwrap() == Some(duty)
        })
        .await;
        assert!(lit, "the LED order waited behind the camera");
        // The roller keeps stepping, and every task keeps beating.
        let steps = STEPS.load(Relaxed);
        let mut seen = [0; 4];
        liveness::all_alive(&mut seen);
        wait(Duration::from_millis(400)).await;
        assert!(STEPS.load(Relaxed) > steps);
        assert!(
            liveness::all_alive(&mut seen),
            "a task stopped coming round"
        );
    };
    // The link is not running: it beats for itself in the firmware; here the test does.
    let link_beats = async {
        loop {
            liveness::beat(liveness::Task::Link);
            wait(liveness::BEAT).await;
        }
    };
    let outcome = embassy_futures::block_on(select4(
        join(test, async {}),
        clock(),
        select(
            pipeline::run(&mut camera, frames, buffers, config),
            roller::run(&mut pins, 16),
        ),
        select(effects::run(&mut leds), link_beats),
    ));
    // The test's body ran to its end: no task ended first.
    assert!(
        matches!(outcome, Either4::First(_)),
        "a task ended before the test did"
    );
}
