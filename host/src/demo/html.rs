//! The demo's `report.html`: one self-contained page (images as data URIs, the Pareto plot
//! inline, no scripts, no external files) that a browser opens without a network.
//!
//! The tables are the Markdown the single-purpose commands write, turned into HTML here,
//! so the page shows the very figures `rollfuse eval` and `rollfuse tradeoff` print.

use super::detection;
use super::markup::{escape, tables};
use super::results::{Demo, Files};
use crate::stream::StopReason;
use anyhow::Context;
use base64::Engine;
use std::fmt::Write;
use std::path::Path;

/// Builds the page from the demo's figures and the images it wrote to `dir`, a section a
/// stage.
pub fn report(demo: &Demo, dir: &Path) -> anyhow::Result<String> {
    let total: f64 = demo.stages.iter().map(|s| s.secs).sum();
    let body = [
        lead(demo, total)?,
        acquisition(demo, dir)?,
        device_strip(demo, dir)?,
        full_resolution(demo, dir)?,
        evaluation(dir)?,
        depth(demo, dir)?,
        detection::section(
            &demo.detection,
            6,
            |name, alt| image(dir, name, alt),
            tables(&read(dir, detection::TABLE_MD)?),
        )?,
        trade_off(demo, dir)?,
        timings(demo, total)?,
    ]
    .concat();
    Ok(format!(
        "<!DOCTYPE html>\n<html lang=en>\n<head>\n<meta charset=utf-8>\n<title>rollfuse demo \
         report</title>\n<style>{STYLE}</style>\n</head>\n<body>\n{body}</body>\n</html>\n"
    ))
}

/// A file the demo wrote to `dir`, as text.
fn read(dir: &Path, name: &str) -> anyhow::Result<String> {
    std::fs::read_to_string(dir.join(name))
        .with_context(|| format!("cannot read {}", dir.join(name).display()))
}

/// The title and what the page shows.
fn lead(demo: &Demo, total: f64) -> anyhow::Result<String> {
    let mut body = String::new();
    let (n, fw, fh) = demo.frames;
    writeln!(
        body,
        "<h1>rollfuse demo</h1>\n<p class=lead>The whole system on simulated data: a rolling \
         acquisition of the <b>{}</b> scene ({n} frames of {fw}×{fh}) fused on the virtual \
         device and on the host, evaluated the way the paper does, depth from the three-sphere \
         scene, and what accuracy costs in time. Made by <code>cargo run --release -- demo</code> \
         in {total:.1} s.</p>",
        escape(&demo.letters_name)
    )?;
    Ok(body)
}

/// 1: a few of the camera frames.
fn acquisition(demo: &Demo, dir: &Path) -> anyhow::Result<String> {
    let mut body = String::new();
    body.push_str("<h2>1. The rolling acquisition</h2>\n<div class=row>");
    for &k in &demo.shown_frames {
        write!(
            body,
            "<figure>{}<figcaption>frame {k}</figcaption></figure>",
            image(dir, &Files::frame(k), &format!("camera frame {k}"))?
        )?;
    }
    body.push_str("</div>\n");
    Ok(body)
}

/// 2: the strip the virtual device fused and streamed.
fn device_strip(demo: &Demo, dir: &Path) -> anyhow::Result<String> {
    let mut body = String::new();
    let s = &demo.stream;
    let faults = s.faults.total();
    writeln!(
        body,
        "<h2>2. Fused on the device, streamed, stitched</h2>\n<p>The shared device pipeline \
         (downsample, refine offsets, integer wavelet fusion of each tile) ran in the virtual \
         device; its tiles crossed the link as real protocol messages: <b>{} tiles</b>, {} \
         bytes, {} messages, {faults} link faults, {} missing tile ranges; {}. The strip is \
         {}×{} (downsampled).</p>\n<figure class=tall>{}<figcaption>the stitched strip \
         (stream/strip.png; manifest in stream/manifest.json)</figcaption></figure>",
        s.tiles_received,
        s.bytes,
        s.messages,
        s.gaps.len(),
        match demo.stream_stop {
            StopReason::DeviceStopped => "the device ended the stream when the scene ran out",
            StopReason::LinkClosed => "the link closed before the device ended the stream",
            StopReason::Silent => "the device fell silent and the session gave up",
            StopReason::TileLimit | StopReason::TimeLimit => "the session stopped at its limit",
        },
        demo.strip_size.0,
        demo.strip_size.1,
        image(dir, Files::STRIP, "the device-fused strip")?
    )?;
    Ok(body)
}

/// 3: the host's full-resolution strip, and the fusion of four frames beside one.
fn full_resolution(demo: &Demo, dir: &Path) -> anyhow::Result<String> {
    let mut body = String::new();
    let a = &demo.alignment;
    writeln!(
        body,
        "<h2>3. Full-resolution fusion on the host</h2>\n<p>The roll at full resolution: \
         {} of {} frames matched to the frames around them ({} placed at their \
         prediction; largest disagreement with the belt's motion: {} rows), and each band \
         of 32 belt rows fused (db2, one level, f32) from the frames in whose contact \
         window, frame rows {}..{}, it lay; each belt point is seen by about {:.0} frames, \
         of which the window keeps the ones pressing it. The strip is {}×{}, beside the \
         device's. Then the middle frame alone and the fusion of the four frames around it \
         (Table III's \"fusion of 4\") over the same footprint.</p>\n<div class=row>\
         <figure class=tall>{}<figcaption>the host's strip, full resolution (fused.png)\
         </figcaption></figure><figure class=tall>{}<figcaption>the device's strip, 2× \
         downsampled (stream/strip.png)</figcaption></figure><figure class=pair>{}\
         <figcaption>the middle frame alone (single.png)</figcaption></figure><figure \
         class=pair>{}<figcaption>fusion of 4 over the same footprint (fused_middle.png)\
         </figcaption></figure></div>",
        a.matched,
        a.frames,
        a.predicted,
        a.max_motion_disagreement,
        a.window.top,
        a.window.top + a.window.rows,
        demo.frames_per_point,
        demo.host_strip_size.0,
        demo.host_strip_size.1,
        image(dir, Files::HOST_STRIP, "the host's full-resolution strip")?,
        image(dir, Files::STRIP, "the device-fused strip")?,
        image(dir, Files::SINGLE, "the middle frame")?,
        image(
            dir,
            Files::FUSED_MIDDLE,
            "the fused image over the middle frame"
        )?
    )?;
    Ok(body)
}

/// 4: Tables II and III.
fn evaluation(dir: &Path) -> anyhow::Result<String> {
    let mut body = String::new();
    writeln!(
        body,
        "<h2>4. Does fusion help? (Tables II and III)</h2>\n<p>Information entropy (IE), \
         MS-SSIM against the ideal contact image, and their spread over 10 strips, over the \
         middle frame's footprint. The same figures as <code>rollfuse eval --scene …</code> \
         for this scene.</p>\n{}",
        tables(&read(dir, Files::EVAL_MD)?)
    )?;
    Ok(body)
}

/// 5: depth maps and Table IV.
fn depth(demo: &Demo, dir: &Path) -> anyhow::Result<String> {
    let mut body = String::new();
    writeln!(
        body,
        "<h2>5. Depth from single and fused frames (Table IV)</h2>\n<div class=row>"
    )?;
    for (name, r) in Files::DEPTH_PNGS.iter().zip(&demo.depth) {
        write!(
            body,
            "<figure>{}<figcaption>{}</figcaption></figure>",
            image(dir, name, &r.method)?,
            escape(&r.method)
        )?;
    }
    writeln!(
        body,
        "</div>\n<p>Three equal spheres: fusion should make their reconstructed areas and \
         peaks alike. The same figures as <code>rollfuse eval --depth</code>.</p>\n{}",
        tables(&read(dir, Files::DEPTH_MD)?)
    )?;
    Ok(body)
}

/// 7: the trade-off plot and table.
fn trade_off(demo: &Demo, dir: &Path) -> anyhow::Result<String> {
    let mut body = String::new();
    let svg = read(dir, Files::PARETO)?;
    let svg = svg.find("<svg").map_or(svg.as_str(), |i| &svg[i..]);
    writeln!(
        body,
        "<h2>7. What accuracy costs in time</h2>\n<p>Each device configuration against the \
         f64 full-resolution reference of the same tile schedule: PSNR against host time \
         (one run each, as <code>rollfuse tradeoff --repeats 1</code>) and {}.</p>\n<div class=plot>{svg}</div>\n<details><summary>the whole table</summary>{}\
         </details>",
        match &demo.mcu_build {
            Some(b) => format!(
                "Cortex-M7 instructions per frame (bench build {})",
                escape(b)
            ),
            None => "(no Cortex-M7 bench results were found: run <code>bash tests/mcu-bench/\
                     run.sh</code> for instruction counts)"
                .into(),
        },
        tables(&read(dir, Files::TRADEOFF_MD)?)
    )?;
    Ok(body)
}

/// 8: the stages' timings.
fn timings(demo: &Demo, total: f64) -> anyhow::Result<String> {
    let mut body = String::new();
    body.push_str(
        "<h2>8. How long each stage took</h2>\n<table><tr><th>stage</th><th>what</th>\
         <th>seconds</th></tr>",
    );
    for st in &demo.stages {
        write!(
            body,
            "<tr><td>{}</td><td>{}</td><td class=num>{:.2}</td></tr>",
            escape(st.name),
            escape(&st.what),
            st.secs
        )?;
    }
    writeln!(
        body,
        "<tr><th>total</th><td></td><td class=num>{total:.2}</td></tr></table>"
    )?;
    Ok(body)
}

const STYLE: &str = "body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;\
padding:0 1em;color:#222}h1{margin-bottom:.2em}.lead{color:#444}\
.row{display:flex;flex-wrap:wrap;gap:12px}figure{margin:0}figcaption{font-size:.85em;color:#555}\
img{image-rendering:pixelated;border:1px solid #ccc;max-width:100%}.row img{height:180px}\
.tall img{height:480px}.pair img{height:240px}table{border-collapse:collapse;font-size:.85em;margin:.5em 0}\
td,th{border:1px solid #ccc;padding:2px 6px;text-align:left}td.num{text-align:right}\
.plot svg{max-width:100%;height:auto}code{background:#f3f3f3;padding:0 3px}";

/// An `<img>` with the PNG at `dir/name` as a data URI.
fn image(dir: &Path, name: &str, alt: &str) -> anyhow::Result<String> {
    let path = dir.join(name);
    let bytes = std::fs::read(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let data = base64::engine::general_purpose::STANDARD.encode(bytes);
    Ok(format!(
        "<img src=\"data:image/png;base64,{data}\" alt=\"{}\">",
        escape(alt)
    ))
}
