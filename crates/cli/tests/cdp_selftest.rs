//! The CDP harness (`tests/cdp`) tried on a page of its own: a WebGL2 triangle and a slider,
//! served by a small HTTP server in the test. Skipped when no Chromium is found, unless
//! `ZEROSET_REQUIRE_BROWSER=1`.

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::thread;
use std::time::{Duration, Instant};

mod cdp;

/// The page: a WebGL2 canvas with a triangle whose colour follows the slider, and listeners that
/// count the mouse events the canvas gets.
const PAGE: &str = r#"<!doctype html>
<html><head><meta charset="utf-8"><title>cdp self-test</title>
<style>body { margin: 0; background: #fff } canvas { display: block }</style></head>
<body>
<canvas id="gl" width="400" height="300"></canvas>
<input id="alpha" type="range" min="0" max="1" step="0.01" value="0.5">
<script>
const state = { down: 0, up: 0, dragMoves: 0, downAt: null, upAt: null, inputs: 0, alpha: 0.5, drawn: 0 };
window.state = state;
const canvas = document.getElementById('gl');
canvas.addEventListener('mousedown', e => { state.down++; state.downAt = [e.clientX, e.clientY, e.button]; });
canvas.addEventListener('mousemove', e => { if (e.buttons & 1) state.dragMoves++; });
canvas.addEventListener('mouseup', e => { state.up++; state.upAt = [e.clientX, e.clientY, e.button]; });
const gl = canvas.getContext('webgl2');
function shader(kind, source) {
  const s = gl.createShader(kind);
  gl.shaderSource(s, source);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}
const program = gl.createProgram();
gl.attachShader(program, shader(gl.VERTEX_SHADER, `#version 300 es
in vec2 p; void main() { gl_Position = vec4(p, 0.0, 1.0); }`));
gl.attachShader(program, shader(gl.FRAGMENT_SHADER, `#version 300 es
precision mediump float; uniform float alpha; out vec4 colour;
void main() { colour = vec4(1.0, alpha, 0.2, 1.0); }`));
gl.linkProgram(program);
if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-0.8, -0.8, 0.8, -0.8, 0.0, 0.8]), gl.STATIC_DRAW);
const p = gl.getAttribLocation(program, 'p');
gl.enableVertexAttribArray(p);
gl.vertexAttribPointer(p, 2, gl.FLOAT, false, 0, 0);
function draw() {
  gl.clearColor(0.1, 0.2, 0.4, 1.0);
  gl.clear(gl.COLOR_BUFFER_BIT);
  gl.useProgram(program);
  gl.uniform1f(gl.getUniformLocation(program, 'alpha'), state.alpha);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  state.drawn++;
}
document.getElementById('alpha').addEventListener('input', e => {
  state.inputs++;
  state.alpha = Number(e.target.value);
  draw();
});
draw();
</script>
</body></html>
"#;

/// Serves [`PAGE`] at `/` (and 404 elsewhere) on a free port until the test ends; returns the
/// page's address.
fn serve() -> String {
    let listener = TcpListener::bind("127.0.0.1:0").expect("cannot bind a local port");
    let port = listener.local_addr().expect("no local address").port();
    thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            // A broken request only loses that request.
            let _ = answer(stream);
        }
    });
    format!("http://127.0.0.1:{port}/")
}

fn answer(stream: TcpStream) -> std::io::Result<()> {
    stream.set_read_timeout(Some(Duration::from_secs(10)))?;
    let mut reader = BufReader::new(stream);
    let mut request = String::new();
    reader.read_line(&mut request)?;
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line)? == 0 || line.trim().is_empty() {
            break;
        }
    }
    let path = request.split_whitespace().nth(1).unwrap_or("");
    let (status, kind, body) = if path == "/" {
        ("200 OK", "text/html; charset=utf-8", PAGE)
    } else {
        ("404 Not Found", "text/plain", "not found")
    };
    let mut stream = reader.into_inner();
    write!(
        stream,
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
}

#[test]
fn drives_a_webgl_page() {
    let Some(exe) = cdp::chromium() else {
        assert!(
            std::env::var_os("ZEROSET_REQUIRE_BROWSER").is_none_or(|v| v != "1"),
            "ZEROSET_REQUIRE_BROWSER=1 but Chromium is required and was not found \
             (set ZEROSET_CHROMIUM or install chromium)"
        );
        println!("cdp_selftest skipped: no Chromium found (set ZEROSET_CHROMIUM to run it)");
        return;
    };
    let url = serve();
    let (width, height) = (640, 480);

    let start = Instant::now();
    let mut browser = cdp::Browser::launch(&exe, width, height).unwrap();
    println!(
        "launch {} : {:.2} s",
        exe.display(),
        start.elapsed().as_secs_f64()
    );

    let start = Instant::now();
    browser.navigate(&url).unwrap();
    println!("navigate: {:.2} s", start.elapsed().as_secs_f64());
    assert_eq!(browser.eval("document.title").unwrap(), "cdp self-test");
    assert_eq!(
        browser
            .eval("!!document.createElement('canvas').getContext('webgl2')")
            .unwrap(),
        true,
        "no WebGL2 in headless Chromium"
    );
    let renderer = browser
        .eval(
            "(() => { const gl = document.createElement('canvas').getContext('webgl2'); \
             const info = gl.getExtension('WEBGL_debug_renderer_info'); \
             return info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER); })()",
        )
        .unwrap();
    println!("WebGL renderer: {renderer}");
    assert_eq!(
        browser
            .eval("window.innerWidth + 'x' + window.innerHeight")
            .unwrap(),
        format!("{width}x{height}")
    );

    // eval: promises are awaited, exceptions are errors (and not page errors).
    assert_eq!(
        browser
            .eval("new Promise(r => setTimeout(() => r(6 * 7), 10))")
            .unwrap(),
        42
    );
    let thrown = browser.eval("null.x").unwrap_err();
    assert!(thrown.contains("TypeError"), "{thrown}");
    assert_eq!(browser.eval("undefined").unwrap(), serde_json::Value::Null);
    // wait_for: a condition that throws at first, then holds.
    browser
        .eval("setTimeout(() => { window.later = 'ready'; }, 300); 0")
        .unwrap();
    assert_eq!(
        browser
            .wait_for(
                "window.later.length && window.later",
                Duration::from_secs(10)
            )
            .unwrap(),
        "ready"
    );
    let timed_out = browser
        .wait_for("false", Duration::from_millis(200))
        .unwrap_err();
    assert!(timed_out.contains("not true"), "{timed_out}");

    // The slider, set as a user would (its input event fires).
    browser.set_input("#alpha", "0.9").unwrap();
    let state = browser.eval("state").unwrap();
    assert_eq!(state["inputs"], 1, "{state}");
    assert_eq!(state["alpha"], 0.9, "{state}");
    assert_eq!(state["drawn"], 2, "{state}");

    // A drag on the canvas.
    let (cx, cy) = browser.center_of("#gl").unwrap();
    assert_eq!((cx, cy), (200.0, 150.0));
    let start = Instant::now();
    browser
        .drag((cx - 50.0, cy), (cx + 50.0, cy + 20.0), 10)
        .unwrap();
    println!("drag (12 events): {:.2} s", start.elapsed().as_secs_f64());
    let state = browser.eval("state").unwrap();
    assert_eq!(state["down"], 1, "{state}");
    assert_eq!(state["up"], 1, "{state}");
    assert_eq!(state["downAt"], serde_json::json!([150, 150, 0]), "{state}");
    assert_eq!(state["upAt"], serde_json::json!([250, 170, 0]), "{state}");
    assert!(state["dragMoves"].as_u64().unwrap_or(0) >= 9, "{state}");
    browser.click((cx, cy)).unwrap();
    let state = browser.eval("state").unwrap();
    assert_eq!(
        (&state["down"], &state["up"]),
        (&2.into(), &2.into()),
        "{state}"
    );

    browser.poll_events().unwrap();
    assert!(
        browser.errors().is_empty(),
        "page errors: {:?}",
        browser.errors()
    );

    let start = Instant::now();
    let png = browser.screenshot_png().unwrap();
    println!(
        "screenshot: {:.2} s, {} bytes",
        start.elapsed().as_secs_f64(),
        png.len()
    );
    let stats = cdp::png_stats(&png).unwrap();
    println!("{stats:?}");
    assert_eq!((stats.width, stats.height), (width, height));
    // White page, blue canvas (400×300 of 640×480) and an orange triangle: not blank.
    assert_eq!(stats.background, [255, 255, 255, 255], "{stats:?}");
    assert!(stats.colours >= 3, "{stats:?}");
    assert!(
        stats.non_background > 0.3 && stats.non_background < 0.5,
        "{stats:?}"
    );
    // A blank page says so.
    browser.eval("document.body.innerHTML = ''").unwrap();
    let blank = cdp::png_stats(&browser.screenshot_png().unwrap()).unwrap();
    assert_eq!((blank.colours, blank.non_background), (1, 0.0), "{blank:?}");

    // The page's errors are collected: console.error, uncaught exceptions, rejected promises,
    // failed loads.
    browser
        .eval(
            "console.error('bad', 7); setTimeout(() => { throw new Error('thrown later'); }); \
             Promise.reject(new Error('rejected')); fetch('/missing').catch(() => {}); 0",
        )
        .unwrap();
    browser
        .wait_for(
            "new Promise(r => setTimeout(() => r(true), 200))",
            Duration::from_secs(10),
        )
        .unwrap();
    browser.poll_events().unwrap();
    let errors = browser.errors();
    println!("collected errors: {errors:#?}");
    let has = |text: &str| errors.iter().any(|e| e.contains(text));
    assert!(has("console.error: bad 7"), "{errors:?}");
    assert!(has("thrown later"), "{errors:?}");
    assert!(has("rejected"), "{errors:?}");
    assert!(has("404"), "{errors:?}");
    browser.clear_errors();
    assert!(browser.errors().is_empty());

    let start = Instant::now();
    drop(browser);
    println!("close: {:.2} s", start.elapsed().as_secs_f64());
}
