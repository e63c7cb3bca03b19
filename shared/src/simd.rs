//! Run-time choice of the vector unit for the hot loops on x86-64 hosts.
//!
//! The kernels are plain Rust loops that the compiler vectorizes. Built for the x86-64
//! baseline they get 4-lane SSE2; the same loops compiled for AVX2 get 8 lanes, and a
//! distributed binary cannot assume AVX2. So each hot kernel is defined through
//! [`kernel!`](crate::simd::kernel), which compiles its body twice — for the baseline and
//! with `#[target_feature(enable = "avx2")]` — and picks the AVX2 copy per call when the
//! CPU has it. Both copies run the same operations in the same order (Rust never fuses a
//! multiply and an add on its own, and no kernel reorders a sum), so the results are the
//! same to the bit; `shared/tests/simd_dispatch.rs` checks it on whole fuse steps.
//!
//! This is the core's only `unsafe`: calling the AVX2 copy, which is sound only where
//! [`avx2`] said yes. On other targets (the firmware's Cortex-M7 among them) the macro
//! emits the plain function and the crate forbids `unsafe` outright.

#[cfg(target_arch = "x86_64")]
use core::sync::atomic::{AtomicBool, Ordering::Relaxed};

#[cfg(target_arch = "x86_64")]
cpufeatures::new!(cpu_avx2, "avx2");

/// Whether [`avx2`] may say yes: on unless [`set_vector_dispatch`] turned it off.
#[cfg(target_arch = "x86_64")]
static ALLOWED: AtomicBool = AtomicBool::new(true);

/// Whether the kernels run their AVX2 copies: the CPU (and its OS) supports AVX2, and
/// [`set_vector_dispatch`] has not turned them off.
#[inline(always)]
pub fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        ALLOWED.load(Relaxed) && cpu_avx2::get()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Lets the kernels use AVX2 where the CPU has it (`true`, the default), or keeps them on
/// the baseline copies (`false`): for measuring what the wider unit buys, and for tests
/// that both copies agree. Results do not depend on it. No effect off x86-64.
pub fn set_vector_dispatch(enabled: bool) {
    #[cfg(target_arch = "x86_64")]
    ALLOWED.store(enabled, Relaxed);
    #[cfg(not(target_arch = "x86_64"))]
    let _ = enabled;
}

/// Defines a free function whose body is compiled twice on x86-64: as written, and in a
/// nested `#[target_feature(enable = "avx2")]` function that the outer one calls when
/// [`avx2`] says so. Anything the body should vectorize with it must be inlined into it
/// (`#[inline(always)]`): target features reach only inlined code. Parameters are plain
/// identifiers (they are passed on); generic parameters take one bound each. On other
/// targets this is the function as written.
macro_rules! kernel {
    (
        $(#[$attr:meta])*
        $vis:vis fn $name:ident $(< $($g:ident : $bound:path),+ >)?
            ( $($arg:ident : $ty:ty),* $(,)? ) $(-> $ret:ty)?
        $body:block
    ) => {
        $(#[$attr])*
        $vis fn $name $(< $($g : $bound),+ >)? ( $($arg : $ty),* ) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            if $crate::simd::avx2() {
                #[target_feature(enable = "avx2")]
                fn avx2 $(< $($g : $bound),+ >)? ( $($arg : $ty),* ) $(-> $ret)? $body
                // SAFETY: `avx2()` is true only where CPUID reports AVX2 and the OS saves
                // the AVX registers (`cpufeatures` checks both).
                #[allow(unsafe_code)]
                let done = unsafe { avx2($($arg),*) };
                return done;
            }
            $body
        }
    };
}

pub(crate) use kernel;
