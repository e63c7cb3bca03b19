//! The study's outputs: the Markdown table, the CSV, the Pareto fronts and their plot.

use super::Measured;
use super::bench::BUDGET_INSTRUCTIONS;
use plotters::prelude::*;
use std::fmt::Write as _;

/// The recommended configuration: the most accurate (PSNR) of those the MCU bench
/// measured within the time budget and the firmware's RAM; fewer instructions break ties.
pub fn recommended(rows: &[Measured]) -> Option<&Measured> {
    rows.iter()
        .filter(|m| m.mcu.is_some_and(|c| c.fits()))
        .max_by(|a, b| {
            let cost = |m: &Measured| m.mcu.map_or(f64::INFINITY, |c| c.instructions_per_frame);
            a.accuracy
                .psnr_db
                .total_cmp(&b.accuracy.psnr_db)
                .then(cost(b).total_cmp(&cost(a)))
        })
}

/// Indices of the rows on the Pareto front of accuracy (PSNR, higher is better) against
/// `cost` (lower is better; rows without one are left out), cheapest first.
pub fn pareto_front(rows: &[Measured], cost: impl Fn(&Measured) -> Option<f64>) -> Vec<usize> {
    let mut points: Vec<(f64, f64, usize)> = rows
        .iter()
        .enumerate()
        .filter_map(|(i, m)| cost(m).map(|c| (c, m.accuracy.psnr_db, i)))
        .collect();
    points.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.total_cmp(&a.1)));
    let mut front = Vec::new();
    let mut best = f64::NEG_INFINITY;
    for (_, psnr, i) in points {
        if psnr > best {
            best = psnr;
            front.push(i);
        }
    }
    front
}

fn mcu_cost(m: &Measured) -> Option<f64> {
    m.mcu.map(|c| c.instructions_per_frame)
}

/// The Markdown table, one row per configuration, with the recommendation.
pub fn markdown(rows: &[Measured], scenes: &[String], mcu_build: Option<&str>) -> String {
    let front = pareto_front(rows, mcu_cost);
    let best = recommended(rows).map(|m| m.setup);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Scenes: {}. Accuracy against the f64 full-resolution fusion of the same tile schedule; \
         host time on this machine, one thread; MCU instructions from the Cortex-M7 bench{}.\n",
        scenes.join(", "),
        match mcu_build {
            Some(b) => format!(" (build {b})"),
            None => " (not found: run `bash tests/mcu-bench/run.sh`)".into(),
        }
    );
    s.push_str(
        "| wavelet | levels | downsample | fuse step | normalized per | PSNR dB | MS-SSIM | max abs err | IE change | host ns / camera px | MCU instructions / frame | within 10 % of a frame | Pareto (MCU) |\n\
         |---|---|---|---|---|---:|---:|---:|---:|---:|---:|---|---|\n",
    );
    for (i, m) in rows.iter().enumerate() {
        let a = &m.accuracy;
        let (mcu, fits) = match m.mcu {
            Some(c) => (
                format!("{:.0}", c.instructions_per_frame),
                match (c.instructions_per_frame <= BUDGET_INSTRUCTIONS, c.fits_ram) {
                    (true, true) => "yes",
                    (false, true) => "no",
                    (_, false) => "no (RAM)",
                },
            ),
            None => ("—".into(), "—"),
        };
        let mark = if Some(m.setup) == best {
            " **recommended**"
        } else {
            ""
        };
        let _ = writeln!(
            s,
            "| {} | {} | {}× | {} | {} | {:.2} | {:.4} | {:.1} | {:+.2} % | {:.1} | {} | {}{} | {} |",
            m.setup.wavelet_name(),
            m.setup.levels,
            m.setup.downsample,
            m.setup.precision_name(),
            m.setup.norm_name(),
            a.psnr_db,
            a.ms_ssim,
            a.max_abs,
            a.ie_change_pct,
            m.host_ns_per_px,
            mcu,
            fits,
            mark,
            if front.contains(&i) { "yes" } else { "" },
        );
    }
    match recommended(rows) {
        Some(m) => {
            let _ = writeln!(
                s,
                "\nRecommended (most accurate within 10 % of a frame and the firmware's RAM): **{}**, \
                 {:.2} dB, {:.0} instructions per frame.",
                m.setup.label(),
                m.accuracy.psnr_db,
                mcu_cost(m).unwrap_or(f64::NAN)
            );
        }
        None => s.push_str("\nNo configuration with MCU figures fits the budget.\n"),
    }
    s
}

/// The CSV: one line per configuration.
pub fn csv(rows: &[Measured]) -> String {
    let mut s = String::from(
        "wavelet,levels,downsample,precision,norm,psnr_db,ms_ssim,max_abs,ie_change_pct,pixels,\
         host_ns_per_px,mcu_instructions_per_frame,mcu_fits_ram\n",
    );
    for m in rows {
        let a = &m.accuracy;
        let (mcu, ram) = m.mcu.map_or((String::new(), String::new()), |c| {
            (
                format!("{:.0}", c.instructions_per_frame),
                u8::from(c.fits_ram).to_string(),
            )
        });
        let _ = writeln!(
            s,
            "{},{},{},{},{},{:.4},{:.6},{:.3},{:.4},{},{:.3},{},{}",
            m.setup.wavelet_name(),
            m.setup.levels,
            m.setup.downsample,
            m.setup.precision_name(),
            m.setup.norm_name(),
            a.psnr_db,
            a.ms_ssim,
            a.max_abs,
            a.ie_change_pct,
            a.pixels,
            m.host_ns_per_px,
            mcu,
            ram
        );
    }
    s
}

/// Fixed-path points in blue, `f32` in orange.
const FIXED: RGBColor = RGBColor(31, 119, 180);
const F32: RGBColor = RGBColor(255, 127, 14);

/// The figure: two panels side by side, pixels.
const FIGURE: (u32, u32) = (1200, 520);
/// Font sizes, pixels: the panel titles, the note shown in place of a panel.
const TITLE_FONT: u32 = 20;
const NOTE_FONT: u32 = 18;
/// Where that note starts, pixels from the panel's top left.
const NOTE_AT: (i32, i32) = (40, 250);
/// Room around each panel and for its axis labels, pixels.
const PANEL_MARGIN: u32 = 12;
const X_LABELS: u32 = 45;
const Y_LABELS: u32 = 55;
/// Padding beyond the data, as a share of its span on each axis.
const X_PAD: f64 = 0.05;
const Y_PAD: f64 = 0.08;
/// Marker radii, pixels: a configuration, the recommended one's ring.
const POINT: i32 = 4;
const RING: i32 = 9;
/// Legend samples: a line's length and a marker's offset, pixels.
const LEGEND_LINE: i32 = 16;
const LEGEND_MARK: i32 = 8;

/// The Pareto plot as SVG: PSNR against MCU instructions per frame (with the budget line;
/// left out when the bench's figures are missing) and against host time.
pub fn pareto_svg(rows: &[Measured]) -> anyhow::Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, FIGURE).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (left, right) = root.split_horizontally(FIGURE.0 / 2);
        let have_mcu = rows.iter().any(|m| m.mcu.is_some());
        if have_mcu {
            panel(
                &left,
                rows,
                "Accuracy vs Cortex-M7 time",
                "MCU instructions per frame (millions)",
                |m| mcu_cost(m).map(|c| c / 1e6),
                Some(BUDGET_INSTRUCTIONS / 1e6),
            )?;
        } else {
            left.draw(&Text::new(
                "No MCU figures: run bash tests/mcu-bench/run.sh",
                NOTE_AT,
                ("sans-serif", NOTE_FONT),
            ))
            .map_err(plot_err)?;
        }
        panel(
            &right,
            rows,
            "Accuracy vs host time",
            "host ns per camera pixel",
            |m| Some(m.host_ns_per_px),
            None,
        )?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

fn plot_err(e: impl std::fmt::Display) -> anyhow::Error {
    anyhow::anyhow!("cannot draw the plot: {e}")
}

/// A configuration's place on a panel: cost, PSNR, and whether it is on the fixed path.
type Point = (f64, f64, bool);

/// A panel's chart, cost along x and PSNR up.
type Chart<'a, DB> = ChartContext<
    'a,
    DB,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// One scatter panel with its Pareto front and an optional vertical budget line.
fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    rows: &[Measured],
    title: &str,
    x_desc: &str,
    cost: impl Fn(&Measured) -> Option<f64>,
    budget: Option<f64>,
) -> anyhow::Result<()> {
    let points = points(rows, &cost);
    anyhow::ensure!(!points.is_empty(), "nothing to plot for {title}");
    let mut chart = chart(area, title, x_desc, &points, budget)?;
    if let Some(b) = budget {
        budget_line(&mut chart, b)?;
    }
    if let Some((m, c)) = recommended(rows).and_then(|m| cost(m).map(|c| (m, c))) {
        chart
            .draw_series(std::iter::once(Circle::new(
                (c, m.accuracy.psnr_db),
                RING,
                BLACK.stroke_width(2),
            )))
            .map_err(plot_err)?
            .label("recommended")
            .legend(|(x, y)| Circle::new((x + LEGEND_MARK, y), RING - 3, BLACK.stroke_width(2)));
    }
    let front: Vec<(f64, f64)> = pareto_front(rows, &cost)
        .into_iter()
        .filter_map(|i| cost(&rows[i]).map(|c| (c, rows[i].accuracy.psnr_db)))
        .collect();
    chart
        .draw_series(LineSeries::new(front, BLACK.stroke_width(1)))
        .map_err(plot_err)?
        .label("Pareto front")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + LEGEND_LINE, y)], BLACK));
    scatter(&mut chart, &points)?;
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(plot_err)
}

/// Every configuration with a finite cost and PSNR.
fn points(rows: &[Measured], cost: &impl Fn(&Measured) -> Option<f64>) -> Vec<Point> {
    rows.iter()
        .filter_map(|m| {
            cost(m).map(|c| {
                let fixed = m.setup.precision == rollfuse_core::device::Precision::Fixed;
                (c, m.accuracy.psnr_db, fixed)
            })
        })
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .collect()
}

/// The panel's axes, spanning the points (and the budget) with some room.
fn chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    x_desc: &str,
    points: &[Point],
    budget: Option<f64>,
) -> anyhow::Result<Chart<'a, DB>> {
    let span = |it: &mut dyn Iterator<Item = f64>| {
        it.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
    };
    let (x0, x1) = span(&mut points.iter().map(|p| p.0).chain(budget));
    let (y0, y1) = span(&mut points.iter().map(|p| p.1));
    let (xpad, ypad) = ((x1 - x0).max(1e-9) * X_PAD, (y1 - y0).max(1e-9) * Y_PAD);
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", TITLE_FONT))
        .margin(PANEL_MARGIN)
        .x_label_area_size(X_LABELS)
        .y_label_area_size(Y_LABELS)
        .build_cartesian_2d((x0 - xpad)..(x1 + xpad), (y0 - ypad)..(y1 + ypad))
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("PSNR vs the f64 reference (dB)")
        .draw()
        .map_err(plot_err)?;
    Ok(chart)
}

/// The time budget as a vertical red line across the panel.
fn budget_line<DB: DrawingBackend>(chart: &mut Chart<'_, DB>, budget: f64) -> anyhow::Result<()> {
    let (y0, y1) = (chart.y_range().start, chart.y_range().end);
    chart
        .draw_series(std::iter::once(PathElement::new(
            vec![(budget, y0), (budget, y1)],
            RED.stroke_width(2),
        )))
        .map_err(plot_err)?
        .label("10 % of a frame")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + LEGEND_LINE, y)], RED.stroke_width(2)));
    Ok(())
}

/// The configurations as dots, one colour per arithmetic.
fn scatter<DB: DrawingBackend>(chart: &mut Chart<'_, DB>, points: &[Point]) -> anyhow::Result<()> {
    for (fixed, color, name) in [(true, FIXED, "fixed"), (false, F32, "f32")] {
        chart
            .draw_series(
                points
                    .iter()
                    .filter(|p| p.2 == fixed)
                    .map(|p| Circle::new((p.0, p.1), POINT, color.filled())),
            )
            .map_err(plot_err)?
            .label(name)
            .legend(move |(x, y)| Circle::new((x + LEGEND_MARK, y), POINT, color.filled()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tradeoff::bench::McuCost;
    use crate::tradeoff::{Accuracy, Setup};

    fn row(levels: u8, psnr_db: f64, instructions: Option<f64>, fits_ram: bool) -> Measured {
        Measured {
            setup: Setup {
                levels,
                ..Setup::DEFAULT
            },
            accuracy: Accuracy {
                psnr_db,
                ms_ssim: 0.9,
                max_abs: 1.0,
                ie_change_pct: 0.0,
                pixels: 1,
            },
            host_ns_per_px: 1.0,
            mcu: instructions.map(|i| McuCost {
                instructions_per_frame: i,
                fits_ram,
            }),
        }
    }

    #[test]
    fn the_recommendation_is_the_most_accurate_that_fits() {
        let rows = [
            row(1, 30.0, Some(1.0e6), true),
            row(2, 35.0, Some(1.5e6), true),
            row(3, 40.0, Some(2.0e6), true),  // over the time budget
            row(4, 45.0, Some(1.2e6), false), // over the RAM
            row(1, 50.0, None, true),         // not measured on the MCU
        ];
        assert_eq!(recommended(&rows).map(|m| m.setup.levels), Some(2));
        // Cheapest first; the RAM-bound row is on the front (the front is about time).
        assert_eq!(pareto_front(&rows, mcu_cost), vec![0, 3]);
        assert_eq!(pareto_front(&rows, |m| Some(m.host_ns_per_px)), vec![4]);
        let md = markdown(&rows, &["s".into()], Some("abc"));
        assert!(md.contains("**recommended**") && md.contains("build abc"));
        assert!(recommended(&rows[2..]).is_none());
    }
}
