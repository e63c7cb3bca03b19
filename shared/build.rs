//! Says whether the target has the Arm DSP extension (`cfg(rollfuse_dsp)`): then
//! [`lanes`](src/lanes.rs) runs each operation as its one instruction. Stable Rust does
//! not expose Arm target features to `cfg`, so the target's name decides: the Cortex-M4
//! and M7 (`thumbv7em`) and the Armv8-M Mainline cores (`thumbv8m.main`) have it.
fn main() {
    println!("cargo::rustc-check-cfg=cfg(rollfuse_dsp)");
    println!("cargo::rerun-if-changed=build.rs");
    let target = std::env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumbv7em") || target.starts_with("thumbv8m.main") {
        println!("cargo::rustc-cfg=rollfuse_dsp");
    }
}
