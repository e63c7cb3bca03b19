//! The `rollfuse` command line: help, version and the demo placeholder.

use std::process::Command;

fn rollfuse(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_rollfuse"))
        .args(args)
        .output()
        .expect("run rollfuse")
}

#[test]
fn help_lists_the_demo() {
    let out = rollfuse(&["--help"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("demo"), "{text}");
}

#[test]
fn demo_says_what_it_will_do() {
    let out = rollfuse(&["demo"]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("report.html"));
}

#[test]
fn unknown_subcommand_fails_with_a_message() {
    let out = rollfuse(&["frobnicate"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("frobnicate"));
}
