//! Speed of depth reconstruction at 640×480: photometric stereo and Poisson integration,
//! on one thread (the figure compared with the numpy/scipy reference,
//! `host/bench/compare_depth.sh`) and on all.
//!
//! `cargo bench -p rollfuse --bench depth`.

use criterion::{Criterion, criterion_group, criterion_main};
use rollfuse::depth::lights::Lights;
use rollfuse::depth::synthetic::ball;
use rollfuse::depth::{poisson, reconstruct, stereo};
use rollfuse::image::Planes;
use std::hint::black_box;

fn depth(c: &mut Criterion) {
    let (w, h) = (640, 480);
    let lights = Lights::product(0.025);
    let (_, image) = ball((w, h), (300.0, 250.0), 2.0, 0.8, &lights, 180.0);
    let background = Planes {
        width: w,
        height: h,
        planes: vec![vec![180.0; w * h]; 3],
    };
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut group = c.benchmark_group("depth 640x480");
    group.bench_function("stereo + Poisson, 1 thread", |b| {
        one.install(|| {
            b.iter(|| reconstruct(black_box(&image), Some(&background), &lights).unwrap())
        })
    });
    group.bench_function("stereo + Poisson, all threads", |b| {
        b.iter(|| reconstruct(black_box(&image), Some(&background), &lights).unwrap())
    });
    group.bench_function("stereo only, 1 thread", |b| {
        b.iter(|| stereo::slopes(black_box(&image), &background, &lights).unwrap())
    });
    let s = stereo::slopes(&image, &background, &lights).unwrap();
    group.bench_function("Poisson f64 (gradients in), 1 thread", |b| {
        one.install(|| b.iter(|| poisson::integrate(black_box(&s.p), &s.q, w, h).unwrap()))
    });
    let rhs: Vec<f32> = s.p.iter().map(|&v| v as f32 * 1e-3).collect();
    group.bench_function("Poisson f32 solve (as depth runs it), 1 thread", |b| {
        one.install(|| b.iter(|| poisson::solve_neumann(black_box(rhs.clone()), w, h).unwrap()))
    });
    group.finish();
}

criterion_group!(benches, depth);
criterion_main!(benches);
