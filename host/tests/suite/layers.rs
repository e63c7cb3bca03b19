//! The host's layers: the library's modules do not reach into the command line. Only
//! `host/src/commands/` and `host/src/main.rs` (the `rollfuse` binary, which declares the
//! commands) may name `crate::commands`, and only they may use clap.

use std::path::{Path, PathBuf};

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The files of `files` outside the command line (`host/src/commands/`, `host/src/main.rs`)
/// whose text contains any of `needles`.
fn outside_the_command_line_naming(files: &[PathBuf], needles: &[&str]) -> Vec<String> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    files
        .iter()
        .filter(|p| !p.starts_with(src.join("commands")) && **p != src.join("main.rs"))
        .filter(|p| {
            let text = std::fs::read_to_string(p).unwrap();
            needles.iter().any(|n| text.contains(n))
        })
        .map(|p| p.display().to_string())
        .collect()
}

#[test]
fn no_library_module_imports_the_commands() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    assert!(files.len() > 20, "found the sources");
    let offenders =
        outside_the_command_line_naming(&files, &["crate::commands", "rollfuse::commands"]);
    assert!(offenders.is_empty(), "{offenders:?}");
}

/// clap is the command line's: no other source file of the workspace — the library, the
/// crates beneath it, the core, the firmware, the Python package — uses it.
#[test]
fn only_the_command_line_uses_clap() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let mut files = Vec::new();
    for dir in [
        "host/src",
        "host/io/src",
        "host/fullres/src",
        "host/depth/src",
        "host/sim/src",
        "host/detect/src",
        "host/link/src",
        "host/records/src",
        "shared/src",
        "firmware/src",
        "python/src",
    ] {
        sources(&root.join(dir), &mut files);
    }
    assert!(files.len() > 100, "found the sources");
    let offenders = outside_the_command_line_naming(&files, &["clap::", "use clap"]);
    assert!(offenders.is_empty(), "{offenders:?}");
}
