//! The studio's HTTP API (`docs/studio.md`) on axum: one guard in front of every route (the
//! `Host` the studio bound, no cross-origin request, the access token but for the page's static
//! files, a body limit), JSON in,
//! JSON or binary meshes out, errors as `{"error": "..."}` with a 4xx status. The computations
//! run on tokio's blocking pool, one at a time, behind the session's mutex; one whose client has
//! gone before its turn is skipped, and `GET /api/state` answers from a copy kept beside the
//! session, without waiting for the computation in progress.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use axum::Router;
use axum::body::{Body, Bytes};
use axum::extract::{Path, Request, State};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, Uri, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::Deserialize;
use serde_json::{Value, json};

use super::assets;
use super::json::RestorationJson;
use super::session::{ApiError, Session};
use crate::restore::Restoration;

/// The largest request body the studio reads (a restoration is under 300 bytes).
pub(crate) const BODY_LIMIT: usize = 64 * 1024;

/// What every request handler shares.
pub(crate) struct App {
    /// The session; requests that compute take turns.
    pub session: Mutex<Session>,
    /// The session's state as `GET /api/state` answers it, updated by every change while the
    /// session is locked.
    state: Mutex<Value>,
    /// The access token.
    pub token: String,
    /// The `Host` header values accepted; `None` when the studio is bound beyond loopback (then
    /// the token alone admits, and `Origin` must still match `Host`).
    pub hosts: Option<Vec<String>>,
    /// Set on Ctrl-C: computations not yet started are refused.
    pub stopping: AtomicBool,
    /// Set while a save writes its files (Ctrl-C waits for it).
    pub saving: AtomicBool,
}

impl App {
    /// The shared state of a server on `session`.
    pub(crate) fn new(session: Session, token: String, hosts: Option<Vec<String>>) -> Self {
        Self {
            state: Mutex::new(session.state()),
            session: Mutex::new(session),
            token,
            hosts,
            stopping: AtomicBool::new(false),
            saving: AtomicBool::new(false),
        }
    }

    /// `session`'s state, kept for `GET /api/state`; call with the session locked.
    fn publish(&self, session: &Session) -> Value {
        let state = session.state();
        *self.state.lock().unwrap_or_else(PoisonError::into_inner) = state.clone();
        state
    }
}

/// The studio's routes behind the guard.
pub(crate) fn router(app: Arc<App>) -> Router {
    Router::new()
        .route("/", get(index))
        .route("/assets/{name}", get(asset))
        .route("/api/state", get(state))
        .route("/api/mesh", get(mesh))
        .route("/api/points", get(points))
        .route("/api/preview", post(preview))
        .route("/api/apply", post(apply))
        .route("/api/undo", post(undo))
        .route("/api/redo", post(redo))
        .route("/api/save", post(save))
        .fallback(not_found)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(middleware::from_fn_with_state(app.clone(), guard))
        .with_state(app)
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let status = StatusCode::from_u16(self.status).unwrap_or(StatusCode::BAD_REQUEST);
        (status, axum::Json(json!({ "error": self.message }))).into_response()
    }
}

fn refuse(status: u16, message: impl Into<String>) -> ApiError {
    ApiError {
        status,
        message: message.into(),
    }
}

/// Admits a request or says why not; adds the headers that keep the page out of frames,
/// caches and referrers (to refusals too).
async fn guard(State(app): State<Arc<App>>, request: Request, next: Next) -> Response {
    let mut response = match admit(&app, request.method(), request.headers(), request.uri()) {
        Ok(()) => next.run(request).await,
        Err(e) => {
            // A refused client does not keep its connection.
            let mut refused = e.into_response();
            refused
                .headers_mut()
                .insert(header::CONNECTION, HeaderValue::from_static("close"));
            refused
        }
    };
    let headers = response.headers_mut();
    for (name, value) in [
        ("cache-control", "no-store"),
        ("referrer-policy", "no-referrer"),
        ("x-content-type-options", "nosniff"),
        ("x-frame-options", "DENY"),
        (
            "content-security-policy",
            "default-src 'self'; script-src 'self' 'unsafe-inline'; style-src 'self' \
             'unsafe-inline'; img-src 'self' data: blob:; connect-src 'self'; \
             frame-ancestors 'none'",
        ),
    ] {
        headers.insert(name, HeaderValue::from_static(value));
    }
    response
}

/// The guard's checks, in order: the `Host` (DNS rebinding), the `Origin` and `Sec-Fetch-Site`
/// (other web pages), the token, the declared body size. The page's static files under
/// `/assets/` (its scripts, styles and three.js: nothing of the user's) need no token, so that no
/// cookie is needed to load them (a cookie would go to every server on localhost).
fn admit(app: &App, method: &Method, headers: &HeaderMap, uri: &Uri) -> Result<(), ApiError> {
    let text = |name: header::HeaderName| headers.get(name).and_then(|v| v.to_str().ok());
    let host = text(header::HOST).unwrap_or("");
    if let Some(hosts) = &app.hosts
        && !hosts.iter().any(|h| h.eq_ignore_ascii_case(host))
    {
        return Err(refuse(
            403,
            format!(
                "this studio answers only at http://{} (the request's Host is {host:?})",
                hosts[0]
            ),
        ));
    }
    if let Some(origin) = text(header::ORIGIN)
        && !origin.eq_ignore_ascii_case(&format!("http://{host}"))
    {
        return Err(refuse(
            403,
            format!("cross-origin request refused (Origin {origin:?})"),
        ));
    }
    // A browser says where a request comes from: only the studio's own page (same-origin) or
    // the user (none: the address typed or opened) may drive it; another port on localhost is
    // "same-site", and refused too. One exception: the page itself may be opened from anywhere
    // (a top-level GET of `/`, which changes nothing and still needs the token) — the start
    // page `zeroset studio` hands the browser is a local file, and Chromium calls its redirect
    // to the studio "cross-site".
    let is = |name: &str, value: &[u8]| {
        headers
            .get(name)
            .is_some_and(|v| v.as_bytes().eq_ignore_ascii_case(value))
    };
    let opens_page = method == Method::GET
        && uri.path() == "/"
        && is("sec-fetch-mode", b"navigate")
        && is("sec-fetch-dest", b"document");
    if let Some(site) = headers.get("sec-fetch-site")
        && !(site.as_bytes().eq_ignore_ascii_case(b"same-origin")
            || site.as_bytes().eq_ignore_ascii_case(b"none")
            || opens_page)
    {
        return Err(refuse(
            403,
            format!(
                "request from another site refused (Sec-Fetch-Site {:?})",
                site.to_str().unwrap_or("?")
            ),
        ));
    }
    if uri.path().starts_with("/assets/") {
        return declared_size(headers);
    }
    let given = query_token(uri).or_else(|| {
        headers
            .get("x-zeroset-token")
            .and_then(|v| v.to_str().ok())
            .filter(|v| !v.is_empty())
            .map(str::to_owned)
    });
    match given {
        Some(t) if same(t.as_bytes(), app.token.as_bytes()) => {}
        Some(_) => {
            return Err(refuse(
                401,
                "wrong access token: open the address zeroset studio printed",
            ));
        }
        None => {
            return Err(refuse(
                401,
                "missing access token: open the address zeroset studio printed (it ends in \
                 ?token=…), or send the header X-Zeroset-Token",
            ));
        }
    }
    declared_size(headers)
}

/// Refuses a request that declares a body over [`BODY_LIMIT`].
fn declared_size(headers: &HeaderMap) -> Result<(), ApiError> {
    let declared = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if declared.is_some_and(|n| n > BODY_LIMIT as u64) {
        return Err(body_too_large());
    }
    Ok(())
}

fn body_too_large() -> ApiError {
    refuse(
        413,
        format!("request body over the studio's limit of {BODY_LIMIT} bytes"),
    )
}

/// The `token` parameter of the query, if any.
fn query_token(uri: &Uri) -> Option<String> {
    uri.query()?
        .split('&')
        .find_map(|pair| pair.strip_prefix("token="))
        .map(str::to_owned)
}

/// Compares two tokens in time independent of where they differ.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Sets its flag when dropped armed: a request's handler dropped before its answer (the client
/// closed the connection).
struct Abandoned(Option<Arc<AtomicBool>>);

impl Drop for Abandoned {
    fn drop(&mut self) {
        if let Some(flag) = self.0.take() {
            flag.store(true, Ordering::SeqCst);
        }
    }
}

/// Whether a request's work is skipped when its client has gone before its turn.
#[derive(Clone, Copy, PartialEq, Eq)]
enum IfGone {
    /// A preview or a mesh: nobody would read it.
    Skip,
    /// A change the user asked for (apply, undo, redo, save): done all the same.
    Do,
}

/// Runs `work` on the session on tokio's blocking pool, in its turn — unless, by then, the
/// studio is stopping, or (with [`IfGone::Skip`]) the client has gone.
async fn with_session<T: Send + 'static>(
    app: Arc<App>,
    if_gone: IfGone,
    work: impl FnOnce(&App, &mut Session) -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    let gone = Arc::new(AtomicBool::new(false));
    let mut abandoned = Abandoned(Some(gone.clone()));
    let result = tokio::task::spawn_blocking(move || {
        let mut session = app.session.lock().unwrap_or_else(PoisonError::into_inner);
        if if_gone == IfGone::Skip && gone.load(Ordering::SeqCst) {
            return Err(refuse(499, "the client closed the connection"));
        }
        if app.stopping.load(Ordering::SeqCst) {
            return Err(refuse(503, "the studio is stopping"));
        }
        work(&app, &mut session)
    })
    .await;
    abandoned.0 = None;
    result.map_err(|e| refuse(500, format!("the computation failed: {e}")))?
}

/// Reads a JSON body: `application/json`, at most [`BODY_LIMIT`] bytes, well-formed.
async fn read_json<T: for<'de> Deserialize<'de>>(
    headers: &HeaderMap,
    body: Body,
) -> Result<T, ApiError> {
    let json = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| {
            v.split(';')
                .next()
                .is_some_and(|t| t.trim().eq_ignore_ascii_case("application/json"))
        });
    if !json {
        return Err(refuse(
            415,
            "send the body as Content-Type: application/json",
        ));
    }
    let bytes: Bytes = axum::body::to_bytes(body, BODY_LIMIT)
        .await
        .map_err(|_| body_too_large())?;
    serde_json::from_slice(&bytes).map_err(|e| refuse(400, format!("malformed JSON: {e}")))
}

fn binary(bytes: Vec<u8>) -> Response {
    ([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response()
}

fn json_response(value: Value) -> Response {
    axum::Json(value).into_response()
}

async fn index() -> Response {
    match assets::find("index.html") {
        Some(asset) => ([(header::CONTENT_TYPE, asset.content_type)], asset.bytes).into_response(),
        None => not_found().await,
    }
}

async fn asset(Path(name): Path<String>) -> Response {
    match assets::find(&name) {
        Some(asset) => ([(header::CONTENT_TYPE, asset.content_type)], asset.bytes).into_response(),
        None => not_found().await,
    }
}

async fn not_found() -> Response {
    refuse(
        404,
        "no such page or API endpoint (docs/studio.md lists them)",
    )
    .into_response()
}

async fn method_not_allowed(method: Method) -> Response {
    refuse(405, format!("{method} is not allowed here")).into_response()
}

async fn state(State(app): State<Arc<App>>) -> Response {
    let state = app
        .state
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .clone();
    json_response(state)
}

async fn mesh(State(app): State<Arc<App>>) -> Result<Response, ApiError> {
    Ok(binary(
        with_session(app, IfGone::Skip, |_, s| s.mesh()).await?,
    ))
}

async fn points(State(app): State<Arc<App>>) -> Result<Response, ApiError> {
    let bytes = with_session(app, IfGone::Skip, |_, s| {
        s.points()
            .ok_or_else(|| refuse(404, "the input is a field file: it has no points"))
    })
    .await?;
    Ok(binary(bytes))
}

async fn restoration(headers: &HeaderMap, body: Body) -> Result<Restoration, ApiError> {
    read_json::<RestorationJson>(headers, body).await?.check()
}

async fn preview(
    State(app): State<Arc<App>>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    let r = restoration(&headers, body).await?;
    Ok(binary(
        with_session(app, IfGone::Skip, move |_, s| s.preview(&r)).await?,
    ))
}

async fn apply(
    State(app): State<Arc<App>>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    let r = restoration(&headers, body).await?;
    let state = with_session(app, IfGone::Do, move |app, s| {
        s.apply(&r)?;
        Ok(app.publish(s))
    })
    .await?;
    Ok(json_response(state))
}

async fn undo(State(app): State<Arc<App>>) -> Result<Response, ApiError> {
    history(app, Session::undo).await
}

async fn redo(State(app): State<Arc<App>>) -> Result<Response, ApiError> {
    history(app, Session::redo).await
}

/// One step of the history (`Session::undo` or `Session::redo`), answered with the state.
async fn history(
    app: Arc<App>,
    step: fn(&mut Session) -> Result<(), ApiError>,
) -> Result<Response, ApiError> {
    let state = with_session(app, IfGone::Do, move |app, s| {
        step(s)?;
        Ok(app.publish(s))
    })
    .await?;
    Ok(json_response(state))
}

/// The body of `POST /api/save`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SaveJson {
    #[serde(default)]
    mesh: bool,
}

async fn save(
    State(app): State<Arc<App>>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    let request = read_json::<SaveJson>(&headers, body).await?;
    let saved = with_session(app, IfGone::Do, move |app, s| {
        app.saving.store(true, Ordering::SeqCst);
        let saved = s.save(request.mesh);
        app.saving.store(false, Ordering::SeqCst);
        saved
    })
    .await?;
    Ok(json_response(saved))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_come_from_the_query_and_compare_exactly() {
        let uri: Uri = "/?a=1&token=abc".parse().unwrap();
        assert_eq!(query_token(&uri).as_deref(), Some("abc"));
        let uri: Uri = "/api/state".parse().unwrap();
        assert_eq!(query_token(&uri), None);
        assert!(same(b"abc", b"abc"));
        assert!(!same(b"abc", b"abd"));
        assert!(!same(b"abc", b"ab"));
    }
}
