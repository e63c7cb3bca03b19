//! The paper's claim on the simulated standardized samples (Table III): fusing four
//! frames raises IE by at least 8 % and lowers its regional spread by at least 20 % against
//! the single middle frame, without losing MS-SSIM (the paper: IE +8 %, IE_std −20 %,
//! MS-SSIM kept).

use rollfuse::eval::tables::{Row, evaluate_scene};
use rollfuse::sim::Scene;
use rollfuse_core::FuseConfig;
use std::path::Path;

fn find<'a>(rows: &'a [Row], method: &str) -> &'a Row {
    rows.iter()
        .find(|r| r.method == method)
        .unwrap_or_else(|| panic!("no row {method}"))
}

#[test]
fn four_frame_fusion_beats_the_single_frame_as_the_paper_reports() {
    for name in ["dots", "lines", "curves"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}.toml"));
        let scene = Scene::load(&path).unwrap();
        let rows = evaluate_scene(&scene, &FuseConfig::default(), 10).unwrap();
        let single = &find(&rows, "single image").report;
        let fused = &find(&rows, "fusion of 4").report;
        let ie_gain = fused.ie / single.ie - 1.0;
        let std_drop = 1.0 - fused.ie_std / single.ie_std;
        let ms_change = fused.ms_ssim.unwrap() - single.ms_ssim.unwrap();
        println!(
            "{name}: IE {ie_gain:+.3}, IE_std {:+.3}, MS-SSIM {ms_change:+.4}",
            -std_drop
        );
        assert!(ie_gain >= 0.08, "{name}: IE +{ie_gain:.3}");
        assert!(std_drop >= 0.20, "{name}: IE_std −{std_drop:.3}");
        assert!(ms_change >= -0.02, "{name}: MS-SSIM {ms_change:+.4}");
        // Every figure is a finite number in its range.
        for r in &rows {
            let m = r.report.ms_ssim.unwrap();
            assert!(
                (0.0..=8.0).contains(&r.report.ie) && (0.0..=1.0).contains(&m),
                "{}: {:?}",
                r.method,
                r.report
            );
        }
    }
}

#[test]
fn too_short_a_sequence_is_refused() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/dots.toml");
    let mut scene = Scene::load(&path).unwrap();
    scene.sensor.frames = 6;
    let err = evaluate_scene(&scene, &FuseConfig::default(), 10).unwrap_err();
    assert!(format!("{err}").contains("at least 7"), "{err}");
}

/// Table IV: fusion evens out the depth the curved gel gives three equal spheres — the
/// spread of their contact areas by at least half, and (unlike the paper's 3-frame
/// fusion) the spread of their heights too.
#[test]
fn fusion_evens_out_the_three_spheres_depth() {
    use rollfuse::eval::depth::evaluate_depth;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/spheres.toml");
    let rows = evaluate_depth(&Scene::load(&path).unwrap()).unwrap();
    let (single, three, two) = (&rows[0], &rows[1], &rows[2]);
    for r in &rows {
        println!(
            "{}: area std {:.4}, peak std {:.4} mm",
            r.method, r.overlap_std, r.peak_std_mm
        );
        assert!(r.overlap.iter().all(|o| (0.0..=1.0).contains(o)));
        assert!(
            r.peak_mm
                .iter()
                .all(|p| p.is_finite() && *p > 0.0 && *p < 1.5)
        );
    }
    assert!(three.overlap_std <= 0.5 * single.overlap_std);
    assert!(three.peak_std_mm < single.peak_std_mm);
    assert!(two.overlap_std < single.overlap_std);
    // Not a scene for depth: refused.
    let gray =
        Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/dots.toml")).unwrap();
    assert!(format!("{}", evaluate_depth(&gray).unwrap_err()).contains("not RGB"));
}
