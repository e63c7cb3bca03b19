//! Every example in the README's and the docs' `sh` blocks, run as written: each file's
//! blocks in order, in a scratch folder of its own that sees the repository's `host/` and
//! `models/`, with `rollfuse` (and `cargo run --release --`) meaning the tool under test.
//! A command must succeed; where the doc shows what the block prints — an `<!-- output -->`
//! line after it (before the next block or heading) and the fenced block right after that
//! line — those lines must appear in that order in what it printed, `[..]` matching
//! anything within a line. A table or block a doc states as a command's result, marked
//! `<!-- output of: COMMAND -->`, is checked the same way against that command, run where
//! the marker stands. Every other table of figures names the command that measures it
//! (`<!-- measured by: COMMAND -->`) or says why it is not a measurement (`<!-- not
//! measured: REASON -->`).
//!
//! A block that cannot run here says why on the line before its fence, `<!-- not run:
//! REASON -->` (a synopsis with placeholders, a USB device, a server that runs until
//! stopped, a benchmark, a training of many minutes); an unmarked block that does not
//! run fails this test, so an example cannot drift from the tool unnoticed. Own harness
//! rather than trycmd: the examples are shell lines (brace expansion, folders made by
//! the line before) inside prose, and the docs' synopses are checked for names and
//! options by `host/tests/suite/cli.rs`.

use crate::common::docs::{named_text, pages, repo};
use std::path::Path;
use std::process::Command;

/// One fenced `sh` block of a doc.
#[derive(Debug)]
struct Block {
    /// Where its fence opens, `file:line`.
    at: String,
    /// Its commands, continuation lines joined and comments dropped.
    commands: Vec<String>,
    /// Why it is not run, from the marker before its fence.
    not_run: Option<String>,
    /// What it prints, from an `<!-- output -->` block right after it.
    output: Option<Vec<String>>,
}

const NOT_RUN: &str = "<!-- not run:";
const OUTPUT: &str = "<!-- output -->";
const OUTPUT_OF: &str = "<!-- output of:";
const MEASURED_BY: &str = "<!-- measured by:";
const NOT_MEASURED: &str = "<!-- not measured:";
/// Units after a number that make it a measured figure.
const UNITS: [&str; 9] = [
    "ms", "s", "µs", "KB", "MB", "GB", "%", "frames/s", "rolls/s",
];

/// The lines of the fenced block whose fence is `lines[open]`, and the index of its
/// closing fence.
fn fenced(lines: &[&str], open: usize) -> (Vec<String>, usize) {
    let close = (open + 1..lines.len())
        .find(|&i| lines[i].trim_start().starts_with("```"))
        .unwrap_or(lines.len());
    let body = lines[open + 1..close]
        .iter()
        .map(|l| l.to_string())
        .collect();
    (body, close)
}

/// The shell commands of an `sh` block's lines.
fn commands(body: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    let mut line = String::new();
    for raw in body {
        let code = raw.split(" #").next().unwrap_or_default().trim_end();
        if code.trim_start().starts_with('#') {
            continue;
        }
        line.push_str(code.trim_end_matches('\\'));
        line.push(' ');
        if !code.ends_with('\\') {
            let whole = std::mem::take(&mut line).trim().to_string();
            if !whole.is_empty() {
                out.push(whole);
            }
        }
    }
    out
}

/// Every `sh` block of `path`.
fn blocks(path: &Path) -> Vec<Block> {
    let (name, text) = named_text(path);
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        if let Some(command) = lines[i].trim().strip_prefix(OUTPUT_OF) {
            let (shown, next) = shown_after(&lines, i);
            out.push(Block {
                at: format!("{name}:{}", i + 1),
                commands: vec![command.trim_end_matches("-->").trim().to_string()],
                not_run: None,
                output: Some(shown),
            });
            i = next;
            continue;
        }
        let Some(lang) = lines[i].trim_start().strip_prefix("```") else {
            i += 1;
            continue;
        };
        let (body, close) = fenced(&lines, i);
        if lang.trim() == "sh" {
            let before = lines[..i].iter().rev().find(|l| !l.trim().is_empty());
            let not_run = before
                .and_then(|l| l.trim().strip_prefix(NOT_RUN))
                .map(|r| r.trim_end_matches("-->").trim().to_string());
            // Its output: the marker before the next fence or heading, prose between.
            let marker = (close + 1..lines.len())
                .take_while(|&k| {
                    let l = lines[k].trim_start();
                    !l.starts_with("```") && !l.starts_with('#')
                })
                .find(|&k| lines[k].trim() == OUTPUT);
            let output = marker
                .and_then(|m| (m + 1..lines.len()).find(|&k| !lines[k].trim().is_empty()))
                .filter(|&fence| lines[fence].trim_start().starts_with("```"))
                .map(|fence| fenced(&lines, fence).0);
            out.push(Block {
                at: format!("{name}:{}", i + 1),
                commands: commands(&body),
                not_run,
                output,
            });
        }
        i = close + 1;
    }
    out
}

/// What a doc shows after the marker at `lines[at]`: the fenced block or the Markdown
/// table that follows it, and the index of the line after that.
fn shown_after(lines: &[&str], at: usize) -> (Vec<String>, usize) {
    let start = (at + 1..lines.len())
        .find(|&k| !lines[k].trim().is_empty())
        .unwrap_or(lines.len());
    if lines
        .get(start)
        .is_some_and(|l| l.trim_start().starts_with("```"))
    {
        let (body, close) = fenced(lines, start);
        return (body, close + 1);
    }
    let end = (start..lines.len())
        .find(|&k| !lines[k].starts_with('|'))
        .unwrap_or(lines.len());
    let table = lines[start..end].iter().map(|l| l.to_string()).collect();
    (table, end)
}

/// The code spans of `text` and the text before each.
fn spans(text: &str) -> Vec<(&str, &str)> {
    let parts: Vec<&str> = text.split('`').collect();
    (1..parts.len())
        .step_by(2)
        .map(|k| (parts[k - 1], parts[k]))
        .collect()
}

/// The examples of a table whose last column is `example` (the README's commands), a
/// block each row: its `cargo run --release --` spans are run, a span after `after` is
/// run first as a `rollfuse` command (the files it needs), and a span after a colon in
/// the row's closing parenthesis is what the example prints.
fn table_examples(path: &Path) -> Vec<Block> {
    let (name, text) = named_text(path);
    let mut out = Vec::new();
    let mut in_table = false;
    for (i, line) in text.lines().enumerate() {
        if !line.starts_with('|') {
            in_table = false;
            continue;
        }
        if line.trim_end().ends_with("| example |") {
            in_table = true;
            continue;
        }
        let Some(cell) = line.trim_end().trim_end_matches('|').rsplit(" | ").next() else {
            continue;
        };
        if !in_table || cell.starts_with("---") {
            continue;
        }
        let mut block = Block {
            at: format!("{name}:{}", i + 1),
            commands: Vec::new(),
            not_run: cell
                .split(NOT_RUN)
                .nth(1)
                .map(|r| r.split("-->").next().unwrap_or_default().trim().to_string()),
            output: None,
        };
        for (before, span) in spans(cell) {
            if span.starts_with("cargo run --release -- ") || span.starts_with("bash ") {
                block.commands.push(span.to_string());
            } else if before.trim_end().ends_with("after") {
                block.commands.push(format!("rollfuse {span}"));
            } else if before.trim_end().ends_with(':') && !span.starts_with('-') {
                block.output = Some(vec![format!("[..]{span}[..]")]);
            }
        }
        if !block.commands.is_empty() {
            out.push(block);
        }
    }
    out
}

/// Whether a table's text states a figure: a decimal, or a number with a unit of time,
/// size or rate.
fn holds_figures(text: &str) -> bool {
    let decimal = text
        .as_bytes()
        .windows(3)
        .any(|w| w[0].is_ascii_digit() && w[1] == b'.' && w[2].is_ascii_digit());
    let words: Vec<&str> = text
        .split(|c: char| c.is_whitespace() || c == '|' || c == '(' || c == ')' || c == ',')
        .filter(|w| !w.is_empty())
        .collect();
    let with_unit = words
        .windows(2)
        .any(|w| w[0].ends_with(|c: char| c.is_ascii_digit()) && UNITS.contains(&w[1]));
    let percent = words
        .iter()
        .any(|w| w.ends_with('%') && w[..w.len() - 1].ends_with(|c: char| c.is_ascii_digit()));
    decimal || with_unit || percent
}

/// Every Markdown table of `path` whose rows state figures, except a table of examples
/// (run by [`table_examples`]): where it starts (`file:line`) and the marker line before
/// it, if any (blank lines between allowed).
fn tables_of_figures(path: &Path) -> Vec<(String, Option<String>)> {
    let (name, text) = named_text(path);
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        if !lines[i].starts_with('|') {
            i += 1;
            continue;
        }
        let end = (i..lines.len())
            .find(|&k| !lines[k].starts_with('|'))
            .unwrap_or(lines.len());
        let rows = lines[(i + 2).min(end)..end].join("\n");
        let examples = lines[i].trim_end().ends_with("| example |");
        if !examples && holds_figures(&rows) {
            let marker = lines[..i]
                .iter()
                .rev()
                .find(|l| !l.trim().is_empty())
                .filter(|l| l.trim_start().starts_with("<!--"))
                .map(|l| l.trim().to_string());
            out.push((format!("{name}:{}", i + 1), marker));
        }
        i = end;
    }
    out
}

/// Whether `line` matches `pattern`, in which `[..]` matches any run of characters.
fn matches(pattern: &str, line: &str) -> bool {
    let pieces: Vec<&str> = pattern.split("[..]").collect();
    let (first, last) = (pieces[0], pieces[pieces.len() - 1]);
    if pieces.len() == 1 {
        return pattern == line;
    }
    if !line.starts_with(first) || !line[first.len()..].ends_with(last) {
        return false;
    }
    let mut rest = &line[first.len()..line.len() - last.len()];
    for piece in &pieces[1..pieces.len() - 1] {
        match rest.find(piece) {
            Some(k) => rest = &rest[k + piece.len()..],
            None => return false,
        }
    }
    true
}

/// A scratch folder for one doc's examples: the repository's scenes and model seen
/// where the examples name them, everything they write kept apart.
fn scratch() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for shared in ["host", "models"] {
        std::os::unix::fs::symlink(repo().join(shared), dir.path().join(shared)).unwrap();
    }
    dir
}

/// Runs one command line as a shell would, `rollfuse` being the tool under test.
fn run(line: &str, dir: &Path, at: &str) -> String {
    let line = line.replace("cargo run --release -- ", "rollfuse ");
    let bin = Path::new(env!("CARGO_BIN_EXE_rollfuse")).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let out = Command::new("bash")
        .args(["-c", &line])
        .current_dir(dir)
        .env("PATH", path)
        .output()
        .expect("run bash");
    let printed = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success(),
        "{at}: `{line}` failed ({}):\n{printed}",
        out.status
    );
    printed
}

/// Checks that the `expected` lines appear in `printed` in order.
fn check_output(expected: &[String], printed: &str, at: &str) {
    let mut lines = printed.lines();
    for want in expected.iter().filter(|l| !l.trim().is_empty()) {
        assert!(
            lines.any(|got| matches(want, got)),
            "{at}: the doc shows `{want}`, which the commands did not print (in this \
             order):\n{printed}"
        );
    }
}

#[test]
fn every_documented_example_runs_as_written() {
    let (mut ran, mut not_run) = (0, 0);
    for doc in pages() {
        let mut blocks = blocks(&doc);
        blocks.extend(table_examples(&doc));
        if blocks.iter().all(|b| b.not_run.is_some()) {
            not_run += blocks.len();
            continue;
        }
        let dir = scratch();
        for block in &blocks {
            if let Some(why) = &block.not_run {
                assert!(
                    !why.is_empty(),
                    "{}: say why the block is not run",
                    block.at
                );
                not_run += 1;
                continue;
            }
            let printed: String = block
                .commands
                .iter()
                .map(|c| run(c, dir.path(), &block.at))
                .collect();
            if let Some(expected) = &block.output {
                check_output(expected, &printed, &block.at);
            }
            ran += 1;
        }
    }
    eprintln!("{ran} example blocks run, {not_run} marked not run");
    assert!(ran >= 2, "only {ran} example blocks found to run");
}

/// Every table of figures in the README and docs says where its figures come from: a
/// command whose output the running test compares (`<!-- output of: COMMAND -->`), the
/// command that measures them where it cannot run here (`<!-- measured by: COMMAND -->`;
/// a script it names must exist, a `rollfuse` command's options are checked by
/// host/tests/suite/cli.rs), or why the table is not a measurement (`<!-- not measured:
/// REASON -->`: options, limits, a scene file's fields).
#[test]
fn every_table_of_figures_says_where_they_come_from() {
    let (mut tables, mut unsaid) = (0, Vec::new());
    for doc in pages() {
        for (at, marker) in tables_of_figures(&doc) {
            tables += 1;
            let marker = marker.unwrap_or_default();
            let said = [OUTPUT_OF, MEASURED_BY, NOT_MEASURED]
                .iter()
                .find_map(|m| marker.strip_prefix(m))
                .map(|r| r.trim_end_matches("-->").trim())
                .filter(|s| !s.is_empty());
            match said {
                Some(command) if marker.starts_with(MEASURED_BY) => {
                    check_scripts_exist(command, &at)
                }
                Some(_) => {}
                None => unsaid.push(at),
            }
        }
    }
    assert!(
        unsaid.is_empty(),
        "tables of figures need `{OUTPUT_OF} COMMAND -->`, `{MEASURED_BY} COMMAND -->` or \
         `{NOT_MEASURED} REASON -->` before them: {}",
        unsaid.join(", ")
    );
    assert!(tables >= 10, "only {tables} tables of figures found");
}

/// Every script `command` runs (`bash FILE`, `python3 FILE`) is in the repository.
fn check_scripts_exist(command: &str, at: &str) {
    let words: Vec<&str> = command.split_whitespace().collect();
    for pair in words.windows(2) {
        if matches!(pair[0], "bash" | "python3") {
            assert!(
                repo().join(pair[1]).is_file(),
                "{at}: the table is measured by `{command}`, but {} does not exist",
                pair[1]
            );
        }
    }
}

#[test]
fn the_harness_matches_wildcards_and_reads_markers() {
    assert!(matches(
        "49 tiles in [..] s ([..] tiles/s",
        "49 tiles in 0.01 s (6422 tiles/s"
    ));
    assert!(matches("a[..]", "a"));
    assert!(!matches("49 tiles in [..] s", "50 tiles in 0.01 s"));
    assert!(!matches("exact", "exact and more"));
    assert!(holds_figures("| a | 0.71 |"));
    assert!(holds_figures("| a | 12 % |") && holds_figures("| a | 8.0 s |"));
    assert!(holds_figures("| a | 3 ms |") && holds_figures("| a | 40%, 2 |"));
    assert!(!holds_figures("| `--levels` | 2 | wavelet levels |"));
    let dir = tempfile::tempdir().unwrap();
    let doc = dir.path().join("x.md");
    std::fs::write(
        &doc,
        "<!-- not run: a synopsis -->\n```sh\nrollfuse fuse FRAMES... \\\n  --out OUT # c\n```\n\n\
         ```sh\n# a comment\nrollfuse eval --out out/eval\n```\nprints\n\n<!-- output -->\n```\nTable II[..]\n```\n\
         <!-- output of: rollfuse eval --out out/eval -->\n| a | b |\n|---|---|\nprose\n\n\
         | a | b |\n|---|---|\n| x | 1.5 |\n\n<!-- measured by: bash x.sh -->\n\n\
         | a | b |\n|---|---|\n| x | 2 s |\n",
    )
    .unwrap();
    let figures = tables_of_figures(&doc);
    assert_eq!(figures.len(), 2, "{figures:?}");
    assert_eq!(figures[0].1, None);
    assert_eq!(
        figures[1].1.as_deref(),
        Some("<!-- measured by: bash x.sh -->")
    );
    let b = blocks(&doc);
    assert_eq!(b.len(), 3);
    assert_eq!(b[2].commands, ["rollfuse eval --out out/eval"]);
    assert_eq!(
        b[2].output.as_deref(),
        Some(&["| a | b |".to_string(), "|---|---|".to_string()][..])
    );
    assert_eq!(b[0].not_run.as_deref(), Some("a synopsis"));
    assert_eq!(b[0].commands, ["rollfuse fuse FRAMES...    --out OUT"]);
    assert_eq!(b[1].commands, ["rollfuse eval --out out/eval"]);
    assert_eq!(
        b[1].output.as_deref(),
        Some(&["Table II[..]".to_string()][..])
    );
}
