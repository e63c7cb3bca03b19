//! Inspection records: every roll, its strip segments, the defects found on it and the
//! faults counted, kept in a database a plant can query — an embedded SQLite file by
//! default, a PostgreSQL server for a site with many lines — and the roll map drawn from
//! them.
//!
//! Guarantees:
//! - **Whole or nothing.** A segment and its defects are committed in one transaction,
//!   after the segment's file is whole on disk, so the records never list a segment that
//!   is not there (its size and CRC-32 are kept to tell a file changed since). A writer
//!   that moves files into place as it goes announces each segment first
//!   ([`Records::announce_segment`]); an announced segment is listed once it is confirmed,
//!   or, if its writer was cut off between the two, once its file is found whole when the
//!   roll ends or is marked interrupted — so a roll lists exactly its segments whole on
//!   disk.
//! - **Interrupted rolls are found.** A roll is `running` while its process lives; the
//!   next [`Records::open`] on the same host marks one whose process has ended as
//!   `interrupted`, its segments as they were recorded.
//! - **Nothing twice.** A roll is keyed by its source (the device session, the recording,
//!   the frame folder): recording the same source again replaces its earlier record, and
//!   recording a segment's defects again replaces that segment's.
//! - **One schema, by version.** Both databases take the same statements; a database
//!   from a newer build is refused ([`Error::NewerSchema`]) before anything is written.
//!
//! ```
//! use rollfuse_records::{Records, RollStart, SegmentRecord, Status};
//! let dir = tempfile::tempdir().unwrap();
//! let mut records = Records::open(dir.path().join("records.db").to_str().unwrap()).unwrap();
//! let roll = records
//!     .begin_roll(&RollStart {
//!         source: "frames /data/roll-7".into(),
//!         line: "3".into(),
//!         device: "host".into(),
//!         configuration: "{}".into(),
//!         out: "/data/roll-7/strip.png".into(),
//!         mm_per_row: Some(0.05),
//!     })
//!     .unwrap();
//! let segment = SegmentRecord { seq: 0, file: "strip.png".into(), first_row: 0, rows: 2000,
//!                               width: 320, bytes: 1, crc32: 0 };
//! records.add_segment(roll, &segment, &[]).unwrap();
//! records.finish_roll(roll, &Status::Complete).unwrap();
//! assert_eq!(records.roll(roll).unwrap().summary.belt_mm, Some(100.0));
//! ```

mod backend;
mod error;
pub mod map;
mod model;
mod process;
mod schema;

pub use backend::{is_postgres, redacted};
pub use error::{Error, Result};
pub use model::{DefectRecord, Filter, Roll, RollStart, RollSummary, SegmentRecord, Status};
pub use schema::VERSION as SCHEMA_VERSION;

use backend::{Backend, Value};

/// An open connection to the records.
pub struct Records {
    db: Backend,
}

/// The columns of a roll's line in `rolls list`, in [`summary_of`]'s order.
const SUMMARY: &str = "r.id, r.line, r.device, r.source, r.status, r.reason, r.started_at, \
    r.ended_at, r.belt_rows, r.mm_per_row, r.out, \
    (SELECT COUNT(*) FROM segments s WHERE s.roll_id = r.id AND s.pending = 0), \
    (SELECT COUNT(*) FROM defects d WHERE d.roll_id = r.id), r.process";

/// Why a roll whose process ended while it ran is interrupted.
const PROCESS_ENDED: &str = "its process ended before the roll was finished";

impl Records {
    /// Opens the records at `target` — a `postgres://` URL or a SQLite file's path (made
    /// if missing) — brings its schema up to date (a database already up to date is only
    /// read) and marks the rolls of this host whose process has ended as interrupted,
    /// where it may write.
    pub fn open(target: &str) -> Result<Records> {
        // A SQLite writer that finds the file busy without waiting (a snapshot another
        // process moved on from, as a batch's workers opening one new file at once can
        // make) starts again, for as long as a writer waits.
        let started = std::time::Instant::now();
        loop {
            match Self::open_once(target) {
                Err(Error::Busy(_)) if started.elapsed() < backend::WAIT => {
                    std::thread::sleep(std::time::Duration::from_millis(50));
                }
                other => return other,
            }
        }
    }

    fn open_once(target: &str) -> Result<Records> {
        let mut db = Backend::open(target)?;
        schema::migrate(&mut db).map_err(|e| match e {
            Error::Database(why) => Error::Open {
                target: redacted(target),
                why,
            },
            other => other,
        })?;
        let mut records = Records { db };
        // Where this user may not write (a reader's account, a full disk) the rolls stay
        // as they are: reading them must not depend on it.
        match records.mark_interrupted() {
            Err(Error::Busy(why)) => Err(Error::Busy(why)),
            _ => Ok(records),
        }
    }

    /// Marks the running rolls whose process has ended as interrupted, and settles the
    /// announced segments of this host's ended rolls; returns the ids marked.
    pub fn mark_interrupted(&mut self) -> Result<Vec<i64>> {
        let running = self.db.query(
            "SELECT id, process FROM rolls WHERE status = 'running'",
            &[],
        )?;
        let ended: Vec<i64> = running
            .iter()
            .filter(|row| process::has_ended(&row[1].text()))
            .map(|row| row[0].int())
            .collect();
        for &id in &ended {
            self.set_status(id, &Status::Interrupted(PROCESS_ENDED.into()))?;
        }
        // Settled here, not as the status is set: a roll whose settling could not be
        // written then (a full disk) is settled at a later open. Only this host can look
        // at its files.
        let unsettled = self.db.query(
            "SELECT DISTINCT r.id, r.process FROM rolls r JOIN segments s \
             ON s.roll_id = r.id WHERE s.pending = 1 AND r.status <> 'running'",
            &[],
        )?;
        for row in unsettled
            .iter()
            .filter(|r| process::is_this_host(&r[1].text()))
        {
            self.settle_announced(row[0].int())?;
        }
        Ok(ended)
    }

    /// Starts the record of a roll, `running`, owned by this process. An earlier record of
    /// the same source is replaced (its segments, defects and faults removed) and its id
    /// kept.
    pub fn begin_roll(&mut self, start: &RollStart) -> Result<i64> {
        if let Some(k) = start.mm_per_row.filter(|k| !(k.is_finite() && *k > 0.0)) {
            return Err(Error::Invalid(format!(
                "a roll's scale must be positive millimetres a row, got {k}"
            )));
        }
        let now = now();
        let fields: [Value; 9] = [
            start.source.as_str().into(),
            start.line.as_str().into(),
            start.device.as_str().into(),
            start.configuration.as_str().into(),
            start.out.as_str().into(),
            start.mm_per_row.into(),
            now.as_str().into(),
            "running".into(),
            process::this_process().as_str().into(),
        ];
        self.db.transaction(|db| {
            let earlier = db.query(
                "SELECT id FROM rolls WHERE source = $1",
                &[start.source.as_str().into()],
            )?;
            let Some(id) = earlier.first().map(|row| row[0].int()) else {
                let made = db.query(
                    "INSERT INTO rolls (source, line, device, configuration, out, mm_per_row, \
                     started_at, status, process) \
                     VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9) RETURNING id",
                    &fields,
                )?;
                return Ok(made[0][0].int());
            };
            for table in ["segments", "defects", "faults"] {
                db.exec(
                    &format!("DELETE FROM {table} WHERE roll_id = $1"),
                    &[id.into()],
                )?;
            }
            let mut with_id = fields.to_vec();
            with_id.push(id.into());
            db.exec(
                "UPDATE rolls SET source = $1, line = $2, device = $3, configuration = $4, \
                 out = $5, mm_per_row = $6, started_at = $7, status = $8, process = $9, \
                 ended_at = NULL, reason = NULL, belt_rows = 0 WHERE id = $10",
                &with_id,
            )?;
            Ok(id)
        })
    }

    /// Records segment `segment` of roll `roll` and the defects found on it (each recorded
    /// as the segment's, whatever its `segment_seq`), in one transaction; a segment
    /// recorded or announced before under the same number is replaced, its defects with
    /// it. Call it once the segment's file is whole on disk.
    pub fn add_segment(
        &mut self,
        roll: i64,
        segment: &SegmentRecord,
        defects: &[DefectRecord],
    ) -> Result<()> {
        self.db
            .transaction(|db| put_segment(db, roll, segment, defects, false))
    }

    /// Announces segment `segment` of roll `roll` before its file is moved into place
    /// under its name: it is not listed until [`Records::add_segment`] confirms it, or
    /// until the roll ends or is marked interrupted with the file found whole (its size
    /// and CRC-32 as announced) — a writer killed between the move and the confirmation
    /// loses no segment that is whole on disk, and one killed before it lists none that
    /// is not.
    pub fn announce_segment(&mut self, roll: i64, segment: &SegmentRecord) -> Result<()> {
        self.db
            .transaction(|db| put_segment(db, roll, segment, &[], true))
    }

    /// Settles roll `roll`'s announced segments: each whose file is whole beside the
    /// roll's strip is listed, the others are forgotten. Only the host that wrote the
    /// roll may call it (another host does not see its files).
    fn settle_announced(&mut self, roll: i64) -> Result<()> {
        let announced = self.db.query(
            "SELECT s.seq, s.file, s.first_row, s.rows, s.width, s.bytes, s.crc32, r.out \
             FROM segments s JOIN rolls r ON r.id = s.roll_id \
             WHERE s.roll_id = $1 AND s.pending = 1",
            &[roll.into()],
        )?;
        for row in &announced {
            let segment = segment_of(row);
            let out = std::path::PathBuf::from(row[7].text());
            let folder = out.parent().unwrap_or(std::path::Path::new(""));
            let whole = segment.matches_file(&folder.join(&segment.file));
            self.db.transaction(|db| {
                if whole {
                    put_segment(db, roll, &segment, &[], false)
                } else {
                    db.exec(
                        "DELETE FROM segments WHERE roll_id = $1 AND seq = $2",
                        &[roll.into(), segment.seq.into()],
                    )?;
                    Ok(())
                }
            })?;
        }
        Ok(())
    }

    /// Replaces the defects recorded on segment `seq` of roll `roll` with `defects`, in one
    /// transaction (a detector run again on a recorded strip).
    pub fn replace_defects(&mut self, roll: i64, seq: i64, defects: &[DefectRecord]) -> Result<()> {
        self.db.transaction(|db| {
            require_roll(db, roll)?;
            db.exec(
                "DELETE FROM defects WHERE roll_id = $1 AND segment_seq = $2",
                &[roll.into(), seq.into()],
            )?;
            for d in defects {
                insert_defect(
                    db,
                    roll,
                    &DefectRecord {
                        segment_seq: Some(seq),
                        ..d.clone()
                    },
                )?;
            }
            Ok(())
        })
    }

    /// Sets the faults counted on roll `roll`, by kind (zero counts are left out).
    pub fn set_faults(&mut self, roll: i64, faults: &[(&str, u64)]) -> Result<()> {
        self.db.transaction(|db| {
            require_roll(db, roll)?;
            db.exec("DELETE FROM faults WHERE roll_id = $1", &[roll.into()])?;
            for &(kind, count) in faults.iter().filter(|f| f.1 > 0) {
                db.exec(
                    "INSERT INTO faults (roll_id, kind, count) VALUES ($1, $2, $3)",
                    &[
                        roll.into(),
                        kind.into(),
                        (count.min(i64::MAX as u64) as i64).into(),
                    ],
                )?;
            }
            Ok(())
        })
    }

    /// Sets roll `roll`'s scale, millimetres of belt a strip row (known only once its
    /// configuration is).
    pub fn set_scale(&mut self, roll: i64, mm_per_row: f64) -> Result<()> {
        if !(mm_per_row.is_finite() && mm_per_row > 0.0) {
            return Err(Error::Invalid(format!(
                "a roll's scale must be positive millimetres a row, got {mm_per_row}"
            )));
        }
        let changed = self.db.exec(
            "UPDATE rolls SET mm_per_row = $1 WHERE id = $2",
            &[mm_per_row.into(), roll.into()],
        )?;
        if changed == 0 {
            return Err(Error::NoSuchRoll(roll));
        }
        Ok(())
    }

    /// Ends roll `roll` with `status` (complete, or failed with the reason), its announced
    /// segments settled.
    pub fn finish_roll(&mut self, roll: i64, status: &Status) -> Result<()> {
        self.set_status(roll, status)?;
        self.settle_announced(roll)
    }

    fn set_status(&mut self, roll: i64, status: &Status) -> Result<()> {
        let ended = (*status != Status::Running).then(now);
        let changed = self.db.exec(
            "UPDATE rolls SET status = $1, reason = $2, ended_at = $3 WHERE id = $4",
            &[
                status.word().into(),
                status.reason().into(),
                ended.as_deref().into(),
                roll.into(),
            ],
        )?;
        if changed == 0 {
            return Err(Error::NoSuchRoll(roll));
        }
        Ok(())
    }

    /// The rolls `filter` selects, the newest first.
    pub fn list(&mut self, filter: &Filter) -> Result<Vec<RollSummary>> {
        let mut sql = format!("SELECT {SUMMARY} FROM rolls r WHERE 1 = 1");
        let mut params: Vec<Value> = Vec::new();
        let mut add = |clause: &str, value: &Option<String>, sql: &mut String| {
            if let Some(v) = value {
                params.push(v.as_str().into());
                sql.push_str(&clause.replace("$?", &format!("${}", params.len())));
            }
        };
        add(" AND r.line = $?", &filter.line, &mut sql);
        add(" AND r.started_at >= $?", &filter.since, &mut sql);
        add(
            " AND EXISTS (SELECT 1 FROM defects d WHERE d.roll_id = r.id AND d.kind = $?)",
            &filter.kind,
            &mut sql,
        );
        sql.push_str(" ORDER BY r.started_at DESC, r.id DESC");
        Ok(self
            .db
            .query(&sql, &params)?
            .iter()
            .map(|r| summary_of(r))
            .collect())
    }

    /// Roll `id`'s whole record.
    pub fn roll(&mut self, id: i64) -> Result<Roll> {
        let rows = self.db.query(
            &format!("SELECT {SUMMARY}, r.configuration FROM rolls r WHERE r.id = $1"),
            &[id.into()],
        )?;
        let row = rows.first().ok_or(Error::NoSuchRoll(id))?;
        let segment_list = self
            .db
            .query(
                "SELECT seq, file, first_row, rows, width, bytes, crc32 FROM segments \
                 WHERE roll_id = $1 AND pending = 0 ORDER BY seq",
                &[id.into()],
            )?
            .iter()
            .map(|r| segment_of(r))
            .collect();
        let defect_list = self
            .db
            .query(
                "SELECT segment_seq, kind, score, belt_row, across_px, x, y, w, h, crop \
                 FROM defects WHERE roll_id = $1 ORDER BY belt_row, id",
                &[id.into()],
            )?
            .iter()
            .map(|r| defect_of(r))
            .collect();
        let faults = self
            .db
            .query(
                "SELECT kind, count FROM faults WHERE roll_id = $1 ORDER BY kind",
                &[id.into()],
            )?
            .iter()
            .map(|r| (r[0].text(), r[1].int()))
            .collect();
        Ok(Roll {
            summary: summary_of(row),
            configuration: row[14].text(),
            segment_list,
            defect_list,
            faults,
        })
    }

    /// The roll recorded from `source`, if any.
    pub fn roll_of_source(&mut self, source: &str) -> Result<Option<RollSummary>> {
        let rows = self.db.query(
            &format!("SELECT {SUMMARY} FROM rolls r WHERE r.source = $1"),
            &[source.into()],
        )?;
        Ok(rows.first().map(|r| summary_of(r)))
    }

    /// The roll whose strip has a segment at `path` (matched by the strip's folder and the
    /// segment's file name), with the segment's number and first belt row.
    pub fn segment_at(&mut self, path: &std::path::Path) -> Result<Option<(i64, SegmentRecord)>> {
        let (Some(folder), Some(name)) = (path.parent(), path.file_name()) else {
            return Ok(None);
        };
        let name = name.to_string_lossy();
        let candidates = self.db.query(
            "SELECT s.seq, s.file, s.first_row, s.rows, s.width, s.bytes, s.crc32, r.id, r.out \
             FROM segments s JOIN rolls r ON r.id = s.roll_id \
             WHERE s.file = $1 AND s.pending = 0",
            &[name.as_ref().into()],
        )?;
        Ok(candidates.iter().find_map(|r| {
            let out = std::path::PathBuf::from(r[8].text());
            let same = out.parent().is_some_and(|p| same_folder(p, folder));
            same.then(|| (r[7].int(), segment_of(r)))
        }))
    }
}

fn same_folder(a: &std::path::Path, b: &std::path::Path) -> bool {
    let canon = |p: &std::path::Path| {
        let p = if p.as_os_str().is_empty() {
            std::path::Path::new(".")
        } else {
            p
        };
        std::fs::canonicalize(p).ok()
    };
    match (canon(a), canon(b)) {
        (Some(x), Some(y)) => x == y,
        _ => a == b,
    }
}

fn require_roll(db: &mut Backend, roll: i64) -> Result<()> {
    if db
        .query("SELECT 1 FROM rolls WHERE id = $1", &[roll.into()])?
        .is_empty()
    {
        return Err(Error::NoSuchRoll(roll));
    }
    Ok(())
}

/// Writes `segment` of roll `roll` (replacing one of its number, and that one's defects)
/// with `defects` on it, announced only (`pending`) or listed, and the roll's belt rows.
fn put_segment(
    db: &mut Backend,
    roll: i64,
    segment: &SegmentRecord,
    defects: &[DefectRecord],
    pending: bool,
) -> Result<()> {
    require_roll(db, roll)?;
    let seq = Value::from(segment.seq);
    db.exec(
        "DELETE FROM defects WHERE roll_id = $1 AND segment_seq = $2",
        &[roll.into(), seq.clone()],
    )?;
    db.exec(
        "DELETE FROM segments WHERE roll_id = $1 AND seq = $2",
        &[roll.into(), seq.clone()],
    )?;
    db.exec(
        "INSERT INTO segments (roll_id, seq, file, first_row, rows, width, bytes, crc32, \
         pending) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9)",
        &[
            roll.into(),
            seq,
            segment.file.as_str().into(),
            segment.first_row.into(),
            segment.rows.into(),
            segment.width.into(),
            segment.bytes.into(),
            i64::from(segment.crc32).into(),
            i64::from(pending).into(),
        ],
    )?;
    for d in defects {
        let on_segment = DefectRecord {
            segment_seq: Some(segment.seq),
            ..d.clone()
        };
        insert_defect(db, roll, &on_segment)?;
    }
    db.exec(
        "UPDATE rolls SET belt_rows = (SELECT COALESCE(SUM(rows), 0) FROM segments \
         WHERE roll_id = $1 AND pending = 0) WHERE id = $1",
        &[roll.into()],
    )?;
    Ok(())
}

/// A segment from the first seven columns of `r`: seq, file, first_row, rows, width,
/// bytes, crc32.
fn segment_of(r: &[Value]) -> SegmentRecord {
    SegmentRecord {
        seq: r[0].int(),
        file: r[1].text(),
        first_row: r[2].int(),
        rows: r[3].int(),
        width: r[4].int(),
        bytes: r[5].int(),
        crc32: r[6].int() as u32,
    }
}

fn insert_defect(db: &mut Backend, roll: i64, d: &DefectRecord) -> Result<()> {
    if !(d.score.is_finite() && d.belt_row.is_finite() && d.across_px.is_finite()) {
        return Err(Error::Invalid(format!(
            "a defect's score and position must be finite numbers, got {:?}",
            (d.score, d.belt_row, d.across_px)
        )));
    }
    let [x, y, w, h] = d.bbox;
    db.exec(
        "INSERT INTO defects (roll_id, segment_seq, kind, score, belt_row, across_px, \
         x, y, w, h, crop) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11)",
        &[
            roll.into(),
            Value::Int(d.segment_seq),
            d.kind.as_str().into(),
            d.score.into(),
            d.belt_row.into(),
            d.across_px.into(),
            x.into(),
            y.into(),
            w.into(),
            h.into(),
            Value::Blob(d.crop.clone()),
        ],
    )?;
    Ok(())
}

/// A roll's summary from [`SUMMARY`]'s columns. A roll still marked running whose process
/// has ended is reported interrupted, though the mark could not be written (a full disk, a
/// reader's account).
fn summary_of(r: &[Value]) -> RollSummary {
    let belt_rows = r[8].int();
    let mm_per_row = r[9].real();
    let (mut status, mut reason) = (r[4].text(), r[5].opt_text());
    if status == Status::Running.word() && process::has_ended(&r[13].text()) {
        let why = Status::Interrupted(PROCESS_ENDED.into());
        (status, reason) = (why.word().to_owned(), why.reason().map(str::to_owned));
    }
    RollSummary {
        id: r[0].int(),
        line: r[1].text(),
        device: r[2].text(),
        source: r[3].text(),
        status,
        reason,
        started_at: r[6].text(),
        ended_at: r[7].opt_text(),
        belt_rows,
        mm_per_row,
        belt_mm: mm_per_row.map(|k| belt_rows as f64 * k),
        out: r[10].text(),
        segments: r[11].int(),
        defects: r[12].int(),
    }
}

fn defect_of(r: &[Value]) -> DefectRecord {
    DefectRecord {
        segment_seq: match r[0] {
            Value::Int(v) => v,
            _ => None,
        },
        kind: r[1].text(),
        score: r[2].real().unwrap_or(0.0),
        belt_row: r[3].real().unwrap_or(0.0),
        across_px: r[4].real().unwrap_or(0.0),
        bbox: [r[5].int(), r[6].int(), r[7].int(), r[8].int()],
        crop: r[9].blob(),
    }
}

/// Now, RFC 3339 in UTC to the second (text sorts as time).
fn now() -> String {
    humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string()
}
