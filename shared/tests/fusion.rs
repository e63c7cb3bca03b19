//! Behaviour of the fuse step and the cyclic fuser, integer and f32.

mod common;

use common::{step_edge, tactile_scene};
use rollfuse_core::float;
use rollfuse_core::fusion::{
    CyclicBuffers, LlWeight, U8Pair, U8Work, fuse_pair, fuse_scratch_len, fuse_u8,
};
use rollfuse_core::{
    Ablation, CyclicFuser, Dims, Error, FuseConfig, LlWeighting, SaliencyNorm, Wavelet,
};

fn cfg(wavelet: Wavelet, levels: u8) -> FuseConfig {
    FuseConfig {
        wavelet,
        levels,
        ..FuseConfig::default()
    }
}

/// Integer fuse of two 8-bit images, as the MCU does it.
fn fuse_int(a: &[u8], b: &[u8], w: usize, h: usize, cfg: &FuseConfig) -> Vec<u8> {
    let dims = Dims::new(w, h).unwrap();
    let (mut wa, mut wb) = (vec![0i32; w * h], vec![0i32; w * h]);
    let mut scratch = vec![0; fuse_scratch_len(dims)];
    let work = U8Work {
        a: &mut wa,
        b: &mut wb,
        scratch: &mut scratch,
    };
    let mut fused = a.to_vec();
    fuse_u8(U8Pair::same(&mut fused, b, dims), cfg, LlWeight::HALF, work).unwrap();
    fused
}

/// f32 fuse of two 8-bit images, rounded and clamped to 8 bits.
fn fuse_f32(a: &[u8], b: &[u8], w: usize, h: usize, cfg: &FuseConfig) -> Vec<u8> {
    let dims = Dims::new(w, h).unwrap();
    let mut fa: Vec<f32> = a.iter().map(|&v| f32::from(v)).collect();
    let mut fb: Vec<f32> = b.iter().map(|&v| f32::from(v)).collect();
    let mut scratch = vec![0f32; float::fuse_scratch_len(dims)];
    float::fuse_pair(&mut fa, &mut fb, dims, cfg, LlWeight::HALF, &mut scratch).unwrap();
    fa.iter()
        .map(|v| v.round().clamp(0.0, 255.0) as u8)
        .collect()
}

fn max_abs_diff(a: &[u8], b: &[u8]) -> u8 {
    a.iter()
        .zip(b)
        .map(|(x, y)| x.abs_diff(*y))
        .max()
        .unwrap_or(0)
}

/// Largest horizontal step between neighbours along row `y`.
fn edge_strength(img: &[u8], w: usize, y: usize) -> u8 {
    img[y * w..(y + 1) * w]
        .windows(2)
        .map(|p| p[0].abs_diff(p[1]))
        .max()
        .unwrap()
}

#[test]
fn fusing_an_image_with_itself_returns_it() {
    for wavelet in [Wavelet::Haar, Wavelet::Db2] {
        for levels in 1..=4 {
            for (w, h) in [(64, 48), (37, 29), (1, 20), (20, 1)] {
                let Ok(()) = Dims::new(w, h).unwrap().check_levels(levels) else {
                    continue;
                };
                let img = tactile_scene(w, h, 7, 0.8);
                let c = cfg(wavelet, levels);
                assert_eq!(
                    fuse_int(&img, &img, w, h, &c),
                    img,
                    "{wavelet:?} L{levels} {w}x{h}"
                );
                let f = fuse_f32(&img, &img, w, h, &c);
                assert!(
                    max_abs_diff(&f, &img) <= 1,
                    "f32 {wavelet:?} L{levels} {w}x{h}"
                );
            }
        }
    }
}

#[test]
fn fusing_with_a_flat_image_keeps_the_edges() {
    let (w, h) = (64, 32);
    let edge = step_edge(w, h, 31, 60, 200);
    let flat = vec![130u8; w * h];
    let original = edge_strength(&edge, w, h / 2);
    for wavelet in [Wavelet::Haar, Wavelet::Db2] {
        for levels in 1..=3 {
            let c = cfg(wavelet, levels);
            let fused = fuse_int(&edge, &flat, w, h, &c);
            let averaged = fuse_int(
                &edge,
                &flat,
                w,
                h,
                &FuseConfig {
                    ablation: Ablation::NoWavelet,
                    ..c
                },
            );
            let kept = edge_strength(&fused, w, h / 2);
            let avg = edge_strength(&averaged, w, h / 2);
            println!("{wavelet:?} L{levels}: edge {original} → fused {kept}, pixel average {avg}");
            // The flat image has no saliency, so the edge's detail bands pass with weight 1:
            // at least three quarters of the step survives, where averaging keeps half.
            assert!(
                kept as f64 >= 0.75 * original as f64,
                "{wavelet:?} L{levels}: {kept}"
            );
            assert!(kept > avg, "{wavelet:?} L{levels}: {kept} vs {avg}");
        }
    }
}

#[test]
fn float_and_integer_fusion_agree_within_two_gray_levels() {
    // Both paths run the same lifting steps with the same boundary rule and weights; they
    // differ only by the integer path's rounding.
    let mut worst = 0;
    for wavelet in [Wavelet::Haar, Wavelet::Db2] {
        for levels in 1..=3 {
            for seed in 0..4 {
                for (w, h) in [(96, 72), (61, 47)] {
                    let shallow = tactile_scene(w, h, seed, 0.2);
                    let deep = tactile_scene(w, h, seed, 1.0);
                    let c = cfg(wavelet, levels);
                    let d = max_abs_diff(
                        &fuse_int(&shallow, &deep, w, h, &c),
                        &fuse_f32(&shallow, &deep, w, h, &c),
                    );
                    println!(
                        "{wavelet:?} L{levels} seed {seed} {w}x{h}: max |f32 − integer| = {d}"
                    );
                    worst = worst.max(d);
                }
            }
        }
    }
    println!("worst: {worst} gray levels");
    assert!(worst <= 2, "{worst} gray levels");
}

#[test]
fn pixel_average_ablation_is_the_rounded_mean() {
    let (w, h) = (17, 9);
    let a = tactile_scene(w, h, 1, 0.5);
    let b = tactile_scene(w, h, 2, 0.9);
    let c = FuseConfig {
        ablation: Ablation::NoWavelet,
        ..FuseConfig::default()
    };
    let fused = fuse_int(&a, &b, w, h, &c);
    for ((&f, &x), &y) in fused.iter().zip(&a).zip(&b) {
        assert_eq!(f as u32, (x as u32 + y as u32).div_ceil(2));
    }
}

#[test]
fn max_high_and_single_ll_ablations_differ_from_the_method() {
    let (w, h) = (48, 40);
    let a = tactile_scene(w, h, 3, 0.1);
    let b = tactile_scene(w, h, 4, 1.0);
    let full = fuse_int(&a, &b, w, h, &FuseConfig::default());
    for ablation in [Ablation::MaxHigh, Ablation::SingleLl] {
        let c = FuseConfig {
            ablation,
            ..FuseConfig::default()
        };
        assert_ne!(fuse_int(&a, &b, w, h, &c), full, "{ablation:?}");
    }
    // With a flat second image, keeping the first image's LL and its (only salient)
    // detail returns the first image.
    let flat = vec![100u8; w * h];
    let c = FuseConfig {
        ablation: Ablation::SingleLl,
        ..FuseConfig::default()
    };
    let kept = fuse_int(&a, &flat, w, h, &c);
    assert!(max_abs_diff(&kept, &a) <= 1);
}

#[test]
fn two_flat_images_fuse_to_their_mean() {
    // Zero Laplacian everywhere: weights must be ½, not 0/0.
    for levels in 1..=4 {
        let fused = fuse_int(&[40; 256], &[200; 256], 16, 16, &cfg(Wavelet::Db2, levels));
        assert!(fused.iter().all(|&v| v == 120), "L{levels}: {fused:?}");
        let fused = fuse_f32(&[40; 256], &[200; 256], 16, 16, &cfg(Wavelet::Db2, levels));
        assert!(fused.iter().all(|&v| v == 120), "f32 L{levels}");
    }
}

struct Owned {
    fused: Vec<u8>,
    a: Vec<i32>,
    b: Vec<i32>,
    scratch: Vec<i32>,
}

impl Owned {
    fn new(w: usize, h: usize) -> Self {
        let n = w * h;
        Self {
            fused: vec![0; n],
            a: vec![0; n],
            b: vec![0; n],
            scratch: vec![0; fuse_scratch_len(Dims::new(w, h).unwrap())],
        }
    }

    fn buffers(&mut self) -> CyclicBuffers<'_> {
        CyclicBuffers {
            fused: &mut self.fused,
            work_a: &mut self.a,
            work_b: &mut self.b,
            scratch: &mut self.scratch,
        }
    }
}

#[test]
fn cyclic_fuser_keeps_a_constant_sequence_constant() {
    let (w, h) = (24, 16);
    let mut mem = Owned::new(w, h);
    for weighting in [LlWeighting::Paper, LlWeighting::Equal] {
        let c = FuseConfig {
            ll_weighting: weighting,
            levels: 2,
            ..FuseConfig::default()
        };
        let mut fuser = CyclicFuser::new(c, w, h, mem.buffers()).unwrap();
        let frame = tactile_scene(w, h, 11, 0.6);
        for n in 1..=20 {
            fuser.push(&frame, w).unwrap();
            assert_eq!(fuser.frames(), n);
            assert_eq!(fuser.fused(), &frame[..]);
        }
    }
}

#[test]
fn equal_ll_weighting_averages_flat_frames_evenly() {
    let (w, h) = (8, 8);
    let mut mem = Owned::new(w, h);
    let c = FuseConfig {
        ll_weighting: LlWeighting::Equal,
        ..FuseConfig::default()
    };
    let mut fuser = CyclicFuser::new(c, w, h, mem.buffers()).unwrap();
    for v in [30u8, 60, 90, 120] {
        fuser.push(&[v; 64], w).unwrap();
    }
    // Equal weights: (30 + 60 + 90 + 120) / 4 = 75 (the paper's pairwise mean gives 97.5).
    assert!(
        fuser.fused().iter().all(|&v| v.abs_diff(75) <= 1),
        "{:?}",
        fuser.fused()
    );
}

#[test]
fn cyclic_fuser_reads_strided_frames_and_refuses_bad_ones() {
    let (w, h) = (10, 6);
    let mut mem = Owned::new(w, h);
    let mut fuser = CyclicFuser::new(FuseConfig::default(), w, h, mem.buffers()).unwrap();
    assert_eq!(fuser.fused(), &[] as &[u8]);
    let stride = 13;
    let mut frame = vec![255u8; stride * h];
    for y in 0..h {
        frame[y * stride..y * stride + w].fill(50);
    }
    fuser.push(&frame, stride).unwrap();
    assert!(fuser.fused().iter().all(|&v| v == 50));
    assert_eq!(
        fuser.push(&frame[..stride * h - 4], stride),
        Err(Error::BufferTooSmall {
            which: "frame",
            needed: stride * (h - 1) + w,
            got: stride * h - 4
        })
    );
    assert_eq!(
        fuser.push(&frame, 5),
        Err(Error::StrideTooSmall {
            stride: 5,
            width: w
        })
    );
    // The good result is untouched by the refused frames.
    assert_eq!(fuser.frames(), 1);
    assert!(fuser.fused().iter().all(|&v| v == 50));
}

#[test]
fn cyclic_fuser_refuses_short_buffers_and_deep_levels() {
    let mut mem = Owned::new(4, 4);
    let c = FuseConfig {
        levels: 3,
        ..FuseConfig::default()
    };
    assert_eq!(
        CyclicFuser::new(c, 4, 4, mem.buffers()).err(),
        Some(Error::LevelsTooDeep { levels: 3, max: 2 })
    );
    assert_eq!(
        CyclicFuser::new(FuseConfig::default(), 5, 4, mem.buffers()).err(),
        Some(Error::BufferTooSmall {
            which: "fused",
            needed: 20,
            got: 16
        })
    );
}

#[test]
fn reference_normalization_saturates_instead_of_overflowing() {
    let (w, h) = (64, 64);
    let a = tactile_scene(w, h, 5, 1.0);
    let b = tactile_scene(w, h, 5, 0.3);
    for r in [0, 1, 10, u32::MAX] {
        for levels in 1..=4 {
            let c = FuseConfig {
                norm: SaliencyNorm::Reference(r),
                levels,
                ..FuseConfig::default()
            };
            let fused = fuse_int(&a, &b, w, h, &c);
            assert_eq!(fused.len(), w * h);
            // The same bounds as with local normalization: both paths scale the reference
            // alike (8-bit units, times each level's LL gain).
            let d = max_abs_diff(&fused, &fuse_f32(&a, &b, w, h, &c));
            println!("r {r} L{levels}: max |f32 − integer| = {d}");
            // With a reference maximum far above every Laplacian (u32::MAX), the integer
            // path's Sal (8 fraction bits) rounds all saliency to 0 and every weight to ½,
            // while the float path keeps the tiny saliencies' ratio: only realistic
            // references are compared.
            if r != u32::MAX {
                assert!(d <= 2, "r {r} L{levels}: {d}");
            }
        }
    }
}

#[test]
fn fuse_pair_refuses_bad_arguments() {
    let dims = Dims::new(8, 8).unwrap();
    let mut a = vec![0i32; 64];
    let mut b = vec![0i32; 64];
    let mut s = vec![0i32; fuse_scratch_len(dims)];
    let c = FuseConfig::default();
    assert_eq!(
        fuse_pair(&mut a, &mut b[..60], dims, &c, LlWeight::HALF, &mut s),
        Err(Error::BufferTooSmall {
            which: "second image",
            needed: 64,
            got: 60
        })
    );
    let short = s.len() - 1;
    assert!(matches!(
        fuse_pair(&mut a, &mut b, dims, &c, LlWeight::HALF, &mut s[..short]),
        Err(Error::BufferTooSmall {
            which: "scratch",
            ..
        })
    ));
    b[3] = 1 << 20;
    assert_eq!(
        fuse_pair(&mut a, &mut b, dims, &c, LlWeight::HALF, &mut s),
        Err(Error::SampleOutOfRange)
    );
    let n = dims.pixels();
    let mut fa = vec![0f32; n];
    let mut fb = vec![f32::NAN; n];
    let mut fs = vec![0f32; float::fuse_scratch_len(dims)];
    assert_eq!(
        float::fuse_pair(&mut fa, &mut fb, dims, &c, LlWeight::HALF, &mut fs),
        Err(Error::InvalidParameter {
            name: "sample (NaN, infinite or beyond ±1e9)"
        })
    );
    fb.fill(1e30);
    assert!(float::fuse_pair(&mut fa, &mut fb, dims, &c, LlWeight::HALF, &mut fs).is_err());
    fb.fill(1.0);
    let deeper = FuseConfig { levels: 4, ..c };
    assert_eq!(
        float::fuse_pair(&mut fa, &mut fb, dims, &deeper, LlWeight::HALF, &mut fs),
        Err(Error::LevelsTooDeep { levels: 4, max: 3 })
    );
    assert!(matches!(
        float::fuse_pair(&mut fa[..n - 1], &mut fb, dims, &c, LlWeight::HALF, &mut fs),
        Err(Error::BufferTooSmall {
            which: "first image",
            ..
        })
    ));
}

/// The float step checks both images in the pass that also finds their level-1 Laplacian
/// maxima: a bad sample anywhere, in either image, under either normalization, is refused
/// before either image changes. The widths take that pass through all its paths: one or
/// two samples (borders only), a short interior (sample by sample), and 75 (an interior
/// of two blocks of 32, one of 8 and one sample).
#[test]
fn float_step_refuses_a_bad_sample_anywhere_and_changes_nothing() {
    for (w, h) in [(9, 7), (1, 3), (2, 2), (75, 3)] {
        let dims = Dims::new(w, h).unwrap();
        let n = dims.pixels();
        let a0: Vec<f32> = (0..n).map(|i| (i * 37 % 251) as f32).collect();
        let b0: Vec<f32> = (0..n).map(|i| (i * 91 % 241) as f32).collect();
        let mut scratch = vec![0f32; float::fuse_scratch_len(dims)];
        for norm in [SaliencyNorm::Local, SaliencyNorm::Reference(100)] {
            let c = FuseConfig {
                norm,
                ..cfg(Wavelet::Db2, 1)
            };
            for bad in [f32::NAN, f32::INFINITY, -2e9] {
                for at in 0..n {
                    for poison_b in [false, true] {
                        let (mut a, mut b) = (a0.clone(), b0.clone());
                        let target = if poison_b { &mut b } else { &mut a };
                        target[at] = bad;
                        let (a1, b1) = (a.clone(), b.clone());
                        let r = float::fuse_pair(
                            &mut a,
                            &mut b,
                            dims,
                            &c,
                            LlWeight::HALF,
                            &mut scratch,
                        );
                        assert!(
                            r.is_err(),
                            "{w}x{h} {norm:?} {bad} at {at} in b: {poison_b}"
                        );
                        let same = |x: &[f32], y: &[f32]| {
                            x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())
                        };
                        assert!(same(&a, &a1) && same(&b, &b1), "an image changed");
                    }
                }
            }
        }
    }
}

/// The fuse step does not clear its window maps before summing into them (each map row is
/// set by its first pixel row): whatever the scratch held before — here NaN or large
/// integers — must not reach the result, for odd and even sizes (the windows' phase 1
/// leaves a last row and column no pixel reaches), flat images (no saliency rows at all)
/// and every level count.
#[test]
fn scratch_contents_do_not_reach_the_result() {
    for (w, h) in [(9, 7), (8, 6), (17, 4), (6, 11), (1, 5)] {
        let dims = Dims::new(w, h).unwrap();
        let n = dims.pixels();
        let a: Vec<i32> = (0..n as i32).map(|i| i * 37 % 251).collect();
        let b: Vec<i32> = (0..n as i32).map(|i| i * 91 % 241).collect();
        let flat = vec![77; n];
        for wavelet in [Wavelet::Haar, Wavelet::Db2] {
            for levels in 1..=dims.max_levels() {
                let c = cfg(wavelet, levels);
                for b in [&b, &flat] {
                    let int = |fill: i32| {
                        let (mut a, mut b) = (a.clone(), b.clone());
                        let mut s = vec![fill; fuse_scratch_len(dims)];
                        fuse_pair(&mut a, &mut b, dims, &c, LlWeight::HALF, &mut s).unwrap();
                        a
                    };
                    assert_eq!(
                        int(0),
                        int(i32::MAX),
                        "integer {w}x{h} {wavelet:?} L{levels}"
                    );
                    let float = |fill: f32| {
                        let mut a: Vec<f32> = a.iter().map(|&v| v as f32).collect();
                        let mut b: Vec<f32> = b.iter().map(|&v| v as f32).collect();
                        let mut s = vec![fill; float::fuse_scratch_len(dims)];
                        float::fuse_pair(&mut a, &mut b, dims, &c, LlWeight::HALF, &mut s).unwrap();
                        a.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                    };
                    assert_eq!(
                        float(0.0),
                        float(f32::NAN),
                        "f32 {w}x{h} {wavelet:?} L{levels}"
                    );
                }
            }
        }
    }
}
