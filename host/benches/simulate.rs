//! Simulator speed: frames per second for the letters scene at 320×240 and 640×480, with
//! `contact + gray` and with every effect.
//!
//! `cargo bench -p rollfuse --bench simulate`; criterion reports frames/s as elements/s.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rollfuse::sim::{Effect, Scene, Simulator};
use std::hint::black_box;

fn letters(width: usize, height: usize, effects: &[Effect]) -> Scene {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml");
    let mut scene = Scene::load(std::path::Path::new(path)).expect("letters scene");
    // Keep the field of view in mm: a larger image is a finer pixel pitch.
    scene.sensor.mm_per_px *= scene.sensor.width_px as f64 / width as f64;
    scene.sensor.width_px = width;
    scene.sensor.height_px = height;
    scene.effects = effects.to_vec();
    scene
}

fn frames(c: &mut Criterion) {
    let mut group = c.benchmark_group("simulate_letters");
    group.throughput(Throughput::Elements(1));
    let all = [
        Effect::Contact,
        Effect::Gel,
        Effect::Gray,
        Effect::Defocus,
        Effect::Noise,
        Effect::Jitter,
        Effect::Background,
    ];
    for (w, h) in [(320, 240), (640, 480)] {
        for (label, effects) in [
            ("contact+gray", &[Effect::Contact, Effect::Gray][..]),
            ("all", &all[..]),
        ] {
            let sim = Simulator::new(&letters(w, h, effects)).expect("scene");
            let n = sim.frames();
            let mut k = 0;
            group.bench_function(BenchmarkId::new(label, format!("{w}x{h}")), |b| {
                b.iter(|| {
                    k = (k + 1) % n;
                    black_box(sim.frame(k))
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, frames);
criterion_main!(benches);
