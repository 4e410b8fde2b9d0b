//! A small Chrome DevTools Protocol (CDP) client for the browser tests: it starts headless
//! Chromium, loads a page, moves the mouse, evaluates JavaScript, takes screenshots and collects
//! the page's console errors and uncaught exceptions.
//!
//! Why CDP rather than WebDriver: WebDriver needs a second program (`chromedriver`, which must
//! match the browser's version) and an HTTP client; CDP is spoken by Chromium itself over one
//! websocket, so the tests need only the browser and the `tungstenite` crate. Everything here is
//! synchronous (no async runtime): one command is in flight at a time, and the events that arrive
//! while waiting for its reply are kept.
//!
//! ```ignore
//! mod cdp;
//! let Some(exe) = cdp::chromium() else { return }; // skip: no browser
//! let mut browser = cdp::Browser::launch(&exe, 800, 600)?;
//! browser.navigate("http://127.0.0.1:7878/")?;
//! browser.drag((400.0, 300.0), (500.0, 300.0), 10)?;
//! let png = browser.screenshot_png()?;
//! assert!(cdp::png_stats(&png)?.non_background > 0.01);
//! assert!(browser.errors().is_empty(), "{:?}", browser.errors());
//! ```
//!
//! WebGL in headless Chromium without a GPU runs on SwiftShader (software, through ANGLE's Vulkan
//! back end). Recent Chromium only falls back to it when told that this is intended: with
//! `--disable-gpu` alone `getContext('webgl2')` is `null`, `--use-gl=swiftshader` no longer
//! changes that (Chromium 148), `--enable-unsafe-swiftshader` does. Hence the flags in
//! [`Browser::launch`].
#![allow(dead_code)] // each test binary uses a part of this

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

use base64::Engine as _;
use serde_json::{Value, json};
use tungstenite::{Message, WebSocket};

/// How long a command may wait for its reply unless [`Browser::set_timeout`] says otherwise.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(60);

/// How long [`Browser::launch`] waits for Chromium to open its debugging port and its page.
pub const LAUNCH_TIMEOUT: Duration = Duration::from_secs(30);

/// Events kept for [`Browser::take_events`] at most; older ones are dropped.
const MAX_EVENTS: usize = 10_000;

/// The Chromium to run: `$ZEROSET_CHROMIUM` if set (and not empty), else the first of
/// `/usr/bin/chromium`, `/usr/bin/chromium-browser`, `/usr/bin/google-chrome` that exists, else
/// the first of those names found on `PATH`. `None`: no browser here.
pub fn chromium() -> Option<PathBuf> {
    if let Some(path) = std::env::var_os("ZEROSET_CHROMIUM").filter(|p| !p.is_empty()) {
        return Some(PathBuf::from(path));
    }
    const NAMES: [&str; 3] = ["chromium", "chromium-browser", "google-chrome"];
    if let Some(path) = NAMES
        .iter()
        .map(|name| Path::new("/usr/bin").join(name))
        .find(|path| path.is_file())
    {
        return Some(path);
    }
    let path_var = std::env::var_os("PATH")?;
    NAMES.iter().find_map(|name| {
        std::env::split_paths(&path_var)
            .map(|dir| dir.join(name))
            .find(|path| path.is_file())
    })
}

/// A mouse button, for [`Browser::mouse`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Button {
    /// No button changes (a move).
    None,
    Left,
    Middle,
    Right,
}

impl Button {
    fn name(self) -> &'static str {
        match self {
            Button::None => "none",
            Button::Left => "left",
            Button::Middle => "middle",
            Button::Right => "right",
        }
    }

    /// The button's bit in the DOM's `MouseEvent.buttons`.
    fn bit(self) -> u32 {
        match self {
            Button::None => 0,
            Button::Left => 1,
            Button::Right => 2,
            Button::Middle => 4,
        }
    }
}

/// A headless Chromium with one page, driven over CDP. Dropping it closes the browser, waits for
/// it and removes its profile directory.
pub struct Browser {
    child: Child,
    socket: WebSocket<TcpStream>,
    next_id: u64,
    timeout: Duration,
    /// Events received and not yet taken, oldest first.
    events: VecDeque<Value>,
    /// Console errors and uncaught exceptions of the page, as text.
    errors: Vec<String>,
    /// The buttons held down, as `MouseEvent.buttons`.
    buttons: u32,
    /// The viewport size asked for.
    size: (u32, u32),
    /// Holds the profile (`profile/`) and Chromium's output (`chromium.log`); dropped last.
    dir: tempfile::TempDir,
}

impl Browser {
    /// Starts `exe` headless with a `width`×`height` viewport on `about:blank` and connects to its
    /// page, with the `Page`, `Runtime` and `Log` domains enabled.
    pub fn launch(exe: &Path, width: u32, height: u32) -> Result<Browser, String> {
        let dir = tempfile::Builder::new()
            .prefix("zeroset-chromium-")
            .tempdir()
            .map_err(|e| format!("cannot create a temporary directory for Chromium: {e}"))?;
        let profile = dir.path().join("profile");
        let log_path = dir.path().join("chromium.log");
        let log = std::fs::File::create(&log_path)
            .map_err(|e| format!("cannot create {}: {e}", log_path.display()))?;
        let log_err = log
            .try_clone()
            .map_err(|e| format!("cannot duplicate {}: {e}", log_path.display()))?;
        let child = Command::new(exe)
            .args([
                "--headless=new",
                "--no-sandbox",
                "--disable-gpu",
                // WebGL on SwiftShader (software): without this flag recent Chromium refuses the
                // fallback and `getContext('webgl')` is null.
                "--enable-unsafe-swiftshader",
                // SwiftShader even where a GPU is found: the same pictures on every machine.
                "--use-angle=swiftshader",
                // Containers often have a small /dev/shm, where renderers crash.
                "--disable-dev-shm-usage",
                "--disable-quic",
                "--no-first-run",
                "--no-default-browser-check",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-default-apps",
                "--disable-extensions",
                "--mute-audio",
                "--hide-scrollbars",
                "--remote-debugging-address=127.0.0.1",
                "--remote-debugging-port=0",
            ])
            .arg(format!("--window-size={width},{height}"))
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg("about:blank")
            .stdin(Stdio::null())
            .stdout(log)
            .stderr(log_err)
            .spawn()
            .map_err(|e| format!("cannot start {}: {e}", exe.display()))?;
        // From here on a failure must not leave Chromium running: `Starting` kills it on drop.
        let mut starting = Starting {
            child: Some(child),
            log: log_path,
        };
        let deadline = Instant::now() + LAUNCH_TIMEOUT;
        let port = starting.port(&profile.join("DevToolsActivePort"), deadline)?;
        let url = starting.page_url(port, deadline)?;
        let stream = TcpStream::connect(("127.0.0.1", port))
            .map_err(|e| starting.failed(format!("cannot connect to port {port}: {e}")))?;
        stream
            .set_read_timeout(Some(DEFAULT_TIMEOUT))
            .and_then(|()| stream.set_write_timeout(Some(DEFAULT_TIMEOUT)))
            .and_then(|()| stream.set_nodelay(true))
            .map_err(|e| format!("cannot set up the debugging socket: {e}"))?;
        let (socket, _) = tungstenite::client(url.as_str(), stream)
            .map_err(|e| starting.failed(format!("websocket handshake with {url}: {e}")))?;
        let child = starting
            .child
            .take()
            .ok_or("Chromium's process was lost during the start")?;
        let mut browser = Browser {
            child,
            socket,
            next_id: 0,
            timeout: DEFAULT_TIMEOUT,
            events: VecDeque::new(),
            errors: Vec::new(),
            buttons: 0,
            size: (width, height),
            dir,
        };
        for domain in ["Page", "Runtime", "Log"] {
            browser.call(&format!("{domain}.enable"), json!({}))?;
        }
        // `--window-size` sizes the window, not necessarily the page's viewport: say it exactly.
        browser.call(
            "Emulation.setDeviceMetricsOverride",
            json!({"width": width, "height": height, "deviceScaleFactor": 1, "mobile": false}),
        )?;
        Ok(browser)
    }

    /// The longest a command waits for its reply (default [`DEFAULT_TIMEOUT`]).
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// The viewport size given to [`Browser::launch`].
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// Sends the CDP command `method` with `params` to the page and returns its `result`; a CDP
    /// error becomes `Err`. Events that arrive meanwhile are kept (see [`Browser::take_events`]
    /// and [`Browser::errors`]).
    pub fn call(&mut self, method: &str, params: Value) -> Result<Value, String> {
        self.next_id += 1;
        let id = self.next_id;
        let request = json!({"id": id, "method": method, "params": params});
        self.socket
            .send(Message::text(request.to_string()))
            .map_err(|e| format!("{method}: cannot send: {e}"))?;
        let deadline = Instant::now() + self.timeout;
        loop {
            let Some(message) = self.receive(deadline)? else {
                return Err(format!(
                    "{method}: no reply within {:.0} s",
                    self.timeout.as_secs_f64()
                ));
            };
            if message.get("id").and_then(Value::as_u64) != Some(id) {
                self.keep(message);
                continue;
            }
            if let Some(error) = message.get("error") {
                return Err(format!("{method}: {error}"));
            }
            return Ok(message.get("result").cloned().unwrap_or(Value::Null));
        }
    }

    /// Waits until the event `method` arrives (or has arrived and was not taken yet), takes it
    /// and returns its `params`.
    pub fn wait_event(&mut self, method: &str, timeout: Duration) -> Result<Value, String> {
        let is_it = |event: &Value| event.get("method").and_then(Value::as_str) == Some(method);
        if let Some(event) = self
            .events
            .iter()
            .position(is_it)
            .and_then(|at| self.events.remove(at))
        {
            return Ok(event.get("params").cloned().unwrap_or(Value::Null));
        }
        let deadline = Instant::now() + timeout;
        while let Some(message) = self.receive(deadline)? {
            if is_it(&message) {
                self.record(&message);
                return Ok(message.get("params").cloned().unwrap_or(Value::Null));
            }
            self.keep(message);
        }
        Err(format!("no {method} within {:.0} s", timeout.as_secs_f64()))
    }

    /// The events received so far and not taken by [`Browser::wait_event`], oldest first; the
    /// queue is emptied.
    pub fn take_events(&mut self) -> Vec<Value> {
        self.events.drain(..).collect()
    }

    /// Reads the events that have already arrived without waiting, so that [`Browser::errors`]
    /// is up to date.
    pub fn poll_events(&mut self) -> Result<(), String> {
        while let Some(message) = self.receive(Instant::now() + Duration::from_millis(1))? {
            self.keep(message);
        }
        Ok(())
    }

    /// The page's console errors (`console.error`, `console.assert` failures, failed resource
    /// loads except the browser's own `/favicon.ico`) and uncaught exceptions (including unhandled promise rejections) seen so far, as
    /// text. Events are read as replies are waited for; call [`Browser::poll_events`] first to
    /// catch up.
    pub fn errors(&self) -> Vec<String> {
        self.errors.clone()
    }

    /// Forgets the errors seen so far.
    pub fn clear_errors(&mut self) {
        self.errors.clear();
    }

    /// Loads `url` in the page and waits for its load event.
    pub fn navigate(&mut self, url: &str) -> Result<(), String> {
        // A load event left from an earlier page must not count.
        self.events.retain(|event| {
            event.get("method").and_then(Value::as_str) != Some("Page.loadEventFired")
        });
        let result = self.call("Page.navigate", json!({"url": url}))?;
        if let Some(error) = result.get("errorText").and_then(Value::as_str) {
            return Err(format!("cannot load {url}: {error}"));
        }
        let timeout = self.timeout;
        self.wait_event("Page.loadEventFired", timeout)
            .map(drop)
            .map_err(|e| format!("loading {url}: {e}"))
    }

    /// Evaluates the expression `js` in the page (a promise is awaited) and returns its value as
    /// JSON (`null` for `undefined` and for values JSON cannot hold). A thrown exception becomes
    /// `Err` with its message.
    pub fn eval(&mut self, js: &str) -> Result<Value, String> {
        let reply = self.call(
            "Runtime.evaluate",
            json!({"expression": js, "awaitPromise": true, "returnByValue": true}),
        )?;
        if let Some(details) = reply.get("exceptionDetails") {
            return Err(format!("{}: {}", short(js), exception_text(details)));
        }
        Ok(reply
            .get("result")
            .and_then(|result| result.get("value"))
            .cloned()
            .unwrap_or(Value::Null))
    }

    /// Evaluates `js_condition` every 50 ms until its value is truthy (as in JavaScript) and
    /// returns that value. An exception counts as "not yet" (the page may not have defined what
    /// the condition looks at); the last one is in the message if time runs out.
    pub fn wait_for(&mut self, js_condition: &str, timeout: Duration) -> Result<Value, String> {
        let deadline = Instant::now() + timeout;
        loop {
            let last = match self.eval(js_condition) {
                Ok(value) if truthy(&value) => return Ok(value),
                Ok(value) => format!("last value {value}"),
                Err(error) => format!("last error {error}"),
            };
            if Instant::now() >= deadline {
                return Err(format!(
                    "{} not true within {:.1} s ({last})",
                    short(js_condition),
                    timeout.as_secs_f64()
                ));
            }
            thread::sleep(Duration::from_millis(50));
        }
    }

    /// Sets the value of the `<input>` (a slider, a text box) that `selector` finds and fires its
    /// `input` and `change` events, as a user's edit does.
    pub fn set_input(&mut self, selector: &str, value: &str) -> Result<(), String> {
        let js = format!(
            "(() => {{ const e = document.querySelector({sel}); if (!e) throw new Error('no ' + {sel}); \
             e.value = {value}; e.dispatchEvent(new Event('input', {{bubbles: true}})); \
             e.dispatchEvent(new Event('change', {{bubbles: true}})); return e.value; }})()",
            sel = Value::from(selector),
            value = Value::from(value),
        );
        self.eval(&js).map(drop)
    }

    /// The centre of the element that `selector` finds, in viewport pixels (for the mouse).
    pub fn center_of(&mut self, selector: &str) -> Result<(f64, f64), String> {
        let js = format!(
            "(() => {{ const e = document.querySelector({sel}); if (!e) throw new Error('no ' + {sel}); \
             const r = e.getBoundingClientRect(); return [r.left + r.width / 2, r.top + r.height / 2]; }})()",
            sel = Value::from(selector),
        );
        let value = self.eval(&js)?;
        match (value[0].as_f64(), value[1].as_f64()) {
            (Some(x), Some(y)) => Ok((x, y)),
            _ => Err(format!("the centre of {selector} is not a point: {value}")),
        }
    }

    /// Dispatches one mouse event at `(x, y)` (viewport pixels): `kind` is `mouseMoved`,
    /// `mousePressed` or `mouseReleased`; `button` is the button pressed or released
    /// ([`Button::None`] for a move). The buttons held down are tracked, so that moves between a
    /// press and a release are drags (`MouseEvent.buttons` set).
    pub fn mouse(&mut self, kind: &str, x: f64, y: f64, button: Button) -> Result<(), String> {
        // The DOM's `buttons` of a press includes the button, of a release no longer does.
        let buttons = match kind {
            "mousePressed" => self.buttons | button.bit(),
            "mouseReleased" => self.buttons & !button.bit(),
            "mouseMoved" => self.buttons,
            _ => return Err(format!("unknown mouse event kind {kind:?}")),
        };
        let click_count = if kind == "mouseMoved" { 0 } else { 1 };
        self.call(
            "Input.dispatchMouseEvent",
            json!({
                "type": kind, "x": x, "y": y, "button": button.name(),
                "buttons": buttons, "clickCount": click_count,
            }),
        )?;
        self.buttons = buttons;
        Ok(())
    }

    /// Drags with the left button from `from` to `to`: press at `from`, `steps` moves along the
    /// straight line (at least one), release at `to`.
    pub fn drag(&mut self, from: (f64, f64), to: (f64, f64), steps: usize) -> Result<(), String> {
        self.drag_with(Button::Left, from, to, steps)
    }

    /// [`Browser::drag`] with any button (the right one pans in three.js's orbit controls).
    pub fn drag_with(
        &mut self,
        button: Button,
        from: (f64, f64),
        to: (f64, f64),
        steps: usize,
    ) -> Result<(), String> {
        self.mouse("mouseMoved", from.0, from.1, Button::None)?;
        self.mouse("mousePressed", from.0, from.1, button)?;
        let steps = steps.max(1);
        for step in 1..=steps {
            let t = step as f64 / steps as f64;
            let x = from.0 + (to.0 - from.0) * t;
            let y = from.1 + (to.1 - from.1) * t;
            self.mouse("mouseMoved", x, y, Button::None)?;
        }
        self.mouse("mouseReleased", to.0, to.1, button)
    }

    /// A left click at `at`.
    pub fn click(&mut self, at: (f64, f64)) -> Result<(), String> {
        self.mouse("mouseMoved", at.0, at.1, Button::None)?;
        self.mouse("mousePressed", at.0, at.1, Button::Left)?;
        self.mouse("mouseReleased", at.0, at.1, Button::Left)
    }

    /// Turns the mouse wheel at `at` by `delta_y` pixels (positive: down, which zooms out in
    /// three.js's orbit controls).
    pub fn wheel(&mut self, at: (f64, f64), delta_y: f64) -> Result<(), String> {
        self.call(
            "Input.dispatchMouseEvent",
            json!({"type": "mouseWheel", "x": at.0, "y": at.1, "deltaX": 0, "deltaY": delta_y}),
        )
        .map(drop)
    }

    /// A PNG screenshot of the viewport.
    pub fn screenshot_png(&mut self) -> Result<Vec<u8>, String> {
        let result = self.call("Page.captureScreenshot", json!({"format": "png"}))?;
        let data = result.get("data").and_then(Value::as_str).ok_or_else(|| {
            format!(
                "Page.captureScreenshot: no data in {}",
                short(&result.to_string())
            )
        })?;
        base64::engine::general_purpose::STANDARD
            .decode(data)
            .map_err(|e| format!("Page.captureScreenshot: bad base64: {e}"))
    }

    /// Chromium's own output so far (its stderr and stdout), for a failing test's message.
    pub fn log(&self) -> String {
        std::fs::read_to_string(self.dir.path().join("chromium.log")).unwrap_or_default()
    }

    /// The next message from the page, `None` if `deadline` passes first.
    fn receive(&mut self, deadline: Instant) -> Result<Option<Value>, String> {
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(None);
            }
            self.socket
                .get_ref()
                .set_read_timeout(Some(left))
                .map_err(|e| format!("cannot set the socket's timeout: {e}"))?;
            let message = match self.socket.read() {
                Ok(message) => message,
                Err(tungstenite::Error::Io(e))
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    // tungstenite keeps a partly read frame; the next read goes on with it.
                    return Ok(None);
                }
                Err(e) => return Err(format!("reading from Chromium: {e}")),
            };
            match message {
                Message::Text(text) => {
                    return serde_json::from_str(text.as_str())
                        .map(Some)
                        .map_err(|e| format!("Chromium sent bad JSON ({e}): {}", short(&text)));
                }
                Message::Close(frame) => {
                    return Err(format!("Chromium closed the connection: {frame:?}"));
                }
                // Pings are answered by tungstenite; CDP sends no binary messages.
                _ => continue,
            }
        }
    }

    /// Queues an event (a message that is not the reply waited for).
    fn keep(&mut self, event: Value) {
        self.record(&event);
        if self.events.len() == MAX_EVENTS {
            self.events.pop_front();
        }
        self.events.push_back(event);
    }

    /// Notes the errors an event reports.
    fn record(&mut self, event: &Value) {
        let params = &event["params"];
        match event.get("method").and_then(Value::as_str) {
            Some("Runtime.consoleAPICalled")
                if matches!(params["type"].as_str(), Some("error" | "assert")) =>
            {
                let args: Vec<String> = params["args"]
                    .as_array()
                    .map(|args| args.iter().map(remote_object_text).collect())
                    .unwrap_or_default();
                let frame = &params["stackTrace"]["callFrames"][0];
                let at = match frame["url"].as_str().filter(|url| !url.is_empty()) {
                    Some(url) => format!(
                        " ({url}:{})",
                        frame["lineNumber"].as_i64().unwrap_or(-1) + 1
                    ),
                    None => String::new(),
                };
                self.errors.push(format!(
                    "console.{}: {}{at}",
                    params["type"].as_str().unwrap_or(""),
                    args.join(" ")
                ));
            }
            Some("Runtime.exceptionThrown") => {
                // "Uncaught" or "Uncaught (in promise)", then the exception.
                let details = &params["exceptionDetails"];
                self.errors.push(format!(
                    "{}: {}",
                    details["text"].as_str().unwrap_or("exception"),
                    exception_text(details)
                ));
            }
            // The browser asks every site for `/favicon.ico` on its own; a server without one is
            // not the page's error.
            Some("Log.entryAdded")
                if params["entry"]["level"].as_str() == Some("error")
                    && !params["entry"]["url"]
                        .as_str()
                        .is_some_and(|url| url.ends_with("/favicon.ico")) =>
            {
                let entry = &params["entry"];
                let url = entry["url"]
                    .as_str()
                    .map(|url| format!(" ({url})"))
                    .unwrap_or_default();
                self.errors.push(format!(
                    "{}: {}{url}",
                    entry["source"].as_str().unwrap_or("log"),
                    entry["text"].as_str().unwrap_or("")
                ));
            }
            _ => {}
        }
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        // Closing through CDP lets Chromium end its renderer and GPU processes before the profile
        // directory is removed; a kill is the fallback.
        self.timeout = Duration::from_secs(5);
        let _ = self.call("Browser.close", json!({}));
        stop(&mut self.child, Duration::from_secs(10));
    }
}

/// Chromium until its page is connected: killed if the launch fails.
struct Starting {
    child: Option<Child>,
    log: PathBuf,
}

impl Starting {
    /// `message`, with Chromium's exit status if it has ended and the end of its output.
    fn failed(&mut self, message: String) -> String {
        let status = match self.child.as_mut().map(Child::try_wait) {
            Some(Ok(Some(status))) => format!("; Chromium exited ({status})"),
            _ => String::new(),
        };
        let log = std::fs::read_to_string(&self.log).unwrap_or_default();
        let tail: Vec<&str> = log.lines().rev().take(20).collect();
        let tail: Vec<&str> = tail.into_iter().rev().collect();
        if tail.is_empty() {
            format!("{message}{status}; it printed nothing")
        } else {
            format!("{message}{status}; its output ends:\n{}", tail.join("\n"))
        }
    }

    /// Fails if Chromium has exited.
    fn check_running(&mut self) -> Result<(), String> {
        match self.child.as_mut().map(Child::try_wait) {
            Some(Ok(None)) => Ok(()),
            _ => Err(self.failed("Chromium ended during its start".into())),
        }
    }

    /// The debugging port, read from the `DevToolsActivePort` file Chromium writes.
    fn port(&mut self, file: &Path, deadline: Instant) -> Result<u16, String> {
        loop {
            // The first line is the port, the second the browser target's path; the file may be
            // seen half written.
            if let Ok(text) = std::fs::read_to_string(file)
                && text.lines().count() >= 2
                && let Some(Ok(port)) = text.lines().next().map(|line| line.trim().parse())
            {
                return Ok(port);
            }
            self.check_running()?;
            if Instant::now() >= deadline {
                let message = format!(
                    "Chromium wrote no {} within {} s",
                    file.display(),
                    LAUNCH_TIMEOUT.as_secs()
                );
                return Err(self.failed(message));
            }
            thread::sleep(Duration::from_millis(50));
        }
    }

    /// The websocket address of the page target, from `/json/list`.
    fn page_url(&mut self, port: u16, deadline: Instant) -> Result<String, String> {
        loop {
            let last = match http_get(port, "/json/list") {
                Ok(body) => match serde_json::from_str::<Value>(&body) {
                    Ok(targets) => {
                        let page = targets.as_array().and_then(|targets| {
                            targets.iter().find_map(|target| {
                                (target["type"].as_str() == Some("page"))
                                    .then(|| target["webSocketDebuggerUrl"].as_str())
                                    .flatten()
                            })
                        });
                        if let Some(url) = page {
                            return Ok(url.to_string());
                        }
                        format!("no page among {}", short(&body))
                    }
                    Err(e) => format!("bad JSON ({e}): {}", short(&body)),
                },
                Err(e) => e,
            };
            self.check_running()?;
            if Instant::now() >= deadline {
                return Err(self.failed(format!("GET /json/list on port {port}: {last}")));
            }
            thread::sleep(Duration::from_millis(100));
        }
    }
}

impl Drop for Starting {
    fn drop(&mut self) {
        if let Some(child) = self.child.as_mut() {
            stop(child, Duration::ZERO);
        }
    }
}

/// Waits up to `grace` for `child` to end, then kills it and reaps it.
fn stop(child: &mut Child, grace: Duration) {
    let deadline = Instant::now() + grace;
    while Instant::now() < deadline {
        if let Ok(Some(_)) = child.try_wait() {
            return;
        }
        thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let _ = child.wait();
}

/// The body of `GET http://127.0.0.1:port/path`, which must answer 200.
fn http_get(port: u16, path: &str) -> Result<String, String> {
    let address = SocketAddr::from(([127, 0, 0, 1], port));
    let timeout = Duration::from_secs(10);
    let mut stream = TcpStream::connect_timeout(&address, timeout)
        .map_err(|e| format!("cannot connect to {address}: {e}"))?;
    stream
        .set_read_timeout(Some(timeout))
        .and_then(|()| stream.set_write_timeout(Some(timeout)))
        .map_err(|e| format!("cannot set the timeouts: {e}"))?;
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
    )
    .map_err(|e| format!("cannot send GET {path}: {e}"))?;
    // Read the head, then the body by its Content-Length (or to the end without one).
    let mut data = Vec::new();
    let mut buffer = [0u8; 8192];
    let mut body_start = None;
    loop {
        if let Some(start) = body_start {
            let head = String::from_utf8_lossy(&data[..start]);
            let length = head.lines().find_map(|line| {
                let (name, value) = line.split_once(':')?;
                name.trim()
                    .eq_ignore_ascii_case("content-length")
                    .then(|| value.trim().parse::<usize>().ok())
                    .flatten()
            });
            if length.is_some_and(|length| data.len() - start >= length) {
                break;
            }
        }
        let read = stream
            .read(&mut buffer)
            .map_err(|e| format!("reading the answer to GET {path}: {e}"))?;
        if read == 0 {
            break;
        }
        data.extend_from_slice(&buffer[..read]);
        if body_start.is_none() {
            body_start = data
                .windows(4)
                .position(|w| w == b"\r\n\r\n")
                .map(|at| at + 4);
        }
    }
    let start = body_start.ok_or_else(|| format!("GET {path}: no complete HTTP answer"))?;
    let head = String::from_utf8_lossy(&data[..start]);
    let status = head.lines().next().unwrap_or("");
    if status.split_whitespace().nth(1) != Some("200") {
        return Err(format!("GET {path}: {status}"));
    }
    String::from_utf8(data[start..].to_vec()).map_err(|e| format!("GET {path}: not UTF-8: {e}"))
}

/// What a screenshot looks like, in numbers: enough to tell a blank page from a drawn one.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageStats {
    pub width: u32,
    pub height: u32,
    /// The number of distinct colours (RGBA).
    pub colours: usize,
    /// The most common colour (RGBA), taken as the background.
    pub background: [u8; 4],
    /// The fraction of pixels whose colour is not `background`, in `[0, 1]`.
    pub non_background: f64,
}

/// Decodes `png` and counts its colours (see [`ImageStats`]).
pub fn png_stats(png: &[u8]) -> Result<ImageStats, String> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(png));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder
        .read_info()
        .map_err(|e| format!("not a PNG image: {e}"))?;
    let size = reader
        .output_buffer_size()
        .ok_or("the PNG image is too large to decode")?;
    let mut pixels = vec![0u8; size];
    let info = reader
        .next_frame(&mut pixels)
        .map_err(|e| format!("cannot decode the PNG image: {e}"))?;
    let channels = match info.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Err("the PNG palette was not expanded".into()),
    };
    let mut counts = std::collections::HashMap::<[u8; 4], usize>::new();
    let row_bytes = info.width as usize * channels;
    for row in pixels.chunks(info.line_size).take(info.height as usize) {
        for pixel in row[..row_bytes].chunks_exact(channels) {
            let rgba = match *pixel {
                [g] => [g, g, g, 255],
                [g, a] => [g, g, g, a],
                [r, g, b] => [r, g, b, 255],
                [r, g, b, a, ..] => [r, g, b, a],
                [] => [0; 4],
            };
            *counts.entry(rgba).or_default() += 1;
        }
    }
    let total = info.width as usize * info.height as usize;
    let (background, most) = counts
        .iter()
        .max_by_key(|(colour, count)| (**count, **colour))
        .map(|(colour, count)| (*colour, *count))
        .unwrap_or(([0; 4], 0));
    Ok(ImageStats {
        width: info.width,
        height: info.height,
        colours: counts.len(),
        background,
        non_background: if total == 0 {
            0.0
        } else {
            (total - most) as f64 / total as f64
        },
    })
}

/// JavaScript's truthiness of a JSON value.
pub fn truthy(value: &Value) -> bool {
    match value {
        Value::Null => false,
        Value::Bool(b) => *b,
        Value::Number(n) => n.as_f64().is_some_and(|n| n != 0.0 && !n.is_nan()),
        Value::String(s) => !s.is_empty(),
        Value::Array(_) | Value::Object(_) => true,
    }
}

/// An exception's message from CDP's `ExceptionDetails`: the exception's description (with its
/// stack) if there is one, else the details' text, and where it was thrown.
fn exception_text(details: &Value) -> String {
    let text = details["exception"]["description"]
        .as_str()
        .or_else(|| details["exception"]["value"].as_str())
        .or_else(|| details["text"].as_str())
        .unwrap_or("unknown exception");
    match details["url"].as_str().filter(|url| !url.is_empty()) {
        Some(url) => format!(
            "{text} ({url}:{}:{})",
            details["lineNumber"].as_i64().unwrap_or(-1) + 1,
            details["columnNumber"].as_i64().unwrap_or(-1) + 1
        ),
        None => text.to_string(),
    }
}

/// A CDP `RemoteObject` as `console.log` would print it, roughly.
fn remote_object_text(object: &Value) -> String {
    match object.get("value") {
        Some(Value::String(s)) => s.clone(),
        Some(value) => value.to_string(),
        None => object["description"]
            .as_str()
            .or_else(|| object["type"].as_str())
            .unwrap_or("?")
            .to_string(),
    }
}

/// `text` cut to 200 characters, for messages.
fn short(text: &str) -> String {
    match text.char_indices().nth(200) {
        Some((at, _)) => format!("{}…", &text[..at]),
        None => text.to_string(),
    }
}
