//! A board with no USB host (powered without its cable): the link waits for one and keeps
//! beating meanwhile, so the watchdog does not restart the board again and again; a host
//! that comes later is served.

mod common;

use common::*;
use embassy_time::Duration;
use rollfuse_core::protocol::Command;
use rollfuse_fw::liveness::Task;
use std::sync::atomic::Ordering::Relaxed;

#[test]
fn the_link_beats_while_no_host_is_there() {
    HOST_CONFIGURED.store(false, Relaxed);
    let test = async {
        beats_throughout(Task::Link, 10, "it waited for a host").await;
        HOST_CONFIGURED.store(true, Relaxed);
        host_sends(1, &Command::Status);
        assert!(
            until(Duration::from_millis(500), || !device_messages().is_empty()).await,
            "the host that came was not answered"
        );
    };
    beside_link_and_roller(test);
}
