//! The core never panics: random sizes (zero included), levels out of range, short
//! buffers, out-of-range samples and every configuration give `Ok` or an `Err`, never a
//! panic or an overflow (tests build with overflow checks on).

use proptest::prelude::*;
use rollfuse_core::fusion::{LlWeight, U8Pair, U8Work, fuse_pair, fuse_scratch_len, fuse_u8};
use rollfuse_core::lifting::{forward_2d, inverse_2d, scratch_len};
use rollfuse_core::{Ablation, Dims, FuseConfig, LlWeighting, SaliencyNorm, Wavelet, float};

fn config() -> impl Strategy<Value = FuseConfig> {
    (
        any::<bool>(),
        0u8..=6,
        0u8..4,
        prop_oneof![
            Just(SaliencyNorm::Local),
            any::<u32>().prop_map(SaliencyNorm::Reference)
        ],
        any::<bool>(),
    )
        .prop_map(|(db2, levels, ablation, norm, equal)| FuseConfig {
            wavelet: if db2 { Wavelet::Db2 } else { Wavelet::Haar },
            levels,
            ablation: [
                Ablation::None,
                Ablation::NoWavelet,
                Ablation::SingleLl,
                Ablation::MaxHigh,
            ][ablation as usize],
            norm,
            ll_weighting: if equal {
                LlWeighting::Equal
            } else {
                LlWeighting::Paper
            },
        })
}

/// A buffer length near `n`: sometimes short by a little, sometimes exact or longer.
fn len_near(n: usize, pick: u8) -> usize {
    match pick % 4 {
        0 => n.saturating_sub(1 + pick as usize % 3),
        1 => n + pick as usize % 5,
        _ => n,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn fuse_u8_never_panics(
        w in 0usize..48, h in 0usize..48, cfg in config(),
        picks in any::<[u8; 4]>(), seed in any::<u64>(), weight in any::<u16>(),
    ) {
        let n = w * h;
        let a0: Vec<u8> = (0..len_near(n, picks[0])).map(|i| (seed >> (i % 56)) as u8).collect();
        let mut a = a0.clone();
        let b: Vec<u8> = (0..len_near(n, picks[1])).map(|i| (seed.rotate_left(i as u32) >> 7) as u8).collect();
        let mut wa = vec![0i32; len_near(n, picks[2])];
        let mut wb = vec![0i32; n];
        let scratch_n = Dims::new(w.max(1), h.max(1)).map(fuse_scratch_len).unwrap_or(0);
        let mut scratch = vec![0i32; len_near(scratch_n, picks[3])];
        let result = match (Dims::new(w, h), Dims::new(w, h)) {
            (Ok(da), Ok(db)) => fuse_u8(U8Pair { a: &mut a, a_dims: da, b: &b, b_dims: db }, &cfg, LlWeight::for_frame(cfg.ll_weighting, u32::from(weight)),
                U8Work { a: &mut wa, b: &mut wb, scratch: &mut scratch },
            ),
            (Err(e), _) | (_, Err(e)) => Err(e),
        };
        // A failed step leaves the first image as it was; a fused one only its region.
        let kept = if result.is_ok() { n.min(a.len()) } else { 0 };
        prop_assert_eq!(&a[kept..], &a0[kept..]);
    }

    #[test]
    fn integer_transforms_and_fuse_pair_never_panic(
        w in 1usize..40, h in 1usize..40, cfg in config(),
        seed in any::<u64>(), wild in any::<bool>(), short in any::<bool>(),
    ) {
        let dims = Dims::new(w, h).unwrap();
        // Sometimes samples far outside the accepted range.
        let scale = if wild { i32::MAX / 255 } else { 1 };
        let img: Vec<i32> = (0..w * h).map(|i| ((seed >> (i % 57)) & 0xff) as i32 * scale).collect();
        let mut scratch = vec![0i32; fuse_scratch_len(dims) - usize::from(short)];
        let mut buf = img.clone();
        let _ = forward_2d(cfg.wavelet, &mut buf, dims, cfg.levels, &mut scratch[..scratch_len(dims) - usize::from(short)]);
        let _ = inverse_2d(cfg.wavelet, &mut buf, dims, cfg.levels, &mut scratch);
        let (mut a, mut b) = (img.clone(), img.iter().rev().copied().collect::<Vec<_>>());
        let _ = fuse_pair(&mut a, &mut b, dims, &cfg, LlWeight::HALF, &mut scratch);
    }

    #[test]
    fn float_fuse_never_panics(
        w in 1usize..40, h in 1usize..40, cfg in config(),
        seed in any::<u64>(), poison in any::<bool>(), short in any::<bool>(),
    ) {
        let dims = Dims::new(w, h).unwrap();
        let n = dims.pixels();
        let mut a: Vec<f32> = (0..n).map(|i| ((seed >> (i % 60)) & 0xfff) as f32).collect();
        let mut b: Vec<f32> = a.iter().rev().copied().collect();
        if poison {
            b[n / 2] = f32::INFINITY;
        }
        let mut scratch = vec![0f32; float::fuse_scratch_len(dims) - usize::from(short)];
        if float::fuse_pair(&mut a, &mut b, dims, &cfg, LlWeight::HALF, &mut scratch).is_ok() {
            prop_assert!(a.iter().all(|v| v.is_finite()));
        }
    }
}
