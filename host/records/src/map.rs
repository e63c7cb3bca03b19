//! The roll map: the roll as a bar in metres, each defect marked where it lies along the
//! belt and across it, coloured by kind — as an SVG for people and a CSV for the cutting
//! room.

use crate::model::Roll;
use std::fmt::Write;

/// Kinds' colours, in the order kinds first appear (repeating past the last).
const COLOURS: [&str; 8] = [
    "#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
];

/// The map needs the roll's scale: without it there are no metres.
pub fn scale(roll: &Roll) -> Result<f64, String> {
    roll.summary.mm_per_row.ok_or_else(|| {
        format!(
            "roll {} has no recorded scale (millimetres a strip row): record it with \
             --mm-per-px, or from a manifest",
            roll.summary.id
        )
    })
}

/// The cutting room's table: one defect a line, along the belt.
///
/// Columns: `kind,score,belt_m,belt_mm,across_mm,segment,x,y,w,h`.
pub fn csv(roll: &Roll) -> Result<String, String> {
    let k = scale(roll)?;
    let mut out = String::from("kind,score,belt_m,belt_mm,across_mm,segment,x,y,w,h\n");
    for d in &roll.defect_list {
        let mm = roll.belt_mm(d).unwrap_or_default();
        let seg = d.segment_seq.map(|s| s.to_string()).unwrap_or_default();
        let [x, y, w, h] = d.bbox;
        let _ = writeln!(
            out,
            "{},{:.4},{:.4},{:.1},{:.1},{seg},{x},{y},{w},{h}",
            csv_field(&d.kind),
            d.score,
            mm / 1000.0,
            mm,
            d.across_px * k,
        );
    }
    Ok(out)
}

/// Quotes a field holding a comma, a quote or a line break.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

/// The map as an SVG: a bar `width_px` wide for the roll's length, metre (or tenth)
/// ticks, a mark for each defect across the bar's height as across the belt, a legend.
pub fn svg(roll: &Roll, width_px: u32) -> Result<String, String> {
    let k = scale(roll)?;
    let length_mm = (roll.summary.belt_rows as f64 * k).max(1.0);
    let (left, right, bar_top, bar_h) = (40.0, 20.0, 50.0, 80.0);
    let span = f64::from(width_px.max(200)) - left - right;
    let x_of = |mm: f64| left + span * (mm / length_mm).clamp(0.0, 1.0);
    // Across the bar as across the strip: its widest segment (or, where no width is
    // known, as far as the defects reach).
    let width_px = roll.segment_list.iter().map(|s| s.width).max().unwrap_or(0);
    let reach_px = roll
        .defect_list
        .iter()
        .map(|d| d.bbox[0] + d.bbox[2])
        .max()
        .unwrap_or(0);
    let strip_mm = (width_px.max(reach_px).max(1)) as f64 * k;
    let mut kinds: Vec<&str> = Vec::new();
    for d in &roll.defect_list {
        if !kinds.contains(&d.kind.as_str()) {
            kinds.push(&d.kind);
        }
    }
    let colour = |kind: &str| COLOURS[kinds.iter().position(|k| *k == kind).unwrap_or(0) % 8];
    let height = bar_top + bar_h + 40.0 + 18.0 * kinds.len() as f64;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width_px}" height="{height:.0}" viewBox="0 0 {width_px} {height:.0}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(
        s,
        r#"<title>roll {} — {:.2} m, {} defects</title>"#,
        roll.summary.id,
        length_mm / 1000.0,
        roll.defect_list.len()
    );
    let _ = writeln!(
        s,
        r#"<text x="{left}" y="20">roll {} · line {} · {} · {:.3} m · {} defects</text>"#,
        roll.summary.id,
        xml(&roll.summary.line),
        xml(&roll.summary.status),
        length_mm / 1000.0,
        roll.defect_list.len()
    );
    let _ = writeln!(
        s,
        r##"<rect x="{left}" y="{bar_top}" width="{span:.1}" height="{bar_h}" fill="#eeeeee" stroke="#444444"/>"##
    );
    let step = tick_step(length_mm);
    let mut t = 0.0;
    while t <= length_mm + 1e-9 {
        let x = x_of(t);
        let _ = writeln!(
            s,
            r##"<line x1="{x:.1}" y1="{}" x2="{x:.1}" y2="{}" stroke="#444444"/><text x="{x:.1}" y="{}" text-anchor="middle">{}</text>"##,
            bar_top + bar_h,
            bar_top + bar_h + 6.0,
            bar_top + bar_h + 20.0,
            distance(t, length_mm)
        );
        t += step;
    }
    for d in &roll.defect_list {
        let x = x_of(roll.belt_mm(d).unwrap_or_default());
        let y = bar_top + bar_h * (d.across_px * k / strip_mm).clamp(0.0, 1.0);
        let _ = writeln!(
            s,
            r#"<circle cx="{x:.1}" cy="{y:.1}" r="4" fill="{}"><title>{} {:.2} at {:.1} mm</title></circle>"#,
            colour(&d.kind),
            xml(&d.kind),
            d.score,
            roll.belt_mm(d).unwrap_or_default()
        );
    }
    for (i, kind) in kinds.iter().enumerate() {
        let y = bar_top + bar_h + 40.0 + 18.0 * i as f64;
        let n = roll.defect_list.iter().filter(|d| d.kind == *kind).count();
        let _ = writeln!(
            s,
            r#"<circle cx="{}" cy="{:.1}" r="4" fill="{}"/><text x="{}" y="{:.1}">{} ({n})</text>"#,
            left + 4.0,
            y - 4.0,
            colour(kind),
            left + 14.0,
            y,
            xml(kind)
        );
    }
    s.push_str("</svg>\n");
    Ok(s)
}

/// Ticks 1, 2 or 5 × a power of ten mm apart, about ten along the roll.
fn tick_step(length_mm: f64) -> f64 {
    let raw = length_mm / 10.0;
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * p)
        .find(|&s| s >= raw)
        .unwrap_or(10.0 * p)
}

/// A tick's label: in metres on a roll of a metre or more, else in millimetres; no
/// trailing zeros.
fn distance(mm: f64, length_mm: f64) -> String {
    let (value, unit) = if length_mm >= 1000.0 {
        (mm / 1000.0, "m")
    } else {
        (mm, "mm")
    };
    let s = format!("{value:.3}");
    format!("{} {unit}", s.trim_end_matches('0').trim_end_matches('.'))
}

fn xml(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_about_ten() {
        assert_eq!(tick_step(1000.0), 100.0);
        assert_eq!(tick_step(1500.0), 200.0);
        assert_eq!(tick_step(42.0), 5.0);
        assert_eq!(distance(200.0, 1500.0), "0.2 m");
        assert_eq!(distance(1000.0, 1500.0), "1 m");
        assert_eq!(distance(5.0, 28.0), "5 mm");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
    }
}
