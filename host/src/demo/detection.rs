//! The demo's detection stage: the built-in detector on one held-out textile roll (a frame
//! and the fused strip, boxes drawn) and the frames-against-fused table over one held-out
//! roll of every fabric, as `rollfuse eval --detect --rolls 17` measures it.

use super::markup::escape;
use crate::detect::Detector;
use crate::detect::data::{RollShape, Style, roll};
use crate::detect::draw::draw;
use crate::eval::detect::{DetectRow, EVAL_SEEDS, evaluate_detect, markdown};
use crate::files::{Batch, PngLayout, add_png};
use crate::progress::Silent;
use crate::sim::textile::FABRICS;
use std::fmt::Write;
use std::path::Path;

/// The roll shown: held out (seed below training's), a 2/2 twill.
const SHOWN_SEED: u64 = EVAL_SEEDS + 4;
/// Held-out rolls in the demo's table: one of each fabric.
const TABLE_ROLLS: usize = FABRICS.len();

/// The frame with its boxes drawn.
pub const FRAME_PNG: &str = "detect_frame.png";
/// The fused strip with its boxes drawn.
pub const STRIP_PNG: &str = "detect_strip.png";
/// The table.
pub const TABLE_MD: &str = "detect.md";

/// What the stage found.
#[derive(Debug, Clone)]
pub struct DetectionDemo {
    /// The shown roll's fabric.
    pub fabric: String,
    /// The frame shown (the one with most defects in contact).
    pub frame: usize,
    /// Defects in its contact band; found there; the fabric it was classified as.
    pub frame_result: (usize, usize, String),
    /// Defects on the strip; found there; the fabric it was classified as.
    pub strip_result: (usize, usize, String),
    /// The table's rows.
    pub rows: Vec<DetectRow>,
}

/// Runs the stage, writing its pictures and table into `out`.
pub fn run(out: &Path) -> anyhow::Result<DetectionDemo> {
    let detector = Detector::built_in()?;
    let shown = roll(SHOWN_SEED, &RollShape::STANDARD)?;
    let (frame, sample) = shown
        .frames
        .iter()
        .enumerate()
        .max_by_key(|(k, s)| (s.boxes.len(), usize::MAX - k))
        .ok_or_else(|| anyhow::anyhow!("the shown roll has no frames"))?;
    let on_frame = detector.detect(&sample.image)?;
    let on_strip = detector.detect(&shown.strip.image)?;
    let mut batch = Batch::new();
    for (name, image, found) in [
        (FRAME_PNG, &sample.image, &on_frame.defects),
        (STRIP_PNG, &shown.strip.image, &on_strip.defects),
    ] {
        let (w, h, rgb) = draw(image, found);
        add_png(&mut batch, &out.join(name), &rgb, (w, h), PngLayout::Rgb8)?;
    }
    let rows = evaluate_detect(
        &detector,
        TABLE_ROLLS,
        &RollShape::STANDARD,
        Style::Standard,
        &Silent,
    )?;
    let table = format!(
        "Held-out rolls: {TABLE_ROLLS} (seeds {EVAL_SEEDS}..{}), the built-in model\n\n{}",
        EVAL_SEEDS + TABLE_ROLLS as u64,
        markdown(&rows)
    );
    batch.add_bytes(&out.join(TABLE_MD), table.as_bytes())?;
    batch.commit()?;
    Ok(DetectionDemo {
        fabric: FABRICS[shown.class].name.to_string(),
        frame,
        frame_result: (sample.boxes.len(), on_frame.defects.len(), on_frame.fabric),
        strip_result: (
            shown.strip.boxes.len(),
            on_strip.defects.len(),
            on_strip.fabric,
        ),
        rows,
    })
}

/// The report's section `number`; `png` embeds a picture of the output folder, `tables`
/// turns the Markdown table into HTML.
pub fn section(
    d: &DetectionDemo,
    number: usize,
    png: impl Fn(&str, &str) -> anyhow::Result<String>,
    table_html: String,
) -> anyhow::Result<String> {
    let mut s = String::new();
    let (ft, ff, fc) = &d.frame_result;
    let (st, sf, sc) = &d.strip_result;
    writeln!(
        s,
        "<h2>{number}. Finding fabric defects (the paper's §IV.B)</h2>\n<p>The built-in \
         detector (a CenterNet on a small ResNet, with a fabric classifier) on a held-out \
         roll of <b>{}</b>: frame {} holds {ft} defects in its contact band and the detector \
         reports {ff}, calling the fabric {}; the fused strip holds {st} and it reports {sf}, \
         calling the fabric {}. Boxes: red hole, green snag, blue slub.</p>\n\
         <div class=pair><figure>{}<figcaption>a single frame</figcaption></figure>\
         <figure>{}<figcaption>the fused strip</figcaption></figure></div>\n\
         <p>Every frame against the fused tiles of the same rolls, as <code>rollfuse eval \
         --detect --rolls 17</code>:</p>\n{table_html}",
        escape(&d.fabric),
        d.frame,
        escape(fc),
        escape(sc),
        png(FRAME_PNG, "detections on a frame")?,
        png(STRIP_PNG, "detections on the fused strip")?,
    )?;
    Ok(s)
}
