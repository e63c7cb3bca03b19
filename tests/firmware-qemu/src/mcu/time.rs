//! embassy-time's driver on the QEMU board, in the board's time: with `-icount shift=0`
//! QEMU runs one instruction per virtual nanosecond, and this driver counts 400
//! instructions as a microsecond, so the tasks see the time a 400 MHz STM32H743 would
//! (at one instruction a cycle).
//!
//! `now` reads the CMSDK APB timer 1 (25 MHz: 10 ticks a board microsecond) counting down
//! from `u32::MAX` without reloading, which outlasts any run (429 board seconds; the
//! timer's interrupt at 0 ends the run). A clock extended by counting SysTick's periods in
//! its interrupt went back a whole period when read as it wrapped — an alarm set from such
//! a reading came a millisecond late, and the step lateness measured the clock, not the
//! firmware. Alarms are one-shot countdowns of timer 0 (also 25 MHz), exact to the tick.

use core::cell::RefCell;
use core::task::Waker;
use critical_section::{CriticalSection, Mutex};
use embassy_time_driver::Driver as _;
use embassy_time_queue_utils::Queue;

/// Timer ticks (25 MHz) per board microsecond (400 instructions at 40 a tick).
const TICKS_PER_US: u64 = 10;
/// Instructions (board cycles) a board microsecond.
pub const CYCLES_PER_US: u64 = 400;

/// The CMSDK APB timers: 0 for alarms, 1 for the clock, and their interrupts.
const TIMER0: usize = 0x4000_0000;
const TIMER1: usize = 0x4000_1000;
/// Timer 0's interrupt number.
pub const TIMER0_IRQ: u16 = 8;
/// Timer 1's interrupt number: the clock ran out.
pub const TIMER1_IRQ: u16 = 9;
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

fn write_timer1(offset: usize, value: u32) {
    // SAFETY: a register of the board's timer 1, which only this driver uses.
    unsafe { core::ptr::write_volatile((TIMER1 + offset) as *mut u32, value) }
}

fn timer1_value() -> u32 {
    // SAFETY: timer 1's current value, read-only here.
    unsafe { core::ptr::read_volatile((TIMER1 + VALUE) as *const u32) }
}

struct Driver {
    queue: Mutex<RefCell<Queue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: Driver = Driver {
    queue: Mutex::new(RefCell::new(Queue::new())),
});

/// Starts the clock: timer 1 counting down from `u32::MAX`.
pub fn start() {
    write_timer1(CTRL, 0);
    write_timer1(RELOAD, u32::MAX);
    write_timer1(VALUE, u32::MAX);
    write_timer1(CTRL, CTRL_ENABLE | CTRL_IRQ);
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
        u64::from(u32::MAX - timer1_value()) / TICKS_PER_US
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            if self.queue.borrow_ref_mut(cs).schedule_wake(at, waker) {
                self.wake_due(cs);
            }
        })
    }
}

/// Board cycles since [`start`] (one instruction a cycle: 40 a tick of the 25 MHz timer),
/// wrapping: the cycle counter the firmware times its fusions with here, as the board's
/// DWT counter does on silicon.
pub fn cycles() -> u32 {
    (u32::MAX - timer1_value()).wrapping_mul((CYCLES_PER_US / TICKS_PER_US) as u32)
}
