//! `zeroset studio` in a real browser: headless Chromium (Debian's package; `.ci/run` installs
//! it) loads the page, sets the bunny's ear mask through the page's corner inputs and face
//! control, orbits the view, moves the α slider twenty times, applies and saves; the test checks
//! that every change reached the screen as a new mesh, that the page logged no error, and that
//! the screenshot is not blank. It prints the round trips (change → mesh on screen) the page
//! measured, as the closing note of issue 25 quotes them; they are reported, not asserted.
//!
//! Without Chromium the test says so and passes, unless `ZEROSET_REQUIRE_BROWSER=1` (CI sets it).
//! `ZEROSET_STUDIO_BIN` runs another `zeroset` binary (a release build, for timings);
//! `ZEROSET_BLESS=1` writes the screenshot to `docs/images/studio.png` for the README.

mod cdp;
mod common;

use std::ffi::OsString;
use std::time::Duration;

use common::sample;
use common::studio::Studio;

/// The page's frames so far.
fn frames(browser: &mut cdp::Browser) -> Vec<serde_json::Value> {
    browser
        .eval("JSON.stringify(window.studio.frames)")
        .ok()
        .and_then(|v| v.as_str().and_then(|s| serde_json::from_str(s).ok()))
        .unwrap_or_default()
}

/// Waits until the page has drawn a frame after the `seen` first ones for `trigger` and no
/// preview is pending; returns that frame.
fn wait_frame(browser: &mut cdp::Browser, seen: usize, trigger: &str) -> serde_json::Value {
    let condition = format!(
        "window.studio.frames.slice({seen}).some(f => f.trigger === {t}) \
         && !document.querySelector('#status').classList.contains('busy')",
        t = serde_json::Value::from(trigger)
    );
    browser
        .wait_for(&condition, Duration::from_secs(60))
        .unwrap_or_else(|e| panic!("no {trigger} frame: {e}; errors {:?}", browser.errors()));
    frames(browser)
        .into_iter()
        .skip(seen)
        .rfind(|f| f["trigger"] == trigger)
        .expect("the frame")
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    if n % 2 == 1 {
        xs[n / 2]
    } else {
        0.5 * (xs[n / 2 - 1] + xs[n / 2])
    }
}

/// The α round trips of a session (ms): change → mesh on screen, the server's part, and the
/// request's (server, transfer, parsing).
#[derive(Default)]
struct Trips {
    total: Vec<f64>,
    server: Vec<f64>,
    request: Vec<f64>,
    /// The last mesh's size.
    triangles: u64,
}

impl std::fmt::Display for Trips {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} triangles; median of {}: {:.0} ms on screen (min {:.0}, max {:.0}); request {:.0} ms, of \
             which server {:.0} ms",
            self.triangles,
            self.total.len(),
            median(self.total.clone()),
            self.total.iter().copied().fold(f64::INFINITY, f64::min),
            self.total.iter().copied().fold(0.0, f64::max),
            median(self.request.clone()),
            median(self.server.clone()),
        )
    }
}

/// Drives one studio session; returns the α round trips.
fn session(exe: &std::path::Path, extra: &[&str], screenshot: bool) -> Trips {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("no_ears.zsf");
    let mut args: Vec<OsString> = vec![sample().into(), "-o".into(), out.clone().into()];
    args.extend(extra.iter().map(OsString::from));
    let studio = match std::env::var_os("ZEROSET_STUDIO_BIN") {
        Some(bin) => Studio::start_with(&bin, &args),
        None => Studio::start(&args),
    };
    let mut browser = cdp::Browser::launch(exe, 1280, 800).expect("launching Chromium");
    browser
        .navigate(&format!("{}/?token={}", studio.base(), studio.token))
        .expect("loading the page");
    browser
        .wait_for(
            "window.studio && window.studio.frames.length > 0",
            Duration::from_secs(60),
        )
        .unwrap_or_else(|e| panic!("the page drew nothing: {e}; errors {:?}", browser.errors()));
    browser.eval("window.studio.ready").expect("ready");
    let renderer = browser
        .eval("window.studio.renderer")
        .expect("the renderer");
    // What the screen costs by itself here: a redraw of the scene and the frame that shows it.
    let redraw = browser
        .eval(
            "new Promise(done => { const t = performance.now(); \
             window.studio.redraw(); requestAnimationFrame(() => requestAnimationFrame(() => \
             done(performance.now() - t))); })",
        )
        .expect("timing a redraw")
        .as_f64()
        .unwrap_or(f64::NAN);
    println!("WebGL renderer: {renderer}; a redraw alone: {redraw:.0} ms");
    let first = frames(&mut browser);
    assert_eq!(first[0]["trigger"], "load");
    let original = first[0]["triangles"].as_u64().unwrap();
    assert!(original > 1000, "the bunny has {original} triangles");

    // The ears: the mask through the corner inputs, the face through its control.
    let seen = frames(&mut browser).len();
    for (id, value) in [
        ("#lo-x", "-0.1"),
        ("#lo-y", "0.145"),
        ("#lo-z", "-0.07"),
        ("#hi-x", "0.005"),
        ("#hi-y", "0.2"),
        ("#hi-z", "0.05"),
    ] {
        browser.set_input(id, value).unwrap();
    }
    browser.set_input("#face", "-y").unwrap();
    let masked = wait_frame(&mut browser, seen, "face");
    let no_ears = masked["triangles"].as_u64().unwrap();
    assert!(
        no_ears < original,
        "{no_ears} triangles with the ears removed, {original} with"
    );

    // Drag the mask's top handle down with the mouse and back up: the mask follows (its corner
    // input changes) and the surface is restored live while dragging.
    let top = browser.eval("window.studio.handleAt('+y')").unwrap();
    let (x, y) = (top[0].as_f64().unwrap(), top[1].as_f64().unwrap());
    let hi_y = |b: &mut cdp::Browser| {
        b.eval("Number(document.querySelector('#hi-y').value)")
            .unwrap()
            .as_f64()
            .unwrap()
    };
    let before_drag = hi_y(&mut browser);
    let seen = frames(&mut browser).len();
    browser.drag((x, y), (x, y + 40.0), 8).unwrap();
    wait_frame(&mut browser, seen, "mask");
    let dragged = hi_y(&mut browser);
    assert!(
        dragged < before_drag,
        "dragging the +y handle down moved the mask's top from {before_drag} to {dragged}"
    );
    let top = browser.eval("window.studio.handleAt('+y')").unwrap();
    let (x, y) = (top[0].as_f64().unwrap(), top[1].as_f64().unwrap());
    let seen = frames(&mut browser).len();
    browser.drag((x, y), (x, y - 40.0), 8).unwrap();
    wait_frame(&mut browser, seen, "mask");
    // Back where it was, give or take a cell of snapping.
    browser.set_input("#hi-y", "0.2").unwrap();

    // Orbit the view (a drag on the canvas, away from the mask's handles).
    let (cx, cy) = browser.center_of("#view").unwrap();
    browser
        .drag((cx - 200.0, cy + 150.0), (cx - 80.0, cy + 120.0), 8)
        .unwrap();

    // α: twenty values across the slider's range, each waited for.
    let (lo, hi) = {
        let r = browser
            .eval("[Number(document.querySelector('#alpha').min), Number(document.querySelector('#alpha').max)]")
            .unwrap();
        (r[0].as_f64().unwrap(), r[1].as_f64().unwrap())
    };
    assert!(lo < hi, "the α slider has a range: {lo} .. {hi}");
    let mut trips = Trips::default();
    let mut triangles = Vec::new();
    for i in 0..20 {
        let alpha = lo + (hi - lo) * (0.05 + 0.9 * i as f64 / 19.0);
        let seen = frames(&mut browser).len();
        browser.set_input("#alpha", &alpha.to_string()).unwrap();
        let frame = wait_frame(&mut browser, seen, "alpha");
        trips.total.push(frame["ms"].as_f64().unwrap());
        trips.server.push(frame["server_ms"].as_f64().unwrap());
        trips.request.push(frame["request_ms"].as_f64().unwrap());
        trips.triangles = frame["triangles"].as_u64().unwrap();
        triangles.push(frame["triangles"].as_u64().unwrap());
    }
    triangles.dedup();
    assert!(
        triangles.len() > 1,
        "α changed nothing on screen: {triangles:?}"
    );
    let state = browser.eval("window.studio.state").unwrap();
    assert_eq!(state["position"], 0, "previews commit nothing");

    if screenshot {
        // The picture for the README: the ears removed at the default α.
        let seen = frames(&mut browser).len();
        let reset = browser.center_of("#alpha-reset").unwrap();
        browser.click(reset).unwrap();
        wait_frame(&mut browser, seen, "alpha");
        let png = browser.screenshot_png().expect("screenshot");
        let stats = cdp::png_stats(&png).unwrap();
        assert_eq!((stats.width, stats.height), (1280, 800));
        assert!(
            stats.non_background > 0.2 && stats.colours > 50,
            "the screenshot looks blank: {stats:?}"
        );
        let shot = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("studio.png");
        std::fs::write(&shot, &png).unwrap();
        if std::env::var_os("ZEROSET_BLESS").is_some() {
            let docs = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/images/studio.png");
            std::fs::write(docs, &png).unwrap();
        }
        println!("screenshot {} ({stats:?})", shot.display());
    }

    // Apply, then Save with the mesh: both files appear, and the state has one step.
    let seen = frames(&mut browser).len();
    let apply = browser.center_of("#apply").unwrap();
    browser.click(apply).unwrap();
    wait_frame(&mut browser, seen, "apply");
    browser
        .eval("document.querySelector('#save-mesh').checked = true")
        .unwrap();
    let save = browser.center_of("#save").unwrap();
    browser.click(save).unwrap();
    let mesh = out.with_extension("ply");
    browser
        .wait_for(
            "(document.querySelector('#status').textContent || '').includes('no_ears.ply')",
            Duration::from_secs(60),
        )
        .unwrap_or_else(|e| {
            panic!(
                "save did not report the mesh: {e}; errors {:?}",
                browser.errors()
            )
        });
    assert!(out.is_file() && mesh.is_file());
    let state = browser.eval("window.studio.state").unwrap();
    assert_eq!(state["position"], 1);
    // The command line says what is on screen: the default α after the reset, else the slider's.
    let command = state["commands"][0].as_str().unwrap();
    assert!(command.contains("--face -y"), "{command}");
    assert_eq!(command.contains("--alpha"), !screenshot, "{command}");
    let errors = browser.errors();
    assert!(errors.is_empty(), "the page logged errors: {errors:?}");
    trips
}

#[test]
fn the_page_restores_live_in_a_real_browser() {
    let Some(exe) = cdp::chromium() else {
        assert!(
            std::env::var_os("ZEROSET_REQUIRE_BROWSER").is_none_or(|v| v != "1"),
            "ZEROSET_REQUIRE_BROWSER=1 but no Chromium was found (apt-get install chromium, or \
             set ZEROSET_CHROMIUM)"
        );
        println!("skipped: no Chromium (apt-get install chromium, or set ZEROSET_CHROMIUM)");
        return;
    };
    let default = session(&exe, &[], true);
    println!("alpha slider → mesh, default grid (64×63×53): {default}");
    let fine = session(&exe, &["--grid", "128,128,128"], false);
    println!("alpha slider → mesh, 128³: {fine}");
}
