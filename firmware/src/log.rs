//! Log lines: defmt on the MCU; on the host (tests) the arguments are evaluated and
//! dropped.

/// An informational line.
#[macro_export]
macro_rules! fw_info {
    ($fmt:literal $(, $arg:expr)* $(,)?) => {{
        #[cfg(target_os = "none")]
        defmt::info!($fmt $(, $arg)*);
        #[cfg(not(target_os = "none"))]
        { $( let _ = &$arg; )* }
    }};
}

/// A warning.
#[macro_export]
macro_rules! fw_warn {
    ($fmt:literal $(, $arg:expr)* $(,)?) => {{
        #[cfg(target_os = "none")]
        defmt::warn!($fmt $(, $arg)*);
        #[cfg(not(target_os = "none"))]
        { $( let _ = &$arg; )* }
    }};
}
