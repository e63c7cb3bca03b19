//! What the live page shows of the inspection records, and how it is read: the current
//! roll's map and the last rolls of its line ([`super::records`] reads it on a thread).

use rollfuse_records::{Filter, Records, RollSummary, map};
use serde::Serialize;
use std::path::PathBuf;

/// Rolls of the line the page lists.
pub const LAST_ROLLS: usize = 10;

/// The map's width on the page, pixels.
const MAP_WIDTH: u32 = 900;

/// Which records the page shows, and which roll is this session's.
#[derive(Debug, Clone)]
pub struct RollView {
    /// A SQLite file's path or a `postgres://` URL.
    pub records: String,
    /// The session's line: its last rolls are listed.
    pub line: String,
    /// The session's strip (absolute): the roll recorded with it is the current one.
    pub strip: PathBuf,
}

/// What the page shows of the records, as last read.
#[derive(Debug, Default, Clone, Serialize)]
pub struct RecordsShown {
    /// The line.
    pub line: String,
    /// This session's roll, once it is recorded.
    pub current: Option<i64>,
    /// The line's last rolls, the newest first.
    pub rolls: Vec<RollSummary>,
    /// Why the records could not be read last time, if they could not.
    pub error: Option<String>,
    /// Whether `/roll.svg` has the current roll's map.
    pub map_ready: bool,
    /// The current roll's map (an SVG), once it has a scale.
    #[serde(skip)]
    pub map: Option<String>,
}

/// Reads the line's last rolls and the current roll's map; on an error, the error (and
/// the connection is opened again next time).
pub fn read(view: &RollView, records: &mut Option<Records>) -> RecordsShown {
    let mut shown = RecordsShown {
        line: view.line.clone(),
        ..RecordsShown::default()
    };
    let result = (|| -> rollfuse_records::Result<()> {
        let db = match records {
            Some(db) => db,
            None => records.insert(Records::open(&view.records)?),
        };
        let filter = Filter {
            line: Some(view.line.clone()),
            ..Filter::default()
        };
        let mut rolls = db.list(&filter)?;
        let strip = view.strip.display().to_string();
        shown.current = rolls.iter().find(|r| r.out == strip).map(|r| r.id);
        rolls.truncate(LAST_ROLLS);
        shown.rolls = rolls;
        if let Some(id) = shown.current {
            shown.map = map::svg(&db.roll(id)?, MAP_WIDTH).ok();
            shown.map_ready = shown.map.is_some();
        }
        Ok(())
    })();
    if let Err(e) = result {
        *records = None;
        shown.error = Some(e.to_string());
    }
    shown
}
