//! A guard below the stack: an overflow faults instead of writing over the statics.
//!
//! The linker script (`memory.x`) puts `.stack_guard`, 16 KiB aligned to its size, between
//! the statics and the stack; one MPU region makes it inaccessible. 16 KiB is also the
//! largest stack frame CI allows (tests/firmware-stack): a function whose frame starts in
//! the stack either faults on its first push into the guard or ends above it, so no frame
//! can reach past the guard into `.bss`.

/// The guard's size; the region's SIZE field encodes it as 2^(SIZE + 1).
pub const GUARD_BYTES: u32 = 16 * 1024;

unsafe extern "C" {
    /// The guard's first byte (`memory.x`).
    static _stack_guard: u8;
}

/// Makes the guard inaccessible. Call before anything deep runs; the rest of memory keeps
/// its default attributes (PRIVDEFENA).
pub fn install(mpu: &mut cortex_m::peripheral::MPU) {
    const SIZE_FIELD: u32 = GUARD_BYTES.trailing_zeros() - 1;
    const XN: u32 = 1 << 28;
    const AP_NO_ACCESS: u32 = 0b000 << 24;
    const ENABLE: u32 = 1;
    const VALID: u32 = 1 << 4;
    const CTRL_ENABLE: u32 = 1;
    const CTRL_PRIVDEFENA: u32 = 1 << 2;
    let base = core::ptr::addr_of!(_stack_guard) as u32;
    // SAFETY: region 0 is set while the MPU is off, then the MPU is enabled with the
    // default map for everything else; the guard holds nothing.
    unsafe {
        mpu.ctrl.write(0);
        mpu.rnr.write(0);
        mpu.rbar.write((base & !(GUARD_BYTES - 1)) | VALID);
        mpu.rasr
            .write(XN | AP_NO_ACCESS | (SIZE_FIELD << 1) | ENABLE);
        mpu.ctrl.write(CTRL_ENABLE | CTRL_PRIVDEFENA);
    }
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
}
