//! A bus suspended and resumed within the heartbeat: the USB stack stopped the roller and
//! streaming at once, and the controller is told, so the host that comes back reads a
//! status that says so (not "running") and may start again.

mod common;

use common::*;
use embassy_time::Duration;
use rollfuse_core::protocol::{self, Command, DeviceMessage, RollerCommand};
use rollfuse_fw::signals::BUS_LOST;
use std::sync::atomic::Ordering::Relaxed;

/// The device's last status reply: (streaming, roller running).
fn last_status() -> Option<(bool, bool)> {
    device_messages()
        .iter()
        .rev()
        .find_map(|m| match protocol::decode(m) {
            Ok((_, DeviceMessage::Status(c))) => Some((c.streaming, c.roller_running)),
            _ => None,
        })
}

#[test]
fn a_lost_bus_is_told_to_the_controller() {
    let test = async {
        host_sends(1, &Command::StreamStart);
        host_sends(
            2,
            &Command::Roller(RollerCommand::Start { speed_um_s: 20_000 }),
        );
        host_sends(3, &Command::Status);
        assert!(
            until(Duration::from_millis(200), || last_status()
                == Some((true, true)))
            .await
        );
        // The bus is suspended (the USB stack's event), then resumes at once.
        BUS_LOST.store(true, Relaxed);
        wait(Duration::from_millis(300)).await;
        host_sends(4, &Command::Status);
        let told = until(Duration::from_millis(200), || {
            last_status() == Some((false, false))
        })
        .await;
        assert!(told, "the status still says running: {:?}", last_status());
        // The host may start streaming again: no Busy.
        host_sends(5, &Command::StreamStart);
        assert!(until(Duration::from_millis(200), || acked(5)).await);
    };
    beside_link_and_roller(test);
}
