//! The slowest belt, one step a second: the step generator keeps beating between steps
//! (the watchdog's timeout is a second), and a stop ends the motion within a step.

mod common;

use common::*;
use embassy_time::{Duration, Instant};
use rollfuse_core::protocol::RollerCommand;
use rollfuse_fw::liveness::Task;
use rollfuse_fw::roller::{self, ORDERS, Order};
use rollfuse_fw::signals;
use std::sync::atomic::Ordering::Relaxed;

#[test]
fn one_step_a_second_beats_between_steps_and_stops_within_one() {
    let test = async {
        // 30 µm/s at 23.562 µm a step: one step a second.
        let command = RollerCommand::Start { speed_um_s: 30 };
        let stops = signals::roller_stops_requested();
        ORDERS.send(Order::Roller { command, stops }).await;
        beats_throughout(Task::Motion, 8, "it waited between steps").await;
        assert!(STEPS.load(Relaxed) >= 2, "the roller did not step");
        roller::stop();
        let asked = Instant::now();
        let stopped = until(Duration::from_secs(2), || !DRIVER_ON.load(Relaxed)).await;
        assert!(stopped, "the roller still turns");
        assert!(
            Instant::now() - asked <= Duration::from_millis(1100),
            "the stop took {:?}",
            Instant::now() - asked
        );
        let steps = STEPS.load(Relaxed);
        wait(Duration::from_secs(2)).await;
        assert_eq!(STEPS.load(Relaxed), steps, "steps after the stop");
    };
    beside_link_and_roller(test);
}
