//! The live page: `coordinator serve --http ADDR` serves one self-contained HTML page (no
//! CDN, everything embedded in the binary) and the JSON it draws from, with updates pushed
//! as server-sent events from the same event bus `coordinator watch` streams.
//!
//! Routes: `/` (the page), `/api/sweeps`, `/api/sweeps/{id}`, `/api/cells/{id}`,
//! `/api/workers`, `/api/events` (SSE), `/api/sweeps/{id}/report/{file}` (the promoted
//! gait's GIF and the score surface, drawn as `coordinator report` draws them) and
//! `/checkpoints/{sha256}` (download). With a token
//! every route needs it: `?token=` once (exchanged for an HttpOnly cookie and a redirect
//! that drops it from the address bar), the cookie, or `Authorization: Bearer`.

mod api;
mod rate;

use crate::service::Coordinator;
use crate::store::SqlStore;
use crate::{Error, Result};
use axum::extract::{Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{Html, IntoResponse, Redirect, Response};
use axum::routing::get;
use axum::Router;
use std::future::Future;
use std::path::PathBuf;
use std::sync::Arc;

/// Name of the file in the data dir that holds the page's bound address.
pub const HTTP_ADDR_FILE: &str = "http.addr";
/// The cookie that carries the token after `?token=`.
const COOKIE: &str = "gaitsweep_token";
/// The page, embedded.
const PAGE: &str = include_str!("page.html");

/// What the handlers share.
#[derive(Clone)]
pub(crate) struct Live {
    pub(crate) coord: Arc<Coordinator<SqlStore>>,
    pub(crate) db: sqlx::AnyPool,
    pub(crate) data_dir: PathBuf,
    /// Held while the report's pictures are drawn.
    pub(crate) drawing: Arc<tokio::sync::Mutex<()>>,
    token: Option<Arc<str>>,
}

/// Serves the page on `listener` until `shutdown` resolves.
pub async fn serve_http(
    listener: tokio::net::TcpListener,
    coord: Arc<Coordinator<SqlStore>>,
    data_dir: PathBuf,
    token: Option<String>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<()> {
    let live = Live {
        db: coord.store.reader().clone(),
        coord,
        data_dir,
        drawing: Arc::default(),
        token: token.map(Arc::from),
    };
    let app = Router::new()
        .route("/", get(page))
        .route("/api/sweeps", get(api::sweeps))
        .route("/api/sweeps/{id}", get(api::sweep))
        .route("/api/cells/{id}", get(api::cell))
        .route("/api/workers", get(api::workers))
        .route("/api/events", get(api::events))
        .route("/api/sweeps/{id}/report/{file}", get(api::report_file))
        .route("/checkpoints/{sha}", get(api::checkpoint))
        .layer(middleware::from_fn_with_state(live.clone(), auth))
        .with_state(live);
    axum::serve(listener, app)
        .with_graceful_shutdown(shutdown)
        .await
        .map_err(|e| Error::Server(format!("live page: {e}")))
}

async fn page() -> impl IntoResponse {
    ([(header::CACHE_CONTROL, "no-store")], Html(PAGE))
}

/// The token from `?token=`, the cookie or a bearer header.
fn presented(req: &Request) -> (Option<String>, bool) {
    let query = req.uri().query().unwrap_or("");
    for pair in query.split('&') {
        if let Some(v) = pair.strip_prefix("token=") {
            return (Some(percent_decode(v)), true);
        }
    }
    let headers = req.headers();
    if let Some(v) = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "))
    {
        return (Some(v.trim().to_string()), false);
    }
    for c in headers.get_all(header::COOKIE) {
        for part in c.to_str().unwrap_or("").split(';') {
            if let Some(v) = part.trim().strip_prefix(&format!("{COOKIE}=")) {
                return (Some(percent_decode(v)), false);
            }
        }
    }
    (None, false)
}

fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'%' if i + 2 < b.len() => {
                let hex = std::str::from_utf8(&b[i + 1..i + 3]).ok();
                match hex.and_then(|h| u8::from_str_radix(h, 16).ok()) {
                    Some(v) => {
                        out.push(v);
                        i += 3;
                        continue;
                    }
                    None => out.push(b'%'),
                }
            }
            b'+' => out.push(b' '),
            c => out.push(c),
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn percent_encode(s: &str) -> String {
    s.bytes()
        .map(|c| match c {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => {
                (c as char).to_string()
            }
            _ => format!("%{c:02X}"),
        })
        .collect()
}

/// Checks the token on every route (constant-time compare); `?token=` becomes a cookie.
async fn auth(State(live): State<Live>, req: Request, next: Next) -> Response {
    let Some(expected) = live.token.clone() else {
        return next.run(req).await;
    };
    let (given, in_query) = presented(&req);
    let ok = given
        .as_deref()
        .is_some_and(|g| crate::auth::same_token(g, &expected));
    if !ok {
        let why = if given.is_some() {
            "the token is wrong"
        } else {
            "this coordinator needs its access token"
        };
        tracing::warn!(path = %req.uri().path(), "live page: request without a valid token");
        return (StatusCode::UNAUTHORIZED, Html(login_page(why))).into_response();
    }
    if in_query {
        // Keep the token out of the address bar, history and logs: set the cookie and
        // send the browser to the same path without it.
        let path = req.uri().path().to_string();
        let cookie = format!(
            "{COOKIE}={}; HttpOnly; SameSite=Strict; Path=/",
            percent_encode(&expected)
        );
        let mut r = Redirect::to(&path).into_response();
        if let Ok(v) = cookie.parse() {
            r.headers_mut().insert(header::SET_COOKIE, v);
        }
        return r;
    }
    next.run(req).await
}

fn login_page(why: &str) -> String {
    format!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>gaitsweep: token needed</title>\
         <style>body{{font:15px system-ui,sans-serif;margin:4em auto;max-width:28em;color:#222}}\
         input{{font:inherit;padding:.3em;width:16em}}button{{font:inherit;padding:.3em .8em}}</style></head>\
         <body><h1>gaitsweep</h1><p>{why}: enter the token given to <code>coordinator serve --token</code>.</p>\
         <form method=\"get\" action=\"/\"><input type=\"password\" name=\"token\" autofocus> \
         <button>open</button></form></body></html>"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_survive_the_query_and_the_cookie() {
        let t = "s3cret &=%/+x";
        assert_eq!(percent_decode(&percent_encode(t)), t);
        assert_eq!(percent_decode("a%2"), "a%2");
        assert_eq!(percent_decode("a+b"), "a b");
    }
}
