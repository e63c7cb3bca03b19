//! A stream of the letters scene for the live page's tests.

use rollfuse::sim::Scene;
use rollfuse::stream::Options;
use std::path::Path;

/// The letters scene cut to `frames` frames.
pub fn letters(frames: usize) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/letters.toml");
    let mut scene = Scene::load(&path).unwrap();
    scene.sensor.frames = frames;
    scene
}

/// A stream's options writing into `out`, with the device's configuration and no limits.
pub fn options(out: &Path) -> Options {
    Options::into_folder(out)
}
