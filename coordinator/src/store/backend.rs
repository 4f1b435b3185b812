//! The two databases the store runs on and the few places their SQL differs. The store's
//! statements are written once in the SQL both databases share: numbered placeholders
//! (`$1`; sqlx binds SQLite's `$N` by number too), `ON CONFLICT`, `RETURNING`, `CASE`
//! instead of SQLite's two-argument `MAX`; the methods below give the fragments that differ.

use crate::{Error, Result};
use sqlx::any::AnyPoolOptions;
use sqlx::Connection;
use std::fmt;

/// The database behind a store.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// One SQLite file in the data dir (the default).
    Sqlite,
    /// A PostgreSQL server.
    Postgres,
}

impl fmt::Display for Backend {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Backend::Sqlite => "sqlite",
            Backend::Postgres => "postgres",
        })
    }
}

/// Where the coordinator keeps its database: `--database` of `coordinator serve`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DatabaseUrl {
    /// A SQLite file.
    Sqlite(std::path::PathBuf),
    /// A PostgreSQL connection URL (`postgres://user:password@host:port/db`).
    Postgres(String),
}

impl DatabaseUrl {
    /// Parses `--database`: `postgres://…` / `postgresql://…`, `sqlite://PATH`, or a plain
    /// file path (SQLite).
    pub fn parse(s: &str) -> Result<Self> {
        let s = s.trim();
        if s.is_empty() {
            return Err(Error::BadRequest(
                "empty --database: give postgres://user@host/db or a SQLite file path".into(),
            ));
        }
        if s.starts_with("postgres://") || s.starts_with("postgresql://") {
            return Ok(DatabaseUrl::Postgres(s.to_string()));
        }
        if let Some(path) = s.strip_prefix("sqlite://").or(s.strip_prefix("sqlite:")) {
            if path.is_empty() || path.starts_with(":memory:") {
                return Err(Error::BadRequest(format!(
                    "--database {s:?}: an in-memory database loses every result at exit; give a file path"
                )));
            }
            return Ok(DatabaseUrl::Sqlite(path.into()));
        }
        if s.contains("://") {
            return Err(Error::BadRequest(format!(
                "--database {s:?}: unknown scheme; use postgres://user@host/db or a SQLite file path"
            )));
        }
        Ok(DatabaseUrl::Sqlite(s.into()))
    }

    /// The backend.
    pub fn backend(&self) -> Backend {
        match self {
            DatabaseUrl::Sqlite(_) => Backend::Sqlite,
            DatabaseUrl::Postgres(_) => Backend::Postgres,
        }
    }

    /// The URL with any password replaced by `***`, for logs.
    pub fn redacted(&self) -> String {
        match self {
            DatabaseUrl::Sqlite(p) => p.display().to_string(),
            DatabaseUrl::Postgres(u) => redact_password(u),
        }
    }
}

fn redact_password(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_string();
    };
    let (rest, query) = match rest.split_once('?') {
        Some((r, q)) => (r, Some(q)),
        None => (rest, None),
    };
    let rest = match rest.rsplit_once('@') {
        Some((userinfo, host)) => match userinfo.split_once(':') {
            Some((user, _)) => format!("{user}:***@{host}"),
            None => format!("{userinfo}@{host}"),
        },
        None => rest.to_string(),
    };
    let query = query.map(|q| {
        q.split('&')
            .map(|kv| match kv.split_once('=') {
                Some((k, _)) if k.eq_ignore_ascii_case("password") => format!("{k}=***"),
                _ => kv.to_string(),
            })
            .collect::<Vec<_>>()
            .join("&")
    });
    match query {
        Some(q) => format!("{scheme}://{rest}?{q}"),
        None => format!("{scheme}://{rest}"),
    }
}

/// `path` made absolute against the working directory (a SQLite path travels through a
/// `sqlite://` URL, where a relative path's first part would read as a host).
pub fn absolute(path: &std::path::Path) -> Result<std::path::PathBuf> {
    std::path::absolute(path).map_err(|e| {
        Error::BadRequest(format!(
            "database path {}: {e}; give an absolute path",
            path.display()
        ))
    })
}

impl Backend {
    /// The statement that opens a write transaction. SQLite takes the write lock at once
    /// (a deferred transaction can fail on a busy snapshot); on PostgreSQL the store's one
    /// writer connection already orders its transactions.
    pub fn begin_write(self) -> &'static str {
        match self {
            Backend::Sqlite => "BEGIN IMMEDIATE",
            Backend::Postgres => "BEGIN",
        }
    }

    /// An integer field of a JSON text column, as a 64-bit integer.
    pub fn json_int(self, column: &str, field: &str) -> String {
        match self {
            Backend::Sqlite => format!("json_extract({column}, '$.{field}')"),
            Backend::Postgres => format!("CAST(CAST({column} AS json) ->> '{field}' AS BIGINT)"),
        }
    }
}

/// Creates the database `name` on the PostgreSQL server `server` (a URL of any database
/// on it) and returns the URL of the new database. Used by the tests and benches, which give
/// each run a database of its own.
pub async fn create_postgres_database(server: &str, name: &str) -> Result<String> {
    use sqlx::{Connection, Executor};
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(Error::BadRequest(format!(
            "database name {name:?}: use letters, digits and _"
        )));
    }
    sqlx::any::install_default_drivers();
    let mut conn = sqlx::AnyConnection::connect(server).await?;
    conn.execute(format!("CREATE DATABASE {name}").as_str())
        .await?;
    conn.close().await?;
    Ok(with_database(server, name))
}

/// A database name no other run on the same server has used: `prefix`, the process id, the
/// time in microseconds and a counter (process ids repeat on a long-lived server).
pub fn unique_database_name(prefix: &str) -> String {
    use std::sync::atomic::{AtomicU32, Ordering};
    static N: AtomicU32 = AtomicU32::new(0);
    let micros = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros());
    format!(
        "{prefix}_{}_{micros}_{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    )
}

/// `url` with its database (the path) replaced by `name`, keeping any query.
fn with_database(url: &str, name: &str) -> String {
    let (scheme, rest) = url.split_once("://").unwrap_or(("postgres", url));
    let (rest, query) = match rest.split_once('?') {
        Some((r, q)) => (r, Some(q)),
        None => (rest, None),
    };
    let authority = rest.split_once('/').map_or(rest, |(a, _)| a);
    let mut out = format!("{scheme}://{authority}/{name}");
    if let Some(q) = query {
        out.push('?');
        out.push_str(q);
    }
    out
}

/// The current time in unix milliseconds (statements bind it rather than asking the
/// database, whose clock functions differ).
pub fn now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as i64)
}

/// The one writer connection. A failed write (a full disk) can leave the connection inside
/// a transaction that the database already rolled back, and every later BEGIN on it fails.
/// The ping waits for the rollback queued when the failed transaction was dropped; a
/// connection still in a transaction after it is replaced by a fresh one.
pub(super) fn writer_pool() -> AnyPoolOptions {
    AnyPoolOptions::new()
        .max_connections(1)
        .before_acquire(|conn, _| {
            Box::pin(async move {
                conn.ping().await?;
                let healthy = !conn.is_in_transaction();
                if !healthy {
                    tracing::warn!(
                        "writer connection left inside a failed transaction; opening a new one"
                    );
                }
                Ok(healthy)
            })
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn database_urls_name_their_backend_and_hide_passwords() {
        let pg = DatabaseUrl::parse("postgres://gs:secret@127.0.0.1:5432/gaitsweep").unwrap();
        assert_eq!(pg.backend(), Backend::Postgres);
        assert_eq!(pg.redacted(), "postgres://gs:***@127.0.0.1:5432/gaitsweep");
        let q = DatabaseUrl::parse("postgres://gs@h/db?sslmode=disable&password=p@ss").unwrap();
        assert_eq!(
            q.redacted(),
            "postgres://gs@h/db?sslmode=disable&password=***"
        );
        assert_eq!(
            DatabaseUrl::parse("sqlite:rel/x.sqlite").unwrap(),
            DatabaseUrl::Sqlite("rel/x.sqlite".into())
        );
        assert!(DatabaseUrl::parse("sqlite::memory:").is_err());
        assert_eq!(
            DatabaseUrl::parse("/data/gaitsweep.sqlite").unwrap(),
            DatabaseUrl::Sqlite("/data/gaitsweep.sqlite".into())
        );
        assert_eq!(
            DatabaseUrl::parse("sqlite:///data/x.sqlite").unwrap(),
            DatabaseUrl::Sqlite("/data/x.sqlite".into())
        );
        assert_eq!(
            with_database("postgres://u@h:5/postgres?sslmode=disable", "t_1"),
            "postgres://u@h:5/t_1?sslmode=disable"
        );
        assert_eq!(
            with_database("postgres://u@h:5", "t_1"),
            "postgres://u@h:5/t_1"
        );
        let e = DatabaseUrl::parse("mysql://x").unwrap_err().to_string();
        assert!(
            e.contains("unknown scheme") && e.contains("postgres://"),
            "{e}"
        );
        assert!(DatabaseUrl::parse(" ").is_err());
    }
}
