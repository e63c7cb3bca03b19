//! `rollfuse fuse` and `rollfuse metrics` from the command line: alignment, outputs, and a
//! clear one-line error with a non-zero exit for every kind of bad input.

use crate::common::rollfuse;
use std::path::{Path, PathBuf};
use std::process::Output;

fn simulate(dir: &Path, scene: &str, frames: usize) -> Vec<PathBuf> {
    let scene = format!("{}/scenes/{scene}.toml", env!("CARGO_MANIFEST_DIR"));
    let n = frames.to_string();
    let out = rollfuse(&[
        "simulate",
        &scene,
        "--out",
        dir.to_str().unwrap(),
        "--frames",
        &n,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (0..frames)
        .map(|k| dir.join(format!("frame_{k:04}.png")))
        .collect()
}

fn args<'a>(frames: &'a [PathBuf], rest: &[&'a str]) -> Vec<&'a str> {
    frames
        .iter()
        .map(|p| p.to_str().unwrap())
        .chain(rest.iter().copied())
        .collect()
}

/// Runs `rollfuse fuse …`.
fn fuse(a: &[&str]) -> Output {
    rollfuse(&[&["fuse"], a].concat())
}

/// Runs `rollfuse fuse …` expecting failure; returns stderr.
fn fails(a: &[&str]) -> String {
    let out = fuse(a);
    assert!(!out.status.success(), "should fail: {a:?}");
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.trim().lines().count() <= 2, "one clear line: {err}");
    err
}

#[test]
fn template_alignment_recovers_the_belt_shift_through_noise() {
    let tmp = tempfile::tempdir().unwrap();
    // The letters scene has noise, defocus and uneven light; frames are 1 mm = 20 px apart.
    let frames = simulate(tmp.path(), "letters", 8);
    let out = tmp.path().join("fused.png");
    let run = fuse(&args(&frames[2..7], &["--out", out.to_str().unwrap()]));
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let rec: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(tmp.path().join("fused.offsets.json")).unwrap(),
    )
    .unwrap();
    let dys: Vec<i64> = rec["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["at"]["dy"].as_i64().unwrap())
        .collect();
    assert_eq!(dys, [0, 20, 40, 60, 80]);
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (320, 240 + 80));
}

#[test]
fn motion_alignment_reads_the_manifest() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "dots", 4);
    let out = tmp.path().join("fused.png");
    let run = fuse(&args(
        &frames,
        &[
            "--out",
            out.to_str().unwrap(),
            "--align",
            "motion",
            "--precision",
            "fixed",
            "--levels",
            "2",
        ],
    ));
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let img = image::open(&out).unwrap();
    // The dots scene moves 3 mm = 60 px between frames.
    assert_eq!((img.width(), img.height()), (320, 240 + 3 * 60));
}

#[test]
fn bad_input_gets_one_clear_line_and_a_nonzero_exit() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "dots", 2);
    let out = tmp.path().join("o.png");
    let o = out.to_str().unwrap();
    // Missing file.
    assert!(
        fails(&args(
            &[frames[0].clone(), tmp.path().join("nope.png")],
            &["--out", o]
        ))
        .contains("nope.png")
    );
    // Not an image.
    let junk = tmp.path().join("junk.png");
    std::fs::write(&junk, b"not a png").unwrap();
    assert!(fails(&args(&[frames[0].clone(), junk.clone()], &["--out", o])).contains("junk.png"));
    // Mixed sizes.
    let small = tmp.path().join("small.png");
    image::GrayImage::new(32, 32).save(&small).unwrap();
    assert!(fails(&args(&[frames[0].clone(), small], &["--out", o])).contains("one size"));
    // Mixed gray and RGB.
    let rgb = tmp.path().join("rgb.png");
    image::RgbImage::new(320, 240).save(&rgb).unwrap();
    assert!(fails(&args(&[frames[0].clone(), rgb], &["--out", o])).contains("gray and RGB"));
    // One frame only.
    assert!(fails(&args(&frames[..1], &["--out", o])).contains("at least two frames"));
    // Zero frames: clap's own message.
    let zero = rollfuse(&["fuse", "--out", o]);
    assert!(!zero.status.success());
    // An output that cannot be written (its folder would be under a file), refused before
    // any work.
    let bad_out = frames[0].join("f.png");
    assert!(
        fails(&args(&frames, &["--out", bad_out.to_str().unwrap()])).contains("is not a folder")
    );
    // The offsets file beside the output cannot be written (a folder is in its place).
    std::fs::create_dir(tmp.path().join("o.offsets.json")).unwrap();
    assert!(fails(&args(&frames, &["--out", o])).contains("o.offsets.json"));
    std::fs::remove_dir(tmp.path().join("o.offsets.json")).unwrap();
    // Out-of-range parameters.
    assert!(fails(&args(&frames, &["--out", o, "--levels", "7"])).contains("--levels"));
    assert!(fails(&args(&frames, &["--out", o, "--min-score", "2"])).contains("--min-score"));
    // An output that is one of the inputs.
    assert!(
        fails(&args(&frames, &["--out", frames[1].to_str().unwrap()]))
            .contains("is the input frame")
    );
    // Nothing was written by the failed runs.
    assert!(!out.exists());
}

#[test]
fn flat_frames_are_reported_and_not_fused_misaligned() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "dots", 2);
    let flat = tmp.path().join("flat.png");
    image::GrayImage::from_pixel(320, 240, image::Luma([120]))
        .save(&flat)
        .unwrap();
    let out = tmp.path().join("f.png");
    let run = fuse(&args(
        &[frames[0].clone(), flat.clone(), frames[1].clone()],
        &["--out", out.to_str().unwrap()],
    ));
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("skipped") && err.contains("flat.png"), "{err}");
    let rec = std::fs::read_to_string(tmp.path().join("f.offsets.json")).unwrap();
    assert!(rec.contains("\"skipped\"") && rec.contains("flat.png"));
}

#[test]
fn metrics_prints_ie_and_ms_ssim_and_refuses_mismatched_references() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "dots", 1);
    let f = frames[0].to_str().unwrap();
    let run = rollfuse(&["metrics", f, "--reference", f, "--json"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert!((v["ms_ssim"].as_f64().unwrap() - 1.0).abs() < 1e-9);
    assert!(v["ie"].as_f64().unwrap() > 3.0);
    assert_eq!(v["strip_ie"].as_array().unwrap().len(), 10);
    let ideal = tmp.path().join("truth/ideal.png");
    let bad = rollfuse(&["metrics", f, "--reference", ideal.to_str().unwrap()]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("reference is"));
}

#[test]
fn parallel_and_single_threaded_fusion_give_identical_bytes() {
    use rollfuse::fullres::align::Offset;
    use rollfuse::fullres::{Placed, Precision, fuse_mosaic};
    use rollfuse::image::{PixelLimit, Planes};
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "spheres", 3);
    let images: Vec<Planes> = frames
        .iter()
        .map(|p| Planes::load(p, PixelLimit::default()).unwrap())
        .collect();
    let placed: Vec<Placed> = images
        .iter()
        .enumerate()
        .map(|(k, image)| Placed {
            image,
            at: Offset {
                dy: 20 * k as i64,
                dx: 0,
            },
        })
        .collect();
    let cfg = rollfuse_core::FuseConfig {
        levels: 2,
        ..Default::default()
    };
    let run = |placed: &[Placed], threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| fuse_mosaic(placed, &cfg, Precision::F32, PixelLimit::default()).unwrap())
    };
    let (one, many) = (run(&placed, 1), run(&placed, 3));
    assert_eq!(one.planes.len(), 3, "RGB is fused per channel");
    assert_eq!(one, many);

    // Gray: one channel, the two images of each step on two threads.
    let gray: Vec<Planes> = images
        .iter()
        .map(|p| Planes {
            planes: vec![p.planes[1].clone()],
            ..p.clone()
        })
        .collect();
    let placed: Vec<Placed> = gray
        .iter()
        .zip(&placed)
        .map(|(image, p)| Placed { image, at: p.at })
        .collect();
    assert_eq!(run(&placed, 1), run(&placed, 2));
}

#[test]
fn sixteen_bit_output_holds_the_eight_bit_result_and_its_fractions() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "dots", 3);
    let (a, b) = (tmp.path().join("a.png"), tmp.path().join("b.png"));
    for (out, bits) in [(&a, "8"), (&b, "16")] {
        let run = fuse(&args(
            &frames,
            &["--out", out.to_str().unwrap(), "--out-bits", bits],
        ));
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
    let eight = image::open(&a).unwrap();
    let sixteen = image::open(&b).unwrap();
    assert_eq!(sixteen.color(), image::ColorType::L16);
    let (eight, sixteen) = (eight.to_luma8(), sixteen.to_luma16());
    let mut fractional = 0;
    for (e, s) in eight.pixels().zip(sixteen.pixels()) {
        let v = f64::from(s[0]) / 257.0;
        assert!((v - f64::from(e[0])).abs() <= 0.5 + 1e-3, "{v} vs {}", e[0]);
        fractional += usize::from(s[0] % 257 != 0);
    }
    assert!(
        fractional > 0,
        "16-bit output keeps fractions of gray levels"
    );
    // clap's own message, which lists the possible values.
    let bad = fuse(&args(
        &frames,
        &["--out", a.to_str().unwrap(), "--out-bits", "12"],
    ));
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("possible values: 8, 16"));
}

#[test]
fn a_mosaic_written_as_npy_holds_the_values_the_png_rounds() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "dots", 3);
    let (png, npy) = (tmp.path().join("a.png"), tmp.path().join("a.npy"));
    for out in [&png, &npy] {
        let run = fuse(&args(&frames, &["--out", out.to_str().unwrap()]));
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
    let eight = image::open(&png).unwrap().to_luma8();
    let bytes = std::fs::read(&npy).unwrap();
    let shape = format!("'shape': ({}, {})", eight.height(), eight.width());
    assert!(String::from_utf8_lossy(&bytes[..128]).contains(&shape));
    let values: Vec<f32> = bytes[bytes.len() - 4 * eight.len()..]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    assert!(
        values.iter().any(|v| v.fract() != 0.0),
        "the values unrounded"
    );
    for (v, p) in values.iter().zip(eight.pixels()) {
        assert_eq!(v.round().clamp(0.0, 255.0) as u8, p[0]);
    }
    // A roll's strip grows in PNG segments: refused before any work.
    let err = fails(&args(
        &frames,
        &["--out", npy.to_str().unwrap(), "--mode", "roll"],
    ));
    assert!(err.contains("PNG segments"), "{err}");
}

#[test]
fn sixteen_bit_frames_fuse_like_their_eight_bit_scaling() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "dots", 2);
    let wide: Vec<PathBuf> = frames
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let img = image::open(p).unwrap().to_luma16();
            let q = tmp.path().join(format!("wide_{k}.png"));
            image::ImageBuffer::<image::Luma<u16>, _>::from_fn(
                img.width(),
                img.height(),
                |x, y| image::Luma([img.get_pixel(x, y)[0] / 256 * 257]),
            )
            .save(&q)
            .unwrap();
            q
        })
        .collect();
    let (a, b) = (tmp.path().join("a.png"), tmp.path().join("b.png"));
    for (input, out) in [(&frames, &a), (&wide, &b)] {
        let run = fuse(&args(
            input,
            &["--out", out.to_str().unwrap(), "--align", "none"],
        ));
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
    assert_eq!(
        image::open(&a).unwrap().to_luma8(),
        image::open(&b).unwrap().to_luma8()
    );
}

#[test]
fn a_roll_given_as_a_folder_becomes_a_strip_with_its_index_and_frame_report() {
    let tmp = tempfile::tempdir().unwrap();
    let frames_dir = tmp.path().join("letters");
    simulate(&frames_dir, "letters", 20);
    let out = tmp.path().join("strip.png");
    let run = fuse(&[frames_dir.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let said = String::from_utf8_lossy(&run.stdout);
    // 20 frames 20 rows apart span more than a frame: a roll, the window from geometry.
    assert!(
        said.contains("from the roller geometry in the manifest"),
        "{said}"
    );
    assert!(said.contains("19 matched, 0 predicted"), "{said}");
    let strip = image::open(&out).unwrap().to_luma8();
    let index: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("strip.json")).unwrap())
            .unwrap();
    assert_eq!(index["segments"][0]["rows"], strip.height());
    assert_eq!(index["details"]["window_source"], "geometry");
    let csv = std::fs::read_to_string(tmp.path().join("strip.frames.csv")).unwrap();
    assert_eq!(csv.lines().count(), 21, "a header and a line per frame");
    assert!(csv.lines().nth(2).unwrap().contains(",0,matched,"), "{csv}");
    // Every line has the header's fields (the score is empty for the first frame).
    let fields = |line: &str| line.split(',').count();
    assert!(csv.lines().all(|l| fields(l) == 7), "{csv}");
    assert_eq!(index["details"]["trusted"], true);
    // Cut into segments of 100 rows: the same rows, in order.
    let seg = tmp.path().join("seg.png");
    let run = fuse(&[
        frames_dir.to_str().unwrap(),
        "--out",
        seg.to_str().unwrap(),
        "--segment-rows",
        "100",
    ]);
    assert!(run.status.success());
    let index: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("seg.json")).unwrap())
            .unwrap();
    let mut joined = Vec::new();
    for s in index["segments"].as_array().unwrap() {
        let part = image::open(tmp.path().join(s["file"].as_str().unwrap())).unwrap();
        joined.extend(part.to_luma8().into_raw());
    }
    assert_eq!(joined, strip.into_raw());
    assert!(
        !seg.exists(),
        "a strip of several segments has no single file"
    );
}

#[test]
fn a_roll_that_fails_midway_leaves_no_output_behind() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "letters", 12);
    // Frame 8 is not an image.
    std::fs::write(&frames[8], b"not a png").unwrap();
    let out = tmp.path().join("out").join("strip.png");
    std::fs::create_dir(tmp.path().join("out")).unwrap();
    let err = fails(&args(
        &frames,
        &["--out", out.to_str().unwrap(), "--mode", "roll"],
    ));
    assert!(err.contains("frame_0008.png"), "{err}");
    let left: Vec<_> = std::fs::read_dir(tmp.path().join("out")).unwrap().collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn a_roll_needs_alignment_and_its_options_are_checked() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "letters", 12);
    let o = tmp.path().join("o.png");
    let o = o.to_str().unwrap();
    assert!(
        fails(&args(
            &frames,
            &["--out", o, "--mode", "roll", "--align", "none"]
        ))
        .contains("aligned")
    );
    assert!(
        fails(&args(
            &frames,
            &["--out", o, "--mode", "roll", "--blend-rows", "7"]
        ))
        .contains("cross-faded")
    );
    assert!(fails(&args(&frames, &["--out", o, "--window-rows", "0"])).contains("--window-rows"));
    // Reaches past the frame (a search that large would take the machine's memory), and
    // none at all, are refused with the frame's size.
    for (option, value) in [
        ("--search-rows", "4611686018427387904"),
        ("--search-rows", "241"),
        ("--search-rows", "0"),
        ("--max-shift", "18446744073709551615"),
        ("--max-drift-cols", "321"),
    ] {
        let err = fails(&args(
            &frames,
            &["--out", o, "--mode", "roll", option, value],
        ));
        assert!(
            err.contains(option) && err.contains("frames'"),
            "{option} {value}: {err}"
        );
    }
    // Segment names that are inputs' names are refused.
    let clash = tmp.path().join("frame.png");
    let named = tmp.path().join("frame.0003.png");
    std::fs::copy(&frames[3], &named).unwrap();
    let mut with_clash = frames.clone();
    with_clash.push(named);
    assert!(
        fails(&args(
            &with_clash,
            &["--out", clash.to_str().unwrap(), "--mode", "roll"]
        ))
        .contains("segments")
    );
}

/// Frames given in reverse belt order: each lies behind the strip already fused, and the
/// command says so rather than writing a short strip in silence. `--mode auto` says what
/// it chose.
#[test]
fn frames_out_of_belt_order_are_said_and_the_mode_chosen_is_printed() {
    let tmp = tempfile::tempdir().unwrap();
    let mut frames = simulate(tmp.path(), "letters", 20);
    let out = tmp.path().join("o.png");
    let o = out.to_str().unwrap();
    let run = fuse(&args(&frames, &["--out", o]));
    assert!(run.status.success());
    let said = String::from_utf8_lossy(&run.stdout);
    assert!(said.contains("mode: roll (the frames span"), "{said}");
    assert!(!String::from_utf8_lossy(&run.stderr).contains("behind"));
    frames.reverse();
    let run = fuse(&args(&frames, &["--out", o, "--mode", "roll"]));
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("of 20 frames lay wholly behind"), "{err}");
    let few = fuse(&args(&frames[..3], &["--out", o, "--align", "none"]));
    assert!(String::from_utf8_lossy(&few.stdout).contains("mode: mosaic (--align none"));
}

#[test]
fn template_rows_are_given_as_docs_fusion_writes_them() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "letters", 6);
    let out = tmp.path().join("fused.png");
    let o = out.to_str().unwrap();
    let run = fuse(&args(
        &frames[2..5],
        &[
            "--out",
            o,
            "--align",
            "template",
            "--template-rows",
            "0.3,0.6",
        ],
    ));
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let err = fails(&args(
        &frames[2..5],
        &["--out", o, "--template-rows", "0.3"],
    ));
    assert!(
        err.contains("--template-rows must be two fractions"),
        "{err}"
    );
}

#[test]
fn a_match_at_the_edge_of_the_search_is_said() {
    let tmp = tempfile::tempdir().unwrap();
    // The letters scene's frames are 20 px apart.
    let frames = simulate(tmp.path(), "letters", 6);
    let out = tmp.path().join("fused.png");
    let o = out.to_str().unwrap();
    let run = fuse(&args(
        &frames[2..5],
        &["--out", o, "--align", "template", "--max-shift", "0"],
    ));
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        err.contains("the edge of the search (--max-shift 0)"),
        "{err}"
    );
    // Searched far enough, nothing is said.
    let run = fuse(&args(&frames[2..5], &["--out", o, "--align", "template"]));
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        run.status.success() && !err.contains("edge of the search"),
        "{err}"
    );
}

/// Writes `n` frames of 320×240 with smooth blobs placed at random in each, unrelated from
/// one frame to the next: texture everywhere, and no frame showing the belt of another.
fn unrelated_frames(dir: &Path, n: usize) {
    std::fs::create_dir_all(dir).unwrap();
    let mut state = 7u64;
    let mut next = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f32 / (1u64 << 53) as f32
    };
    for k in 0..n {
        let blobs: Vec<(f32, f32, f32)> = (0..16)
            .map(|_| (next() * 320.0, next() * 240.0, next() * 80.0 - 40.0))
            .collect();
        let img = image::GrayImage::from_fn(320, 240, |x, y| {
            let v: f32 = blobs
                .iter()
                .map(|&(cx, cy, a)| {
                    let d2 = (x as f32 - cx).powi(2) + (y as f32 - cy).powi(2);
                    a * (-d2 / 72.0).exp()
                })
                .sum();
            image::Luma([(128.0 + v).clamp(0.0, 255.0) as u8])
        });
        img.save(dir.join(format!("frame_{k:04}.png"))).unwrap();
    }
}

#[test]
fn a_roll_whose_frames_match_nothing_is_written_marked_and_exits_3() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = tmp.path().join("frames");
    unrelated_frames(&frames, 40);
    let out = tmp.path().join("strip.png");
    let args = [frames.to_str().unwrap(), "--out", out.to_str().unwrap()];
    let run = fuse(&args);
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(3), "{err}");
    assert!(err.contains("warning: placement:"), "{err}");
    assert!(err.contains("--accept-untrusted"), "{err}");
    assert!(out.exists(), "the strip is written");
    let index: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("strip.json")).unwrap())
            .unwrap();
    assert_eq!(index["details"]["trusted"], false);
    assert!(!index["details"]["doubts"].as_array().unwrap().is_empty());
    // Accepted: the same strip and marks, exit 0.
    let run = fuse(&[&args[..], &["--accept-untrusted"]].concat());
    assert!(run.status.success());
    let index: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("strip.json")).unwrap())
            .unwrap();
    assert_eq!(index["details"]["trusted"], false);
}

/// What killed runs leave — hidden files naming a process no longer running — goes with
/// the next run's first output in that folder; hidden files of running processes, and
/// everything else, stay.
#[test]
fn a_run_sweeps_away_what_killed_runs_left_in_its_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "dots", 3);
    let out = tmp.path().join("strips");
    std::fs::create_dir(&out).unwrap();
    // No process has an id this high (Linux's limit is 2²²).
    let debris = [
        ".strip.0001.png.new-999999999-3.png",
        ".strip.json.part-999999999-7",
        ".strip.png.part-999999999-0",
    ];
    for name in debris {
        std::fs::write(out.join(name), b"half").unwrap();
    }
    let running = format!(".strip.png.part-{}-0", std::process::id());
    std::fs::write(out.join(&running), b"mine").unwrap();
    std::fs::write(out.join(".notes"), b"the user's").unwrap();
    let strip = out.join("strip.png");
    let o = fuse(&args(&frames, &["--out", strip.to_str().unwrap()]));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let left = |name: &str| out.join(name).exists();
    if Path::new("/proc/self").exists() {
        assert!(debris.iter().all(|d| !left(d)), "debris stayed");
    }
    assert!(left(&running) && left(".notes") && left("strip.png"));
}

/// An output that is a symbolic link is written through to its target; one that is a
/// device or a FIFO is refused, and the command says so.
#[test]
fn outputs_write_through_links_and_refuse_special_files() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(tmp.path(), "dots", 2);
    let real = tmp.path().join("kept.png");
    std::fs::write(&real, b"old").unwrap();
    let link = tmp.path().join("link.png");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let o = fuse(&args(&frames, &["--out", link.to_str().unwrap()]));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(
        image::open(&real).is_ok(),
        "the link's target holds the strip"
    );
    // A link to a device leads to the device, which is not replaced.
    let device = tmp.path().join("null.png");
    std::os::unix::fs::symlink("/dev/null", &device).unwrap();
    let err = fails(&args(&frames, &["--out", device.to_str().unwrap()]));
    assert!(err.contains("is a device"), "{err}");
    let meta = std::fs::metadata("/dev/null").unwrap();
    assert!(!meta.is_file(), "/dev/null was replaced");
}

/// Side files belong to one output: a mosaic written over a segmented roll's name takes
/// the roll's index and segments away, a roll over a mosaic its offsets, a splice both.
#[test]
fn an_output_keeps_no_side_file_of_the_one_it_replaced() {
    let tmp = tempfile::tempdir().unwrap();
    let frames = simulate(&tmp.path().join("letters"), "letters", 20);
    let out = tmp.path().join("strip.png");
    let o = out.to_str().unwrap();
    let at = |name: &str| tmp.path().join(name).exists();
    let ok = |run: Output| assert!(run.status.success(), "{run:?}");
    ok(fuse(&args(&frames, &["--out", o, "--segment-rows", "100"])));
    assert!(at("strip.json") && at("strip.frames.csv") && at("strip.0001.png"));
    ok(fuse(&args(&frames[..3], &["--out", o, "--mode", "mosaic"])));
    assert!(at("strip.png") && at("strip.offsets.json"));
    for roll_file in [
        "strip.json",
        "strip.frames.csv",
        "strip.0000.png",
        "strip.0001.png",
    ] {
        assert!(!at(roll_file), "{roll_file} outlived its roll");
    }
    ok(fuse(&args(&frames, &["--out", o])));
    assert!(at("strip.json") && !at("strip.offsets.json"));
    // A file of that name the tool did not write stays.
    std::fs::write(tmp.path().join("strip.offsets.json"), "{\"mine\": 1}").unwrap();
    ok(rollfuse(
        &[&["splice"], &args(&frames[..3], &["--out", o])[..]].concat(),
    ));
    assert!(!at("strip.json") && !at("strip.frames.csv") && at("strip.offsets.json"));
}

/// A strip is compared with the part of the ideal belt it covers: the rows come from its
/// index, or from `--reference-rows`; rows the reference lacks are refused by number.
#[test]
fn metrics_cuts_the_reference_to_a_strips_rows() {
    let tmp = tempfile::tempdir().unwrap();
    let letters = tmp.path().join("letters");
    simulate(&letters, "letters", 20);
    let out = tmp.path().join("strip.png");
    let o = out.to_str().unwrap();
    assert!(
        fuse(&[letters.to_str().unwrap(), "--out", o])
            .status
            .success()
    );
    let ideal = letters.join("truth/ideal.png");
    let i = ideal.to_str().unwrap();
    let run = rollfuse(&["metrics", o, "--reference", i, "--json"]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    let first: usize = err
        .strip_prefix("reference rows ")
        .and_then(|r| r.split("..").next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("the rows are said: {err}"));
    let by_index: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let ms_ssim = by_index["ms_ssim"].as_f64().unwrap();
    assert!(
        ms_ssim > 0.8,
        "the strip is like its part of the belt: {ms_ssim}"
    );
    // The same rows given by hand measure the same; rows further on, less.
    let given = |row: usize| {
        let row = row.to_string();
        let run = rollfuse(&[
            "metrics",
            o,
            "--reference",
            i,
            "--reference-rows",
            &row,
            "--json",
        ]);
        assert!(run.status.success(), "{run:?}");
        let v: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
        v["ms_ssim"].as_f64().unwrap()
    };
    assert_eq!(given(first), ms_ssim);
    assert!(given(first + 7) < ms_ssim);
    let run = rollfuse(&["metrics", o, "--reference", i, "--reference-rows", "100000"]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && err.contains("has no rows 100000.."),
        "{err}"
    );
}
