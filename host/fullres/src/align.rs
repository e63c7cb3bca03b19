//! Frame alignment: where each frame sits on the common (mosaic) canvas.
//!
//! - `motion`: from the commanded belt offsets the simulator or the motion system recorded.
//! - `template`: each frame against the previous one by normalized cross-correlation
//!   (`imageproc::template_matching`) of their Sobel gradient magnitudes: gradients
//!   are zero on undisturbed gel, so the correlation measures structure, not brightness. A
//!   frame whose best score is below the threshold (flat, textureless, or not overlapping)
//!   is reported and left out, never fused misaligned.

use image::{GrayImage, Luma};
use imageproc::template_matching::{MatchTemplateMethod, find_extremes, match_template_parallel};
use rollfuse_io::image::Planes;
use rollfuse_io::progress::Progress;

/// Where a frame's pixel (0, 0) lies on the canvas, pixels: rows (along the belt), columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Offset {
    /// Rows.
    pub dy: i64,
    /// Columns.
    pub dx: i64,
}

/// Template-matching settings.
#[derive(Debug, Clone, Copy)]
pub struct TemplateParams {
    /// The template: rows `[top, bottom)` of the previous frame, as fractions of its height
    /// (default: the central third, where contact is deepest).
    pub rows: (f64, f64),
    /// Largest shift searched along the belt, pixels.
    pub max_dy: usize,
    /// Largest shift searched across the belt, pixels.
    pub max_dx: usize,
    /// Lowest normalized correlation accepted.
    pub min_score: f32,
}

impl Default for TemplateParams {
    fn default() -> Self {
        Self {
            rows: (1.0 / 3.0, 2.0 / 3.0),
            max_dy: 200,
            max_dx: 8,
            min_score: 0.5,
        }
    }
}

/// How close a runner-up's correlation may come to the best one before the match is
/// called ambiguous.
pub const AMBIGUITY_MARGIN: f32 = 0.05;

/// A match is also ambiguous when the runner-up's mismatch (1 − correlation) is within
/// this factor of the best one's: a weak match needs a wider gap to stand out.
pub const AMBIGUITY_RATIO: f32 = 1.25;

/// The result of matching one frame against the previous one.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Match {
    /// Shift of this frame relative to the previous one.
    pub shift: Offset,
    /// Best normalized correlation.
    pub score: f32,
    /// The best other peak's score (a local maximum 3 px or more from the best): close to
    /// `score` means the match is ambiguous (periodic texture, or little of it).
    pub runner_up: f32,
    /// Whether the best shift lies on the edge of the search (`max_dy` along the belt, or
    /// no search at all with `max_dy` 0): the frames may have moved farther.
    pub at_search_edge: bool,
}

/// Gradient magnitude of the gray version of `img`, scaled to 8 bits.
fn gradient_image(img: &Planes) -> GrayImage {
    let (w, h) = (img.width, img.height);
    let n = img.planes.len() as f32;
    let gray: Vec<u8> = (0..w * h)
        .map(|i| {
            (img.planes.iter().map(|p| p[i]).sum::<f32>() / n)
                .round()
                .clamp(0.0, 255.0) as u8
        })
        .collect();
    let gray = GrayImage::from_raw(w as u32, h as u32, gray).expect("size matches");
    let grad = imageproc::gradients::sobel_gradients(&gray);
    GrayImage::from_fn(w as u32, h as u32, |x, y| {
        Luma([(grad.get_pixel(x, y)[0] / 4).min(255) as u8])
    })
}

/// Matches the template band of `prev` inside `next`; `None` if either has no texture or the
/// frames are too small for the band and search window.
pub fn match_frames(prev: &Planes, next: &Planes, p: &TemplateParams) -> Option<Match> {
    let (w, h) = (prev.width, prev.height);
    let (gp, gn) = (gradient_image(prev), gradient_image(next));
    let top = ((p.rows.0 * h as f64) as usize).min(h.saturating_sub(1));
    let bottom = ((p.rows.1 * h as f64) as usize).clamp(top + 1, h);
    let left = p.max_dx.min(w / 4);
    let tw = w.checked_sub(2 * left)?;
    if tw == 0 {
        return None;
    }
    let template = image::imageops::crop_imm(
        &gp,
        left as u32,
        top as u32,
        tw as u32,
        (bottom - top) as u32,
    )
    .to_image();
    if template.pixels().all(|p| p[0] == 0) {
        return None;
    }
    // The search window: the template's own place ± the largest shifts, inside `next`.
    let y0 = top.saturating_sub(p.max_dy);
    let y1 = bottom.saturating_add(p.max_dy).min(h);
    let search =
        image::imageops::crop_imm(&gn, 0, y0 as u32, w as u32, (y1 - y0) as u32).to_image();
    if search.height() < template.height() || search.pixels().all(|p| p[0] == 0) {
        return None;
    }
    let scores = match_template_parallel(
        &search,
        &template,
        MatchTemplateMethod::CrossCorrelationNormalized,
    );
    let best = find_extremes(&scores);
    let (bx, by) = best.max_value_location;
    let score = best.max_value;
    if !score.is_finite() {
        return None;
    }
    let runner_up = runner_up(&scores, (bx, by));
    // The template's top-left found at (bx, y0 + by) in `next`, taken from (left, top) in
    // `prev`: a belt point at prev row r is at next row r − (top − (y0 + by)).
    let shift = Offset {
        dy: top as i64 - (y0 as i64 + by as i64),
        dx: left as i64 - bx as i64,
    };
    Some(Match {
        shift,
        score,
        runner_up,
        at_search_edge: shift.dy.unsigned_abs() >= p.max_dy as u64,
    })
}

/// The best other peak of `scores`: the highest local maximum (no neighbour higher) at
/// least 3 px from the best one at `peak`. The slopes of the best peak itself are not
/// peaks, so a broad peak (blurred texture) is not taken for a second one.
fn runner_up(scores: &image::ImageBuffer<Luma<f32>, Vec<f32>>, peak: (u32, u32)) -> f32 {
    let (w, h) = scores.dimensions();
    let at = |x: u32, y: u32| scores.get_pixel(x, y)[0];
    let is_peak = |x: u32, y: u32| {
        let v = at(x, y);
        (y.saturating_sub(1)..(y + 2).min(h))
            .flat_map(|ny| (x.saturating_sub(1)..(x + 2).min(w)).map(move |nx| (nx, ny)))
            .all(|(nx, ny)| at(nx, ny) <= v)
    };
    scores
        .enumerate_pixels()
        .filter(|(x, y, _)| x.abs_diff(peak.0) > 3 || y.abs_diff(peak.1) > 3)
        .filter(|(_, _, v)| v[0].is_finite())
        .filter(|(x, y, _)| is_peak(*x, *y))
        .map(|(_, _, v)| v[0])
        .fold(0.0f32, f32::max)
}

/// How one frame of a sequence was aligned by [`align_chain`].
#[derive(Debug, Clone)]
pub enum Aligned {
    /// Placed at `at` on the canvas; `matched` is `None` for the first frame.
    Placed {
        /// The frame's offset on the canvas.
        at: Offset,
        /// The match that placed it.
        matched: Option<Match>,
    },
    /// Left out, with the reason (no texture, or a match below the threshold).
    Skipped(String),
}

impl Match {
    /// Whether another shift, away from the best one, scores within
    /// [`AMBIGUITY_MARGIN`] of it, or mismatches within [`AMBIGUITY_RATIO`] times as much
    /// (periodic texture, or little of it): the offset is then a guess among several.
    pub fn is_ambiguous(&self) -> bool {
        self.score - self.runner_up < AMBIGUITY_MARGIN
            || 1.0 - self.runner_up < AMBIGUITY_RATIO * (1.0 - self.score)
    }

    /// Why this match may be wrong, each reason a phrase that follows the frame's name:
    /// ambiguous (periodic texture), or at the edge of a search of `max_dy` rows.
    pub fn doubts(&self, max_dy: usize) -> Vec<String> {
        let mut out = Vec::new();
        if self.is_ambiguous() {
            out.push(format!(
                "matches ambiguously (score {:.3}, runner-up {:.3}): periodic texture?",
                self.score, self.runner_up
            ));
        }
        if self.at_search_edge {
            out.push(format!(
                "matched at {} rows, the edge of the search (--max-shift {max_dy}): it may have moved farther",
                self.shift.dy
            ));
        }
        out
    }
}

/// Aligns a sequence by template matching: the first frame at the origin, every next one
/// against the last frame kept. A frame that does not match is skipped (never placed at a
/// guessed offset) and the next one is matched against the last kept frame instead.
/// `progress` counts the frames matched.
pub fn align_chain(
    frames: &[Planes],
    params: &TemplateParams,
    progress: &dyn Progress,
) -> Vec<Aligned> {
    progress.start("aligning", Some(frames.len() as u64), "frames");
    let mut out = Vec::with_capacity(frames.len());
    let mut at = Offset { dy: 0, dx: 0 };
    let mut last = 0;
    for (k, frame) in frames.iter().enumerate() {
        if k == 0 {
            out.push(Aligned::Placed { at, matched: None });
            continue;
        }
        progress.advance_to(k as u64);
        match match_frames(&frames[last], frame, params) {
            Some(m) if m.score >= params.min_score => {
                at = Offset {
                    dy: at.dy + m.shift.dy,
                    dx: at.dx + m.shift.dx,
                };
                last = k;
                out.push(Aligned::Placed {
                    at,
                    matched: Some(m),
                });
            }
            Some(m) => out.push(Aligned::Skipped(format!(
                "best match score {:.3} is below the minimum score {} (--min-score)",
                m.score, params.min_score
            ))),
            // A flat frame matched against is named: the frame skipped is not to blame.
            None if gradient_image(&frames[last]).pixels().all(|p| p[0] == 0) => {
                out.push(Aligned::Skipped(format!(
                    "frame {} of the list, which it is matched against, is flat (no texture)",
                    last + 1
                )))
            }
            None => out.push(Aligned::Skipped(
                "no texture to match (flat frame or no overlap)".into(),
            )),
        }
    }
    progress.finish();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn matched(score: f32, runner_up: f32) -> Match {
        Match {
            shift: Offset { dy: 17, dx: 0 },
            score,
            runner_up,
            at_search_edge: false,
        }
    }

    #[test]
    fn a_runner_up_within_the_margin_makes_a_match_ambiguous() {
        // Frames 100 rows apart matched at 17 (score 0.70, runner-up 0.66, or 0.647).
        assert!(matched(0.70, 0.66).is_ambiguous());
        assert!(matched(0.700, 0.647).is_ambiguous());
        assert!(matched(0.99, 0.97).is_ambiguous());
        assert!(!matched(0.90, 0.70).is_ambiguous());
        assert!(!matched(0.70, 0.55).is_ambiguous());
    }
}
