//! Detections drawn on their image, for people to look at.

use super::Found;
use rollfuse_io::image::Planes;
use rollfuse_sim::textile::DefectKind;

/// The colour a defect kind is drawn in.
pub fn kind_colour(kind: DefectKind) -> [u8; 3] {
    match kind {
        DefectKind::Hole => [230, 40, 40],
        DefectKind::Snag => [40, 200, 60],
        DefectKind::Slub => [50, 110, 255],
    }
}

/// A gray image as RGB with each box outlined 2 px wide in its kind's colour.
pub fn draw(image: &Planes, found: &[Found]) -> (usize, usize, Vec<u8>) {
    outline(image, found.iter().map(|f| (f.box_px, kind_colour(f.kind))))
}

/// `image` as RGB with each box outlined 2 pixels wide in its colour.
pub fn outline(
    image: &Planes,
    boxes: impl IntoIterator<Item = ([f32; 4], [u8; 3])>,
) -> (usize, usize, Vec<u8>) {
    let (w, h) = (image.width, image.height);
    let mut rgb: Vec<u8> = image.to_u8().iter().flat_map(|&g| [g, g, g]).collect();
    for (box_px, c) in boxes {
        let [x0, y0, x1, y1] = box_px.map(|v| v.round() as i64);
        let mut put = |x: i64, y: i64| {
            if (0..w as i64).contains(&x) && (0..h as i64).contains(&y) {
                let at = 3 * (y as usize * w + x as usize);
                rgb[at..at + 3].copy_from_slice(&c);
            }
        };
        for t in 0..2 {
            for x in x0..=x1 {
                put(x, y0 + t);
                put(x, y1 - t);
            }
            for y in y0..=y1 {
                put(x0 + t, y);
                put(x1 - t, y);
            }
        }
    }
    (w, h, rgb)
}
