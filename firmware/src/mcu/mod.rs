//! The firmware proper (only built for the MCU).

mod bus;
mod camera;
mod frame_sync;
mod irqs;
mod leds;
mod selftest;

use defmt::{error, info, warn};
use embassy_executor::{InterruptExecutor, Spawner};
use embassy_futures::join::join5;
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{Config, Peri, interrupt, peripherals};
use embassy_time::{Instant, Timer};
use rollfuse_core::protocol::DeviceConfig;
use rollfuse_fw::buffers::{self, TX};
use rollfuse_fw::pipeline;
use rollfuse_fw::roller::{self, StepPins};
use rollfuse_fw::{cycles, effects, link, liveness, outbox, stack_guard};
use {defmt_rtt as _, panic_probe as _};

/// The executor of the roller's step generator, at interrupt priority: fusion in thread
/// mode never delays a step. Its interrupt is one no peripheral here uses.
static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();

#[interrupt]
unsafe fn UART4() {
    // SAFETY: the executor is started on this interrupt in `main`, before it is enabled.
    unsafe { EXECUTOR_HIGH.on_interrupt() }
}

/// The stepper driver on its pins: DIR PF12 (fixed forward), STEP PF13, ENABLE PF14
/// (low = on; the driver starts off).
struct Stepper {
    _dir: Output<'static>,
    step: Output<'static>,
    enable: Output<'static>,
}

impl Stepper {
    fn new(
        dir: Peri<'static, peripherals::PF12>,
        step: Peri<'static, peripherals::PF13>,
        enable: Peri<'static, peripherals::PF14>,
    ) -> Self {
        Self {
            _dir: Output::new(dir, Level::Low, Speed::Low),
            step: Output::new(step, Level::Low, Speed::High),
            enable: Output::new(enable, Level::High, Speed::Low),
        }
    }
}

impl StepPins for Stepper {
    fn step(&mut self, high: bool) {
        self.step.set_level(Level::from(high));
    }

    fn enable(&mut self, on: bool) {
        // The driver's ENABLE input is active low.
        self.enable.set_level(Level::from(!on));
    }
}

/// The roller's task, on the interrupt-priority executor.
#[embassy_executor::task]
async fn roller_task(mut pins: Stepper, spacing_px: u16) {
    roller::run(&mut pins, spacing_px).await
}

/// 400 MHz from the PLL on HSI (480 MHz needs voltage scale 0, which only revision V
/// silicon has; 400 MHz runs on every H743), HSI48 for USB.
fn clocks() -> Config {
    use embassy_stm32::rcc::*;
    let mut config = embassy_stm32::Config::default();
    config.rcc.hsi = Some(HSIPrescaler::DIV1); // 64 MHz
    config.rcc.csi = true;
    // USB's 48 MHz, trimmed to the host's start-of-frame packets (no crystal needed).
    config.rcc.hsi48 = Some(Hsi48Config {
        sync_from_usb: true,
    });
    config.rcc.pll1 = Some(Pll {
        source: PllSource::HSI,
        prediv: PllPreDiv::DIV4, // 64 MHz / 4 = 16 MHz
        mul: PllMul::MUL50,      // 16 MHz × 50 = 800 MHz VCO
        fracn: None,
        divp: Some(PllDiv::DIV2), // 800 / 2 = 400 MHz: the core
        divq: Some(PllDiv::DIV8), // 800 / 8 = 100 MHz
        divr: None,
    });
    config.rcc.sys = Sysclk::PLL1_P; // 400 MHz
    config.rcc.ahb_pre = AHBPrescaler::DIV2; // 200 MHz: AXI, AHB (the DCMI, the DMA)
    config.rcc.apb1_pre = APBPrescaler::DIV2; // 100 MHz: I2C1, TIM2 (time), TIM4 (LEDs)
    config.rcc.apb2_pre = APBPrescaler::DIV2; // 100 MHz
    config.rcc.apb3_pre = APBPrescaler::DIV2; // 100 MHz
    config.rcc.apb4_pre = APBPrescaler::DIV2; // 100 MHz: IWDG's bus
    config.rcc.voltage_scale = VoltageScale::Scale1; // enough for 400 MHz
    config.rcc.mux.usbsel = mux::Usbsel::HSI48;
    config
}

/// ES0392's AXI SRAM erratum on revision Y chips (REV_ID below 0x2000): a read that
/// follows an interrupted write may return corrupt data. The workaround, as ST's own
/// start-up code applies it: the AXI switch's read issuing capability for the AXI SRAM
/// (target 7) down to 1, READ_ISS_OVERRIDE in AXI_TARG7_FN_MOD.
fn axi_sram_read_erratum() {
    /// AXI_TARG7_FN_MOD in the AXI interconnect's GPV (RM0433).
    const AXI_TARG7_FN_MOD: *mut u32 = 0x5100_8108 as *mut u32;
    const READ_ISS_OVERRIDE: u32 = 1;
    if embassy_stm32::pac::DBGMCU.idc().read().rev_id() < 0x2000 {
        // SAFETY: a documented register of the AXI interconnect, written once at start-up
        // before anything else touches the bus matrix's configuration.
        unsafe { AXI_TARG7_FN_MOD.write_volatile(READ_ISS_OVERRIDE) };
    }
}

#[embassy_executor::main]
async fn main(_spawner: Spawner) {
    axi_sram_read_erratum();
    let p = embassy_stm32::init(clocks());
    // D2 SRAM1–3 (the camera's frame) clocked for the CPU, then the DTCM and D2 sections
    // given the zeros their statics were built with (firmware/src/buffers.rs).
    embassy_stm32::pac::RCC.ahb2enr().modify(|w| {
        w.set_sram1en(true);
        w.set_sram2en(true);
        w.set_sram3en(true);
    });
    // SAFETY: first thing after the clocks; nothing has taken a placed static yet.
    unsafe { buffers::zero_placed() };
    // The stepper's pins before anything slow (the camera's bus can take a second to time
    // out): a driver whose ENABLE is pulled down would otherwise power up with STEP floating.
    let stepper = Stepper::new(p.PF12, p.PF13, p.PF14);
    info!(
        "rollfuse-fw {}, serial {}, reset by {}",
        env!("CARGO_PKG_VERSION"),
        embassy_stm32::uid::uid_hex(),
        reset_cause()
    );
    freeze_watchdog_on_debug_halt();
    set_up_core();
    self_test();
    let Some(mut controller) = rollfuse_fw::controller() else {
        // The default configuration fits the sensor (a host test checks it); if not,
        // there is nothing to serve.
        error!("default configuration refused");
        return;
    };
    let initial = controller.pipeline_config();
    let (mut device, mut read_ep, mut write_ep) = bus::start(p.USB_OTG_FS, p.PA12, p.PA11);
    outbox::init();
    let mut leds = leds::Leds::new(p.TIM4, p.PD12, p.PD13, p.PD14);
    let mut camera = camera::start(camera::Wiring {
        mco: p.MCO1,
        xclk: p.PA8,
        i2c: p.I2C1,
        scl: p.PB8,
        sda: p.PB9,
        i2c_tx_dma: p.DMA1_CH1,
        i2c_rx_dma: p.DMA1_CH2,
        dcmi: p.DCMI,
        dma: p.DMA1_CH0,
        // D3 on PC9 and VSYNC on PG9: PE1 and PB7 drive user LEDs on the NUCLEO-H743ZI
        // boards (firmware/README.md, pin map).
        data: camera::DataPins {
            d0: p.PC6,
            d1: p.PC7,
            d2: p.PE0,
            d3: p.PC9,
            d4: p.PE4,
            d5: p.PD3,
            d6: p.PE5,
            d7: p.PE6,
        },
        vsync: p.PG9,
        hsync: p.PA4,
        pixclk: p.PA6,
    })
    .await;
    start_roller(stepper);

    let tx = TX.take();
    let serve = async {
        loop {
            link::serve(&mut read_ep, &mut write_ep, &mut controller, tx).await;
        }
    };
    let frames = pipeline::run(&mut camera, buffers::frames(), buffers::pipeline(), initial);
    let effects = effects::run(&mut leds);
    let alive = feed_watchdog(p.IWDG1, p.PB0);
    join5(device.run(), serve, effects, alive, frames).await;
}

/// Why the chip last reset (RCC_RSR), the flags then cleared so the next boot reads its
/// own. A watchdog or software reset also sets the pin flag, a power-on also the
/// brown-out and pin flags: the most specific flag is named.
fn reset_cause() -> &'static str {
    let rcc = embassy_stm32::pac::RCC;
    let rsr = rcc.rsr().read();
    let flags = [
        (
            rsr.iwdg1rstf(),
            "the watchdog (a task stopped coming round)",
        ),
        (rsr.wwdg1rstf(), "the window watchdog"),
        (rsr.lpwrrstf(), "a low-power error"),
        (rsr.sftrstf(), "software"),
        (rsr.porrstf(), "power-on"),
        (rsr.borrstf(), "brown-out"),
        (rsr.pinrstf(), "the reset pin"),
    ];
    let cause = flags
        .iter()
        .find(|(set, _)| *set)
        .map_or("an unknown cause", |(_, cause)| cause);
    rcc.rsr().modify(|w| w.set_rmvf(true));
    cause
}

/// The watchdog stops while a debugger halts the core (DBGMCU_APB4FZ1.DBG_IWDG1), so a
/// breakpoint does not reset the board; without a debugger the bit changes nothing.
fn freeze_watchdog_on_debug_halt() {
    embassy_stm32::pac::DBGMCU
        .apb4fzr1()
        .modify(|w| w.set_iwdg1(true));
}

/// The stack guard before anything deep runs; instructions from flash through the
/// I-cache; the DWT's cycle counter timing each fusion for `Status`. The D-cache stays
/// off: the DCMI's DMA writes frames to D2 SRAM that the CPU then reads, and without cache
/// maintenance a cached CPU would see stale lines.
fn set_up_core() {
    use cortex_m::peripheral::DWT;
    if let Some(mut core) = cortex_m::Peripherals::take() {
        stack_guard::install(&mut core.MPU);
        core.SCB.enable_icache();
        core.DCB.enable_trace();
        // The Cortex-M7's DWT ignores writes until its software lock is removed.
        DWT::unlock();
        core.DWT.enable_cycle_counter();
        cycles::count_with(DWT::cycle_count);
    }
}

/// Fuses a known edge once and logs what it kept and how long it took.
fn self_test() {
    let t0 = Instant::now();
    match selftest::run() {
        Ok(step) => info!(
            "fusion self-test: edge step {} of 160 kept, {} us",
            step,
            t0.elapsed().as_micros()
        ),
        Err(_) => error!("fusion self-test failed"),
    }
}

/// The watchdog restarts the firmware 1 s after a task stopped coming round its loop
/// (`liveness`); the board LED (LD1) blinks while every task does.
async fn feed_watchdog(
    iwdg: Peri<'static, peripherals::IWDG1>,
    led: Peri<'static, peripherals::PB0>,
) {
    let mut watchdog = IndependentWatchdog::new(iwdg, 1_000_000);
    watchdog.unleash();
    let mut led = Output::new(led, Level::High, Speed::Low);
    let mut seen = [0; 4];
    loop {
        Timer::after_millis(400).await;
        if liveness::all_alive(&mut seen) {
            watchdog.pet();
            led.toggle();
        } else {
            warn!("a task is late: the watchdog is not fed");
        }
    }
}

/// Starts the roller's task on the interrupt-priority executor (UART4's interrupt, a
/// priority above thread mode's fusion).
fn start_roller(stepper: Stepper) {
    interrupt::UART4.set_priority(Priority::P6);
    let high = EXECUTOR_HIGH.start(interrupt::UART4);
    match roller_task(stepper, DeviceConfig::default().frame_spacing_px) {
        Ok(task) => high.spawn(task),
        Err(_) => error!("the roller's task could not start"),
    }
}
