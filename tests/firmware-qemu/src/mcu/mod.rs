//! The run: the firmware's statics and tasks as `firmware/src/mcu/mod.rs` wires them,
//! with this board's time driver and mock peripherals, then a report.

mod camera;
mod session;
mod stack;
mod time;
mod usb;

use core::sync::atomic::{AtomicU32, Ordering::Relaxed};
use cortex_m::peripheral::NVIC;
use cortex_m_rt::{ExceptionFrame, exception};
use cortex_m_semihosting::{debug, hprintln};
use embassy_executor::{InterruptExecutor, Spawner};
use embassy_futures::join::join5;
use embassy_futures::select::select;
use embassy_time::Timer;
use rollfuse_core::protocol::{DeviceConfig, LedDuty};
use rollfuse_fw::buffers::{self, TX};
use rollfuse_fw::effects::{self, Leds};
use rollfuse_fw::roller::{self, StepPins};
use rollfuse_fw::{link, liveness, outbox, pipeline, stack_guard};

/// The interrupt the roller's executor runs on (unused by the board's peripherals).
const ROLLER_IRQ: u16 = 30;

/// An interrupt number for the NVIC.
#[derive(Clone, Copy)]
struct Irq(u16);

// SAFETY: the numbers are the board's interrupt lines.
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        self.0
    }
}

static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();

#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    match irqn as u16 {
        time::TIMER0_IRQ => time::on_timer0(),
        time::TIMER1_IRQ => fail("the board clock ran out"),
        // SAFETY: the executor was started on this interrupt before it was enabled.
        ROLLER_IRQ => unsafe { EXECUTOR_HIGH.on_interrupt() },
        _ => fail("unexpected interrupt"),
    }
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    hprintln!(
        "hard fault at pc {:#010x} (a stack overflow into the guard faults here)",
        frame.pc()
    );
    exit(debug::EXIT_FAILURE)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    exit(debug::EXIT_FAILURE)
}

/// Ends QEMU with `code`.
fn exit(code: debug::ExitStatus) -> ! {
    debug::exit(code);
    loop {
        cortex_m::asm::wfi();
    }
}

fn fail(why: &str) -> ! {
    hprintln!("firmware-qemu: {}", why);
    exit(debug::EXIT_FAILURE)
}

/// The firmware's logs are not read here.
#[defmt::global_logger]
struct NoLog;

// SAFETY: nothing is written anywhere.
unsafe impl defmt::Logger for NoLog {
    fn acquire() {}
    unsafe fn flush() {}
    unsafe fn release() {}
    unsafe fn write(_: &[u8]) {}
}

defmt::timestamp!("{=u64:us}", embassy_time::Instant::now().as_micros());

/// Steps taken, as the stepper driver saw them.
static STEPS_SEEN: AtomicU32 = AtomicU32::new(0);

/// The stepper's pins.
struct Pins;

impl StepPins for Pins {
    fn step(&mut self, high: bool) {
        if high {
            STEPS_SEEN.fetch_add(1, Relaxed);
        }
    }
    fn enable(&mut self, _: bool) {}
}

/// The LEDs.
struct MockLeds;

impl Leds for MockLeds {
    fn set(&mut self, _: LedDuty) {}
}

#[embassy_executor::task]
async fn roller_task(mut pins: Pins, spacing_px: u16) {
    roller::run(&mut pins, spacing_px).await
}

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    // SAFETY: first thing; nothing has taken a placed static yet.
    unsafe { buffers::zero_placed() };
    let Some(mut core) = cortex_m::Peripherals::take() else {
        fail("core peripherals taken");
    };
    stack_guard::install(&mut core.MPU);
    if cfg!(feature = "touch-guard") {
        stack::touch_guard();
    }
    time::start();
    rollfuse_fw::cycles::count_with(time::cycles);
    // SAFETY: priorities set before the interrupts are first raised; the alarm's above the
    // roller's executor, as the board's timer is.
    unsafe {
        core.NVIC.set_priority(Irq(time::TIMER0_IRQ), 0x40);
        core.NVIC.set_priority(Irq(ROLLER_IRQ), 0x60);
        NVIC::unmask(Irq(time::TIMER0_IRQ));
        NVIC::unmask(Irq(time::TIMER1_IRQ));
    }
    let Some(mut controller) = rollfuse_fw::controller() else {
        fail("default configuration refused");
    };
    let initial = controller.pipeline_config();
    outbox::init();
    let tx = TX.take();
    let (mut read_ep, mut write_ep) = (usb::Out::new(), usb::In::new());
    let serve = async {
        loop {
            link::serve(&mut read_ep, &mut write_ep, &mut controller, tx).await;
        }
    };
    let mut camera = camera::Sensor;
    let frames = pipeline::run(&mut camera, buffers::frames(), buffers::pipeline(), initial);
    let mut leds = MockLeds;
    let effects = effects::run(&mut leds);

    let spacing = DeviceConfig::default().frame_spacing_px;
    let Ok(task) = roller_task(Pins, spacing) else {
        fail("the roller's task could not start");
    };
    if cfg!(feature = "roller-in-thread") {
        spawner.spawn(task);
    } else {
        EXECUTOR_HIGH.start(Irq(ROLLER_IRQ)).spawn(task);
    }

    // The watchdog's feeder, counting the looks at which a task had not come round.
    let alive = async {
        let mut seen = [0; 4];
        loop {
            Timer::after_millis(400).await;
            if !liveness::all_alive(&mut seen) {
                session::MISSED_BEATS.fetch_add(1, Relaxed);
            }
        }
    };
    let tasks = join5(serve, frames, effects, alive, async {});
    select(tasks, async {
        session::run(&STEPS_SEEN).await;
        stack::report();
        exit(debug::EXIT_SUCCESS);
    })
    .await;
    fail("a task ended");
}
