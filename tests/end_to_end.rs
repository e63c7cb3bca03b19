//! End-to-end: a rolling acquisition fused cyclically on the integer (MCU) path keeps the
//! full contact of every strip, where any single frame has it in one strip only.

use rollfuse_core::fusion::{CyclicBuffers, fuse_scratch_len};
use rollfuse_core::{CyclicFuser, Dims, FuseConfig, LlWeighting, Wavelet};
use rollfuse_tests::{rolling_frames, strip_contrast};

#[test]
fn cyclic_fusion_evens_out_contact_across_the_roll() {
    let (w, h, n) = (96, 96, 6);
    let frames = rolling_frames(w, h, n);
    let strips = 6;
    let strip = |img: &[u8], s: usize| strip_contrast(img, w, s * h / strips, (s + 1) * h / strips);

    for wavelet in [Wavelet::Haar, Wavelet::Db2] {
        for weighting in [LlWeighting::Paper, LlWeighting::Equal] {
            let cfg = FuseConfig {
                wavelet,
                levels: 2,
                ll_weighting: weighting,
                ..FuseConfig::default()
            };
            let (mut fused, mut a, mut b) =
                (vec![0u8; w * h], vec![0i32; w * h], vec![0i32; w * h]);
            let mut scratch = vec![0i32; fuse_scratch_len(Dims::new(w, h).unwrap())];
            let bufs = CyclicBuffers {
                fused: &mut fused,
                work_a: &mut a,
                work_b: &mut b,
                scratch: &mut scratch,
            };
            let mut fuser = CyclicFuser::new(cfg, w, h, bufs).unwrap();
            for f in &frames {
                fuser.push(f, w).unwrap();
            }
            let out = fuser.fused();
            let middle = &frames[n / 2];
            let fused_c: Vec<f64> = (0..strips).map(|s| strip(out, s)).collect();
            let single_c: Vec<f64> = (0..strips).map(|s| strip(middle, s)).collect();
            let best_c: Vec<f64> = (0..strips)
                .map(|s| frames.iter().map(|f| strip(f, s)).fold(0.0, f64::max))
                .collect();
            println!(
                "{wavelet:?} {weighting:?}\n fused  {fused_c:.2?}\n single {single_c:.2?}\n best   {best_c:.2?}"
            );
            for s in 0..strips {
                // Every strip keeps most of the contrast of the frame that pressed it hardest.
                assert!(
                    fused_c[s] >= 0.6 * best_c[s],
                    "strip {s}: {} vs {}",
                    fused_c[s],
                    best_c[s]
                );
            }
            // The weakest strip of the fusion beats the weakest strip of the middle frame.
            let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
            assert!(min(&fused_c) > 2.0 * min(&single_c));
        }
    }
}
