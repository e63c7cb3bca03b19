//! A host that stops reading (or stops talking) stops the roller and streaming within the
//! heartbeat timeout, even with the link stuck writing to it — and the link keeps beating
//! meanwhile, so the watchdog does not restart the board first.

mod common;

use common::*;
use embassy_time::{Duration, Instant};
use rollfuse_core::protocol::{Command, RollerCommand};
use rollfuse_fw::link;
use rollfuse_fw::liveness::Task;
use rollfuse_fw::signals::STOP_STREAM;
use std::sync::atomic::Ordering::Relaxed;

#[test]
fn a_host_that_stops_reading_stops_the_roller_within_the_heartbeat() {
    let test = async {
        host_sends(1, &Command::StreamStart);
        host_sends(
            2,
            &Command::Roller(RollerCommand::Start { speed_um_s: 20_000 }),
        );
        assert!(until(Duration::from_millis(100), || acked(1) && acked(2)).await);
        // The effects task is not running here: the roller gets its order directly.
        roller_turning().await;
        // The host stops reading and says nothing more; a tile is waiting to go.
        HOST_READS.store(false, Relaxed);
        queue_tile(0, 8, 8);
        let gone_at = Instant::now();
        // While its write waits on the silent host, the link keeps beating: the watchdog
        // (1 s) must not restart the board before the heartbeat (3 s) has acted.
        beats_throughout(Task::Link, 5, "its write waited").await;
        let stopped = until(link::HEARTBEAT + Duration::from_secs(1), || {
            !DRIVER_ON.load(Relaxed)
        })
        .await;
        assert!(stopped, "the roller still turns with the host gone");
        assert!(
            Instant::now() - gone_at <= link::HEARTBEAT + Duration::from_millis(500),
            "stopped only after {:?}",
            Instant::now() - gone_at
        );
        assert!(STOP_STREAM.signaled(), "streaming was not told to stop");
        // With the host silent, the link goes on waiting (and beating) without spinning:
        // a spinning task would never let this wait end.
        wait(link::HEARTBEAT * 2).await;
    };
    beside_link_and_roller(test);
}
