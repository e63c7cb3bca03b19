//! The stack's high-water mark: cortex-m-rt painted it (`paint-stack`) before `main`; the
//! lowest word no longer holding the paint is as deep as it went.

use cortex_m_semihosting::hprintln;

unsafe extern "C" {
    static _stack_start: u32;
    static _stack_end: u32;
    static _stack_guard: u32;
}

/// cortex-m-rt's paint.
const PAINT: u32 = 0xCCCC_CCCC;

/// Prints `stack high-water: N bytes of M`.
pub fn report() {
    let top = core::ptr::addr_of!(_stack_start) as usize;
    let bottom = core::ptr::addr_of!(_stack_end) as usize;
    let mut deepest = top;
    let mut at = bottom;
    while at < top {
        // SAFETY: inside the stack region the linker left; read only.
        if unsafe { core::ptr::read_volatile(at as *const u32) } != PAINT {
            deepest = at;
            break;
        }
        at += 4;
    }
    hprintln!(
        "stack high-water: {} bytes of {}",
        top - deepest,
        top - bottom
    );
}

/// Reads the stack guard's first word, which must fault.
pub fn touch_guard() {
    // SAFETY: a read; the MPU makes it fault.
    let word = unsafe { core::ptr::read_volatile(core::ptr::addr_of!(_stack_guard)) };
    hprintln!(
        "the stack guard was readable ({:#x}): the MPU region is not in force",
        word
    );
}
