//! Speed of the defect detector on one 320×240 frame with the built-in model: on one
//! thread (the figure held against the camera's 33 ms a frame) and on all.
//!
//! `cargo bench -p rollfuse --bench detect`.

use criterion::{Criterion, criterion_group, criterion_main};
use rollfuse::detect::Detector;
use rollfuse::detect::data::{RollShape, roll};
use std::hint::black_box;

fn detect(c: &mut Criterion) {
    let shape = RollShape {
        frames: 3,
        ..RollShape::STANDARD
    };
    let frame = roll(1, &shape).expect("a simulated roll").frames[1]
        .image
        .clone();
    let detector = Detector::built_in().expect("the built-in model");
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a thread pool");
    let mut group = c.benchmark_group("detect 320x240");
    group.bench_function("1 thread", |b| {
        one.install(|| b.iter(|| detector.detect(black_box(&frame)).expect("detects")))
    });
    group.bench_function("all threads", |b| {
        b.iter(|| detector.detect(black_box(&frame)).expect("detects"))
    });
    group.finish();
}

criterion_group!(benches, detect);
criterion_main!(benches);
