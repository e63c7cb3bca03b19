//! `rollfuse demo` end to end on small scenes: every artefact is written, every figure is
//! finite and in range, the report is self-contained, and its tables are the ones
//! `rollfuse eval` writes for the same scenes.

use rollfuse::demo::{self, Files, Options, STAGES};
use rollfuse::progress::Progress;
use std::path::Path;
use std::process::Command;
use std::sync::Mutex;

/// The stages the demo says it starts, in order.
#[derive(Default)]
struct Started(Mutex<Vec<u64>>);

impl Progress for Started {
    fn start(&self, _: &str, _: Option<u64>, _: &str) {}
    fn advance_to(&self, done: u64) {
        self.0.lock().unwrap().push(done);
    }
    fn message(&self, _: &str) {}
    fn note(&self, _: &str) {}
    fn finish(&self) {}
}

/// The small camera both scenes use: 160×120 at 0.1 mm per pixel, frames 1 mm apart.
const SMALL_SENSOR: &str = "
roller_radius_mm = 12.0
gel_thickness_mm = 1.5
mm_per_px = 0.1
width_px = 160
height_px = 120
frame_spacing_mm = 1.0
";

/// The letters scene, smaller: 14 frames of a shorter word (at 4× downsampling a frame has
/// 30 rows, and fewer frames leave no tile with all four observations).
fn letters_scene() -> String {
    format!(
        r#"name = "letters-small"
seed = 1
effects = ["contact", "gel", "gray", "defocus", "background", "noise"]

[object]
kind = "letters"
text = "TAC"
height_mm = 1.0

[sensor]{SMALL_SENSOR}press_depth_mm = 0.8
frames = 14
"#
    )
}

/// The three spheres, smaller.
fn spheres_scene() -> String {
    format!(
        r#"name = "spheres-small"
seed = 3
effects = ["contact", "gel", "rgb", "noise"]

[object]
kind = "spheres"
diameter_mm = 4.0

[sensor]{SMALL_SENSOR}press_depth_mm = 1.0
frames = 16
"#
    )
}

fn rollfuse(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_rollfuse"))
        .args(args)
        .output()
        .expect("run rollfuse");
    assert!(
        out.status.success(),
        "rollfuse {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_demo_writes_a_self_contained_report_with_sane_figures() {
    let tmp = tempfile::tempdir().unwrap();
    let letters = tmp.path().join("letters.toml");
    let spheres = tmp.path().join("spheres.toml");
    std::fs::write(&letters, letters_scene()).unwrap();
    std::fs::write(&spheres, spheres_scene()).unwrap();
    let out = tmp.path().join("demo");
    let opts = Options {
        out: out.clone(),
        letters: Some(letters.clone()),
        spheres: Some(spheres.clone()),
        bench: None,
    };
    let started = Started::default();
    let d = demo::run(&opts, &started).unwrap();
    let started = started.0.into_inner().unwrap();
    assert_eq!(started, (0..STAGES.len() as u64).collect::<Vec<_>>());

    // Every artefact, non-empty.
    let mut files = vec![
        Files::STRIP,
        Files::STREAM_MANIFEST,
        Files::HOST_STRIP,
        Files::SINGLE,
        Files::FUSED_MIDDLE,
        Files::EVAL_MD,
        Files::EVAL_CSV,
        Files::DEPTH_MD,
        Files::DEPTH_CSV,
        Files::TRADEOFF_MD,
        Files::TRADEOFF_CSV,
        Files::PARETO,
        Files::REPORT,
    ];
    files.extend(Files::DEPTH_PNGS);
    for f in files {
        let len = std::fs::metadata(out.join(f)).map_or(0, |m| m.len());
        assert!(len > 0, "{f} missing or empty");
    }

    // The device streamed the whole scene, with nothing lost.
    assert!(d.stream.tiles_received > 0);
    assert_eq!(d.stream.faults.total(), 0, "{:?}", d.stream.faults);
    assert!(d.stream.gaps.is_empty());
    assert_eq!(d.stream_stop, rollfuse::stream::StopReason::DeviceStopped);
    // Matching placed every frame where the belt's motion put it.
    assert_eq!(d.alignment.matched, d.alignment.frames - 1);
    assert!(
        d.alignment.max_motion_disagreement <= 1,
        "{:?}",
        d.alignment
    );

    // Figures finite and in range.
    assert_eq!(d.eval.len(), 9);
    for r in &d.eval {
        let m = &r.report;
        assert!(m.ie > 0.0 && m.ie <= 8.0, "{}: IE {}", r.method, m.ie);
        assert!(m.ie_std.is_finite() && m.ie_std >= 0.0);
        let ms = m.ms_ssim.unwrap();
        assert!((0.0..=1.0).contains(&ms), "{}: MS-SSIM {ms}", r.method);
        assert!(m.ms_ssim_std.unwrap().is_finite());
    }
    assert_eq!(d.depth.len(), 3);
    for r in &d.depth {
        assert_eq!(r.overlap.len(), 3);
        assert!(r.overlap.iter().all(|o| (0.0..=1.0).contains(o)), "{r:?}");
        assert!(
            r.peak_mm.iter().all(|p| p.is_finite() && *p >= 0.0),
            "{r:?}"
        );
        assert!(r.overlap_std.is_finite() && r.peak_std_mm.is_finite());
    }
    assert_eq!(d.tradeoff.len(), 72);
    for m in &d.tradeoff {
        assert!(m.accuracy.psnr_db.is_finite() && m.accuracy.psnr_db > 10.0);
        assert!((0.0..=1.0).contains(&m.accuracy.ms_ssim));
        assert!(m.host_ns_per_px.is_finite() && m.host_ns_per_px > 0.0);
        assert!(m.mcu.is_none(), "no bench given");
    }
    assert_eq!(d.detection.rows.len(), 2, "frames and fused tiles");
    for r in &d.detection.rows {
        assert!(r.count > 0 && r.tally.hits + r.tally.misses > 0, "{r:?}");
        assert!((0.0..=1.0).contains(&r.accuracy()));
    }
    assert_eq!(
        d.stages.len(),
        STAGES.len() - 1,
        "the report's own stage is printed"
    );
    assert!(d.stages.iter().all(|s| s.secs.is_finite() && s.secs >= 0.0));

    // The report: every section, every picture embedded, nothing fetched from elsewhere.
    let html = read(&out.join(Files::REPORT));
    assert!(html.starts_with("<!DOCTYPE html>") && html.trim_end().ends_with("</html>"));
    for h in ["1. ", "2. ", "3. ", "4. ", "5. ", "6. ", "7. ", "8. "] {
        assert!(html.contains(&format!("<h2>{h}")), "section {h}");
    }
    let images = html.matches("<img src=\"data:image/png;base64,").count();
    assert_eq!(
        images,
        6 + 1 + 4 + 3 + 2,
        "frames, device strip, the host's strip beside it and the pair, depth maps, detections"
    );
    assert_eq!(html.matches("src=").count(), images, "only data URIs");
    assert!(!html.contains("<script") && !html.contains("<link"));
    assert!(html.contains("<svg"));
    assert!(html.contains("max-|high|"), "escaped bars kept in the cell");

    // The same figures as `rollfuse eval` (and `--depth`) on the same scenes.
    let eval = tmp.path().join("eval");
    let e = eval.to_str().unwrap();
    rollfuse(&["eval", "--scene", letters.to_str().unwrap(), "--out", e]);
    assert_eq!(
        read(&eval.join("eval.csv")),
        read(&out.join(Files::EVAL_CSV))
    );
    rollfuse(&[
        "eval",
        "--depth",
        "--scene",
        spheres.to_str().unwrap(),
        "--out",
        e,
    ]);
    assert_eq!(
        read(&eval.join("depth.csv")),
        read(&out.join(Files::DEPTH_CSV))
    );
}
