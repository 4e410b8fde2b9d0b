//! `zeroset studio`'s HTTP API against the real server on an ephemeral port: access control
//! (token, host, origin, sizes), clear 4xx errors, previews as well-formed binary meshes,
//! undo/redo, and the saved field and mesh byte-identical to `zeroset restore` and `zeroset
//! mesh` run with the command lines the studio prints.

mod common;

use common::studio::{Studio, parse_mesh};
use common::{sample, zeroset};

/// The bunny's ears (the README's example).
const EARS: &str = r#"{"mode":"protrusion","mask":[[-0.1,0.145,-0.07],[0.005,0.2,0.05]],"face":"-y","alpha":null}"#;

#[test]
fn the_token_is_required_and_other_origins_and_hosts_are_refused() {
    let studio = Studio::start([sample()]);
    // No token, a wrong one: 401 with a sentence.
    let none = studio.request("GET", "/api/state", &[], b"");
    assert_eq!(none.status, 401);
    assert!(none.error().contains("access token"), "{}", none.error());
    let wrong = studio.request("GET", "/api/state", &[("X-Zeroset-Token", "0123")], b"");
    assert_eq!(wrong.status, 401);
    let page = studio.request("GET", "/", &[], b"");
    assert_eq!(page.status, 401, "the page itself needs the token");
    // The token in the query (the printed address) or the header; the page's static files
    // (scripts, styles, three.js) need none, and no cookie is set.
    let page = studio.request("GET", &format!("/?token={}", studio.token), &[], b"");
    assert_eq!(page.status, 200);
    assert!(String::from_utf8_lossy(&page.body).contains("<canvas"));
    assert!(!page.headers.contains_key("set-cookie"));
    let script = studio.request("GET", "/assets/studio.js", &[], b"");
    assert_eq!(script.status, 200);
    assert!(script.headers["content-type"].starts_with("text/javascript"));
    assert_eq!(studio.get("/api/state").status, 200);
    let empty = studio.request("GET", "/api/state", &[("X-Zeroset-Token", "")], b"");
    assert_eq!(empty.status, 401);
    // Another origin, another Host (DNS rebinding), a cross-site fetch: 403 even with the token.
    let token = studio.token.clone();
    let origin = studio.request(
        "GET",
        "/api/state",
        &[
            ("X-Zeroset-Token", &token),
            ("Origin", "http://evil.example"),
        ],
        b"",
    );
    assert_eq!(origin.status, 403);
    assert!(
        origin.error().contains("cross-origin"),
        "{}",
        origin.error()
    );
    let same_origin = studio.request(
        "GET",
        "/api/state",
        &[("X-Zeroset-Token", &token), ("Origin", &studio.base())],
        b"",
    );
    assert_eq!(same_origin.status, 200);
    let host = studio.request(
        "GET",
        "/api/state",
        &[("X-Zeroset-Token", &token), ("Host", "evil.example")],
        b"",
    );
    assert_eq!(host.status, 403);
    let site = studio.request(
        "GET",
        "/api/state",
        &[
            ("X-Zeroset-Token", &token),
            ("Sec-Fetch-Site", "cross-site"),
        ],
        b"",
    );
    assert_eq!(site.status, 403);
    // ...but the page itself opens from anywhere with its token: the browser's start page is a
    // local file, whose redirect Chromium marks cross-site. Only a navigation, only the page.
    let navigate = [
        ("Sec-Fetch-Site", "cross-site"),
        ("Sec-Fetch-Mode", "navigate"),
        ("Sec-Fetch-Dest", "document"),
    ];
    let opened = studio.request("GET", &format!("/?token={token}"), &navigate, b"");
    assert_eq!(opened.status, 200);
    let api = studio.request("GET", &format!("/api/state?token={token}"), &navigate, b"");
    assert_eq!(api.status, 403);
    let no_token = studio.request("GET", "/", &navigate, b"");
    assert_eq!(no_token.status, 401);
    // Refusals carry the same protective headers as answers.
    assert_eq!(api.headers["x-frame-options"], "DENY");
    assert_eq!(no_token.headers["cache-control"], "no-store");
    // Paths: only the fixed asset table; no file-system path is reachable.
    for path in [
        "/assets/../Cargo.toml",
        "/assets/%2e%2e%2fCargo.toml",
        "/etc/passwd",
        "/api/nothing",
    ] {
        assert_eq!(studio.get(path).status, 404, "{path}");
    }
}

#[test]
fn bad_requests_get_4xx_with_a_message() {
    let studio = Studio::start([sample()]);
    let token = studio.token.clone();
    let cases = [
        ("{\"mode\":\"protrusion\",\"mask\":", 400, "malformed JSON"),
        (
            r#"{"mode":"sculpt","mask":[[0,0,0],[1,1,1]]}"#,
            400,
            "unknown variant",
        ),
        (
            r#"{"mode":"protrusion","mask":[[-0.1,0.145,-0.07],[0.005,0.2,0.05]],"coarse":[2,2,2]}"#,
            400,
            "unknown field",
        ),
        (
            r#"{"mode":"protrusion","mask":[[-0.1,0.145,-0.07],[0.005,0.2,0.05]],"alpha":2}"#,
            400,
            "give a face",
        ),
        (
            r#"{"mode":"protrusion","mask":[[-6,0.145,-0.065],[-5,0.2,0.04]],"face":"-y"}"#,
            400,
            "the mask must lie in the field's box",
        ),
        (
            r#"{"mode":"protrusion","mask":[[-0.095,0.145,-0.065],[0,0.2,0.04]],"face":"up"}"#,
            400,
            "a face is +x",
        ),
        (
            r#"{"mode":"denoise","mask":[[-0.095,0.145,-0.065],[0,0.2,0.04]],"coarse":[100000000000,4,4]}"#,
            400,
            "coarse",
        ),
        (
            r#"{"mode":"denoise","mask":[[-0.095,0.145,-0.065],[0,0.2,0.04]],"coarse":[0,4,4]}"#,
            400,
            "at least 1",
        ),
    ];
    for (body, status, needle) in cases {
        let answer = studio.post("/api/preview", body);
        assert_eq!(answer.status, status, "{body}: {}", answer.error());
        assert!(
            answer.error().contains(needle),
            "{body}: {:?} does not say {needle:?}",
            answer.error()
        );
    }
    // An α that overflows the restored field: previewed, but not committed.
    let huge = r#"{"mode":"protrusion","mask":[[-0.1,0.145,-0.07],[0.005,0.2,0.05]],"face":"-y","alpha":1e308}"#;
    let overflow = studio.post("/api/apply", huge);
    assert_eq!(overflow.status, 400);
    assert!(
        overflow.error().contains("overflows"),
        "{}",
        overflow.error()
    );
    assert_eq!(studio.get("/api/state").json()["position"], 0);
    // Not JSON, too large, nothing to undo, nothing to save.
    let form = studio.request(
        "POST",
        "/api/preview",
        &[
            ("X-Zeroset-Token", &token),
            ("Content-Type", "application/x-www-form-urlencoded"),
        ],
        b"mode=protrusion",
    );
    assert_eq!(form.status, 415);
    let huge = vec![b' '; 200_000];
    let large = studio.request(
        "POST",
        "/api/preview",
        &[
            ("X-Zeroset-Token", &token),
            ("Content-Type", "application/json"),
        ],
        &huge,
    );
    assert_eq!(large.status, 413);
    assert!(large.error().contains("65536"), "{}", large.error());
    assert_eq!(studio.post("/api/undo", "").status, 409);
    assert_eq!(studio.post("/api/redo", "").status, 409);
    let save = studio.post("/api/save", r#"{"mesh":false}"#);
    assert_eq!(save.status, 409);
    assert!(save.error().contains("-o"), "{}", save.error());
    assert_eq!(studio.get("/api/preview").status, 405);
}

#[test]
fn previews_are_well_formed_meshes_and_undo_redo_walk_the_history() {
    let studio = Studio::start([sample()]);
    let state = studio.get("/api/state").json();
    assert_eq!(state["grid"]["counts"], serde_json::json!([64, 63, 53]));
    assert_eq!(state["points"], 2000);
    let points = studio.get("/api/points");
    assert_eq!(&points.body[..8], b"ZSP1\xd0\x07\0\0");
    assert_eq!(points.body.len(), 8 + 12 * 2000);

    let before = parse_mesh(&studio.get("/api/mesh").body);
    let preview = studio.post("/api/preview", EARS);
    assert_eq!(preview.status, 200);
    assert_eq!(preview.headers["content-type"], "application/octet-stream");
    let after = parse_mesh(&preview.body);
    // Every index names a vertex, every normal is a unit vector, positions are centred.
    for mesh in [&before, &after] {
        let v = mesh.positions.len() as u32;
        assert!(mesh.triangles.iter().flatten().all(|&i| i < v));
        for n in &mesh.normals {
            let len = n.iter().map(|&c| (c as f64 / 32767.0).powi(2)).sum::<f64>();
            assert!((len.sqrt() - 1.0).abs() < 1e-3, "normal {n:?}");
        }
        let far = mesh
            .positions
            .iter()
            .flatten()
            .fold(0f32, |m, c| m.max(c.abs()));
        assert!(far < 0.1, "positions are relative to the box centre: {far}");
    }
    // Removing the ears removes surface: fewer triangles, and far fewer vertices up where the
    // ears were (world y above 0.16).
    assert!(after.triangles.len() < before.triangles.len());
    let offset_y = state["offset"][1].as_f64().unwrap() as f32;
    let high = |m: &common::studio::WireMesh| {
        m.positions
            .iter()
            .filter(|p| p[1] + offset_y > 0.16)
            .count()
    };
    assert!(
        2 * high(&after) < high(&before),
        "{} vertices above the head after, {} before",
        high(&after),
        high(&before)
    );
    // The ears go whole: one surface is left (the mask encloses them with cells to spare); a
    // speck of a few vertices where the slope condition meets the head is not an ear.
    assert_eq!(pieces(&before, 20), 1);
    assert_eq!(pieces(&after, 20), 1, "pieces of the ears stayed behind");
    let alpha = after.report["alpha_used"].as_f64().unwrap();
    assert_eq!(after.report["default_alpha"].as_f64(), Some(alpha));
    let range = after.report["alpha_range"].as_array().unwrap();
    let (lo, hi) = (range[0].as_f64().unwrap(), range[1].as_f64().unwrap());
    assert!(lo < alpha && alpha < hi);
    // The default here is near 0 (the ears' own cross-section): the slider still reaches the
    // α that flattens, a few times the field's slope (±8|α₀| alone was ±0.3).
    assert!(hi >= 3.0 && lo == -hi, "{range:?}");
    // With α given, the default is still reported (the slider's mark).
    let flat = parse_mesh(
        &studio
            .post(
                "/api/preview",
                &EARS.replace("\"alpha\":null", "\"alpha\":1.5"),
            )
            .body,
    );
    assert_eq!(flat.report["alpha_used"], 1.5);
    assert_eq!(flat.report["default_alpha"].as_f64(), Some(alpha));
    // A preview commits nothing; apply does; undo and redo walk back and forth.
    assert_eq!(studio.get("/api/state").json()["position"], 0);
    let state = studio.post("/api/apply", EARS).json();
    assert_eq!(
        (state["position"].as_u64(), state["can_undo"].as_bool()),
        (Some(1), Some(true))
    );
    let committed = parse_mesh(&studio.get("/api/mesh").body);
    assert_eq!(committed.triangles.len(), after.triangles.len());
    let state = studio.post("/api/undo", "").json();
    assert_eq!(
        (state["position"].as_u64(), state["can_redo"].as_bool()),
        (Some(0), Some(true))
    );
    let undone = parse_mesh(&studio.get("/api/mesh").body);
    assert!(undone.triangles == before.triangles && undone.positions == before.positions);
    studio.post("/api/redo", "");
    let redone = parse_mesh(&studio.get("/api/mesh").body);
    assert!(redone.triangles == committed.triangles && redone.positions == committed.positions);
}

/// The number of connected pieces of a mesh (triangles sharing vertices) with at least
/// `min_vertices` vertices, by union-find.
fn pieces(mesh: &common::studio::WireMesh, min_vertices: usize) -> usize {
    let mut parent: Vec<usize> = (0..mesh.positions.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for t in &mesh.triangles {
        for k in 1..3 {
            let (a, b) = (
                root(&mut parent, t[0] as usize),
                root(&mut parent, t[k] as usize),
            );
            parent[a] = b;
        }
    }
    let used: std::collections::HashSet<u32> = mesh.triangles.iter().flatten().copied().collect();
    let mut sizes = std::collections::HashMap::<usize, usize>::new();
    for i in used {
        *sizes.entry(root(&mut parent, i as usize)).or_default() += 1;
    }
    sizes.values().filter(|&&n| n >= min_vertices).count()
}

/// Splits a command line the studio printed (no quoting: the test's paths have no spaces).
fn words(line: &str) -> Vec<String> {
    assert!(!line.contains('\''), "{line}");
    line.split_whitespace().skip(1).map(str::to_owned).collect()
}

#[test]
fn saved_field_and_mesh_equal_the_cli_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("studio.zsf");
    let studio = Studio::start([sample().as_os_str(), "-o".as_ref(), out.as_os_str()]);
    // Two restorations that compose: the ears with an α no decimal rounds exactly, then a
    // de-noise of the back with point resampling.
    let ears = EARS.replace("\"alpha\":null", "\"alpha\":0.7312345678901234");
    assert_eq!(studio.post("/api/apply", &ears).status, 200);
    let back = r#"{"mode":"denoise","mask":[[-0.05,0.05,-0.03],[0.05,0.12,0.06]],"coarse":[6,6,4],"resampling":"point"}"#;
    let state = studio.post("/api/apply", back).json();
    let saved = studio.post("/api/save", r#"{"mesh":true}"#);
    assert_eq!(saved.status, 200, "{}", saved.error());
    let saved = saved.json();
    let mesh_path = dir.path().join("studio.ply");
    assert_eq!(saved["mesh"].as_str(), Some(mesh_path.to_str().unwrap()));

    // The CLI, run with the printed command lines (renamed into a directory of its own).
    let commands: Vec<String> = state["commands"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap().to_owned())
        .collect();
    assert_eq!(commands.len(), 2, "{commands:?}");
    assert!(
        commands[0].contains("--alpha 0.7312345678901234"),
        "{}",
        commands[0]
    );
    assert!(
        commands[1].contains("--point-resampling"),
        "{}",
        commands[1]
    );
    let cli_dir = tempfile::tempdir().unwrap();
    let from = dir.path().to_str().unwrap();
    let to = cli_dir.path().to_str().unwrap();
    for line in &commands {
        let out = zeroset(words(&line.replace(from, to)));
        assert!(
            out.status.success(),
            "{line}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let cli = std::fs::read(cli_dir.path().join("studio.zsf")).unwrap();
    assert_eq!(
        std::fs::read(&out).unwrap(),
        cli,
        "the saved field differs from the CLI's"
    );
    let cli_mesh = cli_dir.path().join("cli.ply");
    let meshed = zeroset([
        "mesh".as_ref(),
        cli_dir.path().join("studio.zsf").as_os_str(),
        "-o".as_ref(),
        cli_mesh.as_os_str(),
    ]);
    assert!(meshed.status.success());
    assert_eq!(
        std::fs::read(&mesh_path).unwrap(),
        std::fs::read(&cli_mesh).unwrap(),
        "the saved mesh differs from zeroset mesh's"
    );

    // Saving without the mesh says that the one beside it is an earlier state's.
    assert_eq!(studio.post("/api/undo", "{}").status, 200);
    let saved = studio.post("/api/save", r#"{"mesh":false}"#).json();
    assert_eq!(saved["mesh"], serde_json::Value::Null);
    assert_eq!(
        saved["stale_mesh"].as_str(),
        Some(mesh_path.to_str().unwrap())
    );
    // A mesh that cannot be written replaces neither file.
    let field_before = std::fs::read(&out).unwrap();
    std::fs::remove_file(&mesh_path).unwrap();
    std::fs::create_dir(&mesh_path).unwrap();
    std::fs::write(mesh_path.join("keep"), b"").unwrap();
    assert_eq!(studio.post("/api/redo", "{}").status, 200);
    let failed = studio.post("/api/save", r#"{"mesh":true}"#);
    assert_eq!(failed.status, 500);
    assert!(
        failed.error().contains("was not replaced"),
        "{}",
        failed.error()
    );
    assert_eq!(std::fs::read(&out).unwrap(), field_before);
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n.to_string_lossy().starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[cfg(unix)]
#[test]
fn ctrl_c_stops_the_server_cleanly() {
    let studio = Studio::start([sample()]);
    assert_eq!(studio.get("/api/state").status, 200);
    // A client that never finishes its request does not keep the server alive.
    let mut half = std::net::TcpStream::connect(&studio.addr).unwrap();
    std::io::Write::write_all(&mut half, b"GET /api/state HTTP/1.1\r\n").unwrap();
    let start = std::time::Instant::now();
    let (status, rest) = studio.interrupt();
    assert!(
        start.elapsed().as_secs() < 20,
        "{:?} to stop",
        start.elapsed()
    );
    assert!(status.success(), "{status:?}");
    assert!(rest.contains("stopped"), "{rest}");
}

#[test]
fn a_connection_that_sends_nothing_is_closed() {
    use std::io::Read;
    let studio = Studio::start([sample()]);
    let mut silent = std::net::TcpStream::connect(&studio.addr).unwrap();
    std::io::Write::write_all(&mut silent, b"GET /api/state HTTP/1.1\r\n").unwrap();
    silent
        .set_read_timeout(Some(std::time::Duration::from_secs(30)))
        .unwrap();
    let start = std::time::Instant::now();
    let mut rest = Vec::new();
    // Closed by the server (end of stream, perhaps after a 408): not by our 30 s timeout.
    let read = silent.read_to_end(&mut rest);
    let waited = start.elapsed();
    assert!(read.is_ok(), "{read:?} after {waited:?}");
    assert!(waited.as_secs() < 20, "{waited:?}");
    // Meanwhile, and after, the studio answers others.
    assert_eq!(studio.get("/api/state").status, 200);
}

#[test]
fn an_existing_output_needs_force_and_a_non_loopback_host_warns() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("taken.zsf");
    std::fs::write(&out, b"mine").unwrap();
    let refused = zeroset([
        "studio".as_ref(),
        sample().as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
        "--no-browser".as_ref(),
    ]);
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--force"));
    assert_eq!(std::fs::read(&out).unwrap(), b"mine");
    // Save's mesh goes beside the field as .ply: never over the input, even with --force.
    let ply = dir.path().join("scan.ply");
    std::fs::write(&ply, b"ply\nformat ascii 1.0\nend_header\n").unwrap();
    let clash = zeroset([
        "studio".as_ref(),
        ply.as_os_str(),
        "-o".as_ref(),
        dir.path().join("scan.zsf").as_os_str(),
        "--force".as_ref(),
        "--no-browser".as_ref(),
    ]);
    assert!(!clash.status.success());
    let err = String::from_utf8_lossy(&clash.stderr);
    assert!(err.contains("overwrite the input"), "{err}");
    assert_eq!(
        std::fs::read(&ply).unwrap(),
        b"ply\nformat ascii 1.0\nend_header\n"
    );

    let mut studio = std::process::Command::new(env!("CARGO_BIN_EXE_zeroset"))
        .args([
            "studio",
            sample().to_str().unwrap(),
            "--no-browser",
            "--port",
            "0",
        ])
        .args(["--host", "0.0.0.0"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = std::io::BufReader::new(studio.stderr.take().unwrap());
    let mut line = String::new();
    std::io::BufRead::read_line(&mut err, &mut line).unwrap();
    let _ = studio.kill();
    let _ = studio.wait();
    assert!(
        line.contains("warning") && line.contains("other machines"),
        "{line}"
    );
}
