//! Opening the coordinator's database for reading, from the report, the live page, the
//! TensorBoard export and the benchmarks: the one place that knows the data dir's file name.

use super::backend::{absolute, DatabaseUrl};
use crate::{Error, Result};
use sqlx::any::AnyPoolOptions;
use sqlx::sqlite::SqliteConnectOptions;
use sqlx::{AnyPool, ConnectOptions};
use std::path::Path;

/// Name of the database file in a coordinator's data dir.
pub const DB_FILE: &str = "gaitsweep.sqlite";

/// Opens the coordinator's database for reading: `database` (a PostgreSQL URL or a SQLite
/// file, as `coordinator serve --database`) or else the data dir's SQLite file (read-only;
/// WAL: works while the coordinator runs).
pub async fn open(data_dir: &Path, database: Option<&str>) -> Result<AnyPool> {
    sqlx::any::install_default_drivers();
    let url = match database.map(DatabaseUrl::parse).transpose()? {
        Some(DatabaseUrl::Postgres(u)) => {
            return AnyPoolOptions::new()
                .max_connections(1)
                .connect(&u)
                .await
                .map_err(|e| Error::OpenDb {
                    what: format!("connect to {}", DatabaseUrl::Postgres(u.clone()).redacted()),
                    message: e.to_string(),
                });
        }
        Some(DatabaseUrl::Sqlite(path)) => path,
        None => data_dir.join(DB_FILE),
    };
    let url = absolute(&url)?;
    if !url.is_file() {
        return Err(Error::OpenDb {
            what: format!("no database at {}", url.display()),
            message: "is --data-dir the coordinator's data dir (or --database its database)?"
                .into(),
        });
    }
    let opts = SqliteConnectOptions::new()
        .filename(&url)
        .read_only(true)
        .to_url_lossy();
    AnyPoolOptions::new()
        .max_connections(1)
        .after_connect(|conn, _| {
            Box::pin(async move {
                sqlx::Executor::execute(conn, "PRAGMA busy_timeout = 10000;")
                    .await
                    .map(|_| ())
            })
        })
        .connect(opts.as_str())
        .await
        .map_err(|e| Error::OpenDb {
            what: format!("open {} read-only", url.display()),
            message: e.to_string(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn a_data_dir_without_a_database_says_what_to_check() {
        let dir = tempfile::tempdir().unwrap();
        let e = open(dir.path(), None).await.unwrap_err().to_string();
        assert!(
            e.contains("no database at") && e.contains("--data-dir"),
            "{e}"
        );
        let e = open(dir.path(), Some("mysql://x"))
            .await
            .unwrap_err()
            .to_string();
        assert!(!e.is_empty());
    }
}
