//! A stop reaches the step generator with every queue full.

mod common;

use common::*;
use embassy_futures::select::select;
use embassy_time::Duration;
use rollfuse_core::device::Effect;
use rollfuse_core::protocol::{Command, RollerCommand};
use rollfuse_fw::roller::{ORDERS, Order};
use rollfuse_fw::signals::{Accepted, EFFECTS};
use std::sync::atomic::Ordering::Relaxed;

#[test]
fn stop_reaches_the_step_generator_with_every_queue_full() {
    let test = async {
        // The roller turns.
        roller_turning().await;
        // Every queue full: nothing drains the effects here, and the roller's orders are
        // topped up as it takes them.
        while EFFECTS.try_send(Accepted::now(Effect::StreamStart)).is_ok() {}
        let top_up = async {
            loop {
                while ORDERS.try_send(Order::FrameSpacing(16)).is_ok() {}
                embassy_futures::yield_now().await;
            }
        };
        let stopping = async {
            host_sends(7, &Command::Roller(RollerCommand::Stop));
            // The ramp down from 20 mm/s at 100 mm/s² takes 0.2 s.
            until(Duration::from_secs(2), || !DRIVER_ON.load(Relaxed)).await
        };
        let stopped = match select(stopping, top_up).await {
            embassy_futures::select::Either::First(s) => s,
            embassy_futures::select::Either::Second(()) => false,
        };
        assert!(stopped, "the roller still turns after a Stop");
        assert!(acked(7), "the Stop was not acknowledged");
        assert!(EFFECTS.is_full(), "the effect queue was drained");
        let after = STEPS.load(Relaxed);
        wait(Duration::from_millis(200)).await;
        assert_eq!(STEPS.load(Relaxed), after, "steps after the stop");
    };
    beside_link_and_roller(test);
}
