//! Anomaly mode on the simulator's cloth: fitted on defect-free frames of one fabric, it
//! must tell that fabric's defective frames from its clean ones and box the defects.

use rollfuse::detect::anomaly::NormalModel;
use rollfuse::detect::data::{RollShape, Sample, roll_scene};
use rollfuse::eval::anomaly::{self, Figures};
use rollfuse::image::Planes;
use rollfuse::sim::scene::Object;
use rollfuse::sim::{Scene, Simulator};
use std::process::Command;

/// A roll of `fabric` at its nominal scale with `defects` defects, from `seed`.
fn scene(fabric: &str, seed: u64, defects: usize, frames: usize) -> Scene {
    let shape = RollShape {
        frames,
        defects,
        ..RollShape::STANDARD
    };
    let mut scene = roll_scene(seed, &shape);
    scene.object = Object::Textile {
        fabric: fabric.to_string(),
        defects,
        scale: 1.0,
    };
    scene.sensor.press_depth_mm = 0.35;
    scene
}

/// Every frame of `scene`, labelled.
fn frames(scene: &Scene) -> Vec<Sample> {
    let sim = Simulator::new(scene).unwrap();
    rollfuse::detect::data::frames(&sim, 0).0
}

/// Anomaly mode on a roll of `fabric` from `seed`, as `eval --detect --normal` measures
/// it: fitted on 20 of the roll's clean frames, scored on the others.
fn measure(fabric: &str, seed: u64) -> Figures {
    // One roll: the simulator presses the gel relative to the roll's tallest point, so
    // the contact of a roll with defects differs from that of one without.
    let f = anomaly::measure(&frames(&scene(fabric, seed, 6, 120))).unwrap();
    eprintln!(
        "{fabric}, roll {seed}: AUROC {:.3} over {} defective and {} clean frames; recall \
         {:.2}, precision {:.2}",
        f.auroc, f.defective_frames, f.clean_frames, f.recall, f.precision
    );
    f
}

/// What anomaly mode promises on a twill, a plain weave and a knit, each on two rolls:
/// image AUROC at least 0.95, recall at least 0.8 at precision at least 0.7
/// (docs/detect.md states the measured figures).
#[test]
fn a_twill_a_plain_weave_and_a_knit_are_learned_from_clean_frames() {
    for (fabric, seed) in ["twill_2_2", "plain", "jersey"]
        .into_iter()
        .flat_map(|f| [(f, 2), (f, 3)])
    {
        let f = measure(fabric, seed);
        assert!(
            f.auroc >= 0.95,
            "{fabric}, roll {seed}: AUROC {:.3}",
            f.auroc
        );
        assert!(
            f.recall >= 0.8,
            "{fabric}, roll {seed}: recall {:.2}",
            f.recall
        );
        assert!(
            f.precision >= 0.7,
            "{fabric}, roll {seed}: precision {:.2}",
            f.precision
        );
    }
}

#[test]
fn too_few_images_other_widths_and_other_heights_are_refused_with_the_reason() {
    let frames: Vec<Planes> = frames(&scene("plain", 4, 0, 6))
        .into_iter()
        .map(|s| s.image)
        .collect();
    let few = NormalModel::fit(&frames[..3]).unwrap_err().to_string();
    assert!(few.contains("at least 4"), "{few}");
    let model = NormalModel::fit(&frames).unwrap();
    let blank = |width: usize, height: usize| Planes {
        width,
        height,
        planes: vec![vec![0.0; width * height]],
    };
    let err = model.detect(&blank(160, 240)).unwrap_err().to_string();
    assert!(err.contains("fitted on images 320 wide"), "{err}");
    let err = model.detect(&blank(320, 120)).unwrap_err().to_string();
    assert!(err.contains("240-row images"), "{err}");
}

#[test]
fn a_model_of_another_format_or_damaged_is_refused_on_loading() {
    let tmp = tempfile::tempdir().unwrap();
    let frames: Vec<Planes> = frames(&scene("plain", 4, 0, 4))
        .into_iter()
        .map(|s| s.image)
        .collect();
    let path = tmp.path().join("plain.json");
    NormalModel::fit(&frames).unwrap().save(&path).unwrap();
    assert!(NormalModel::load(&path).is_ok());
    let text = std::fs::read_to_string(&path).unwrap();
    let older = tmp.path().join("older.json");
    std::fs::write(
        &older,
        text.replace("rollfuse-normal-2", "rollfuse-normal-1"),
    )
    .unwrap();
    let err = format!("{:#}", NormalModel::load(&older).unwrap_err());
    assert!(err.contains("format `rollfuse-normal-1`"), "{err}");
    let cut = tmp.path().join("cut.json");
    std::fs::write(&cut, &text[..text.len() / 2]).unwrap();
    let err = format!("{:#}", NormalModel::load(&cut).unwrap_err());
    assert!(err.contains("is not a normal model"), "{err}");
}

/// `rollfuse ARGS`, which must succeed: its standard output.
fn rollfuse_ok(args: &[&std::ffi::OsStr]) -> String {
    let run = Command::new(env!("CARGO_BIN_EXE_rollfuse"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    String::from_utf8_lossy(&run.stdout).into_owned()
}

#[test]
fn fit_normal_and_detect_normal_from_the_command_line() {
    let tmp = tempfile::tempdir().unwrap();
    let all = frames(&scene("jersey", 2, 6, 120));
    let mut clean = Vec::new();
    let mut defective = None;
    for (k, s) in all.iter().enumerate() {
        let path = tmp.path().join(format!("f{k:03}.png"));
        if s.boxes.is_empty() && s.blurred.is_empty() && clean.len() < 20 {
            s.image.save_png(&path).unwrap();
            clean.push(path);
        } else if s.boxes.len() == 1 && s.blurred.is_empty() && defective.is_none() {
            s.image.save_png(&path).unwrap();
            defective = Some(path);
        }
    }
    let model = tmp.path().join("jersey.json");
    let mut args: Vec<&std::ffi::OsStr> = vec!["fit-normal".as_ref()];
    args.extend(clean.iter().map(|p| p.as_os_str()));
    args.extend(["--out".as_ref(), model.as_os_str()]);
    let fitted = rollfuse_ok(&args);
    assert!(
        fitted.contains("learned 20 images of 320 × 240"),
        "{fitted}"
    );
    let image = defective.expect("a frame with one defect in contact");
    let json = tmp.path().join("a.json");
    let stdout = rollfuse_ok(&[
        "detect".as_ref(),
        image.as_os_str(),
        "--normal".as_ref(),
        model.as_os_str(),
        "--json".as_ref(),
        json.as_os_str(),
    ]);
    let out: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(out[0]["anomaly_score"].as_f64().unwrap() > 0.0);
    for d in out[0]["defects"].as_array().unwrap() {
        assert_eq!(d["kind"], "anomaly");
    }
    assert!(stdout.contains("anomaly score"), "{stdout}");
    // The live page checks the strip in windows of any height: a model of each row of
    // camera frames is refused before the stream starts, with what to do instead.
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/textile.toml");
    let run = Command::new(env!("CARGO_BIN_EXE_rollfuse"))
        .args(["stream", "--device", "sim", "--scene"])
        .arg(&scene)
        .arg("--out")
        .arg(tmp.path().join("live"))
        .args(["--serve", "127.0.0.1:0", "--detect", "--normal"])
        .arg(&model)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && err.contains("--every-row-alike"),
        "{err}"
    );
    // The normal model is not the defect detector's: the two are not mixed.
    let run = Command::new(env!("CARGO_BIN_EXE_rollfuse"))
        .args(["detect".as_ref(), image.as_os_str(), "--normal".as_ref()])
        .arg(&model)
        .args(["--model", "x.safetensors"])
        .output()
        .unwrap();
    assert!(!run.status.success());
}

/// `eval --detect --normal` measures anomaly mode on held-out rolls, each fitted on its
/// own clean frames: one line a roll, its figures in the JSON too.
#[test]
fn eval_measures_anomaly_mode_on_held_out_rolls() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("eval");
    let stdout = rollfuse_ok(&[
        "eval".as_ref(),
        "--detect".as_ref(),
        "--normal".as_ref(),
        "--rolls".as_ref(),
        "2".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(stdout.contains("Median over 2 of 2 rolls"), "{stdout}");
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("anomaly.json")).unwrap()).unwrap();
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for r in rows {
        let f = &r["figures"];
        let auroc = f["auroc"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&auroc), "{r}");
        assert!(f["defective_frames"].as_u64().unwrap() > 0, "{r}");
    }
    assert!(
        std::fs::read_to_string(out.join("anomaly.md"))
            .unwrap()
            .contains("| 1 | ")
    );
    // Anomaly mode has no model file to evaluate: a detector's is refused with it.
    let run = Command::new(env!("CARGO_BIN_EXE_rollfuse"))
        .args(["eval", "--detect", "--normal", "--model", "m.safetensors"])
        .output()
        .unwrap();
    assert!(!run.status.success());
}
