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

/// The mean of the errors (the strip moved as a whole) and their spread (standard
/// deviation: how far apart frames are placed relative to each other).
fn mean_and_spread(errors: &[f64]) -> (f64, f64) {
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<f64>() / n;
    let spread = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
    (mean, spread)
}

/// The commanded positions alone are off by up to ±2 px (a spread of 1.15); matched steps
/// anchored to them bring every scene within a row, and the scenes to 0.7 on average. No
/// scene's strip is moved as a whole by more than 0.4 rows: the filter rounds each
/// correction to the nearest sixteenth of a row (rounded down, the half sixteenth lost
/// every frame adds up, through the filter's small gain, to half a row).
#[test]
fn the_device_places_frames_within_a_row_of_the_belt() {
    let scenes = ["letters", "dots", "lines", "curves"];
    let mut spreads = Vec::new();
    for name in scenes {
        let (mean, spread) = mean_and_spread(&placement_errors(name));
        eprintln!(
            "{name}: the device's placement off by {mean:+.2} rows on average, spread {spread:.2}"
        );
        assert!(
            spread <= 1.0,
            "{name}: frames placed {spread:.2} rows apart"
        );
        assert!(
            mean.abs() <= 0.4,
            "{name}: frames placed {mean:+.2} rows off"
        );
        spreads.push(spread);
    }
    let mean = spreads.iter().sum::<f64>() / spreads.len() as f64;
    assert!(mean <= 0.7, "frames placed {mean:.2} rows apart on average");
}
