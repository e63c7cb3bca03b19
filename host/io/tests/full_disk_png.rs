//! A disk that fills while a PNG is being encoded: the error names the file and says the
//! disk is full, and nothing is left at the target. Its own test binary, because the
//! full-disk seam holds for the whole process.

use rollfuse_io::files::{PngLayout, fail_writes_after, write_png};

#[test]
fn a_disk_that_fills_mid_image_names_the_image() {
    assert!(fail_writes_after(1000));
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("noise.png");
    // Incompressible pixels, more than the writer buffers: the disk fills mid-encoding.
    let mut state = 1u32;
    let pixels: Vec<u8> = (0..512 * 512)
        .map(|_| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 24) as u8
        })
        .collect();
    let e = write_png(&target, &pixels, (512, 512), PngLayout::Gray8).unwrap_err();
    // An I/O error among the causes (the PNG encoder passes the disk's error on with its
    // message, as kind `Other`).
    assert!(e.io_kind().is_some(), "{e:?}");
    let message = format!("{:#}", anyhow::Error::from(e));
    assert!(
        message.contains(&format!("cannot write {}", target.display()))
            && message.contains("no space left on device"),
        "{message}"
    );
    assert!(!target.exists());
}
