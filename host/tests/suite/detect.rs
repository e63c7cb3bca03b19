//! The defect detector from the command line and the library: the model file's round
//! trip, the outputs of `rollfuse detect`, and one clear line for each kind of bad input
//! (missing, corrupt or mismatched model; wrong channels; too small).

use burn::tensor::Device;
use rollfuse::detect::model::{About, save};
use rollfuse::detect::net::{Net, Widths};
use rollfuse::detect::{Detector, data};
use rollfuse::image::{PixelLimit, Planes};
use std::path::Path;

use crate::common::{fails, rollfuse};

const TINY: Widths = Widths([4, 8, 8, 8]);

fn about(widths: Widths) -> About {
    About {
        widths,
        fabrics: rollfuse::sim::textile::FABRICS
            .iter()
            .map(|f| f.name.to_string())
            .collect(),
        made_by: "test".into(),
        familiarity: None,
        threshold: None,
    }
}

/// An untrained tiny model written to `path`; its about says `says`.
fn tiny_model(path: &Path, says: Widths) {
    let net = Net::new(TINY, 17, &Device::flex());
    save(path, &net, &about(says)).unwrap();
}

/// A 320×240 frame of a simulated textile roll, saved as PNG.
fn frame(dir: &Path) -> std::path::PathBuf {
    let shape = data::RollShape {
        frames: 3,
        ..data::RollShape::STANDARD
    };
    let roll = data::roll(7, &shape).unwrap();
    let path = dir.join("frame.png");
    roll.frames[1].image.save_png(&path).unwrap();
    path
}

#[test]
fn a_saved_model_loads_and_detects_the_same() {
    let tmp = tempfile::tempdir().unwrap();
    let model = tmp.path().join("m.safetensors");
    tiny_model(&model, TINY);
    let img = Planes::load(&frame(tmp.path()), PixelLimit::default()).unwrap();
    let a = Detector::load(&model).unwrap().detect(&img).unwrap();
    let b = Detector::load(&model).unwrap().detect(&img).unwrap();
    assert_eq!(a.probabilities, b.probabilities);
    assert_eq!(a.probabilities.len(), 17);
    let sum: f32 = a.probabilities.iter().sum();
    assert!((sum - 1.0).abs() < 1e-4, "{sum}");
    assert_eq!(Detector::load(&model).unwrap().about().widths, TINY);
}

#[test]
fn detect_writes_json_and_drawings_and_keeps_its_inputs() {
    let tmp = tempfile::tempdir().unwrap();
    let model = tmp.path().join("m.safetensors");
    tiny_model(&model, TINY);
    let img = frame(tmp.path());
    let (m, i) = (model.to_str().unwrap(), img.to_str().unwrap());
    let json = tmp.path().join("out.json");
    let draw = tmp.path().join("drawn");
    let out = rollfuse(&[
        "detect",
        i,
        "--model",
        m,
        "--json",
        json.to_str().unwrap(),
        "--draw",
        draw.to_str().unwrap(),
        "--threshold",
        "0.05",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(v[0]["image"], i);
    // Every fabric's probability, by name.
    let p = v[0]["probabilities"].as_object().unwrap();
    assert_eq!(p.len(), 17);
    assert!(p["twill_2_2"].as_f64().unwrap() >= 0.0);
    assert!(v[0]["defects"].is_array());
    let drawn = Planes::load(&draw.join("frame_detect.png"), PixelLimit::default()).unwrap();
    assert_eq!(
        (drawn.width, drawn.height, drawn.planes.len()),
        (320, 240, 3)
    );
    // Upsampled first, boxes still in the image's own pixels.
    let half = tmp.path().join("half.png");
    let small = Planes::load(&img, PixelLimit::default()).unwrap();
    let (w, h) = (small.width / 2, small.height / 2);
    Planes {
        width: w,
        height: h,
        planes: vec![
            (0..w * h)
                .map(|k| small.planes[0][(k / w) * 2 * small.width + (k % w) * 2])
                .collect(),
        ],
    }
    .save_png(&half)
    .unwrap();
    let json2 = tmp.path().join("half.json");
    let out = rollfuse(&[
        "detect",
        half.to_str().unwrap(),
        "--model",
        m,
        "--json",
        json2.to_str().unwrap(),
        "--threshold",
        "0.01",
        "--upsample",
        "2",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json2).unwrap()).unwrap();
    let boxes = v[0]["defects"].as_array().unwrap();
    assert!(
        !boxes.is_empty(),
        "an untrained model at threshold 0.01 finds something"
    );
    for b in boxes {
        let b: Vec<f64> = b["box_px"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert!(
            b[0] >= 0.0 && b[2] <= w as f64 && b[1] >= 0.0 && b[3] <= h as f64,
            "{b:?}"
        );
    }
    // The JSON may not be written over the image it reads.
    fails(&["detect", i, "--model", m, "--json", i], "input image");
    // A folder that is not there is made (`--out` rule, README); one that cannot be, as
    // under a file, is said before any image is run.
    let nd2 = tmp.path().join("nd2/x.json");
    let out = rollfuse(&["detect", i, "--model", m, "--json", nd2.to_str().unwrap()]);
    assert!(out.status.success(), "{out:?}");
    assert!(nd2.exists());
    let under_a_file = tmp.path().join("nd2/x.json/y.json");
    let out = rollfuse(&[
        "detect",
        i,
        "--model",
        m,
        "--json",
        under_a_file.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("x.json is not a folder"), "{err}");
}

#[test]
fn bad_models_are_one_clear_line() {
    let tmp = tempfile::tempdir().unwrap();
    let img = frame(tmp.path());
    let i = img.to_str().unwrap();
    let missing = tmp.path().join("none.safetensors");
    fails(
        &["detect", i, "--model", missing.to_str().unwrap()],
        "cannot read model",
    );
    let junk = tmp.path().join("junk.safetensors");
    std::fs::write(&junk, b"\xff\x00\x00\x00\x00\x00\x00\x00not a model at all").unwrap();
    fails(
        &["detect", i, "--model", junk.to_str().unwrap()],
        "is not a safetensors file",
    );
    let shaped = tmp.path().join("shaped.safetensors");
    tiny_model(&shaped, Widths([4, 8, 16, 8]));
    fails(
        &["detect", i, "--model", shaped.to_str().unwrap()],
        "does not fit",
    );
    // A real model cut short.
    let good = tmp.path().join("good.safetensors");
    tiny_model(&good, TINY);
    let bytes = std::fs::read(&good).unwrap();
    let cut = tmp.path().join("cut.safetensors");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    fails(&["detect", i, "--model", cut.to_str().unwrap()], "model");
    // The right shapes in another dtype.
    let wide = tmp.path().join("f64.safetensors");
    std::fs::write(&wide, in_f64(&bytes)).unwrap();
    fails(
        &["detect", i, "--model", wide.to_str().unwrap()],
        "a detector's tensors are F32",
    );
    // Familiarity statistics that do not describe this model.
    let odd = tmp.path().join("odd.safetensors");
    std::fs::write(&odd, with_metadata(&bytes, "familiarity", "{\"dim\": 3}")).unwrap();
    fails(
        &["detect", i, "--model", odd.to_str().unwrap()],
        "its familiarity statistics are unreadable",
    );
    // A threshold outside 0..=1.
    let high = tmp.path().join("high.safetensors");
    std::fs::write(&high, with_metadata(&bytes, "threshold", "1.5")).unwrap();
    fails(
        &["detect", i, "--model", high.to_str().unwrap()],
        "its threshold",
    );
}

/// A model's own threshold is kept in its file and used unless `--threshold` says
/// otherwise; the built-in model's is the one docs/detect.md states.
#[test]
fn a_model_s_threshold_is_its_default() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("m.safetensors");
    let net = Net::new(TINY, 17, &Device::flex());
    let kept = About {
        threshold: Some(0.55),
        ..about(TINY)
    };
    save(&path, &net, &kept).unwrap();
    assert_eq!(Detector::load(&path).unwrap().threshold, 0.55);
    tiny_model(&path, TINY);
    let default = rollfuse::detect::DEFAULT_THRESHOLD;
    assert_eq!(Detector::load(&path).unwrap().threshold, default);
    assert_eq!(Detector::built_in().unwrap().threshold, 0.4);
}

/// A safetensors file's bytes with metadata `key` set to `value`.
fn with_metadata(bytes: &[u8], key: &str, value: &str) -> Vec<u8> {
    use safetensors::SafeTensors;
    let (_, meta) = SafeTensors::read_metadata(bytes).unwrap();
    let file = SafeTensors::deserialize(bytes).unwrap();
    let mut metadata = meta.metadata().clone().unwrap_or_default();
    metadata.insert(key.into(), value.into());
    safetensors::serialize(file.tensors(), Some(metadata)).unwrap()
}

/// A safetensors file's bytes with every F32 tensor stored as F64, its metadata kept.
fn in_f64(bytes: &[u8]) -> Vec<u8> {
    use safetensors::{Dtype, SafeTensors, tensor::TensorView};
    let (_, meta) = SafeTensors::read_metadata(bytes).unwrap();
    let file = SafeTensors::deserialize(bytes).unwrap();
    let wide: Vec<(String, Vec<usize>, Vec<u8>)> = file
        .tensors()
        .into_iter()
        .map(|(name, t)| {
            assert_eq!(t.dtype(), Dtype::F32);
            let data = t
                .data()
                .chunks_exact(4)
                .flat_map(|b| f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])).to_le_bytes())
                .collect();
            (name, t.shape().to_vec(), data)
        })
        .collect();
    let views = wide.iter().map(|(name, shape, data)| {
        (
            name.clone(),
            TensorView::new(Dtype::F64, shape.clone(), data).unwrap(),
        )
    });
    safetensors::serialize(views, meta.metadata().clone()).unwrap()
}

/// Training and held-out sizes past reason are refused before any work (they would
/// overflow, or take the machine's memory for a batch).
#[test]
fn training_and_evaluation_sizes_past_reason_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let model = tmp.path().join("m.safetensors");
    let m = model.to_str().unwrap();
    let train = |extra: &[&'static str]| -> Vec<&str> {
        [&["train", "--out", m, "--rolls", "1"][..], extra].concat()
    };
    fails(
        &train(&["--steps", "18446744073709551615"]),
        "at most 1000000 steps",
    );
    fails(
        &train(&["--batch", "1000000000"]),
        "at most 256 crops a step",
    );
    fails(&train(&["--validation-rolls", "10001"]), "validation rolls");
    let e = tmp.path().join("e");
    fails(
        &[
            "eval",
            "--detect",
            "--rolls",
            "18446744073709551615",
            "--out",
            e.to_str().unwrap(),
        ],
        "held-out rolls",
    );
    assert!(!model.exists() && !e.exists());
}

#[test]
fn bad_images_are_one_clear_line() {
    let tmp = tempfile::tempdir().unwrap();
    let model = tmp.path().join("m.safetensors");
    tiny_model(&model, TINY);
    let m = model.to_str().unwrap();
    let rgb = tmp.path().join("rgb.png");
    Planes {
        width: 64,
        height: 64,
        planes: vec![vec![100.0; 64 * 64]; 3],
    }
    .save_png(&rgb)
    .unwrap();
    fails(
        &["detect", rgb.to_str().unwrap(), "--model", m],
        "gray images",
    );
    let small = tmp.path().join("small.png");
    Planes {
        width: 16,
        height: 40,
        planes: vec![vec![100.0; 16 * 40]],
    }
    .save_png(&small)
    .unwrap();
    fails(
        &["detect", small.to_str().unwrap(), "--model", m],
        "smaller than",
    );
    let text = tmp.path().join("text.png");
    std::fs::write(&text, "not a png").unwrap();
    fails(
        &["detect", text.to_str().unwrap(), "--model", m],
        "text.png",
    );
}

#[test]
fn a_textile_scene_writes_its_defects() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/textile.toml");
    let out = rollfuse(&["simulate", scene, "--out", tmp.path().to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(tmp.path().join("truth/defects.json")).unwrap())
            .unwrap();
    assert_eq!(v["fabric"], "twill_2_2");
    assert_eq!(v["class"], 5);
    assert_eq!(v["defects"].as_array().unwrap().len(), 3);
    assert_eq!(v["frames"].as_array().unwrap().len(), 30);
    // Some frame shows some defect in its contact band.
    let frames = v["frames"].as_array().unwrap();
    assert!(frames.iter().any(|f| {
        f["defects"]
            .as_array()
            .unwrap()
            .iter()
            .any(|d| d["in_contact"] == true)
    }));
    // Other objects write none.
    let letters = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml");
    let other = tmp.path().join("letters");
    let out = rollfuse(&[
        "simulate",
        letters,
        "--out",
        other.to_str().unwrap(),
        "--frames",
        "2",
    ]);
    assert!(out.status.success());
    assert!(!other.join("truth/defects.json").exists());
    let out = tmp.path().join("never");
    for (from, to, says) in [
        (
            "\"twill_2_2\"",
            "\"silk\"",
            "object.fabric must be one of plain, voile",
        ),
        (
            "defects = 3",
            "defects = 101",
            "object.defects must be at most 100",
        ),
        (
            "defects = 3",
            "defects = 3\nscale = 3.0",
            "object.scale must be in 0.5..=2",
        ),
    ] {
        let scene = write_scene(tmp.path(), from, to);
        fails(&["simulate", &scene, "--out", out.to_str().unwrap()], says);
    }
    assert!(!out.exists());
}

/// The textile scene with `from` replaced by `to`.
fn write_scene(dir: &Path, from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/textile.toml"))
        .unwrap()
        .replace(from, to);
    let p = dir.join("bad.toml");
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

/// The built-in model knows its own cloth and says it does not know what is not cloth:
/// frames of the letters scene and of the independently rendered roll of shapes are an
/// unknown fabric, frames of held-out simulated cloth (seeds training never used) are not.
#[test]
fn the_built_in_model_tells_cloth_it_knows_from_what_is_not_cloth() {
    let detector = Detector::built_in().unwrap();
    let letters = rollfuse::sim::Scene::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/letters.toml"
    )))
    .unwrap();
    let sim = rollfuse::sim::Simulator::new(&letters).unwrap();
    let fixture = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/roll-narrow-contact"
    ));
    let not_cloth = [10, 20, 30].map(|k| sim.frame(k).image).into_iter().chain(
        ["frame_050.png", "frame_150.png"]
            .map(|f| Planes::load(&fixture.join(f), PixelLimit::default()).unwrap()),
    );
    for (k, image) in not_cloth.enumerate() {
        let d = detector.detect(&image).unwrap();
        assert_eq!(
            d.fabric,
            rollfuse::detect::UNKNOWN_FABRIC,
            "image {k}: {d:?}"
        );
        assert!(d.unfamiliarity.unwrap() > 1.0, "image {k}: {d:?}");
    }
    let shape = data::RollShape {
        frames: 4,
        ..data::RollShape::STANDARD
    };
    for seed in [3, 8, 12] {
        let roll = data::roll(seed, &shape).unwrap();
        for s in roll.frames.iter().chain(&roll.fused) {
            let d = detector.detect(&s.image).unwrap();
            let u = d.unfamiliarity.unwrap();
            assert!(
                u <= 1.0 && d.fabric == d.most_like,
                "seed {seed}: {u:.2} {d:?}"
            );
        }
    }
}

/// `rollfuse detect` says so in words, and its JSON says how far off the image is.
#[test]
fn an_unknown_fabric_is_said_in_words() {
    let tmp = tempfile::tempdir().unwrap();
    let frame = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/roll-narrow-contact/frame_100.png"
    ));
    let json = tmp.path().join("d.json");
    let out = rollfuse(&[
        "detect",
        frame.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("unknown fabric ("), "{text}");
    assert!(
        text.contains("× the distance of the cloth the model knows"),
        "{text}"
    );
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(v[0]["fabric"], "unknown");
    assert!(v[0]["most_like"].is_string());
    assert!(v[0]["unfamiliarity"].as_f64().unwrap() > 1.0);
}
