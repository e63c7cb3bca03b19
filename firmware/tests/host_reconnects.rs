//! A host that dies in the middle of a message, and a new host that opens the device
//! without a bus reset (the host tool restarted): the link gives the stuck send up at the
//! heartbeat and discards the packet the dead host never took, so the new host's Hello is
//! answered by a clean Info on its first try — not by the dead host's tile with the answer
//! glued on.

mod common;

use common::*;
use embassy_time::Duration;
use rollfuse_core::protocol::{self, Command, DeviceMessage};
use rollfuse_fw::link;
use std::sync::atomic::Ordering::Relaxed;

#[test]
fn a_new_host_gets_a_clean_answer_to_its_first_hello_after_one_died_mid_message() {
    let test = async {
        host_sends(1, &Command::Status);
        assert!(until(Duration::from_millis(100), || device_messages().len() == 1).await);
        // The host dies: it stops reading and talking while a tile goes out. The tile's
        // first packet loads; the rest wait.
        HOST_READS.store(false, Relaxed);
        queue_tile(3, 100, 10);
        wait(link::HEARTBEAT + Duration::from_millis(500)).await;
        // A new host opens the device: it reads, and sends Hello first.
        WRITTEN.lock().unwrap().clear();
        HOST_READS.store(true, Relaxed);
        host_sends(1, &Command::Hello);
        assert!(until(Duration::from_millis(100), || !device_messages().is_empty()).await);
        let first = &device_messages()[0];
        match protocol::decode::<DeviceMessage>(first) {
            Ok((_, DeviceMessage::Info(_))) => {}
            other => panic!(
                "the new host's first message ({} bytes) is not an Info: {other:?}",
                first.len()
            ),
        }
    };
    beside_link_and_roller(test);
}
