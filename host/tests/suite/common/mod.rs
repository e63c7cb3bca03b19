//! Helpers shared by the command-line tests.

pub mod docs;
pub mod strip_score;

use std::process::{Command, Output};

/// Runs the `rollfuse` binary with `args`.
pub fn rollfuse(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rollfuse"))
        .args(args)
        .output()
        .expect("run rollfuse")
}

/// Runs `rollfuse args` and checks it fails with one line on stderr that contains `says`
/// and no panic.
pub fn fails(args: &[&str], says: &str) {
    let out = rollfuse(args);
    assert!(!out.status.success(), "{args:?} should fail");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    assert!(err.contains(says), "{args:?}: {err}");
}
