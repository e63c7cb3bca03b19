//! `rollfuse fuse` on a roll: frames decoded on a second thread, aligned, fused over the
//! contact window and written as strip segments as they are finished.

use super::args::{AlignArg, Args, OutBits};
use crate::commands::bars::{Bars, Show};
use crate::commands::check_writable;
use crate::commands::side_files::{self, Side};
use anyhow::bail;
use rollfuse::files::PendingFile;
use rollfuse::frames::{manifest_path, motion_offsets, refuse_overwriting_inputs};
use rollfuse::fullres::register::{Placement, Summary};
use rollfuse::fullres::roll::{Bands, StripSink};
use rollfuse::fullres::strip::{Placing, StripOptions, StripReport, WindowChoice, fuse_strip};
use rollfuse::fullres::window::{Geometry, WindowSource};
use rollfuse::image::{PixelLimit, Planes};
use rollfuse::progress::Progress;
use rollfuse::sim::Manifest;
use rollfuse::strip_file::{Segment, StripWriter};
use rollfuse_core::FuseConfig;
use std::path::{Path, PathBuf};
use std::sync::mpsc::sync_channel;

/// Frames decoded ahead of the fusion.
const DECODE_AHEAD: usize = 4;

/// The roller geometry recorded in a simulator manifest, if the manifest is there and its
/// frames are `width × height`.
fn manifest_geometry(manifest: &Path, (width, height): (u32, u32)) -> Option<Geometry> {
    let roller = Manifest::read(manifest).ok()?.roller()?;
    if roller.image_size != [width as usize, height as usize] {
        return None;
    }
    // The apex is the middle row, as the simulator renders it (`Sensor::roller_geometry`);
    // the focal row is where the camera focuses, not where the roller touches.
    Some(Geometry {
        roller_radius_mm: roller.radius_mm,
        press_depth_mm: roller.press_depth_mm,
        mm_per_px: roller.mm_per_px,
        apex_row: f64::from(height) / 2.0,
    })
}

/// What the strip's index records besides its segments.
#[derive(serde::Serialize)]
struct Details<'a> {
    mode: &'static str,
    align: &'static str,
    frames_csv: String,
    /// Whether the frames' placement can be trusted ([`StripReport::doubts`]).
    trusted: bool,
    #[serde(flatten)]
    report: &'a StripReport,
}

/// Fuses the roll named by `args` (frames already decoded in `loaded`, if any).
/// Progress is shown as `show` says.
pub fn run(
    args: &Args,
    loaded: Option<Vec<Planes>>,
    cfg: &FuseConfig,
    show: Show,
    limit: PixelLimit,
) -> anyhow::Result<()> {
    let out = &args.out;
    let csv_path = Side::FramesCsv.path(out);
    let index_path = StripWriter::index_path(out);
    check_outputs(args, &csv_path, &index_path)?;
    let _folder = rollfuse::files::NewFolder::for_file(out)?;
    let opts = strip_options(args, cfg)?;
    // Opened before the work: a database that cannot be had is said at once.
    let mut records = args.record.open()?;
    let mut csv = PendingFile::create(&csv_path)?;
    csv.write_all(b"frame,file,row,col,source,score,sigma\n")?;
    let bars = Bars::new(show);
    bars.start("fusing the roll", Some(args.frames.len() as u64), "frames");
    let started = std::time::Instant::now();
    let files = &args.frames;
    let on_frame = |p: &Placement| {
        let k = p.frame;
        bars.advance_to(k as u64 + 1);
        let score = p.score.map(|s| format!("{s:.4}")).unwrap_or_default();
        let line = format!(
            "{k},{},{:.3},{},{},{score},{:.3}\n",
            files[k].display(),
            p.row,
            p.col,
            p.source.name(),
            p.sigma
        );
        Ok(csv.write_all(line.as_bytes())?)
    };
    let make_sink = |width: usize, channels: usize| {
        Ok(StripWriter::new(
            out,
            width,
            channels,
            args.out_bits.bits(),
            args.segment_rows,
        )?)
    };
    let (writer, report) = fuse_files(files, loaded, limit, &opts, make_sink, on_frame)?;
    bars.finish();
    let took = started.elapsed().as_secs_f64();
    let details = Details {
        mode: "roll",
        align: match args.align {
            AlignArg::Template => "template",
            AlignArg::Motion => "motion",
            AlignArg::None => "none",
        },
        frames_csv: csv_path
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned(),
        trusted: report.doubts.is_empty(),
        report: &report,
    };
    csv.commit()?;
    let segments = writer.finish(&details)?;
    side_files::remove_others(out, &[Side::Strip, Side::FramesCsv])?;
    print_summary(args, &report, &segments, took, &index_path);
    if let Some(records) = &mut records {
        record(records, args, &details, &segments)?;
    }
    untrusted(&report, args.accept_untrusted, &index_path)
}

/// Keeps the fused roll in the records: its source the frames, its configuration the
/// strip's details, complete, or failed when its placement cannot be trusted.
fn record(
    records: &mut rollfuse_records::Records,
    args: &Args,
    details: &Details,
    segments: &[Segment],
) -> anyhow::Result<()> {
    let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let (first, last) = (&args.frames[0], &args.frames[args.frames.len() - 1]);
    let manifest = manifest_path(args.manifest.as_deref(), &args.frames);
    let manifest_scale = rollfuse::image::dimensions(first)
        .ok()
        .and_then(|size| manifest_geometry(&manifest, size))
        .map(|g| g.mm_per_px);
    let start = rollfuse_records::RollStart {
        source: format!(
            "frames {} … {}",
            absolute(first).display(),
            absolute(last).display()
        ),
        line: args.record.line.clone(),
        device: "host".into(),
        configuration: serde_json::to_string(details)?,
        out: absolute(&args.out).display().to_string(),
        mm_per_row: args.mm_per_px.or(manifest_scale),
    };
    let status = if details.trusted {
        rollfuse_records::Status::Complete
    } else {
        rollfuse_records::Status::Failed("its placement cannot be trusted".into())
    };
    let id = rollfuse::records::record_strip(records, &start, &args.out, segments, &status)?;
    println!(
        "records: roll {id}, {} segment{} ({})",
        segments.len(),
        if segments.len() == 1 { "" } else { "s" },
        status.word()
    );
    Ok(())
}

/// Warns of every doubt about the placement; an error (exit 3) unless `accepted`.
fn untrusted(report: &StripReport, accepted: bool, index: &Path) -> anyhow::Result<()> {
    if report.doubts.is_empty() {
        return Ok(());
    }
    for why in &report.doubts {
        eprintln!("warning: placement: {why}");
    }
    if accepted {
        return Ok(());
    }
    Err(crate::commands::Untrusted(format!(
        "the strip was written but its placement cannot be trusted ({} marks it \
         \"trusted\": false); --accept-untrusted exits 0 for such a strip",
        index.display()
    ))
    .into())
}

/// Refuses outputs that cannot be written or would overwrite an input.
fn check_outputs(args: &Args, csv_path: &Path, index_path: &Path) -> anyhow::Result<()> {
    let out = args.out.as_path();
    for p in [out, csv_path, index_path] {
        check_writable(p)?;
    }
    refuse_overwriting_inputs(
        &[out, csv_path, index_path],
        &args.frames,
        args.manifest.as_deref(),
    )?;
    let records: Vec<(&str, &Path)> = args.record.as_input().into_iter().collect();
    rollfuse::files::refuse_overwriting(&[out, csv_path, index_path], &records)?;
    let mut inputs: Vec<(&str, &Path)> =
        args.frames.iter().map(|p| ("input", p.as_path())).collect();
    inputs.extend(records);
    rollfuse::strip_file::refuse_segment_names(out, &inputs)?;
    if args.precision == rollfuse::fullres::Precision::Fixed && args.out_bits == OutBits::Sixteen {
        eprintln!("note: --precision fixed makes 8-bit values; the 16-bit file holds them scaled");
    }
    Ok(())
}

/// How the frames are placed (`--align`, the manifest's rows) and fused (the window from
/// `--window-rows`, the manifest's roller, or measured; the bands).
fn strip_options(args: &Args, cfg: &FuseConfig) -> anyhow::Result<StripOptions> {
    let (w, h) = rollfuse::image::dimensions(&args.frames[0])?;
    let manifest = manifest_path(args.manifest.as_deref(), &args.frames);
    let commanded = || -> anyhow::Result<Vec<f64>> {
        Ok(motion_offsets(&manifest, &args.frames)?
            .into_iter()
            .map(|o| o.dy as f64)
            .collect())
    };
    let placing = match args.align {
        AlignArg::None => {
            bail!("a roll must be aligned: use --align template or motion, or --mode mosaic")
        }
        AlignArg::Motion => Placing::Commanded(commanded()?),
        AlignArg::Template => Placing::Track {
            params: Some(args.track_params(h as usize)),
            commanded: args.manifest.is_some().then(commanded).transpose()?,
        },
    };
    let window = match (args.window_rows, manifest_geometry(&manifest, (w, h))) {
        (Some(0), _) => bail!("--window-rows must be at least 1"),
        (Some(rows), _) => WindowChoice::Rows(rows),
        (None, Some(g)) => WindowChoice::Geometry(g),
        (None, None) => WindowChoice::Measure,
    };
    Ok(StripOptions {
        window,
        bands: Bands {
            band_rows: args.band_rows,
            blend_rows: args.blend_rows,
        },
        cfg: *cfg,
        precision: args.precision,
        placing,
    })
}

/// Fuses `files` (already `loaded`, or decoded on a second thread as fusion goes, each
/// within `limit`).
fn fuse_files<S: StripSink>(
    files: &[PathBuf],
    loaded: Option<Vec<Planes>>,
    limit: PixelLimit,
    opts: &StripOptions,
    make_sink: impl FnOnce(usize, usize) -> anyhow::Result<S>,
    on_frame: impl FnMut(&Placement) -> anyhow::Result<()>,
) -> anyhow::Result<(S, StripReport)> {
    match loaded {
        Some(frames) => Ok(fuse_strip(
            frames.into_iter().map(Ok),
            opts,
            make_sink,
            on_frame,
        )?),
        None => std::thread::scope(|scope| {
            // Decoding on a second thread overlaps with fusion.
            let (tx, rx) = sync_channel(DECODE_AHEAD);
            scope.spawn(move || {
                for path in files {
                    let frame = Planes::load(path, limit).map_err(anyhow::Error::from);
                    let failed = frame.is_err();
                    if tx.send(frame).is_err() || failed {
                        break;
                    }
                }
            });
            Ok(fuse_strip(rx, opts, make_sink, on_frame)?)
        }),
    }
}

fn print_summary(args: &Args, r: &StripReport, segments: &[Segment], took: f64, index: &Path) {
    let n = args.frames.len();
    println!(
        "contact window: frame rows {}..{} ({} rows, {})",
        r.window.top,
        r.window.top + r.window.rows,
        r.window.rows,
        match (r.window_source, r.no_contact) {
            (WindowSource::Option, _) => "--window-rows".to_string(),
            (WindowSource::Geometry, _) => "from the roller geometry in the manifest".into(),
            (WindowSource::Measured, _) => format!(
                "measured on the first {} frames",
                n.min(rollfuse::fullres::strip::MEASURE_FRAMES)
            ),
            (WindowSource::Default, Some(why)) => format!(
                "the middle half: no contact could be measured on the first frames, {}",
                why.describe()
            ),
            (WindowSource::Default, None) => "the middle half".into(),
        }
    );
    if let Some(p) = &r.placement {
        print_placement(p);
    }
    let s = &r.summary;
    if s.bands_outside_window + s.gap_bands > 0 || s.bands_skipped > 0 {
        eprintln!(
            "warning: {} band(s) outside every contact window (fused from the nearest frame), \
             {} band(s) no frame covered (written as zeros), {} band(s) passed over where the \
             belt jumped (a new segment)",
            s.bands_outside_window, s.gap_bands, s.bands_skipped
        );
    }
    if s.frames_behind > 0 {
        eprintln!(
            "warning: {} of {n} frames lay wholly behind the strip already fused (frames out \
             of belt order, or the belt ran backwards): they added nothing",
            s.frames_behind
        );
    }
    let files: Vec<&str> = segments.iter().map(|s| s.file.as_str()).collect();
    println!(
        "fused {n} frames into {} strip rows ({} bands) → {} (index {}); {:.2} s, {:.2} ms a frame",
        s.rows,
        s.bands,
        if files.len() == 1 {
            files[0].to_string()
        } else {
            format!(
                "{} segments {} … {}",
                files.len(),
                files[0],
                files[files.len() - 1]
            )
        },
        index.display(),
        took,
        1e3 * took / n as f64
    );
}

/// The placement's sources and what rests on predictions.
fn print_placement(p: &Summary) {
    println!(
        "alignment: {} matched, {} predicted (no texture to match), {} unmatched (texture that \
         matched nothing), 1 first; {} matches kept, {} dropped as inconsistent{}",
        p.matched,
        p.predicted,
        p.unmatched,
        p.matches,
        p.inconsistent,
        match p.found_again {
            0 => String::new(),
            n => format!(", belt found again {n} time(s) by a wide search"),
        }
    );
    if p.travel_rows > 0.0 {
        let (run, at) = p.longest_guess;
        println!(
            "placement: {:.0} of {:.0} rows of travel ({:.1} %) rest on predictions{}",
            p.predicted_rows,
            p.travel_rows,
            100.0 * p.predicted_rows / p.travel_rows,
            if run > 0 {
                format!("; the longest run of predicted frames is {run}, from frame {at}")
            } else {
                String::new()
            }
        );
    }
}
