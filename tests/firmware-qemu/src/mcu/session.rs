//! What the host does, and what the run measures: a streaming session at 26 mm/s (a
//! frame trigger about every camera frame), then a host that goes silent.

use super::{camera, time, usb};
use core::sync::atomic::{AtomicU32, Ordering::Relaxed};
use cortex_m_semihosting::hprintln;
use embassy_time::{Duration, Instant, Timer};
use rollfuse_core::protocol::{Command, LedDuty, RollerCommand};
use rollfuse_fw::counters::COUNTERS;
use rollfuse_fw::{link, roller, signals};

/// Looks of the watchdog's feeder at which some task had not come round.
pub static MISSED_BEATS: AtomicU32 = AtomicU32::new(0);

/// The belt speed: 16-pixel frame spacing at 50 µm a pixel is a trigger every 31 ms.
const SPEED_UM_S: u32 = 26_000;

/// The host tool's side of the link.
struct Host {
    seq: u32,
}

impl Host {
    async fn send(&mut self, command: Command) {
        self.seq += 1;
        usb::send(self.seq, &command).await;
    }
}

/// Runs the session and prints its measurements.
pub async fn run(steps: &AtomicU32) {
    let mut host = Host { seq: 0 };
    host.send(Command::Leds(LedDuty::ALL_ON)).await;
    host.send(Command::StreamStart).await;
    host.send(Command::Roller(RollerCommand::Start {
        speed_um_s: SPEED_UM_S,
    }))
    .await;
    // Past the ramp (0.26 s at 100 mm/s²), then two seconds of steps while frames are
    // fused, the host asking for the status every second as the tool does.
    Timer::after_millis(500).await;
    let _ = roller::take_worst_lateness();
    let (steps0, fused0) = (steps.load(Relaxed), COUNTERS.frames_fused.load(Relaxed));
    let (bytes0, window) = (usb::seen().tile_bytes, Instant::now());
    for _ in 0..2 {
        Timer::after_secs(1).await;
        host.send(Command::Status).await;
    }
    let late = roller::take_worst_lateness();
    let bytes = usb::seen().tile_bytes - bytes0;
    hprintln!(
        "usb load: {} bytes of tiles in {} ms, {} kB/s",
        bytes,
        window.elapsed().as_millis(),
        u64::from(bytes) * 1000 / window.elapsed().as_micros().max(1)
    );
    let mode = if cfg!(feature = "roller-in-thread") {
        "roller in thread mode"
    } else {
        "roller at interrupt priority"
    };
    hprintln!(
        "step lateness: max {} us over {} steps while {} frames were fused ({})",
        late.as_micros(),
        steps.load(Relaxed) - steps0,
        COUNTERS.frames_fused.load(Relaxed) - fused0,
        mode
    );

    host.send(Command::Roller(RollerCommand::Stop)).await;
    host.send(Command::StreamStop).await;
    let statuses = usb::seen().statuses;
    let ended = until(Duration::from_secs(2), || usb::seen().statuses > statuses).await;
    let seen = usb::seen();
    hprintln!(
        "session: {} frames captured, {} fused, {} triggers overrun, {} captures timed out; {} tiles emitted, {} received, {} dropped; {} commands acknowledged, {} refused, {} bad messages; final status {}",
        COUNTERS.frames_captured.load(Relaxed),
        COUNTERS.frames_fused.load(Relaxed),
        COUNTERS.camera_overruns.load(Relaxed),
        COUNTERS.camera_timeouts.load(Relaxed),
        COUNTERS.tiles_emitted.load(Relaxed),
        seen.tiles,
        COUNTERS.tiles_dropped.load(Relaxed),
        seen.acks,
        seen.naks,
        seen.bad,
        if ended { "received" } else { "MISSING" }
    );
    hprintln!(
        "capture re-arming: at most {} us after the last capture's frame ended (VSYNC {} us after it); {} re-armed after VSYNC",
        camera::LATEST_REARM_US.load(Relaxed),
        camera::vsync_after_frame_us(),
        camera::REARMED_LATE.load(Relaxed)
    );
    // What the device reports of its fusions' cost (here instructions, one a cycle).
    let (mean, worst) = seen
        .status
        .map_or((0, 0), |s| (s.fusion_cycles_mean, s.fusion_cycles_worst));
    hprintln!(
        "fusion cycles in the status: mean {} worst {} ({} us and {} us at 400 MHz)",
        mean,
        worst,
        u64::from(mean) / time::CYCLES_PER_US,
        u64::from(worst) / time::CYCLES_PER_US
    );

    stop_while_sending(&mut host).await;
    host_goes_silent(&mut host, steps).await;
    new_host_says_hello(&mut host).await;
    hprintln!(
        "watchdog: {} looks found a task late",
        MISSED_BEATS.load(Relaxed)
    );
}

/// The roller turning and tiles streaming, the host stops reading and then sends a Stop:
/// how soon the roller is told, with the link's send stuck on the host.
async fn stop_while_sending(host: &mut Host) {
    host.send(Command::StreamStart).await;
    host.send(Command::Roller(RollerCommand::Start {
        speed_um_s: SPEED_UM_S,
    }))
    .await;
    Timer::after_millis(500).await;
    usb::HOST_READS.store(false, Relaxed);
    // Past a frame's time: a tile is in flight, stuck.
    Timer::after_millis(100).await;
    let stops = signals::roller_stops_requested();
    let sent_at = Instant::now();
    host.send(Command::Roller(RollerCommand::Stop)).await;
    // Looked at every 100 us: the bound checked is 10 ms.
    while signals::roller_stops_requested() == stops
        && sent_at.elapsed() < Duration::from_millis(500)
    {
        Timer::after_micros(100).await;
    }
    let (acted, took) = (
        signals::roller_stops_requested() != stops,
        sent_at.elapsed(),
    );
    usb::HOST_READS.store(true, Relaxed);
    host.send(Command::StreamStop).await;
    Timer::after_millis(500).await;
    hprintln!(
        "stop while sending: {} {} us after the Stop was sent, the link's send stuck on a host that reads nothing",
        if acted {
            "roller told to stop"
        } else {
            "roller NOT TOLD TO STOP"
        },
        took.as_micros()
    );
}

/// The roller turning and tiles streaming, the host stops reading, then says nothing
/// more: how long after its last command the last step came.
async fn host_goes_silent(host: &mut Host, steps: &AtomicU32) {
    host.send(Command::StreamStart).await;
    host.send(Command::Roller(RollerCommand::Start {
        speed_um_s: SPEED_UM_S,
    }))
    .await;
    let last_command = Instant::now();
    Timer::after_millis(500).await;
    usb::HOST_READS.store(false, Relaxed);
    let mut last = steps.load(Relaxed);
    let mut last_step = Instant::now();
    let still = Duration::from_millis(500);
    while last_step.duration_since(last_command) < Duration::from_secs(8)
        && Instant::now().duration_since(last_step) < still
    {
        Timer::after_millis(10).await;
        let now = steps.load(Relaxed);
        if now != last {
            last = now;
            last_step = Instant::now();
        }
    }
    let stopped = Instant::now().duration_since(last_step) >= still;
    hprintln!(
        "host gone: {} {} ms after its last command (heartbeat {} ms; it stopped reading after 500 ms)",
        if stopped {
            "roller stopped"
        } else {
            "roller STILL TURNING"
        },
        last_step.duration_since(last_command).as_millis(),
        link::HEARTBEAT.as_millis()
    );
}

/// The silent host was killed mid-message; a new host process opens the device without a
/// bus reset and says Hello: whether the answer comes alone, on the first try.
async fn new_host_says_hello(host: &mut Host) {
    usb::new_host();
    let before = usb::seen();
    host.send(Command::Hello).await;
    let answered = until(Duration::from_millis(500), || {
        let now = usb::seen();
        now.infos > before.infos || now.bad > before.bad
    })
    .await;
    let now = usb::seen();
    hprintln!(
        "reconnect: a new host's first Hello {}",
        if now.infos > before.infos && now.bad == before.bad {
            "answered on the first try (an Info alone)"
        } else if answered {
            "FAILED: its first message did not decode"
        } else {
            "FAILED: not answered"
        }
    );
}

/// Waits until `cond` holds, at most `limit`; whether it held.
async fn until(limit: Duration, cond: impl Fn() -> bool) -> bool {
    let end = Instant::now() + limit;
    while Instant::now() < end {
        if cond() {
            return true;
        }
        Timer::after_millis(5).await;
    }
    cond()
}
