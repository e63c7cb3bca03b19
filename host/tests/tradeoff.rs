//! The trade-off study on the letters scene the virtual device streams: the reference is
//! what it claims to be, and the fixed-point default stays within 1 dB of the f32 path.

use rollfuse::progress::Silent;
use rollfuse::sim::Scene;
use rollfuse::tradeoff::bench::McuTable;
use rollfuse::tradeoff::{Setup, acquire, report, study};
use rollfuse_core::device::Precision;

fn letters() -> rollfuse::tradeoff::Acquisition {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/letters.toml");
    acquire(&Scene::load(std::path::Path::new(path)).unwrap()).unwrap()
}

#[test]
fn fixed_default_is_within_one_db_of_f32_and_full_resolution_matches_the_reference() {
    let acq = letters();
    let f32_default = Setup {
        precision: Precision::F32,
        ..Setup::DEFAULT
    };
    // At full resolution the device fuses exactly the reference's observations: only
    // rounding separates them (8-bit tiles every step; the integer lifting's rounding).
    let full = Setup {
        downsample: 1,
        ..Setup::DEFAULT
    };
    let setups = [Setup::DEFAULT, f32_default, full];
    let rows = study(&[acq], &setups, 1, &McuTable::empty(), &Silent).unwrap();
    let (fixed, float, full) = (&rows[0].accuracy, &rows[1].accuracy, &rows[2].accuracy);
    for a in [fixed, float, full] {
        assert!(
            a.psnr_db.is_finite() && a.ms_ssim > 0.0 && a.ms_ssim <= 1.0,
            "{a:?}"
        );
        assert!(a.pixels > 0 && rows.iter().all(|m| m.host_ns_per_px > 0.0));
    }
    assert!(
        float.psnr_db - fixed.psnr_db <= 1.0,
        "fixed {:.2} dB, f32 {:.2} dB",
        fixed.psnr_db,
        float.psnr_db
    );
    // Measured: 55.9 dB, max 3.11 gray levels (2.69 when the per-frame maximum was the
    // whole frame's; the window's is smaller, so saliencies and their rounding spread).
    assert!(full.psnr_db > 50.0 && full.max_abs <= 3.5, "{full:?}");
    // Downsampling loses detail the reference has: it must show.
    assert!(fixed.psnr_db < full.psnr_db - 6.0, "{fixed:?} vs {full:?}");
    // No MCU figures: nothing to recommend, and the table says why.
    assert!(report::recommended(&rows).is_none());
    let md = report::markdown(&rows, &["letters".into()], None);
    assert!(md.contains("tests/mcu-bench/run.sh") && md.lines().count() > 5);
    assert_eq!(report::csv(&rows).lines().count(), 1 + setups.len());
    assert!(report::pareto_svg(&rows).unwrap().starts_with("<svg"));
}
