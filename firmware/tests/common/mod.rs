//! Mock peripherals and virtual time for the firmware's tasks on the host.
#![allow(dead_code)]

use embassy_futures::select::{Either3, select, select3};
use embassy_futures::yield_now;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Instant, MockDriver};
use embassy_usb_driver::{
    Direction, Endpoint, EndpointAddress, EndpointError, EndpointIn, EndpointInfo, EndpointOut,
    EndpointType,
};
use rollfuse_core::protocol::{self, Command, DeviceMessage, MAX_MESSAGE};
use rollfuse_fw::{link, outbox, roller};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering::Relaxed};

/// Virtual time: advances 50 µs per turn of the test's loop, forever. Joined with a
/// test's body, it makes every timer of the tasks fire in order, with no wall clock.
pub async fn clock() {
    loop {
        MockDriver::get().advance(Duration::from_micros(50));
        yield_now().await;
    }
}

/// Waits `d` of virtual time.
pub async fn wait(d: Duration) {
    embassy_time::Timer::after(d).await
}

/// Requires `task` to beat within each of `spans` spans of 400 ms (as often as the
/// watchdog's feeder looks): what the watchdog sees of a task that waits `while`.
pub async fn beats_throughout(task: rollfuse_fw::liveness::Task, spans: usize, while_: &str) {
    for _ in 0..spans {
        let before = rollfuse_fw::liveness::beats(task);
        wait(Duration::from_millis(400)).await;
        assert!(
            rollfuse_fw::liveness::beats(task) > before,
            "{task:?} stopped beating while {while_}"
        );
    }
}

/// Waits until `cond` holds, for at most `limit` of virtual time; whether it held.
pub async fn until(limit: Duration, cond: impl Fn() -> bool) -> bool {
    let end = Instant::now() + limit;
    while Instant::now() < end {
        if cond() {
            return true;
        }
        yield_now().await;
    }
    cond()
}

/// The stepper's pins: counts steps, keeps the driver's state.
pub struct Pins;

pub static STEPS: AtomicU32 = AtomicU32::new(0);
pub static DRIVER_ON: AtomicBool = AtomicBool::new(false);

impl rollfuse_fw::roller::StepPins for Pins {
    fn step(&mut self, high: bool) {
        if high {
            STEPS.fetch_add(1, Relaxed);
        }
    }
    fn enable(&mut self, on: bool) {
        DRIVER_ON.store(on, Relaxed);
    }
}

fn info(dir: Direction) -> EndpointInfo {
    EndpointInfo {
        addr: EndpointAddress::from_parts(1, dir),
        ep_type: EndpointType::Bulk,
        max_packet_size: 64,
        interval_ms: 0,
    }
}

/// Packets the host sends.
pub static HOST_OUT: Channel<CriticalSectionRawMutex, Vec<u8>, 64> = Channel::new();

/// Whether a host has configured the device: the endpoints wait for it.
pub static HOST_CONFIGURED: AtomicBool = AtomicBool::new(true);

/// Waits until [`HOST_CONFIGURED`].
async fn configured() {
    while !HOST_CONFIGURED.load(Relaxed) {
        yield_now().await;
    }
}

/// The bulk OUT endpoint: packets from [`HOST_OUT`]; waits forever when there are none.
pub struct Out(EndpointInfo);

impl Out {
    pub fn new() -> Self {
        Self(info(Direction::Out))
    }
}

impl Endpoint for Out {
    fn info(&self) -> &EndpointInfo {
        &self.0
    }
    async fn wait_enabled(&mut self) {
        configured().await
    }
}

impl EndpointOut for Out {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, EndpointError> {
        let p = HOST_OUT.receive().await;
        buf[..p.len()].copy_from_slice(&p);
        Ok(p.len())
    }
}

/// Whether the host reads what the device writes.
pub static HOST_READS: AtomicBool = AtomicBool::new(true);
/// What the host took, packet by packet.
pub static WRITTEN: Mutex<Vec<Vec<u8>>> = Mutex::new(Vec::new());
/// The packet loaded in the IN endpoint and not yet taken (the OTG core's FIFO).
pub static LOADED: Mutex<Option<Vec<u8>>> = Mutex::new(None);

/// The host takes the loaded packet, if it reads.
fn host_takes() {
    if HOST_READS.load(Relaxed)
        && let Some(packet) = LOADED.lock().unwrap().take()
    {
        WRITTEN.lock().unwrap().push(packet);
    }
}

/// The bulk IN endpoint as the OTG core behaves: a write waits until the host has taken
/// the packet before (which it does only while [`HOST_READS`]), then loads its own and
/// returns. A write abandoned leaves the packet before it loaded.
pub struct In(EndpointInfo);

impl In {
    pub fn new() -> Self {
        Self(info(Direction::In))
    }
}

impl Endpoint for In {
    fn info(&self) -> &EndpointInfo {
        &self.0
    }
    async fn wait_enabled(&mut self) {
        configured().await
    }
}

impl EndpointIn for In {
    async fn write(&mut self, buf: &[u8]) -> Result<(), EndpointError> {
        loop {
            host_takes();
            if LOADED.lock().unwrap().is_none() {
                break;
            }
            yield_now().await;
        }
        *LOADED.lock().unwrap() = Some(buf.to_vec());
        Ok(())
    }
}

impl link::DiscardLoaded for In {
    fn discard_loaded(&mut self) {
        LOADED.lock().unwrap().take();
    }
}

/// Sends `command` as the host would: one transfer of 64-byte packets ending short.
pub fn host_sends(seq: u32, command: &Command) {
    let mut buf = [0u8; 256];
    let n = protocol::encode(seq, command, &mut buf).unwrap();
    let mut packets: Vec<Vec<u8>> = buf[..n].chunks(64).map(<[u8]>::to_vec).collect();
    if n % 64 == 0 {
        packets.push(Vec::new());
    }
    for p in packets {
        HOST_OUT.try_send(p).unwrap();
    }
}

/// The messages the device wrote, reassembled from packets (a short packet ends one).
pub fn device_messages() -> Vec<Vec<u8>> {
    host_takes();
    let mut out = Vec::new();
    let mut cur = Vec::new();
    for p in WRITTEN.lock().unwrap().iter() {
        cur.extend_from_slice(p);
        if p.len() < 64 {
            out.push(std::mem::take(&mut cur));
        }
    }
    out
}

/// Whether the device acknowledged command `seq`.
pub fn acked(seq: u32) -> bool {
    device_messages().iter().any(|m| {
        matches!(
            protocol::decode::<DeviceMessage>(m),
            Ok((_, DeviceMessage::Ack { command_seq })) if command_seq == seq
        )
    })
}

/// Starts the roller at 20 mm/s with an order straight to it (no effects task needed)
/// and waits until it has taken 100 steps.
pub async fn roller_turning() {
    roller::ORDERS
        .send(roller::Order::Roller {
            command: rollfuse_core::protocol::RollerCommand::Start { speed_um_s: 20_000 },
            stops: rollfuse_fw::signals::roller_stops_requested(),
        })
        .await;
    assert!(until(Duration::from_secs(1), || STEPS.load(Relaxed) > 100).await);
}

/// Queues a tile of `width` × `height` pixels for the link, as the pipeline would.
pub fn queue_tile(index: u32, width: u16, height: u16) {
    let mut claim = outbox::try_claim().expect("a free outbox slot");
    claim.message().kind = outbox::Kind::Tile {
        index,
        width,
        height,
        observations: 1,
    };
    claim.message().len = usize::from(width) * usize::from(height);
    claim.send();
}

/// LEDs that do nothing.
pub struct NoLeds;

impl rollfuse_fw::effects::Leds for NoLeds {
    fn set(&mut self, _: rollfuse_core::protocol::LedDuty) {}
}

/// [`beside_link_and_roller`] with the effects task running too, so accepted commands
/// reach the roller and the pipeline's queue as on the board.
pub fn beside_link_roller_and_effects(test: impl Future<Output = ()>) {
    let mut leds = NoLeds;
    beside_link_and_roller(async {
        match select(test, rollfuse_fw::effects::run(&mut leds)).await {
            embassy_futures::select::Either::First(()) => {}
            embassy_futures::select::Either::Second(()) => panic!("the effects task ended"),
        }
    });
}

/// Runs `test` in virtual time beside the roller and the link (served again whenever it
/// returns, as on the board, with mock endpoints), and requires the test's body to finish
/// first: no task may end before it.
pub fn beside_link_and_roller(test: impl Future<Output = ()>) {
    outbox::init();
    let mut controller = rollfuse_fw::controller().expect("the default configuration fits");
    let (mut read, mut write) = (Out::new(), In::new());
    let mut tx = Box::new([0u8; MAX_MESSAGE]);
    let mut pins = Pins;
    let outcome = embassy_futures::block_on(select3(
        test,
        clock(),
        select(roller::run(&mut pins, 16), async {
            loop {
                link::serve(&mut read, &mut write, &mut controller, &mut tx).await;
            }
        }),
    ));
    assert!(
        matches!(outcome, Either3::First(())),
        "a task ended before the test did"
    );
}
