//! The device pipeline's placement of frames on a rolled belt, against the simulator's
//! truth: its matched steps and the commanded motion together keep every frame near
//! where the belt really was, though each commanded position is off by up to ±2 px.

use rollfuse::link::sim::{camera_bytes, sensor_for};
use rollfuse::pipeline_memory::PipelineMemory;
use rollfuse::sim::{Scene, Simulator};
use rollfuse_core::device::{Pipeline, PipelineConfig};

/// Each frame's offset from the device pipeline at its default configuration minus where
/// the belt really was, rows, over the built-in scene `name` rolled as `eval --roll` rolls
/// it.
fn placement_errors(name: &str) -> Vec<f64> {
    let path = format!("{}/scenes/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(std::path::Path::new(&path)).unwrap();
    let scene = rollfuse::eval::roll::rolled(&scene).unwrap();
    let sim = Simulator::new(&scene).unwrap();
    let (sensor, wire) = sensor_for(&scene, &sim);
    let cfg = PipelineConfig::from_wire(&wire, sensor).unwrap();
    assert_eq!(cfg.downsample(), 1, "rows are camera pixels");
    let mut memory = PipelineMemory::new(&cfg.memory());
    let mut pipeline = Pipeline::new(cfg, memory.buffers()).unwrap();
    // Positions count from the first frame's commanded one, as the virtual device's do.
    let origin = sim.strip_row_of_top(sim.frame(0).offset_mm);
    (0..sim.frames())
        .map(|k| {
            let frame = sim.frame(k);
            let commanded = sim.strip_row_of_top(frame.offset_mm) - origin;
            let truth = sim.strip_row_of_top(frame.actual_offset_mm) - origin;
            let px = commanded.round().max(0.0) as u64;
            let report = pipeline
                .push_frame(&camera_bytes(&frame.image), px, |_| {})
                .unwrap();
            report.offset as f64 - truth
        })
        .collect()
}

/// The spread (standard deviation) of the errors: how far apart frames are placed
/// relative to each other, which is what misregisters a strip; a constant error only
/// moves it.
fn spread(errors: &[f64]) -> f64 {
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<f64>() / n;
    (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// The commanded positions alone are off by up to ±2 px (a spread of 1.15); matched steps
/// anchored to them bring every scene within a row, and the scenes to 0.7 on average.
#[test]
fn the_device_places_frames_within_a_row_of_the_belt() {
    let scenes = ["letters", "dots", "lines", "curves"];
    let spreads: Vec<f64> = scenes
        .iter()
        .map(|name| spread(&placement_errors(name)))
        .collect();
    for (name, s) in scenes.iter().zip(&spreads) {
        eprintln!("{name}: the device's placement spread {s:.2} rows");
        assert!(*s <= 1.0, "{name}: frames placed {s:.2} rows apart");
    }
    let mean = spreads.iter().sum::<f64>() / spreads.len() as f64;
    assert!(mean <= 0.7, "frames placed {mean:.2} rows apart on average");
}
