//! `rollfuse rolls`: the inspection records read back — the rolls of a line, one roll's
//! record, and its roll map (docs/records.md).

use anyhow::{Context, ensure};
use rollfuse::files::Batch;
use rollfuse_records::{Filter, Records, Roll, RollSummary, map};
use std::path::{Path, PathBuf};

/// Where a command keeps its roll in the records.
#[derive(clap::Args, Debug, Clone)]
pub struct RecordTo {
    /// Keep the roll in the inspection records: a SQLite file (made if missing) or a
    /// `postgres://` URL (docs/records.md).
    #[arg(long, value_name = "DB")]
    pub records: Option<String>,
    /// The production line the roll is from, as the records name it.
    #[arg(
        long,
        value_name = "LINE",
        default_value = "default",
        requires = "records"
    )]
    pub line: String,
}

impl RecordTo {
    /// The records, opened, if asked for.
    pub fn open(&self) -> anyhow::Result<Option<Records>> {
        self.records.as_deref().map(open).transpose()
    }

    /// The records' file, an input no output may overwrite (none for a server).
    pub fn as_input(&self) -> Option<(&'static str, &Path)> {
        records_file(self.records.as_deref()?)
    }
}

/// `target` as an input no output may overwrite, when it is a SQLite file.
pub fn records_file(target: &str) -> Option<(&'static str, &Path)> {
    (!rollfuse_records::is_postgres(target)).then(|| ("records", Path::new(target)))
}

/// Opens the records at `target`.
pub fn open(target: &str) -> anyhow::Result<Records> {
    Ok(Records::open(target)?)
}

/// `rollfuse rolls`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    command: RollsCommand,
}

#[derive(clap::Subcommand, Debug)]
enum RollsCommand {
    /// The rolls, the newest first: one a line, its id first, its status in words.
    List(ListArgs),
    /// One roll's record: its segments, defects and faults.
    Show(ShowArgs),
    /// The roll as a bar in metres with each defect marked (SVG), and a CSV of the defects
    /// for the cutting room beside it.
    Map(MapArgs),
}

#[derive(clap::Args, Debug)]
struct ListArgs {
    /// The records: a SQLite file or a `postgres://` URL.
    #[arg(long, value_name = "DB")]
    records: String,
    /// Only this line's rolls.
    #[arg(long)]
    line: Option<String>,
    /// Only rolls started at or after this time: RFC 3339 (`2026-11-20T06:00:00Z`) or a
    /// date (`2026-11-20`, midnight UTC).
    #[arg(long, value_name = "TIME")]
    since: Option<String>,
    /// Only rolls with a defect of this kind.
    #[arg(long)]
    kind: Option<String>,
    /// JSON for scripts: an array of the rolls.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args, Debug)]
struct ShowArgs {
    /// The roll's id (`rolls list`'s first column).
    id: i64,
    /// The records: a SQLite file or a `postgres://` URL.
    #[arg(long, value_name = "DB")]
    records: String,
    /// JSON for scripts.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args, Debug)]
struct MapArgs {
    /// The roll's id (`rolls list`'s first column).
    id: i64,
    /// The records: a SQLite file or a `postgres://` URL.
    #[arg(long, value_name = "DB")]
    records: String,
    /// The map, an `.svg` file; the defects' CSV is written beside it as `STEM.csv`.
    #[arg(long)]
    out: PathBuf,
    /// The map's width, pixels.
    #[arg(long, default_value_t = 1200)]
    width: u32,
}

/// Runs `rollfuse rolls`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        RollsCommand::List(a) => list(a),
        RollsCommand::Show(a) => show(a),
        RollsCommand::Map(a) => write_map(a),
    }
}

fn list(a: ListArgs) -> anyhow::Result<()> {
    let since = a.since.as_deref().map(parse_time).transpose()?;
    let filter = Filter {
        line: a.line,
        since,
        kind: a.kind,
    };
    let rolls = open(&a.records)?.list(&filter)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rolls)?);
        return Ok(());
    }
    for r in &rolls {
        println!("{}", list_line(r));
    }
    if rolls.is_empty() {
        eprintln!(
            "no rolls in {} match",
            rollfuse_records::redacted(&a.records)
        );
    }
    Ok(())
}

/// `ID STATUS line L started T, LENGTH, N segments, M defects: OUT`.
fn list_line(r: &RollSummary) -> String {
    format!(
        "{} {} line {} started {}, {}, {} segment{}, {} defect{}: {}",
        r.id,
        r.status,
        r.line,
        r.started_at,
        length(r),
        r.segments,
        plural(r.segments),
        r.defects,
        plural(r.defects),
        r.out
    )
}

fn plural(n: i64) -> &'static str {
    if n == 1 { "" } else { "s" }
}

fn length(r: &RollSummary) -> String {
    match r.belt_mm {
        Some(mm) => format!("{:.3} m", mm / 1000.0),
        None => format!("{} rows (scale unknown)", r.belt_rows),
    }
}

/// RFC 3339, or a date taken as midnight UTC, as the records' text of a time.
fn parse_time(text: &str) -> anyhow::Result<String> {
    let full = if text.len() == 10 {
        format!("{text}T00:00:00Z")
    } else {
        text.to_owned()
    };
    let t = humantime::parse_rfc3339_weak(&full)
        .or_else(|_| humantime::parse_rfc3339(&full))
        .with_context(|| {
            format!("--since {text}: not a time (RFC 3339, 2026-11-20T06:00:00Z, or a date)")
        })?;
    Ok(humantime::format_rfc3339_seconds(t).to_string())
}

fn show(a: ShowArgs) -> anyhow::Result<()> {
    let roll = open(&a.records)?.roll(a.id)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&roll)?);
        return Ok(());
    }
    print!("{}", record_text(&roll));
    Ok(())
}

/// A roll's record as text.
fn record_text(roll: &Roll) -> String {
    let s = &roll.summary;
    let mut t = format!(
        "roll {}: {}{}\nline {}, device {}, from {}\nstarted {}, ended {}\nlength {}\nstrip {}\nconfiguration {}\n",
        s.id,
        s.status,
        s.reason
            .as_deref()
            .map(|r| format!(" ({r})"))
            .unwrap_or_default(),
        s.line,
        s.device,
        s.source,
        s.started_at,
        s.ended_at.as_deref().unwrap_or("-"),
        length(s),
        s.out,
        roll.configuration
    );
    t += &format!("{} segments:\n", roll.segment_list.len());
    for g in &roll.segment_list {
        t += &format!(
            "  {} {}: belt rows {}..{}, {} bytes, crc32 {:08x}\n",
            g.seq,
            g.file,
            g.first_row,
            g.first_row + g.rows,
            g.bytes,
            g.crc32
        );
    }
    t += &format!("{} defects:\n", roll.defect_list.len());
    for d in &roll.defect_list {
        let at = match roll.belt_mm(d) {
            Some(mm) => format!("{mm:.1} mm"),
            None => format!("row {:.0}", d.belt_row),
        };
        let [x, y, w, h] = d.bbox;
        t += &format!(
            "  {} {:.2} at {at}, box {w}×{h} at ({x}, {y}) in segment {}\n",
            d.kind,
            d.score,
            d.segment_seq.map_or("-".to_owned(), |s| s.to_string())
        );
    }
    if !roll.faults.is_empty() {
        let f: Vec<String> = roll
            .faults
            .iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        t += &format!("faults: {}\n", f.join(", "));
    }
    t
}

fn write_map(a: MapArgs) -> anyhow::Result<()> {
    ensure!(
        a.out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("svg")),
        "--out {}: the map is an .svg file (its CSV goes beside it)",
        a.out.display()
    );
    let csv_path = a.out.with_extension("csv");
    for p in [&a.out, &csv_path] {
        rollfuse::files::check_writable(p)?;
    }
    let inputs: Vec<_> = records_file(&a.records).into_iter().collect();
    rollfuse::files::refuse_overwriting(&[&a.out, &csv_path], &inputs)?;
    let roll = open(&a.records)?.roll(a.id)?;
    let svg = map::svg(&roll, a.width).map_err(anyhow::Error::msg)?;
    let csv = map::csv(&roll).map_err(anyhow::Error::msg)?;
    let _folder = rollfuse::files::NewFolder::for_file(&a.out)?;
    let mut batch = Batch::new();
    batch.add_bytes(&a.out, svg.as_bytes())?;
    batch.add_bytes(&csv_path, csv.as_bytes())?;
    batch.commit()?;
    println!(
        "wrote {} and {}: roll {}, {}, {} defects",
        a.out.display(),
        csv_path.display(),
        roll.summary.id,
        length(&roll.summary),
        roll.defect_list.len()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_are_taken_as_rfc_3339_or_a_date() {
        assert_eq!(parse_time("2026-11-20").unwrap(), "2026-11-20T00:00:00Z");
        assert_eq!(
            parse_time("2026-11-20T06:30:00Z").unwrap(),
            "2026-11-20T06:30:00Z"
        );
        assert!(parse_time("last week").is_err());
    }
}
