//! CenterNet's targets and their decoding, in plain Rust: boxes become a centre heatmap per
//! defect kind, a size and a sub-cell offset at each centre; the network's outputs become
//! boxes again by keeping the local maxima of the heatmap.
//!
//! Output cells are [`STRIDE`] image pixels square; sizes are in cells.

use rollfuse_sim::textile::DefectKind;
use serde::Serialize;

/// Overlap a detection needs with a true defect of its kind to count as found.
pub const MIN_IOU: f32 = 0.3;
/// Image pixels an output cell.
pub const STRIDE: usize = 8;
/// Defect kinds (heatmap channels).
pub const KINDS: usize = DefectKind::ALL.len();

/// A labelled box in image pixels (edges: `x0 ≤ x < x1`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Labelled {
    /// The defect's kind.
    pub kind: DefectKind,
    /// `[x0, y0, x1, y1]`, pixels.
    pub box_px: [f32; 4],
}

/// A detected defect.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Found {
    /// The defect's kind.
    pub kind: DefectKind,
    /// The heatmap's peak, 0..1.
    pub score: f32,
    /// `[x0, y0, x1, y1]`, pixels.
    pub box_px: [f32; 4],
}

/// Training targets for one image of `cells = (gw, gh)` output cells, each plane row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Targets {
    /// Output cells across and down.
    pub cells: (usize, usize),
    /// Gaussian peaks at the centres, `KINDS` planes.
    pub heat: Vec<f32>,
    /// Width and height at each centre cell, cells (2 planes).
    pub size: Vec<f32>,
    /// Centre's offset inside its cell, 0..1 (2 planes).
    pub offset: Vec<f32>,
    /// 1 at centre cells, 0 elsewhere.
    pub mask: Vec<f32>,
    /// 0 over defects that are to be neither found nor missed, 1 elsewhere.
    pub counted: Vec<f32>,
}

/// Output cells for an image of `w × h` pixels.
pub fn cells(w: usize, h: usize) -> (usize, usize) {
    (w.div_ceil(STRIDE), h.div_ceil(STRIDE))
}

/// Encodes `boxes` on a `w × h` image; over the `ignored` boxes nothing counts.
pub fn encode(boxes: &[Labelled], ignored: &[Labelled], w: usize, h: usize) -> Targets {
    let (gw, gh) = cells(w, h);
    let n = gw * gh;
    let mut t = Targets {
        cells: (gw, gh),
        heat: vec![0.0; KINDS * n],
        size: vec![0.0; 2 * n],
        offset: vec![0.0; 2 * n],
        mask: vec![0.0; n],
        counted: vec![1.0; n],
    };
    let s = STRIDE as f32;
    for b in ignored {
        let [x0, y0, x1, y1] = b.box_px.map(|v| (v / s).max(0.0));
        for y in (y0 as usize)..(y1.ceil() as usize).min(gh) {
            for x in (x0 as usize)..(x1.ceil() as usize).min(gw) {
                t.counted[y * gw + x] = 0.0;
            }
        }
    }
    for b in boxes {
        let [x0, y0, x1, y1] = b.box_px;
        let (cx, cy) = ((x0 + x1) / 2.0 / s, (y0 + y1) / 2.0 / s);
        let (bw, bh) = ((x1 - x0) / s, (y1 - y0) / s);
        if !(bw > 0.0 && bh > 0.0 && cx >= 0.0 && cy >= 0.0) {
            continue;
        }
        let (ix, iy) = (cx as usize, cy as usize);
        if ix >= gw || iy >= gh {
            continue;
        }
        // The peak spreads over about a third of the box, as CenterNet's radius does.
        let sigma = (bw.min(bh) / 6.0).max(0.5);
        let plane = &mut t.heat[kind_index(b.kind) * n..][..n];
        let reach = (3.0 * sigma).ceil() as isize;
        for dy in -reach..=reach {
            for dx in -reach..=reach {
                let (x, y) = (ix as isize + dx, iy as isize + dy);
                if x < 0 || y < 0 || x >= gw as isize || y >= gh as isize {
                    continue;
                }
                let g = (-((dx * dx + dy * dy) as f32) / (2.0 * sigma * sigma)).exp();
                let at = y as usize * gw + x as usize;
                plane[at] = plane[at].max(g);
            }
        }
        let at = iy * gw + ix;
        t.size[at] = bw;
        t.size[n + at] = bh;
        t.offset[at] = cx - ix as f32;
        t.offset[n + at] = cy - iy as f32;
        t.mask[at] = 1.0;
    }
    t
}

/// The heatmap channel of `kind`.
pub fn kind_index(kind: DefectKind) -> usize {
    DefectKind::ALL.iter().position(|&k| k == kind).unwrap_or(0)
}

/// The network's outputs for one image, each plane row-major over `cells`.
pub struct Outputs<'a> {
    /// Output cells across and down.
    pub cells: (usize, usize),
    /// Heatmap after the sigmoid, `KINDS` planes.
    pub heat: &'a [f32],
    /// Width and height, cells (2 planes).
    pub size: &'a [f32],
    /// Offsets in the cell (2 planes).
    pub offset: &'a [f32],
}

/// Boxes of different kinds overlapping at least this much are one defect: the size and
/// offset heads are shared by the kinds, so two kinds peaking in one cell give one box
/// twice.
pub const SAME_DEFECT_IOU: f32 = 0.7;

/// Boxes at the heatmap's 3 × 3 local maxima scoring at least `threshold`, best first, at
/// most `limit`; of boxes of different kinds at one place ([`SAME_DEFECT_IOU`]) only the
/// best-scoring is kept.
pub fn decode(out: &Outputs, threshold: f32, limit: usize) -> Vec<Found> {
    let (gw, gh) = out.cells;
    let n = gw * gh;
    let s = STRIDE as f32;
    let mut found = Vec::new();
    for (k, &kind) in DefectKind::ALL.iter().enumerate() {
        let plane = &out.heat[k * n..(k + 1) * n];
        for y in 0..gh {
            for x in 0..gw {
                let v = plane[y * gw + x];
                if v < threshold || !is_peak(plane, (gw, gh), x, y) {
                    continue;
                }
                let at = y * gw + x;
                let (cx, cy) = (x as f32 + out.offset[at], y as f32 + out.offset[n + at]);
                let (bw, bh) = (out.size[at].max(0.0), out.size[n + at].max(0.0));
                found.push(Found {
                    kind,
                    score: v,
                    box_px: [
                        (cx - bw / 2.0) * s,
                        (cy - bh / 2.0) * s,
                        (cx + bw / 2.0) * s,
                        (cy + bh / 2.0) * s,
                    ],
                });
            }
        }
    }
    found.sort_by(|a, b| b.score.total_cmp(&a.score));
    let mut kept: Vec<Found> = Vec::with_capacity(found.len().min(limit));
    for f in found {
        if kept.len() == limit {
            break;
        }
        if !kept
            .iter()
            .any(|k| iou(k.box_px, f.box_px) >= SAME_DEFECT_IOU)
        {
            kept.push(f);
        }
    }
    kept
}

/// Whether `(x, y)` is at least every neighbour (ties keep the first in reading order).
fn is_peak(plane: &[f32], (gw, gh): (usize, usize), x: usize, y: usize) -> bool {
    let v = plane[y * gw + x];
    for ny in y.saturating_sub(1)..(y + 2).min(gh) {
        for nx in x.saturating_sub(1)..(x + 2).min(gw) {
            let u = plane[ny * gw + nx];
            let before = (ny, nx) < (y, x);
            if u > v || (before && u == v) {
                return false;
            }
        }
    }
    true
}

/// Intersection over union of two boxes.
pub fn iou(a: [f32; 4], b: [f32; 4]) -> f32 {
    let w = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let h = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let inter = w * h;
    let area = |r: [f32; 4]| (r[2] - r[0]).max(0.0) * (r[3] - r[1]).max(0.0);
    let union = area(a) + area(b) - inter;
    if union > 0.0 { inter / union } else { 0.0 }
}

/// How detections compare with the truth on one image.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Tally {
    /// Detections matched to a true defect of the same kind.
    pub hits: usize,
    /// Detections matching none.
    pub false_alarms: usize,
    /// True defects no detection matched.
    pub misses: usize,
}

impl Tally {
    /// Hits over detections (0 with none).
    pub fn precision(&self) -> f64 {
        share(self.hits, self.hits + self.false_alarms)
    }

    /// Hits over true defects (0 with none).
    pub fn recall(&self) -> f64 {
        share(self.hits, self.hits + self.misses)
    }

    /// Adds another tally.
    pub fn add(&mut self, o: Tally) {
        self.hits += o.hits;
        self.false_alarms += o.false_alarms;
        self.misses += o.misses;
    }
}

/// `a / b`, 0 when `b` is 0 (a share of nothing).
pub fn share(a: usize, b: usize) -> f64 {
    if b == 0 { 0.0 } else { a as f64 / b as f64 }
}

/// Matches `found` (best first) greedily to `truth` of the same kind at IoU ≥ `min_iou`.
pub fn tally(found: &[Found], truth: &[Labelled], min_iou: f32) -> Tally {
    tally_ignoring(found, truth, &[], min_iou)
}

/// [`tally`], where a detection that matches no true defect but overlaps an `ignored`
/// one (IoU ≥ `min_iou`, any kind) is not counted at all.
pub fn tally_ignoring(
    found: &[Found],
    truth: &[Labelled],
    ignored: &[Labelled],
    min_iou: f32,
) -> Tally {
    let mut taken = vec![false; truth.len()];
    let mut t = Tally::default();
    for f in found {
        let best = truth
            .iter()
            .enumerate()
            .filter(|(i, b)| !taken[*i] && b.kind == f.kind)
            .map(|(i, b)| (i, iou(f.box_px, b.box_px)))
            .filter(|&(_, o)| o >= min_iou)
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match best {
            Some((i, _)) => {
                taken[i] = true;
                t.hits += 1;
            }
            None if ignored.iter().any(|b| iou(f.box_px, b.box_px) >= min_iou) => {}
            None => t.false_alarms += 1,
        }
    }
    t.misses = taken.iter().filter(|&&x| !x).count();
    t
}

/// [`tally_ignoring`] with every kind taken as one: was each defect boxed at all?
pub fn tally_any_kind(
    found: &[Found],
    truth: &[Labelled],
    ignored: &[Labelled],
    min_iou: f32,
) -> Tally {
    let one = DefectKind::ALL[0];
    let found: Vec<Found> = found.iter().map(|&f| Found { kind: one, ..f }).collect();
    let truth: Vec<Labelled> = truth.iter().map(|&b| Labelled { kind: one, ..b }).collect();
    tally_ignoring(&found, &truth, ignored, min_iou)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Targets read back as if the network had output them.
    fn outputs(t: &Targets) -> Outputs<'_> {
        Outputs {
            cells: t.cells,
            heat: &t.heat,
            size: &t.size,
            offset: &t.offset,
        }
    }

    #[test]
    fn encoding_then_decoding_gives_the_boxes_back() {
        let boxes = [
            Labelled {
                kind: DefectKind::Snag,
                box_px: [37.0, 51.0, 101.0, 66.0],
            },
            Labelled {
                kind: DefectKind::Hole,
                box_px: [200.0, 120.0, 240.0, 170.0],
            },
        ];
        let t = encode(&boxes, &[], 320, 240);
        let found = decode(&outputs(&t), 0.5, 10);
        assert_eq!(found.len(), 2);
        let r = tally(&found, &boxes, 0.99);
        assert_eq!((r.hits, r.false_alarms, r.misses), (2, 0, 0));
    }

    #[test]
    fn two_kinds_peaking_at_one_place_are_one_defect_of_the_better_kind() {
        let boxes = [Labelled {
            kind: DefectKind::Slub,
            box_px: [40.0, 40.0, 90.0, 64.0],
        }];
        let mut t = encode(&boxes, &[], 160, 120);
        let n = t.cells.0 * t.cells.1;
        // The snag plane peaks at the slub's cell too, less strongly.
        let (slub, snag) = (kind_index(DefectKind::Slub), kind_index(DefectKind::Snag));
        for i in 0..n {
            t.heat[snag * n + i] = 0.6 * t.heat[slub * n + i];
        }
        let found = decode(&outputs(&t), 0.3, 10);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].kind, DefectKind::Slub);
    }

    #[test]
    fn tally_counts_wrong_kinds_as_both_errors() {
        let truth = [Labelled {
            kind: DefectKind::Hole,
            box_px: [0.0, 0.0, 10.0, 10.0],
        }];
        let found = [Found {
            kind: DefectKind::Slub,
            score: 0.9,
            box_px: [0.0, 0.0, 10.0, 10.0],
        }];
        let r = tally(&found, &truth, 0.3);
        assert_eq!((r.hits, r.false_alarms, r.misses), (0, 1, 1));
        // Taking every kind as one, the box found it.
        let r = tally_any_kind(&found, &truth, &[], 0.3);
        assert_eq!((r.hits, r.false_alarms, r.misses), (1, 0, 0));
        assert_eq!((r.precision(), r.recall()), (1.0, 1.0));
        let r = tally_ignoring(&found, &[], &truth, 0.3);
        assert_eq!((r.hits, r.false_alarms, r.misses), (0, 0, 0));
        assert!((iou([0.0, 0.0, 10.0, 10.0], [5.0, 0.0, 15.0, 10.0]) - 1.0 / 3.0).abs() < 1e-6);
    }

    #[test]
    fn boxes_outside_the_image_are_skipped() {
        let t = encode(
            &[Labelled {
                kind: DefectKind::Hole,
                box_px: [400.0, 10.0, 420.0, 30.0],
            }],
            &[],
            320,
            240,
        );
        assert!(t.mask.iter().all(|&m| m == 0.0));
    }
}
