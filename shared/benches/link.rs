//! Speed of the device link and the device pipeline on the host: encoding and decoding
//! tile messages (bytes/s), and one camera frame through the device pipeline at the
//! default configuration (QVGA YUYV in at full resolution, db2, 1 level, 16-row tiles,
//! 4 frames per tile).
//!
//! `cargo bench -p rollfuse-core --bench link`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rollfuse_core::device::{CAMERA, ModuleBuffers, Pipeline, PipelineConfig};
use rollfuse_core::protocol::{self, DeviceConfig, DeviceMessage, MAX_MESSAGE, Tile};
use std::hint::black_box;

fn messages(c: &mut Criterion) {
    let pixels: Vec<u8> = (0..320 * 16).map(|i| (i * 7) as u8).collect();
    let tile = DeviceMessage::Tile(Tile {
        index: 1234,
        width: 320,
        height: 16,
        observations: 4,
        pixels: &pixels,
    });
    let mut buf = vec![0u8; MAX_MESSAGE];
    let n = protocol::encode(0, &tile, &mut buf).unwrap();
    let mut group = c.benchmark_group("link");
    group.throughput(Throughput::Bytes(n as u64));
    group.bench_function("encode tile 320x16", |b| {
        b.iter(|| protocol::encode(black_box(7), black_box(&tile), &mut buf).unwrap())
    });
    let encoded = buf[..n].to_vec();
    group.bench_function("decode tile 320x16", |b| {
        b.iter(|| protocol::decode::<DeviceMessage>(black_box(&encoded)).unwrap())
    });
    group.finish();
}

fn pipeline(c: &mut Criterion) {
    let cfg = PipelineConfig::from_wire(&DeviceConfig::default(), CAMERA).unwrap();
    let mut memory = Box::new(ModuleBuffers::new());
    let mut p = Pipeline::new(cfg, memory.buffers()).unwrap();
    // Textured YUYV frames of a belt moving 16 camera rows per frame.
    let camera = |k: usize| -> Vec<u8> {
        let w = CAMERA.width;
        (0..w * CAMERA.height)
            .flat_map(|i| {
                let (x, y) = (i % w, i / w + 16 * k);
                let luma = (60 + ((x * 7) ^ (y * 13)) % 90 + (y * 31 % 50)) as u8;
                [luma, 128]
            })
            .collect()
    };
    let frames: Vec<Vec<u8>> = (0..16).map(camera).collect();
    let mut k = 0u64;
    let mut group = c.benchmark_group("device pipeline");
    group.throughput(Throughput::Elements(320 * 240));
    group.bench_function("frame 320x240", |b| {
        b.iter(|| {
            let f = &frames[(k % 16) as usize];
            // Positions keep growing so the belt never runs backwards.
            let r = p.push_frame(f, 16 * k, |t| {
                black_box(t);
            });
            k += 1;
            r
        })
    });
    group.finish();
}

criterion_group!(benches, messages, pipeline);
criterion_main!(benches);
