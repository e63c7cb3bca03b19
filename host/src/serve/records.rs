//! The inspection records on the live page (`stream --serve --records DB`): the current
//! roll's map and the last rolls of its line. A thread of its own reads them every
//! [`REFRESH`]; requests are answered from what it read last, so no request waits on the
//! database and a database that is slow or gone only makes the view old (its error is
//! shown with it).

use super::state::{Shared, lock};
use rollfuse_records::{Filter, Records, RollSummary, map};
use serde::Serialize;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

/// How often the records are read again.
pub const REFRESH: Duration = Duration::from_secs(2);

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

/// Starts the thread that reads the records for the page until `stopping`.
pub(super) fn start(
    view: RollView,
    shared: Arc<Shared>,
    stopping: Arc<AtomicBool>,
) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("serve-records".into())
        .spawn(move || {
            let mut records: Option<Records> = None;
            while !stopping.load(Ordering::Relaxed) {
                let shown = read(&view, &mut records);
                *lock(&shared.records) = Some(shown);
                // Short sleeps: the server's drop waits for this thread.
                for _ in 0..REFRESH.as_millis() / 100 {
                    if stopping.load(Ordering::Relaxed) {
                        return;
                    }
                    std::thread::sleep(Duration::from_millis(100));
                }
            }
        })
}

/// Reads the line's last rolls and the current roll's map; on an error, the error (and
/// the connection is opened again next time).
fn read(view: &RollView, records: &mut Option<Records>) -> RecordsShown {
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
