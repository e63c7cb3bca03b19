//! The f32 transforms against PyWavelets' `dwt2`/`idwt2` in `periodization` mode, on the
//! committed vectors of `tests/vectors/gen.py`.

use rollfuse_core::lifting::filter_bank::{dwt2, idwt2, level_scratch_len, subband_dims};
use rollfuse_core::{Dims, Wavelet};
use serde_json::Value;

const TOLERANCE: f64 = 1e-4;

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn max_diff(got: impl Iterator<Item = f32>, want: &[f64]) -> f64 {
    got.zip(want)
        .map(|(g, w)| (g as f64 - w).abs())
        .fold(0.0, f64::max)
}

#[test]
fn dwt2_and_idwt2_match_pywavelets_periodization() {
    let doc: Value = serde_json::from_str(include_str!("vectors/pywt_dwt2.json")).unwrap();
    let cases = doc["cases"].as_array().unwrap();
    assert!(cases.len() >= 16);
    for case in cases {
        let wavelet = match case["wavelet"].as_str().unwrap() {
            "haar" => Wavelet::Haar,
            "db2" => Wavelet::Db2,
            other => panic!("unknown wavelet {other}"),
        };
        let (w, h) = (
            case["width"].as_u64().unwrap() as usize,
            case["height"].as_u64().unwrap() as usize,
        );
        let dims = Dims::new(w, h).unwrap();
        let input: Vec<f32> = floats(&case["input"]).iter().map(|&v| v as f32).collect();
        let (bw, bh) = subband_dims(w, h);
        let mut coeffs = vec![0f32; 4 * bw * bh];
        let mut scratch = vec![0f32; level_scratch_len(Dims::new(2 * bw, 2 * bh).unwrap())];
        dwt2(wavelet, &input, dims, &mut coeffs, &mut scratch).unwrap();

        // Mallat grid: cA | cV over cH | cD (PyWavelets' cV is high along rows).
        let band = |x0: usize, y0: usize| {
            let c = &coeffs;
            (0..bh).flat_map(move |y| (0..bw).map(move |x| c[(y0 + y) * 2 * bw + x0 + x]))
        };
        let label = format!("{wavelet:?} {w}x{h}");
        for (name, x0, y0) in [("cA", 0, 0), ("cV", bw, 0), ("cH", 0, bh), ("cD", bw, bh)] {
            let want = floats(&case[name]);
            assert_eq!(want.len(), bw * bh, "{label} {name}");
            let d = max_diff(band(x0, y0), &want);
            assert!(d <= TOLERANCE, "{label} {name}: max diff {d}");
        }

        let mut out = vec![0f32; w * h];
        idwt2(wavelet, &mut coeffs, dims, &mut out, &mut scratch).unwrap();
        let d = max_diff(out.iter().copied(), &floats(&case["idwt2"]));
        assert!(d <= TOLERANCE, "{label} idwt2: max diff {d}");
    }
}

#[test]
fn dwt2_refuses_short_buffers() {
    let dims = Dims::new(5, 3).unwrap();
    let img = [0f32; 15];
    let mut out = [0f32; 23];
    let mut scratch = [0f32; 48];
    let err = dwt2(Wavelet::Db2, &img, dims, &mut out, &mut scratch).unwrap_err();
    assert_eq!(
        err,
        rollfuse_core::Error::BufferTooSmall {
            which: "output",
            needed: 24,
            got: 23
        }
    );
}
