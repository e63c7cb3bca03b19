//! A stop of the stream meant for one session does not reach another: a start accepted
//! before a stop but still queued is not carried out, and a stop signalled before a start
//! was accepted (the pipeline busy meanwhile) does not end the stream that start begins.

mod common;

use common::*;
use embassy_futures::select::{Either3, select, select3};
use embassy_time::Duration;
use rollfuse_core::device::{CAMERA, ModuleBuffers, Order, PipelineConfig};
use rollfuse_core::protocol::{DeviceConfig, RollerCommand};
use rollfuse_fw::counters::COUNTERS;
use rollfuse_fw::pipeline::{self, Camera, FRAME_WORDS};
use rollfuse_fw::roller::{self, ORDERS};
use rollfuse_fw::signals::{self, STREAM, StreamOrder};
use rollfuse_fw::{liveness, outbox};
use std::sync::atomic::Ordering::Relaxed;

/// A camera that never answers: while a stream runs, each triggered capture times out and
/// is counted, so the count shows whether a stream runs.
struct Silent;

impl Camera for Silent {
    async fn capture(&mut self, _: &mut [u32; FRAME_WORDS]) -> bool {
        std::future::pending().await
    }
    fn reset(&mut self) {}
}

/// Whether captures are being made (a stream runs) over the next second.
async fn streaming() -> bool {
    let before = COUNTERS.camera_timeouts.load(Relaxed);
    wait(Duration::from_secs(1)).await;
    COUNTERS.camera_timeouts.load(Relaxed) > before
}

fn start() -> StreamOrder {
    StreamOrder {
        order: Order::Start,
        stops: signals::stream_stops_requested(),
    }
}

#[test]
fn a_stream_stop_ends_only_the_stream_it_was_meant_for() {
    outbox::init();
    let config = PipelineConfig::from_wire(&DeviceConfig::default(), CAMERA).unwrap();
    let frames = pipeline::Frames::new(
        Box::leak(Box::new([0u32; FRAME_WORDS])),
        Box::leak(Box::new([0u32; FRAME_WORDS])),
    );
    let buffers = Box::leak(Box::new(ModuleBuffers::new())).buffers();
    let (mut camera, mut pins) = (Silent, Pins);
    let test = async {
        let command = RollerCommand::Start { speed_um_s: 20_000 };
        let stops = rollfuse_fw::signals::roller_stops_requested();
        ORDERS.send(roller::Order::Roller { command, stops }).await;
        // A start accepted, then the host gone (its stop seen by a pipeline with no stream
        // to end) before the pipeline took the start: not started.
        let overtaken = start();
        signals::stop_stream();
        wait(Duration::from_millis(100)).await;
        STREAM.send(overtaken).await;
        assert!(
            !streaming().await,
            "a start from before the stop began a stream"
        );
        // The host gone again while no stream runs, its stop not yet seen; a new host's
        // start accepted after it, and both taken at once: the stream runs on.
        signals::stop_stream();
        STREAM.send(start()).await;
        assert!(
            streaming().await,
            "the stream did not start, or a stop from before ended it"
        );
        assert!(
            streaming().await,
            "a stop from before the start ended the stream"
        );
        // A stop after the start ends it.
        signals::stop_stream();
        wait(Duration::from_millis(500)).await;
        assert!(!streaming().await, "the stop did not end the stream");
    };
    let beats = async {
        loop {
            liveness::beat(liveness::Task::Link);
            liveness::beat(liveness::Task::Effects);
            wait(liveness::BEAT).await;
        }
    };
    let outcome = embassy_futures::block_on(select3(
        test,
        clock(),
        select(
            select(
                pipeline::run(&mut camera, frames, buffers, config),
                roller::run(&mut pins, 16),
            ),
            beats,
        ),
    ));
    assert!(
        matches!(outcome, Either3::First(())),
        "a task ended before the test did"
    );
}
