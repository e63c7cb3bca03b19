//! A Stop acts while a full-size tile is being sent to a host that reads nothing: the link
//! reads the host's packets during a send, carries a completed command out at once, and
//! sends its answer after the message in flight.

mod common;

use common::*;
use embassy_time::{Duration, Instant};
use rollfuse_core::protocol::{self, Command, DeviceMessage, MAX_TILE_BYTES, RollerCommand};
use rollfuse_fw::signals::roller_stops_requested;
use std::sync::atomic::Ordering::Relaxed;

/// How soon a Stop must reach the roller, whatever the link is sending.
const STOP_BOUND: Duration = Duration::from_millis(10);

#[test]
fn a_stop_acts_within_10_ms_while_a_tile_waits_on_a_host_that_reads_nothing() {
    let test = async {
        host_sends(1, &Command::Status);
        assert!(until(Duration::from_millis(100), || device_messages().len() == 1).await);
        roller_turning().await;
        // The host stops reading; a tile of the largest size goes out and waits on it.
        HOST_READS.store(false, Relaxed);
        queue_tile(7, 160, 100);
        assert_eq!(160 * 100, MAX_TILE_BYTES);
        wait(Duration::from_millis(50)).await;
        // A status request and then a Stop, both while the tile is stuck.
        let stops = roller_stops_requested();
        host_sends(2, &Command::Status);
        host_sends(3, &Command::Roller(RollerCommand::Stop));
        let sent_at = Instant::now();
        let acted = until(STOP_BOUND, || roller_stops_requested() != stops).await;
        assert!(
            acted,
            "the Stop waited behind the tile for {:?}",
            Instant::now() - sent_at
        );
        assert!(
            until(Duration::from_secs(2), || !DRIVER_ON.load(Relaxed)).await,
            "the roller did not ramp down"
        );
        // The host reads again: the tile comes whole, then both answers, in order.
        HOST_READS.store(true, Relaxed);
        assert!(until(Duration::from_millis(100), || device_messages().len() == 4).await);
        let kinds: Vec<String> = device_messages()[1..]
            .iter()
            .map(|m| match protocol::decode::<DeviceMessage>(m) {
                Ok((_, DeviceMessage::Tile(t))) => format!("tile {}", t.index),
                Ok((_, DeviceMessage::Status(_))) => "status".into(),
                Ok((_, DeviceMessage::Ack { command_seq })) => format!("ack {command_seq}"),
                other => format!("{other:?}"),
            })
            .collect();
        assert_eq!(kinds, ["tile 7", "status", "ack 3"]);
    };
    beside_link_and_roller(test);
}
