//! A stop reaches the step generator with every queue full.

mod common;

use common::*;
use embassy_futures::join::join;
use embassy_futures::select::{Either3, select, select3};
use embassy_time::Duration;
use rollfuse_core::device::Effect;
use rollfuse_core::protocol::{Command, MAX_MESSAGE, RollerCommand};
use rollfuse_fw::roller::{self, ORDERS, Order};
use rollfuse_fw::signals::EFFECTS;
use rollfuse_fw::{link, outbox};
use std::sync::atomic::Ordering::Relaxed;

#[test]
fn stop_reaches_the_step_generator_with_every_queue_full() {
    outbox::init();
    let mut controller = rollfuse_fw::controller().expect("the default configuration fits");
    let (mut read, mut write) = (Out::new(), In::new());
    let mut tx = Box::new([0u8; MAX_MESSAGE]);
    let mut pins = Pins;
    let test = async {
        // The roller turns.
        ORDERS
            .send(Order::Roller(RollerCommand::Start { speed_um_s: 20_000 }))
            .await;
        assert!(until(Duration::from_secs(1), || STEPS.load(Relaxed) > 100).await);
        // Every queue full: nothing drains the effects here, and the roller's orders are
        // topped up as it takes them.
        while EFFECTS.try_send(Effect::StreamStart).is_ok() {}
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
    let outcome = embassy_futures::block_on(select3(
        join(test, async {}),
        clock(),
        select(roller::run(&mut pins, 16), async {
            // As on the board: the link is served again when a host comes back.
            loop {
                link::serve(&mut read, &mut write, &mut controller, &mut tx).await;
            }
        }),
    ));
    // The test's body ran to its end: no task ended first.
    assert!(
        matches!(outcome, Either3::First(_)),
        "a task ended before the test did"
    );
}
