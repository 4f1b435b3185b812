//! Helpers of the end-to-end tests: real `coordinator` and `worker` processes from
//! `target/release`, one temp dir per test, bounded waits.

#![allow(dead_code)]

use gaitsweep_core::pb::{
    self, sweep_service_client::SweepServiceClient, worker_service_client::WorkerServiceClient,
};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use tonic::transport::Channel;

/// Serialises the tests that train (two cores only). Each test runs on its own runtime, so
/// the lock is tokio's, which any runtime can await and which an earlier test's panic does
/// not poison.
pub static HEAVY: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

/// Takes the heavy-test lock in an async test.
pub async fn heavy() -> tokio::sync::MutexGuard<'static, ()> {
    HEAVY.lock().await
}

/// Takes the heavy-test lock in a test without a runtime.
pub fn heavy_blocking() -> tokio::sync::MutexGuard<'static, ()> {
    HEAVY.blocking_lock()
}

/// A binary built next to this test executable (target/release/NAME).
pub fn bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("current exe");
    let dir = exe.parent().and_then(Path::parent).expect("target/release");
    let path = dir.join(name);
    assert!(
        path.is_file(),
        "{} is missing: build the binaries first with `cargo build --release --workspace --bins`",
        path.display()
    );
    path
}

/// A child process killed (SIGKILL) when dropped, with its log in a file.
pub struct Proc {
    pub child: Child,
    pub log: PathBuf,
}

impl Proc {
    pub fn spawn(name: &str, args: &[String], log: PathBuf) -> Proc {
        let out = std::fs::File::create(&log).expect("create log");
        let child = Command::new(bin(name))
            .args(args)
            .env("RUST_LOG", "info")
            .stdout(out.try_clone().unwrap())
            .stderr(out)
            .stdin(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {name}: {e}"));
        Proc { child, log }
    }

    /// SIGTERM, then a bounded wait for the process to exit (a worker finishes its epoch,
    /// uploads a checkpoint and gives its cell back first).
    pub async fn stop(&mut self, what: &str) {
        let st = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(st.success());
        wait_for(what, Duration::from_secs(60), || {
            let exited = self.child.try_wait().ok().flatten().is_some();
            async move { exited.then_some(()) }
        })
        .await;
    }

    /// kill -9.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Polls `f` every 100 ms until it yields a value or `timeout` passes (then panics with `what`).
pub async fn wait_for<T, F, Fut>(what: &str, timeout: Duration, mut f: F) -> T
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = Option<T>>,
{
    let start = Instant::now();
    loop {
        if let Some(v) = f().await {
            return v;
        }
        assert!(
            start.elapsed() < timeout,
            "timed out after {timeout:?} waiting for {what}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Polls `sql`, a query for one integer on `db` (a `COUNT` or a `MAX`: NULL is no value
/// yet), until it is at least `at_least` or `timeout` passes; returns the value.
pub async fn wait_for_at_least(
    db: &sqlx::AnyPool,
    what: &str,
    timeout: Duration,
    sql: &str,
    at_least: i64,
) -> i64 {
    wait_for(what, timeout, || {
        let db = db.clone();
        let sql = sql.to_string();
        async move {
            let n: Option<i64> = sqlx::query_scalar(&sql).fetch_one(&db).await.ok()?;
            n.filter(|&n| n >= at_least)
        }
    })
    .await
}

/// A running coordinator.
pub struct Coord {
    pub proc: Proc,
    pub addr: String,
    pub data: PathBuf,
    /// Its PostgreSQL database (`--database`), if not the data dir's SQLite file.
    pub database: Option<String>,
}

/// The database of an end-to-end test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Db {
    /// The default: SQLite in the data dir.
    Sqlite,
    /// A database of its own on the server of `GAITSWEEP_TEST_PG`.
    Postgres,
}

impl Db {
    /// The `--database` of a new coordinator: none for SQLite, a fresh database on the
    /// test server for PostgreSQL.
    pub async fn fresh(self) -> Option<String> {
        match self {
            Db::Sqlite => None,
            Db::Postgres => {
                let server = std::env::var("GAITSWEEP_TEST_PG").expect(
                    "the PostgreSQL end-to-end tests need a server: run scripts/test.sh (it \
                     starts a throwaway one) or set GAITSWEEP_TEST_PG=postgres://user@host:port/postgres",
                );
                let name = gaitsweep_coordinator::store::backend::unique_database_name("gs_e2e");
                Some(
                    gaitsweep_coordinator::store::backend::create_postgres_database(&server, &name)
                        .await
                        .expect("create the test database"),
                )
            }
        }
    }
}

impl Coord {
    /// Starts `coordinator serve` on `listen` with the data dir `data` and extra flags.
    pub async fn start(root: &Path, listen: &str, extra: &[&str]) -> Coord {
        Self::start_on(root, listen, None, extra).await
    }

    /// As [`Coord::start`], with the database `database` (`--database`; `None`: SQLite in
    /// the data dir).
    pub async fn start_on(
        root: &Path,
        listen: &str,
        database: Option<&str>,
        extra: &[&str],
    ) -> Coord {
        let data = root.join("data");
        let addr_file = data.join("coordinator.addr");
        let _ = std::fs::remove_file(&addr_file);
        let mut args: Vec<String> = ["serve", "--listen", listen, "--data-dir"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        args.push(data.display().to_string());
        if let Some(d) = database {
            args.push("--database".into());
            args.push(d.to_string());
        }
        args.extend(extra.iter().map(|s| s.to_string()));
        let n = std::fs::read_dir(root).map(|d| d.count()).unwrap_or(0);
        let proc = Proc::spawn(
            "coordinator",
            &args,
            root.join(format!("coordinator-{n}.log")),
        );
        let addr = wait_for(
            "the coordinator's address file",
            Duration::from_secs(30),
            || {
                let f = addr_file.clone();
                async move { std::fs::read_to_string(f).ok().filter(|s| !s.is_empty()) }
            },
        )
        .await;
        if database.is_some() {
            let log = proc.log.clone();
            wait_for(
                "the coordinator to say its database is PostgreSQL",
                Duration::from_secs(30),
                || {
                    let text = std::fs::read_to_string(&log).unwrap_or_default();
                    async move { text.contains("backend=postgres").then_some(()) }
                },
            )
            .await;
            assert!(
                !data.join("gaitsweep.sqlite").exists(),
                "a coordinator on PostgreSQL wrote no SQLite file"
            );
        }
        Coord {
            proc,
            addr,
            data,
            database: database.map(str::to_string),
        }
    }

    pub fn url(&self) -> String {
        format!("http://{}", self.addr)
    }

    pub async fn channel(&self) -> Channel {
        Channel::from_shared(self.url())
            .unwrap()
            .connect()
            .await
            .expect("connect to coordinator")
    }

    pub async fn sweeps(&self) -> SweepServiceClient<Channel> {
        SweepServiceClient::new(self.channel().await)
    }

    pub async fn workers(&self) -> WorkerServiceClient<Channel> {
        WorkerServiceClient::new(self.channel().await)
    }

    /// The coordinator's database, for reading (the same pool the report uses).
    pub async fn db(&self) -> sqlx::AnyPool {
        gaitsweep_coordinator::store::reader::open(&self.data, self.database.as_deref())
            .await
            .expect("open db")
    }
}

/// Starts a worker daemon with one slot and one thread.
pub fn start_worker(root: &Path, url: &str, name: &str) -> Proc {
    let work = root.join(format!("work-{name}"));
    let args: Vec<String> = vec![
        "--connect".into(),
        url.into(),
        "--slots".into(),
        "1".into(),
        "--threads".into(),
        "1".into(),
        "--work-dir".into(),
        work.display().to_string(),
        "--max-backoff-seconds".into(),
        "1".into(),
    ];
    Proc::spawn("worker", &args, root.join(format!("worker-{name}.log")))
}

/// A tiny sweep spec on the anymal preset.
pub fn tiny_spec(w1: &[f64], w2: &[f64], epochs: u32) -> String {
    format!(
        "name = \"e2e\"\nrobot = \"anymal\"\nterrains = [\"flat\"]\nw1 = {{ values = {w1:?} }}\nw2 = {{ values = {w2:?} }}\n\
         agents_per_cell = 4\nepochs = {epochs}\ncheckpoint_every = 1\nseed = 3\neval = {{ robots = 2, seconds = 1.0 }}\n"
    )
}

pub async fn create(c: &mut SweepServiceClient<Channel>, toml: String) -> pb::Sweep {
    c.create_sweep(pb::CreateSweepRequest {
        spec: Some(pb::create_sweep_request::Spec::Toml(toml)),
    })
    .await
    .expect("create sweep")
    .into_inner()
}

/// Waits until the sweep is no longer running; returns it.
pub async fn wait_done(coord: &Coord, id: i64, timeout: Duration, logs: &[&Proc]) -> pb::Sweep {
    let start = Instant::now();
    loop {
        if let Ok(mut c) = tokio::time::timeout(Duration::from_secs(5), coord.sweeps()).await {
            if let Ok(s) = c.get_sweep(pb::GetSweepRequest { sweep_id: id }).await {
                let s = s.into_inner();
                if s.state != pb::SweepState::Running as i32 {
                    return s;
                }
            }
        }
        if start.elapsed() > timeout {
            for p in logs {
                eprintln!("---- {}\n{}", p.log.display(), tail(&p.log_text(), 40));
            }
            panic!("sweep {id} not finished after {timeout:?}");
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

pub fn tail(s: &str, n: usize) -> String {
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

pub fn sha256_file(p: &Path) -> String {
    use sha2::Digest;
    hex::encode(sha2::Sha256::digest(std::fs::read(p).expect("read file")))
}

/// The python of the venv scripts/setup.sh installs (torch, tensorboard).
pub fn python() -> PathBuf {
    let cache = std::env::var_os("GAITSWEEP_CACHE")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".cache/gaitsweep")))
        .expect("HOME or GAITSWEEP_CACHE is set");
    let py = cache.join("venv/bin/python");
    assert!(
        py.exists(),
        "{} is missing: run the tests through scripts/test.sh, which installs it",
        py.display()
    );
    py
}

/// A headless browser on this machine: Debian's `chromium` (scripts/test.sh installs it), or
/// another Chromium by its usual names.
pub fn chromium() -> Option<String> {
    ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| {
            Command::new(b)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
        .map(str::to_string)
}

/// Runs headless Chromium on `url` with `extra` flags; its stdout.
pub fn browse(browser: &str, url: &str, extra: &[&str]) -> String {
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--window-size=1400,1000",
            "--virtual-time-budget=1500",
        ])
        .args(extra)
        .arg(url)
        .output()
        .expect("run chromium");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// [`chromium`], or a panic that says how to install it.
pub fn chromium_or_panic() -> String {
    chromium().expect(
        "headless chromium is needed for this test: scripts/test.sh installs Debian's `chromium` \
         (apt-get install chromium)",
    )
}

/// A plain GET (with `Authorization: Bearer` when `token` is given): the status line and
/// the body.
pub fn http_get(addr: &str, path: &str, token: Option<&str>) -> (String, Vec<u8>) {
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let auth = token.map_or(String::new(), |t| format!("Authorization: Bearer {t}\r\n"));
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\n{auth}Connection: close\r\n\r\n"
    )
    .unwrap();
    let mut raw = Vec::new();
    let _ = s.read_to_end(&mut raw);
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .map_or(raw.len(), |i| i + 4);
    let head = String::from_utf8_lossy(&raw[..split]).into_owned();
    (
        head.lines().next().unwrap_or("").to_string(),
        raw[split..].to_vec(),
    )
}
