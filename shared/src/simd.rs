//! Run-time choice of the vector unit for the hot loops on x86-64 hosts.
//!
//! The kernels are plain Rust loops that the compiler vectorizes. Built for the x86-64
//! baseline they get 4-lane SSE2; the same loops compiled for AVX2 get 8 lanes and for
//! AVX-512 16, and a distributed binary can assume neither. So each hot kernel is defined
//! through [`kernel!`](crate::simd::kernel), which compiles its body three times — for the
//! baseline, with `#[target_feature(enable = "avx2")]` and with the AVX-512 features of
//! the `x86-64-v4` level — and per call runs the widest copy the CPU has. All copies run
//! the same operations in the same order (Rust never fuses a multiply and an add on its
//! own, and no kernel reorders a sum), so the results are the same to the bit;
//! `shared/tests/simd_dispatch.rs` checks it on whole fuse steps.
//!
//! This is the core's only `unsafe`: calling a wider copy, which is sound only where
//! [`avx2`] or [`avx512`] said yes. On other targets (the firmware's Cortex-M7 among them)
//! the macro emits the plain function and the crate forbids `unsafe` outright.

#[cfg(target_arch = "x86_64")]
use core::sync::atomic::{AtomicU8, Ordering::Relaxed};

#[cfg(target_arch = "x86_64")]
cpufeatures::new!(cpu_avx2, "avx2");
// The AVX-512 subsets of the `x86-64-v4` level, which the kernels' wide copies enable.
#[cfg(target_arch = "x86_64")]
cpufeatures::new!(
    cpu_avx512, "avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl"
);

/// A vector unit the kernels can run on, narrowest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum VectorUnit {
    /// The target's baseline: SSE2 on x86-64, scalar code elsewhere.
    Baseline,
    /// AVX2: 8 lanes of `f32` (x86-64 only).
    Avx2,
    /// AVX-512 (F, BW, CD, DQ, VL): 16 lanes of `f32` (x86-64 only).
    Avx512,
}

/// The widest unit the kernels may use, as a [`VectorUnit`] discriminant: the widest
/// unless [`set_vector_limit`] narrowed it.
#[cfg(target_arch = "x86_64")]
static LIMIT: AtomicU8 = AtomicU8::new(VectorUnit::Avx512 as u8);

/// Whether the kernels run their AVX2 copies (where they do not run the AVX-512 ones):
/// the CPU (and its OS) supports AVX2, and [`set_vector_limit`] allows it.
#[inline(always)]
pub fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        LIMIT.load(Relaxed) >= VectorUnit::Avx2 as u8 && cpu_avx2::get()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether the kernels run their AVX-512 copies: the CPU (and its OS, for the 512-bit
/// registers) supports the `x86-64-v4` AVX-512 subsets, and [`set_vector_limit`] allows it.
#[inline(always)]
pub fn avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        LIMIT.load(Relaxed) >= VectorUnit::Avx512 as u8 && cpu_avx512::get()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The unit the kernels run on now: the widest the CPU has within the limit.
pub fn vector_unit() -> VectorUnit {
    if avx512() {
        VectorUnit::Avx512
    } else if avx2() {
        VectorUnit::Avx2
    } else {
        VectorUnit::Baseline
    }
}

/// Lets the kernels use units up to `limit` where the CPU has them ([`VectorUnit::Avx512`],
/// the widest, is the default): for measuring what each wider unit buys, and for tests
/// that all copies agree. Results do not depend on it. No effect off x86-64.
pub fn set_vector_limit(limit: VectorUnit) {
    #[cfg(target_arch = "x86_64")]
    LIMIT.store(limit as u8, Relaxed);
    #[cfg(not(target_arch = "x86_64"))]
    let _ = limit;
}

/// Defines a free function whose body is compiled three times on x86-64: as written, and
/// in nested `#[target_feature]` functions for AVX2 and for AVX-512 that the outer one
/// calls when [`avx512`] or [`avx2`] says so. Anything the body should vectorize with them
/// must be inlined into it (`#[inline(always)]`): target features reach only inlined code.
/// Parameters are plain identifiers (they are passed on); generic parameters take one
/// bound each. On other targets this is the function as written.
macro_rules! kernel {
    (
        $(#[$attr:meta])*
        $vis:vis fn $name:ident $(< $($g:ident : $bound:path),+ $(,)? >)?
            ( $($arg:ident : $ty:ty),* $(,)? ) $(-> $ret:ty)?
        $body:block
    ) => {
        $(#[$attr])*
        $vis fn $name $(< $($g : $bound),+ >)? ( $($arg : $ty),* ) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            if $crate::simd::avx512() {
                #[target_feature(enable = "avx512f,avx512bw,avx512cd,avx512dq,avx512vl")]
                fn avx512 $(< $($g : $bound),+ >)? ( $($arg : $ty),* ) $(-> $ret)? $body
                // SAFETY: `avx512()` is true only where CPUID reports these subsets and the
                // OS saves the 512-bit and mask registers (`cpufeatures` checks both).
                #[allow(unsafe_code)]
                let done = unsafe { avx512($($arg),*) };
                return done;
            }
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
