//! The inspection records on the live page (`stream --serve --records DB`): the current
//! roll's map and the last rolls of its line. A thread of its own reads them every
//! [`REFRESH`]; requests are answered from what it read last, so no request waits on the
//! database and a database that is slow or gone only makes the view old (its error is
//! shown with it).

use super::roll_view::read;
pub use super::roll_view::{LAST_ROLLS, RecordsShown, RollView};
use super::state::{Shared, lock};
use rollfuse_records::Records;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

/// How often the records are read again.
pub const REFRESH: Duration = Duration::from_secs(2);

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
