//! A binary copied away from the source tree and run from another folder still has its
//! defaults: the built-in scenes are compiled in, and a missing MCU bench table is a note.

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
    // The three-sphere scene (eval --depth's default, the demo's depth stage).
    let depth = run(&binary, &elsewhere, &["eval", "--depth", "--out", "depth"]);
    assert!(depth.contains("depth.md"), "{depth}");
    assert!(elsewhere.join("depth/depth.csv").is_file());
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
