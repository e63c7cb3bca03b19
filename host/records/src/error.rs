//! The records' one error type: what went wrong, said for the person running the line.

use std::fmt;

/// Why the records could not be opened, read or written.
#[derive(Debug)]
pub enum Error {
    /// The database could not be reached or opened (`target` has any password removed).
    Open {
        /// The file or the URL, password removed.
        target: String,
        /// The database's own words.
        why: String,
    },
    /// The database was made by a newer rollfuse: nothing is read or written.
    NewerSchema {
        /// The schema version found.
        found: i64,
        /// The newest this build knows.
        supported: i64,
    },
    /// A statement failed (a full disk, a lost connection, a constraint).
    Database(String),
    /// Another writer held the database longer than a writer waits.
    Busy(String),
    /// No roll has this id.
    NoSuchRoll(i64),
    /// A value that cannot be recorded (a roll's scale that is not positive, say).
    Invalid(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Open { target, why } => {
                write!(f, "cannot open the records at {target}: {why}")
            }
            Error::NewerSchema { found, supported } => write!(
                f,
                "the records were written by a newer rollfuse (schema version {found}; this \
                 one knows up to {supported}): upgrade rollfuse to use them"
            ),
            Error::Database(why) => write!(f, "records: {why}"),
            Error::Busy(why) => write!(
                f,
                "records: another writer held the database too long ({why})"
            ),
            Error::NoSuchRoll(id) => write!(f, "no roll {id} in the records"),
            Error::Invalid(why) => write!(f, "records: {why}"),
        }
    }
}

impl std::error::Error for Error {}

impl From<rusqlite::Error> for Error {
    fn from(e: rusqlite::Error) -> Self {
        match e.sqlite_error_code() {
            Some(rusqlite::ErrorCode::DatabaseBusy | rusqlite::ErrorCode::DatabaseLocked) => {
                Error::Busy(e.to_string())
            }
            _ => Error::Database(e.to_string()),
        }
    }
}

impl From<postgres::Error> for Error {
    fn from(e: postgres::Error) -> Self {
        // The server's message (a full disk, a constraint) is in its `DbError`; the
        // client's own Display says only "db error".
        match e.as_db_error() {
            Some(db) => Error::Database(format!("{} ({})", db.message(), db.code().code())),
            None => Error::Database(e.to_string()),
        }
    }
}

/// Results of the records.
pub type Result<T> = std::result::Result<T, Error>;
