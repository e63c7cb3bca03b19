//! The hot loops' AVX-512 and AVX2 copies give what their baseline copies give, to the bit
//! (`rollfuse_core::simd`). A test binary of its own: the limit is process-wide.

mod common;

use common::tactile_scene;
use rollfuse_core::fusion::{LlWeight, fuse_pair, fuse_scratch_len};
use rollfuse_core::simd::{VectorUnit, avx2, avx512, set_vector_limit, vector_unit};
use rollfuse_core::{Ablation, Dims, FuseConfig, LlWeighting, SaliencyNorm, Wavelet, float};

/// Every configuration a fuse step can take that changes which loops run.
fn configs() -> Vec<FuseConfig> {
    let mut out = Vec::new();
    for wavelet in [Wavelet::Haar, Wavelet::Db2] {
        for levels in 1..=3 {
            let ablations = [
                Ablation::None,
                Ablation::MaxHigh,
                Ablation::SingleLl,
                Ablation::NoWavelet,
            ];
            for ablation in ablations {
                out.push(FuseConfig {
                    wavelet,
                    levels,
                    ablation,
                    norm: SaliencyNorm::Local,
                    ll_weighting: LlWeighting::Paper,
                });
            }
            out.push(FuseConfig {
                wavelet,
                levels,
                norm: SaliencyNorm::Reference(300),
                ..FuseConfig::default()
            });
        }
    }
    out
}

/// One fuse step of two scenes on every path, as raw bits: f32, f64 and the integer path.
fn fuse_all(w: usize, h: usize, cfg: &FuseConfig) -> (Vec<u32>, Vec<u64>, Vec<i32>) {
    let dims = Dims::new(w, h).unwrap();
    let (a, b) = (tactile_scene(w, h, 3, 0.8), tactile_scene(w, h, 4, 0.3));
    let ll = LlWeight::for_frame(LlWeighting::Equal, 3);

    let (mut fa, mut fb): (Vec<f32>, Vec<f32>) = (
        a.iter().map(|&v| f32::from(v) * 1.37).collect(),
        b.iter().map(|&v| f32::from(v) * 0.71).collect(),
    );
    let mut scratch = vec![0f32; float::fuse_scratch_len(dims)];
    float::fuse_pair(&mut fa, &mut fb, dims, cfg, ll, &mut scratch).unwrap();

    let (mut da, mut db): (Vec<f64>, Vec<f64>) = (
        a.iter().map(|&v| f64::from(v) * 1.37).collect(),
        b.iter().map(|&v| f64::from(v) * 0.71).collect(),
    );
    let mut scratch = vec![0f64; float::fuse_scratch_len(dims)];
    float::fuse_pair(&mut da, &mut db, dims, cfg, ll, &mut scratch).unwrap();

    let (mut ia, mut ib): (Vec<i32>, Vec<i32>) = (
        a.iter().map(|&v| i32::from(v) * 16).collect(),
        b.iter().map(|&v| i32::from(v) * 16).collect(),
    );
    let mut scratch = vec![0i32; fuse_scratch_len(dims)];
    fuse_pair(&mut ia, &mut ib, dims, cfg, ll, &mut scratch).unwrap();

    (
        fa.iter().map(|v| v.to_bits()).collect(),
        da.iter().map(|v| v.to_bits()).collect(),
        ia,
    )
}

// One test, so nothing else in this binary moves the limit meanwhile.
#[test]
fn every_vector_unit_fuses_to_the_same_bits() {
    let (has_avx2, has_avx512) = (avx2(), avx512());
    assert!(has_avx2 || !has_avx512, "every AVX-512 CPU has AVX2");
    set_vector_limit(VectorUnit::Baseline);
    assert_eq!(vector_unit(), VectorUnit::Baseline, "the limit must hold");
    assert!(!avx2() && !avx512());
    set_vector_limit(VectorUnit::Avx2);
    assert!(!avx512(), "the AVX2 limit must keep AVX-512 off");
    assert_eq!(avx2(), has_avx2, "the AVX2 limit must allow AVX2");
    set_vector_limit(VectorUnit::Avx512);
    assert_eq!(
        (avx2(), avx512()),
        (has_avx2, has_avx512),
        "the widest limit allows all"
    );
    // The wider units this CPU has, each compared with the baseline.
    let wide: Vec<VectorUnit> = [
        (VectorUnit::Avx2, has_avx2),
        (VectorUnit::Avx512, has_avx512),
    ]
    .into_iter()
    .filter_map(|(unit, has)| has.then_some(unit))
    .collect();
    if !has_avx512 {
        eprintln!("SKIPPED (AVX-512 part): no AVX-512 on this CPU; its copies never run here");
    }
    if wide.is_empty() {
        eprintln!("SKIPPED: no AVX2 on this CPU; the baseline copies are the only ones run");
        return;
    }
    // Odd and even sizes, one-row and one-column regions, and widths that leave vector
    // remainders of every length (of 4, 8 and 16 lanes).
    let sizes = [
        (64, 48),
        (37, 29),
        (17, 1),
        (1, 23),
        (2, 2),
        (45, 8),
        (130, 67),
        (95, 21),
    ];
    let mut compared = 0;
    for &(w, h) in &sizes {
        for cfg in configs() {
            if Dims::new(w, h).unwrap().check_levels(cfg.levels).is_err() {
                continue;
            }
            set_vector_limit(VectorUnit::Baseline);
            let baseline = fuse_all(w, h, &cfg);
            for &unit in &wide {
                set_vector_limit(unit);
                assert_eq!(vector_unit(), unit);
                let result = fuse_all(w, h, &cfg);
                assert!(
                    result == baseline,
                    "{w}×{h} {cfg:?}: {unit:?} and baseline differ"
                );
                compared += 1;
            }
        }
    }
    set_vector_limit(VectorUnit::Avx512);
    assert!(compared > 100, "only {compared} cases ran");
}
