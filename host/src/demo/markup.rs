//! Text as HTML: escaping, and the Markdown the commands write (pipe tables, paragraphs,
//! bold and code) as the report shows it.

use std::fmt::Write;

/// `&`, `<`, `>` and `"` as entities.
pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Markdown as the commands write it — pipe tables and plain paragraphs, `**bold**` — as
/// HTML. A `\|` inside a cell is a literal bar.
pub fn tables(markdown: &str) -> String {
    let mut out = String::new();
    let mut in_table = false;
    for line in markdown.lines() {
        let line = line.trim();
        if let Some(inner) = line.strip_prefix('|') {
            let cells = split_cells(inner.strip_suffix('|').unwrap_or(inner));
            if cells.iter().all(|c| is_rule(c)) {
                continue;
            }
            let tag = if in_table { "td" } else { "th" };
            if !in_table {
                out.push_str("<table>");
                in_table = true;
            }
            out.push_str("<tr>");
            for c in cells {
                let class = if tag == "td" && looks_numeric(&c) {
                    " class=num"
                } else {
                    ""
                };
                let _ = write!(out, "<{tag}{class}>{}</{tag}>", inline(&c));
            }
            out.push_str("</tr>\n");
            continue;
        }
        if in_table {
            out.push_str("</table>\n");
            in_table = false;
        }
        if !line.is_empty() {
            let _ = writeln!(out, "<p>{}</p>", inline(line));
        }
    }
    if in_table {
        out.push_str("</table>\n");
    }
    out
}

/// The cells of a table row without its outer bars, `\|` kept as `|`.
fn split_cells(row: &str) -> Vec<String> {
    let mut cells = vec![String::new()];
    let mut chars = row.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                chars.next();
                if let Some(cell) = cells.last_mut() {
                    cell.push('|');
                }
            }
            '|' => cells.push(String::new()),
            c => {
                if let Some(cell) = cells.last_mut() {
                    cell.push(c);
                }
            }
        }
    }
    cells.into_iter().map(|c| c.trim().to_string()).collect()
}

/// A header rule cell: `---`, `:---`, `---:`.
fn is_rule(cell: &str) -> bool {
    !cell.is_empty() && cell.chars().all(|c| c == '-' || c == ':')
}

fn looks_numeric(cell: &str) -> bool {
    cell.chars()
        .next()
        .is_some_and(|c| c.is_ascii_digit() || c == '-' || c == '+')
        && cell.chars().any(|c| c.is_ascii_digit())
}

/// Escapes the text and turns `**x**` into bold and `` `x` `` into code.
fn inline(text: &str) -> String {
    let mut out = String::new();
    for (k, part) in escape(text).split("**").enumerate() {
        if k % 2 == 1 {
            let _ = write!(out, "<b>{part}</b>");
        } else {
            for (j, piece) in part.split('`').enumerate() {
                if j % 2 == 1 {
                    let _ = write!(out, "<code>{piece}</code>");
                } else {
                    out.push_str(piece);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_become_html_with_escaped_bars_and_bold() {
        let md = "Intro with **bold** & `code`.\n\n| a | b |\n|---|---:|\n| max-\\|high\\| | 1.5 |\n| <x> | -2 % |\n\nAfter.\n";
        let html = tables(md);
        assert_eq!(
            html,
            "<p>Intro with <b>bold</b> &amp; <code>code</code>.</p>\n<table><tr><th>a</th><th>b</th></tr>\n\
             <tr><td>max-|high|</td><td class=num>1.5</td></tr>\n\
             <tr><td>&lt;x&gt;</td><td class=num>-2 %</td></tr>\n</table>\n<p>After.</p>\n"
        );
    }

    #[test]
    fn an_unclosed_table_is_closed() {
        assert_eq!(
            tables("| a |\n| 1 |"),
            "<table><tr><th>a</th></tr>\n<tr><td class=num>1</td></tr>\n</table>\n"
        );
    }
}
