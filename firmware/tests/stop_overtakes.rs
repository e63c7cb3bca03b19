//! A Stop overtakes the roller orders accepted before it: a Start still queued behind a
//! busy pipeline when the Stop comes is dropped when it reaches the roller, and a Start
//! accepted after the Stop is carried out. The effects task keeps beating while it waits.

mod common;

use common::*;
use embassy_time::Duration;
use rollfuse_core::device::Order;
use rollfuse_core::protocol::{Command, RollerCommand};
use rollfuse_fw::liveness::Task;
use rollfuse_fw::signals::{self, STREAM, StreamOrder};
use std::sync::atomic::Ordering::Relaxed;

#[test]
fn a_stop_drops_the_roller_orders_accepted_before_it() {
    let test = async {
        // The pipeline is busy (sending raw frames, say): its queue is full and nothing
        // takes from it, so the effects task waits to queue the stream's next order.
        let stop = StreamOrder {
            order: Order::Stop,
            stops: signals::stream_stops_requested(),
        };
        while STREAM.try_send(stop).is_ok() {}
        host_sends(1, &Command::StreamStart);
        let start = Command::Roller(RollerCommand::Start { speed_um_s: 20_000 });
        host_sends(2, &start);
        host_sends(3, &Command::Roller(RollerCommand::Stop));
        assert!(
            until(Duration::from_millis(100), || acked(1)
                && acked(2)
                && acked(3))
            .await
        );
        // The effects task waits on the full queue, beating: the watchdog would be fed.
        beats_throughout(Task::Effects, 4, "it waited behind the full queue").await;
        // The pipeline catches up: the effects task queues its order, then hands the
        // roller the Start accepted before the Stop.
        let drained = until(Duration::from_secs(1), || {
            while STREAM.try_receive().is_ok() {}
            false
        })
        .await;
        assert!(!drained);
        assert_eq!(STEPS.load(Relaxed), 0, "the roller turned after the Stop");
        assert!(!DRIVER_ON.load(Relaxed), "the driver is on after the Stop");
        // A Start accepted after the Stop turns the roller.
        host_sends(4, &start);
        let turns = until(Duration::from_secs(1), || STEPS.load(Relaxed) > 100).await;
        assert!(turns, "a Start after the Stop was dropped too");
    };
    beside_link_roller_and_effects(test);
}
