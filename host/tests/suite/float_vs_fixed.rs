//! Float vs integer fusion on the product's own kind of image: consecutive frames of the
//! simulated scenes (contact fading toward the image edges, defocus, uneven light, noise).
//! The core's test `float_and_integer_fusion_agree_within_two_gray_levels` covers synthetic
//! images with texture up to the borders.

use rollfuse::sim::{Scene, Simulator};
use rollfuse_core::fusion::{LlWeight, U8Pair, U8Work, fuse_scratch_len, fuse_u8};
use rollfuse_core::{Dims, FuseConfig, Wavelet, float};
use std::path::Path;

#[test]
fn float_and_fixed_agree_within_two_gray_levels_on_simulated_frames() {
    let mut worst = 0;
    for name in ["letters", "dots", "fabric", "screw"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}.toml"));
        let scene = Scene::load(&path).unwrap();
        let sim = Simulator::new(&scene).unwrap();
        let m = sim.frames() / 2;
        let (a, b) = (sim.frame(m).image.to_u8(), sim.frame(m + 1).image.to_u8());
        let dims = Dims::new(scene.sensor.width_px, scene.sensor.height_px).unwrap();
        let n = dims.pixels();
        for wavelet in [Wavelet::Haar, Wavelet::Db2] {
            for levels in 1..=3 {
                let cfg = FuseConfig {
                    wavelet,
                    levels,
                    ..FuseConfig::default()
                };
                let (mut wa, mut wb) = (vec![0i32; n], vec![0i32; n]);
                let mut scratch = vec![0; fuse_scratch_len(dims)];
                let work = U8Work {
                    a: &mut wa,
                    b: &mut wb,
                    scratch: &mut scratch,
                };
                let mut fused = a.clone();
                fuse_u8(
                    U8Pair::same(&mut fused, &b, dims),
                    &cfg,
                    LlWeight::HALF,
                    work,
                )
                .unwrap();
                let mut fa: Vec<f32> = a.iter().map(|&v| f32::from(v)).collect();
                let mut fb: Vec<f32> = b.iter().map(|&v| f32::from(v)).collect();
                let mut fscratch = vec![0f32; float::fuse_scratch_len(dims)];
                float::fuse_pair(&mut fa, &mut fb, dims, &cfg, LlWeight::HALF, &mut fscratch)
                    .unwrap();
                let d = fused
                    .iter()
                    .zip(&fa)
                    .map(|(&i, &f)| i.abs_diff(f.round().clamp(0.0, 255.0) as u8))
                    .max()
                    .unwrap();
                println!("{name} {wavelet:?} L{levels}: max |f32 − fixed| = {d}");
                worst = worst.max(d);
            }
        }
    }
    println!("worst over the whole image: {worst} gray levels");
    assert!(worst <= 2, "{worst} gray levels");
}
