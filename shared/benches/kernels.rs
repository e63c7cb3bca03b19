//! Speed of the core kernels: forward and inverse lifting (Haar, db2; 1 and 3 levels) and
//! one fuse step (integer and f32; f32 also on the hot loops' AVX2 and baseline copies,
//! where the CPU has wider units), at the device's downsampled tile size (160×120), at
//! 640×480 (fuse step) and at full camera resolution (1280×960).
//!
//! `cargo bench -p rollfuse-core --bench kernels`; throughput is reported in pixels/s.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rollfuse_core::fusion::{LlWeight, U8Pair, U8Work, fuse_scratch_len, fuse_u8};
use rollfuse_core::lifting::{forward_2d, inverse_2d, scratch_len};
use rollfuse_core::simd::{VectorUnit, set_vector_limit};
use rollfuse_core::{Dims, FuseConfig, Wavelet, float};
use std::hint::black_box;

const SIZES: [(usize, usize); 2] = [(160, 120), (1280, 960)];
/// The fuse step also at the host's common 640×480.
const FUSE_SIZES: [(usize, usize); 3] = [(160, 120), (640, 480), (1280, 960)];

/// A textured 8-bit test image (smooth ramps plus a fine pattern), deterministic.
fn image(w: usize, h: usize, phase: usize) -> Vec<u8> {
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let ramp = (x * 97 / w + y * 61 / h) as u32;
            let texture = (((x + phase) * 7) ^ (y * 13)) % 40;
            (60 + ramp + texture as u32).min(255) as u8
        })
        .collect()
}

fn lifting(c: &mut Criterion) {
    let mut group = c.benchmark_group("lifting");
    for (w, h) in SIZES {
        let dims = Dims::new(w, h).unwrap();
        group.throughput(Throughput::Elements(dims.pixels() as u64));
        let src: Vec<i32> = image(w, h, 0).iter().map(|&v| v.into()).collect();
        let mut scratch = vec![0; scratch_len(dims)];
        for wavelet in [Wavelet::Haar, Wavelet::Db2] {
            for levels in [1u8, 3] {
                let id = format!("{wavelet:?}/L{levels}/{w}x{h}");
                let mut buf = src.clone();
                group.bench_function(BenchmarkId::new("forward", &id), |b| {
                    b.iter(|| {
                        buf.copy_from_slice(&src);
                        forward_2d(wavelet, black_box(&mut buf), dims, levels, &mut scratch)
                            .unwrap();
                    })
                });
                let mut coeffs = src.clone();
                forward_2d(wavelet, &mut coeffs, dims, levels, &mut scratch).unwrap();
                group.bench_function(BenchmarkId::new("inverse", &id), |b| {
                    b.iter(|| {
                        buf.copy_from_slice(&coeffs);
                        inverse_2d(wavelet, black_box(&mut buf), dims, levels, &mut scratch)
                            .unwrap();
                    })
                });
            }
        }
    }
    group.finish();
}

fn fuse_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("fuse_step");
    group.sample_size(20);
    for (w, h) in FUSE_SIZES {
        let dims = Dims::new(w, h).unwrap();
        group.throughput(Throughput::Elements(dims.pixels() as u64));
        let (a, b) = (image(w, h, 0), image(w, h, 3));
        for wavelet in [Wavelet::Haar, Wavelet::Db2] {
            let cfg = FuseConfig {
                wavelet,
                levels: 2,
                ..FuseConfig::default()
            };
            let id = format!("{wavelet:?}/L2/{w}x{h}");

            let (mut wa, mut wb) = (vec![0; w * h], vec![0; w * h]);
            let mut scratch = vec![0; fuse_scratch_len(dims)];
            // The result replaces the first image: each step starts from a fresh copy.
            let mut fused = a.clone();
            group.bench_function(BenchmarkId::new("integer", &id), |bench| {
                bench.iter(|| {
                    let work = U8Work {
                        a: &mut wa,
                        b: &mut wb,
                        scratch: &mut scratch,
                    };
                    fused.copy_from_slice(&a);
                    fuse_u8(
                        U8Pair::same(&mut fused, &b, dims),
                        &cfg,
                        LlWeight::HALF,
                        work,
                    )
                    .unwrap();
                })
            });

            let load = |img: &[u8]| img.iter().map(|&v| f32::from(v)).collect::<Vec<f32>>();
            let (fa0, fb0) = (load(&a), load(&b));
            let (mut fa, mut fb) = (fa0.clone(), fb0.clone());
            let mut fscratch = vec![0f32; float::fuse_scratch_len(dims)];
            // Also on narrower copies of the hot loops (`simd`): what each wider unit
            // buys, in the same run (the same copies where the CPU lacks the unit).
            let units = [
                ("f32", VectorUnit::Avx512),
                ("f32-avx2", VectorUnit::Avx2),
                ("f32-baseline", VectorUnit::Baseline),
            ];
            for (name, unit) in units {
                set_vector_limit(unit);
                group.bench_function(BenchmarkId::new(name, &id), |bench| {
                    bench.iter(|| {
                        fa.copy_from_slice(&fa0);
                        fb.copy_from_slice(&fb0);
                        let ll = LlWeight::HALF;
                        float::fuse_pair(&mut fa, &mut fb, dims, &cfg, ll, &mut fscratch).unwrap();
                    })
                });
            }
            set_vector_limit(VectorUnit::Avx512);
        }
    }
    group.finish();
}

criterion_group!(benches, lifting, fuse_step);
criterion_main!(benches);
