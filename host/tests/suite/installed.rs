//! A binary copied away from the source tree and run from another folder still has its
//! defaults and runs the whole demo: the built-in scenes and model are compiled in, and a
//! missing MCU bench table is a note.

use std::path::Path;
use std::process::Command;

/// Runs the copied binary in `cwd`; panics with its output unless it succeeds.
fn run(binary: &Path, cwd: &Path, args: &[&str]) -> String {
    let out = Command::new(binary)
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{args:?}: {err}");
    String::from_utf8_lossy(&out.stdout).to_string() + &err
}

#[test]
fn a_copied_binary_runs_its_built_in_scenes_from_anywhere() {
    let tmp = tempfile::tempdir().unwrap();
    let (bin, elsewhere) = (tmp.path().join("bin"), tmp.path().join("elsewhere"));
    std::fs::create_dir_all(&bin).unwrap();
    std::fs::create_dir_all(&elsewhere).unwrap();
    let binary = bin.join("rollfuse");
    std::fs::copy(env!("CARGO_BIN_EXE_rollfuse"), &binary).unwrap();
    // The whole demo: the letters, spheres and textile scenes built in, the bench table
    // absent (a note, not a failure).
    let demo = run(
        &binary,
        &elsewhere,
        &["demo", "--out", "demo", "--progress", "none"],
    );
    assert!(demo.contains("no MCU bench results"), "{demo}");
    for file in [
        "report.html",
        "depth.csv",
        "detect.md",
        "tradeoff.md",
        "eval.md",
    ] {
        assert!(
            elsewhere.join("demo").join(file).is_file(),
            "{file}: {demo}"
        );
    }
    // The letters scene (tradeoff's default, the demo's roll), the bench table absent.
    let study = run(
        &binary,
        &elsewhere,
        &["tradeoff", "--repeats", "1", "--out", "study"],
    );
    assert!(study.contains("no MCU bench results"), "{study}");
    assert!(elsewhere.join("study/tradeoff.md").is_file());
    // No default names the folder the binary was built in.
    for command in ["demo", "eval", "tradeoff"] {
        let help = run(&binary, &elsewhere, &[command, "--help"]);
        assert!(
            !help.contains(env!("CARGO_MANIFEST_DIR")),
            "{command} --help: {help}"
        );
    }
}
