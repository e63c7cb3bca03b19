//! embassy-time's driver on the QEMU board, in the board's time: with `-icount shift=0`
//! QEMU runs one instruction per virtual nanosecond, and this driver counts 400
//! instructions as a microsecond, so the tasks see the time a 400 MHz STM32H743 would
//! (at one instruction a cycle).
//!
//! `now` counts SysTick (25 MHz: 10 ticks a board microsecond) wrapping every
//! millisecond; alarms are one-shot countdowns of the CMSDK APB timer 0 (also 25 MHz),
//! exact to the tick rather than rounded to SysTick's period.

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering::Relaxed};
use core::task::Waker;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{SCB, SYST};
use critical_section::{CriticalSection, Mutex};
use embassy_time_driver::Driver as _;
use embassy_time_queue_utils::Queue;

/// Timer ticks (25 MHz) per board microsecond (400 instructions at 40 a tick).
const TICKS_PER_US: u64 = 10;

/// SysTick wraps once a board millisecond.
const PERIOD_US: u64 = 1000;

/// The CMSDK APB timer 0 and its interrupt.
const TIMER0: usize = 0x4000_0000;
/// Timer 0's interrupt number.
pub const TIMER0_IRQ: u16 = 8;
const CTRL: usize = 0x00;
const VALUE: usize = 0x04;
const RELOAD: usize = 0x08;
const INTCLEAR: usize = 0x0C;
const CTRL_ENABLE: u32 = 1;
const CTRL_IRQ: u32 = 1 << 3;

fn timer0(offset: usize, value: u32) {
    // SAFETY: a register of the board's timer 0, which only this driver uses.
    unsafe { core::ptr::write_volatile((TIMER0 + offset) as *mut u32, value) }
}

static PERIODS: AtomicU32 = AtomicU32::new(0);

struct Driver {
    queue: Mutex<RefCell<Queue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: Driver = Driver {
    queue: Mutex::new(RefCell::new(Queue::new())),
});

/// Starts the clock: SysTick from the core clock, its interrupt every board millisecond.
pub fn start(mut syst: SYST) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload((PERIOD_US * TICKS_PER_US - 1) as u32);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// SysTick: a millisecond went by.
pub fn on_systick() {
    PERIODS.fetch_add(1, Relaxed);
}

/// Timer 0: an alarm is due.
pub fn on_timer0() {
    timer0(INTCLEAR, 1);
    timer0(CTRL, 0);
    critical_section::with(|cs| DRIVER.wake_due(cs));
}

impl Driver {
    /// Wakes what is due and sets the alarm for what comes next.
    fn wake_due(&self, cs: CriticalSection<'_>) {
        let mut queue = self.queue.borrow_ref_mut(cs);
        let mut next = queue.next_expiration(self.now());
        while !Self::set_alarm(next, self.now()) {
            next = queue.next_expiration(self.now());
        }
    }

    /// Sets timer 0 to fire at `at`; `false` if that has passed already.
    fn set_alarm(at: u64, now: u64) -> bool {
        timer0(CTRL, 0);
        if at == u64::MAX {
            return true;
        }
        if at <= now {
            return false;
        }
        let ticks = ((at - now) * TICKS_PER_US).min(u64::from(u32::MAX)) as u32;
        timer0(RELOAD, ticks);
        timer0(VALUE, ticks);
        timer0(CTRL, CTRL_ENABLE | CTRL_IRQ);
        true
    }
}

impl embassy_time_driver::Driver for Driver {
    fn now(&self) -> u64 {
        critical_section::with(|_| {
            let mut periods = u64::from(PERIODS.load(Relaxed));
            let mut current = SYST::get_current();
            // The interrupt is pending from the tick that reached 0 (interrupts are masked
            // here): read again; past 0 the counter has reloaded and the period ended, at
            // 0 it is the period's last tick.
            if SCB::is_pendst_pending() {
                current = SYST::get_current();
                if current != 0 {
                    periods += 1;
                }
            }
            let reload = PERIOD_US * TICKS_PER_US - 1;
            periods * PERIOD_US + (reload - u64::from(current)) / TICKS_PER_US
        })
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            if self.queue.borrow_ref_mut(cs).schedule_wake(at, waker) {
                self.wake_due(cs);
            }
        })
    }
}
