//! The records' schema, one list of migrations applied in order; the version reached is
//! kept in `schema_version`. A database from a newer build is refused before anything is
//! read or written.

use crate::backend::{Backend, Types};
use crate::error::{Error, Result};

/// The newest schema this build writes.
pub const VERSION: i64 = 2;

/// Migration `n` (from version `n` to `n + 1`) in this database's column types.
fn migration(n: i64, t: &Types) -> Option<String> {
    let Types {
        id,
        int,
        real,
        blob,
    } = t;
    match n {
        0 => Some(format!(
            "CREATE TABLE rolls (
                id {id},
                source TEXT NOT NULL UNIQUE,
                line TEXT NOT NULL,
                device TEXT NOT NULL,
                configuration TEXT NOT NULL,
                out TEXT NOT NULL,
                mm_per_row {real},
                started_at TEXT NOT NULL,
                ended_at TEXT,
                belt_rows {int} NOT NULL DEFAULT 0,
                status TEXT NOT NULL,
                reason TEXT,
                process TEXT NOT NULL
            );
            CREATE INDEX rolls_by_line ON rolls (line, started_at);
            CREATE TABLE segments (
                roll_id {int} NOT NULL REFERENCES rolls (id) ON DELETE CASCADE,
                seq {int} NOT NULL,
                file TEXT NOT NULL,
                first_row {int} NOT NULL,
                rows {int} NOT NULL,
                width {int} NOT NULL,
                bytes {int} NOT NULL,
                crc32 {int} NOT NULL,
                PRIMARY KEY (roll_id, seq)
            );
            CREATE TABLE defects (
                id {id},
                roll_id {int} NOT NULL REFERENCES rolls (id) ON DELETE CASCADE,
                segment_seq {int},
                kind TEXT NOT NULL,
                score {real} NOT NULL,
                belt_row {real} NOT NULL,
                across_px {real} NOT NULL,
                x {int} NOT NULL,
                y {int} NOT NULL,
                w {int} NOT NULL,
                h {int} NOT NULL,
                crop {blob}
            );
            CREATE INDEX defects_by_roll ON defects (roll_id, kind);
            CREATE TABLE faults (
                roll_id {int} NOT NULL REFERENCES rolls (id) ON DELETE CASCADE,
                kind TEXT NOT NULL,
                count {int} NOT NULL,
                PRIMARY KEY (roll_id, kind)
            );"
        )),
        // A segment announced before its file is moved into place (`pending` 1) is listed
        // only once it is confirmed, or found whole when an interrupted roll is settled;
        // every open looks for unsettled ones, through a partial index of just those.
        1 => Some(format!(
            "ALTER TABLE segments ADD COLUMN pending {int} NOT NULL DEFAULT 0;
            CREATE INDEX segments_announced ON segments (roll_id) WHERE pending = 1;"
        )),
        _ => None,
    }
}

/// The schema version of a database that has one.
fn version_of(db: &mut Backend) -> Option<i64> {
    let rows = db.query("SELECT version FROM schema_version", &[]).ok()?;
    rows.first().map(|row| row[0].int())
}

/// Brings the schema to [`VERSION`], or refuses a newer one. A database already at
/// [`VERSION`] is only read, so a user who may only read the records can open them.
pub fn migrate(db: &mut Backend) -> Result<()> {
    match version_of(db) {
        Some(VERSION) => return Ok(()),
        Some(found) if found > VERSION => {
            return Err(Error::NewerSchema {
                found,
                supported: VERSION,
            });
        }
        _ => {}
    }
    let types = db.types();
    let version_table = format!(
        "CREATE TABLE IF NOT EXISTS schema_version (version {} NOT NULL)",
        types.int
    );
    if let Backend::Postgres(_) = db {
        db.batch(&version_table)?;
    }
    db.transaction(|db| {
        // Two processes opening a new database at once must not both migrate it: SQLite's
        // IMMEDIATE transaction holds the file from its start (the version table made
        // inside it), PostgreSQL locks the version table.
        match db {
            Backend::Postgres(_) => db.batch("LOCK TABLE schema_version IN EXCLUSIVE MODE")?,
            Backend::Sqlite(_) => db.batch(&version_table)?,
        }
        let found = db
            .query("SELECT version FROM schema_version", &[])?
            .first()
            .map_or(0, |row| row[0].int());
        if found > VERSION {
            return Err(Error::NewerSchema {
                found,
                supported: VERSION,
            });
        }
        for n in found..VERSION {
            let sql = migration(n, &types)
                .ok_or_else(|| Error::Database(format!("no migration from version {n}")))?;
            db.batch(&sql)?;
        }
        if found == 0 {
            db.exec(
                "INSERT INTO schema_version (version) VALUES ($1)",
                &[VERSION.into()],
            )?;
        } else if found < VERSION {
            db.exec("UPDATE schema_version SET version = $1", &[VERSION.into()])?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A database left at version 1 by an older build keeps its rows, now listed whole.
    #[test]
    fn a_version_1_database_is_brought_up_to_date_with_its_rows() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.db");
        let mut db = Backend::open(path.to_str().unwrap()).unwrap();
        let types = db.types();
        db.batch(&migration(0, &types).unwrap()).unwrap();
        db.batch(
            "CREATE TABLE schema_version (version INTEGER NOT NULL);
             INSERT INTO schema_version (version) VALUES (1);
             INSERT INTO rolls (source, line, device, configuration, out, started_at, status,
                                process)
             VALUES ('old', '1', 'host', '{}', '/s.png', 't', 'complete', 'h:1:1');
             INSERT INTO segments (roll_id, seq, file, first_row, rows, width, bytes, crc32)
             VALUES (1, 0, 's.png', 0, 10, 4, 5, 6);",
        )
        .unwrap();
        migrate(&mut db).unwrap();
        assert_eq!(version_of(&mut db), Some(VERSION));
        let rows = db.query("SELECT seq, pending FROM segments", &[]).unwrap();
        assert_eq!((rows[0][0].int(), rows[0][1].int()), (0, 0));
    }
}
