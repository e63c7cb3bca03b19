//! The `rollfuse` command line: help, version, unknown commands, and each command's basics.

use crate::common::docs;
use crate::common::rollfuse;

#[test]
fn help_lists_the_demo() {
    let out = rollfuse(&["--help"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("demo"), "{text}");
}

#[test]
fn demo_refuses_a_missing_scene_before_any_work() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("demo");
    let run = rollfuse(&[
        "demo",
        "--out",
        dir.to_str().unwrap(),
        "--letters",
        "/nonexistent/letters.toml",
    ]);
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("/nonexistent/letters.toml"), "{err}");
    assert!(!dir.join("report.html").exists());
}

#[test]
fn unknown_subcommand_fails_with_a_message() {
    let out = rollfuse(&["frobnicate"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("frobnicate"));
}

/// Bad arguments are one line and exit code 1, as every other error; help is exit code 0.
#[test]
fn argument_errors_are_one_line_and_exit_1() {
    for (args, says) in [
        (&["frobnicate"][..], "unrecognized subcommand 'frobnicate'"),
        (
            &["fuse", "--outt", "x.png", "a.png"],
            "similar argument exists: '--out'",
        ),
        (
            &["fuse"],
            "required arguments were not provided: --out <OUT> <FRAMES>...",
        ),
        (
            &["eval", "--depth", "--roll"],
            "'--depth' cannot be used with '--roll'",
        ),
    ] {
        let out = rollfuse(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
    let help = rollfuse(&["fuse", "--help"]);
    assert_eq!(help.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&help.stdout).contains("Usage:"));
}

#[test]
fn simulate_writes_frames_truth_and_manifest() {
    let out = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/dots.toml");
    let dir = out.path().join("dots");
    let run = rollfuse(&[
        "simulate",
        scene,
        "--out",
        dir.to_str().unwrap(),
        "--frames",
        "3",
        "--seed",
        "9",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    for f in [
        "frame_0000.png",
        "frame_0002.png",
        "manifest.json",
        "contact_sheet.png",
        "truth/height.npy",
        "truth/height.png",
        "truth/ideal.png",
    ] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    assert!(!dir.join("frame_0003.png").exists());
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["seed"], 9);
    assert_eq!(manifest["frames"].as_array().unwrap().len(), 3);
}

#[test]
fn simulate_refuses_missing_and_bad_scenes_in_one_line() {
    let out = tempfile::tempdir().unwrap();
    let o = out.path().to_str().unwrap();
    let missing = rollfuse(&["simulate", "/no/such/scene.toml", "--out", o]);
    assert!(!missing.status.success());
    let msg = String::from_utf8_lossy(&missing.stderr);
    assert!(msg.contains("cannot read scene file"), "{msg}");

    let bad = out.path().join("bad.toml");
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/dots.toml")).unwrap();
    std::fs::write(
        &bad,
        text.replace("roller_radius_mm = 12.0", "roller_radius_mm = -1.0"),
    )
    .unwrap();
    let run = rollfuse(&["simulate", bad.to_str().unwrap(), "--out", o]);
    assert!(!run.status.success());
    let msg = String::from_utf8_lossy(&run.stderr);
    assert!(msg.contains("sensor.roller_radius_mm"), "{msg}");
    assert!(!msg.contains("panicked"), "{msg}");

    let zero = rollfuse(&[
        "simulate",
        concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/dots.toml"),
        "--out",
        o,
        "--frames",
        "0",
    ]);
    assert!(!zero.status.success());
    assert!(String::from_utf8_lossy(&zero.stderr).contains("sensor.frames"));
}

/// A `w × h` palette PNG whose palette is 256 grays, pixel values `v(x, y)`.
fn palette_png(path: &std::path::Path, w: u32, h: u32, v: impl Fn(u32, u32) -> u8) {
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
    let chunk = |out: &mut Vec<u8>, kind: &[u8], data: &[u8]| {
        out.extend((data.len() as u32).to_be_bytes());
        let mut d = crc.digest();
        d.update(kind);
        d.update(data);
        out.extend(kind);
        out.extend(data);
        out.extend(d.finalize().to_be_bytes());
    };
    // Scanlines: a filter byte 0, then the pixels.
    let mut raw = Vec::new();
    for y in 0..h {
        raw.push(0);
        raw.extend((0..w).map(|x| v(x, y)));
    }
    // zlib with stored (uncompressed) deflate blocks.
    let mut z = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = raw.chunks(65_535).collect();
    for (k, b) in blocks.iter().enumerate() {
        z.push(u8::from(k + 1 == blocks.len()));
        z.extend((b.len() as u16).to_le_bytes());
        z.extend((!(b.len() as u16)).to_le_bytes());
        z.extend(*b);
    }
    let (mut a, mut b) = (1u32, 0u32);
    for &x in &raw {
        a = (a + u32::from(x)) % 65_521;
        b = (b + a) % 65_521;
    }
    z.extend(((b << 16) | a).to_be_bytes());
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend(w.to_be_bytes());
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 3, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    let grays: Vec<u8> = (0..=255u8).flat_map(|g| [g, g, g]).collect();
    chunk(&mut png, b"PLTE", &grays);
    chunk(&mut png, b"IDAT", &z);
    chunk(&mut png, b"IEND", &[]);
    std::fs::write(path, png).unwrap();
}

/// Each error names the input at fault and what to do.
#[test]
fn errors_name_the_input_at_fault() {
    use rollfuse::image::{PixelLimit, Planes};
    let tmp = tempfile::tempdir().unwrap();
    let at = |name: &str| tmp.path().join(name);
    let textured = |w: usize, h: usize| Planes {
        width: w,
        height: h,
        planes: vec![
            (0..w * h)
                .map(|i| ((i * 37 + i / w * 11) % 251) as f32)
                .collect(),
        ],
    };
    // A gray palette is gray: it fuses with a gray frame.
    palette_png(&at("palette.png"), 64, 48, |x, y| {
        ((x * 37 + y * 11) % 251) as u8
    });
    assert_eq!(
        Planes::load(&at("palette.png"), PixelLimit::default())
            .unwrap()
            .planes
            .len(),
        1
    );
    textured(64, 48).save_png(&at("gray.png")).unwrap();
    let out = rollfuse(&[
        "fuse",
        at("palette.png").to_str().unwrap(),
        at("gray.png").to_str().unwrap(),
        "--out",
        at("fused.png").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    // A flat first frame is blamed, not the frame matched against it.
    Planes {
        width: 64,
        height: 48,
        planes: vec![vec![128.0; 64 * 48]],
    }
    .save_png(&at("flat.png"))
    .unwrap();
    let out = rollfuse(&[
        "fuse",
        at("flat.png").to_str().unwrap(),
        at("gray.png").to_str().unwrap(),
        "--out",
        at("never.png").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("frame 1 of the list, which it is matched against, is flat"),
        "{err}"
    );
    // A frame over the pixel limit by itself: no mode helps, the limit must rise.
    let out = rollfuse(&[
        "fuse",
        at("gray.png").to_str().unwrap(),
        at("gray.png").to_str().unwrap(),
        "--max-pixels",
        "1000",
        "--out",
        at("never.png").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("raise --max-pixels to at least 3072"), "{err}");
    assert!(!err.contains("--mode roll"), "{err}");
    // MS-SSIM strips too thin for its window: how many strips would do.
    textured(16, 16).save_png(&at("tiny.png")).unwrap();
    let tiny = at("tiny.png");
    let out = rollfuse(&[
        "metrics",
        tiny.to_str().unwrap(),
        "--reference",
        tiny.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("16 rows in 10 strips leave 1: pass --strips 1 or fewer"),
        "{err}"
    );
}

/// Off a terminal (here: a pipe) progress is plain lines, a stage's last saying it is
/// done; `--progress-every 0` prints one at every step, so the test needs no clock.
#[test]
fn progress_off_a_terminal_is_plain_lines() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/dots.toml");
    let out = tmp.path().join("sim");
    let simulate = |extra: &[&str]| {
        let mut args = vec!["simulate", scene, "--frames", "3", "--out"];
        args.push(out.to_str().unwrap());
        args.extend_from_slice(extra);
        let run = rollfuse(&args);
        assert!(run.status.success(), "{args:?}");
        String::from_utf8(run.stderr).unwrap()
    };
    let lines = simulate(&["--progress-every", "0"]);
    let said: Vec<&str> = lines.lines().collect();
    assert_eq!(said.len(), 4, "a line a frame and one at the end: {lines}");
    assert!(
        said[0].starts_with("simulating dots: 1/3 frames (33 %), "),
        "{lines}"
    );
    assert!(
        said[2].starts_with("simulating dots: 3/3 frames (100 %), "),
        "{lines}"
    );
    assert!(
        said[3].starts_with("simulating dots: done, 3 frames in "),
        "{lines}"
    );
    // Work shorter than the interval says nothing; `none` says nothing at all.
    assert_eq!(simulate(&["--progress-every", "3600"]), "");
    assert_eq!(
        simulate(&["--progress", "none", "--progress-every", "0"]),
        ""
    );
    let plain = simulate(&["--progress", "plain", "--progress-every", "0"]);
    assert_eq!(plain.lines().count(), 4, "{plain}");
}

/// The words after `rollfuse` (or `cargo run --release --`) of a command line, skipping
/// any `VAR=value` before it; `None` for a line of another command.
fn rollfuse_args(line: &str) -> Option<Vec<String>> {
    let words: Vec<&str> = line
        .split_whitespace()
        .skip_while(|w| w.contains('='))
        .collect();
    let start = match words.as_slice() {
        [first, ..] if *first == "rollfuse" || first.ends_with("/rollfuse") => 1,
        ["cargo", "run", "--release", "--", ..] => 4,
        _ => return None,
    };
    let args: Vec<String> = words[start..].iter().map(|w| w.to_string()).collect();
    (!args.is_empty()).then_some(args)
}

/// The `rollfuse` commands the README and docs show: the lines of their `sh` blocks
/// (continuation lines joined, comments dropped), the commands their tables are stated as
/// the output of or measured by (`<!-- output of: … -->`, `<!-- measured by: … -->`), and
/// those in the prose's code spans; each as its arguments, with the file it comes from.
fn documented_commands() -> Vec<(String, Vec<String>)> {
    let mut commands = Vec::new();
    for file in docs::pages() {
        let (name, text) = docs::named_text(&file);
        let mut in_sh = false;
        let mut line = String::new();
        let mut found = Vec::new();
        for raw in text.lines() {
            if let Some(lang) = raw.trim_start().strip_prefix("```") {
                in_sh = !in_sh && lang.trim() == "sh";
                continue;
            }
            if !in_sh {
                let stated = ["<!-- output of:", "<!-- measured by:"]
                    .iter()
                    .find_map(|m| raw.trim().strip_prefix(m))
                    .map(|c| c.trim_end_matches("-->"));
                let spans = raw.split('`').skip(1).step_by(2);
                found.extend(stated.into_iter().chain(spans).filter_map(rollfuse_args));
                continue;
            }
            let code = raw.split(" #").next().unwrap_or_default().trim_end();
            line.push_str(code.trim_end_matches('\\'));
            line.push(' ');
            if !code.ends_with('\\') {
                found.extend(rollfuse_args(&std::mem::take(&mut line)));
            }
        }
        commands.extend(found.into_iter().map(|args| (name.clone(), args)));
    }
    commands
}

/// Every command the README and docs show names a subcommand the tool has and only options
/// that subcommand takes (its `--help` lists them), so the docs cannot drift from the
/// tool's options. What the commands print is checked by the tests of each command.
#[test]
fn every_documented_command_names_a_subcommand_and_options_the_tool_has() {
    let commands = documented_commands();
    assert!(
        commands.len() >= 20,
        "only {} commands found",
        commands.len()
    );
    let mut helps = std::collections::HashMap::new();
    let help_of = |words: &[&str], file: &str| {
        let out = rollfuse(&[words, &["--help"][..]].concat());
        assert!(
            out.status.success(),
            "{file}: `rollfuse {}` is not a command",
            words.join(" ")
        );
        String::from_utf8_lossy(&out.stdout).to_string()
    };
    for (file, args) in &commands {
        // Options before any subcommand (`rollfuse --max-pixels N …`): the tool's own.
        let global = args[0].starts_with('-');
        let sub = if global { "" } else { args[0].as_str() };
        let words: &[&str] = if global { &[] } else { &[sub] };
        let mut help = helps
            .entry(sub.to_string())
            .or_insert_with(|| help_of(words, file))
            .clone();
        // A command of commands (`rolls list`): its subcommand's options.
        let nested = !global && help.contains("\nCommands:") && args.len() > 1;
        if nested {
            let key = format!("{sub} {}", args[1]);
            help = helps
                .entry(key)
                .or_insert_with(|| help_of(&[sub, &args[1]], file))
                .clone();
        }
        for word in &args[usize::from(!global) + usize::from(nested)..] {
            let flag = word.trim_start_matches('[').trim_end_matches(']');
            let flag = flag.split('=').next().unwrap_or_default();
            if !flag.starts_with("--") {
                continue;
            }
            let listed = help
                .split(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
                .any(|w| w == flag);
            assert!(
                listed,
                "{file}: `rollfuse {}` — {} has no {flag}",
                args.join(" "),
                if global { "rollfuse" } else { sub }
            );
        }
    }
}
