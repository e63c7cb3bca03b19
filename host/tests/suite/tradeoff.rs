//! The trade-off study on the letters scene the virtual device streams: the reference is
//! what it claims to be, the default (full resolution, integer) is within issue 42's
//! 54 dB of it, and at 2× the integer path stays within 1 dB of the `f32` path.

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
fn full_resolution_default_matches_the_reference_and_fixed_2x_is_within_one_db_of_f32() {
    let acq = letters();
    // Half resolution, where downsampling would mask nothing the arithmetic loses.
    let half = Setup {
        levels: 2,
        downsample: 2,
        ..Setup::DEFAULT
    };
    let half_f32 = Setup {
        precision: Precision::F32,
        ..half
    };
    let setups = [half, half_f32, Setup::DEFAULT];
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
    // At full resolution the device fuses exactly the reference's observations: only
    // rounding separates them (8-bit tiles every step; the integer lifting's rounding).
    // Measured: 55.53 dB.
    assert!(full.psnr_db >= 54.0 && full.max_abs <= 3.5, "{full:?}");
    // Downsampling loses detail the reference has: it must show.
    assert!(fixed.psnr_db < full.psnr_db - 6.0, "{fixed:?} vs {full:?}");
    // No MCU figures: nothing to recommend, and the table says why.
    assert!(report::recommended(&rows).is_none());
    let md = report::markdown(&rows, &["letters".into()], None);
    assert!(md.contains("tests/mcu-bench/run.sh") && md.lines().count() > 5);
    assert_eq!(report::csv(&rows).lines().count(), 1 + setups.len());
    assert!(report::pareto_svg(&rows).unwrap().starts_with("<svg"));
}
