//! A `zeroset studio` server for the tests: started on a free port without a browser, its
//! address read from the first line of its output, stopped when dropped; and a small HTTP/1.1
//! client on `std::net` (one request per connection).

use std::collections::HashMap;
use std::ffi::OsStr;
use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::net::TcpStream;
use std::process::{Child, ChildStdout, Command, Stdio};
use std::time::Duration;

/// A running studio.
pub struct Studio {
    child: Child,
    /// The rest of its standard output, after the address line.
    pub stdout: BufReader<ChildStdout>,
    /// `127.0.0.1:PORT`.
    pub addr: String,
    /// The access token.
    pub token: String,
}

/// An answer: status, headers (names lower-case), body.
pub struct Answer {
    pub status: u16,
    pub headers: HashMap<String, String>,
    pub body: Vec<u8>,
}

impl Answer {
    /// The body as JSON (panics with the body's text if it is not).
    pub fn json(&self) -> serde_json::Value {
        serde_json::from_slice(&self.body).unwrap_or_else(|e| {
            panic!(
                "not JSON ({e}): {}",
                String::from_utf8_lossy(&self.body[..self.body.len().min(300)])
            )
        })
    }

    /// The `error` sentence of a JSON error body.
    pub fn error(&self) -> String {
        self.json()["error"]
            .as_str()
            .unwrap_or_else(|| panic!("no error message in {:?}", self.json()))
            .to_owned()
    }
}

impl Studio {
    /// `zeroset studio ARGS --no-browser --port 0` (plus `binary`'s default: the test build).
    pub fn start<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> Studio {
        Self::start_with(env!("CARGO_BIN_EXE_zeroset").as_ref(), args)
    }

    /// As [`Studio::start`] with another `zeroset` binary (e.g. a release build).
    pub fn start_with<S: AsRef<OsStr>>(
        binary: &OsStr,
        args: impl IntoIterator<Item = S>,
    ) -> Studio {
        let mut child = Command::new(binary)
            .arg("studio")
            .args(args)
            .args(["--no-browser", "--port", "0"])
            .env("ZEROSET_CACHE_DIR", "")
            .env_remove("ZEROSET_MEMORY_LIMIT")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("cannot start zeroset studio");
        let mut stdout = BufReader::new(child.stdout.take().expect("stdout"));
        let mut first = String::new();
        stdout.read_line(&mut first).expect("reading the address");
        let Some(url) = first.trim().strip_prefix("zeroset studio: http://") else {
            let mut err = String::new();
            child.stderr.take().map(|mut e| e.read_to_string(&mut err));
            let _ = child.wait();
            panic!("the first line is not the address: {first:?}; stderr: {err}");
        };
        let (addr, token) = url.split_once("/?token=").expect("a token in the address");
        Studio {
            addr: addr.to_owned(),
            token: token.to_owned(),
            child,
            stdout,
        }
    }

    /// `http://127.0.0.1:PORT`.
    pub fn base(&self) -> String {
        format!("http://{}", self.addr)
    }

    /// A request with the token in `X-Zeroset-Token`.
    pub fn get(&self, path: &str) -> Answer {
        let token = self.token.clone();
        self.request("GET", path, &[("X-Zeroset-Token", &token)], b"")
    }

    /// A JSON `POST` with the token.
    pub fn post(&self, path: &str, json: &str) -> Answer {
        let token = self.token.clone();
        self.request(
            "POST",
            path,
            &[
                ("X-Zeroset-Token", &token),
                ("Content-Type", "application/json"),
            ],
            json.as_bytes(),
        )
    }

    /// Any request: `headers` are sent as given (a `Host` among them replaces the default).
    pub fn request(
        &self,
        method: &str,
        path: &str,
        headers: &[(&str, &str)],
        body: &[u8],
    ) -> Answer {
        let mut stream = TcpStream::connect(&self.addr).expect("connecting to the studio");
        stream
            .set_read_timeout(Some(Duration::from_secs(120)))
            .expect("timeout");
        let mut head = format!("{method} {path} HTTP/1.1\r\nConnection: close\r\n");
        if !headers.iter().any(|(k, _)| k.eq_ignore_ascii_case("host")) {
            head.push_str(&format!("Host: {}\r\n", self.addr));
        }
        for (k, v) in headers {
            head.push_str(&format!("{k}: {v}\r\n"));
        }
        if !body.is_empty() || method == "POST" {
            head.push_str(&format!("Content-Length: {}\r\n", body.len()));
        }
        head.push_str("\r\n");
        stream.write_all(head.as_bytes()).expect("sending");
        // A server may answer (413) before reading a large body and close: ignore that error.
        let _ = stream.write_all(body);
        let mut raw = Vec::new();
        let _ = stream.read_to_end(&mut raw);
        parse(&raw)
    }

    /// Sends SIGINT (Ctrl-C) and waits: the exit status and the rest of standard output.
    #[cfg(unix)]
    pub fn interrupt(mut self) -> (std::process::ExitStatus, String) {
        let pid = self.child.id().to_string();
        Command::new("kill")
            .args(["-INT", &pid])
            .status()
            .expect("kill -INT");
        let mut rest = String::new();
        self.stdout
            .read_to_string(&mut rest)
            .expect("reading stdout");
        let status = self.child.wait().expect("waiting for the studio");
        (status, rest)
    }
}

impl Drop for Studio {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Parses an HTTP/1.1 answer (a `Content-Length` or chunked body).
fn parse(raw: &[u8]) -> Answer {
    let end = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or_else(|| panic!("no HTTP head in {:?}", String::from_utf8_lossy(raw)));
    let head = String::from_utf8_lossy(&raw[..end]).to_string();
    let mut lines = head.split("\r\n");
    let status: u16 = lines
        .next()
        .and_then(|l| l.split(' ').nth(1))
        .and_then(|s| s.parse().ok())
        .expect("a status line");
    let headers: HashMap<String, String> = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_owned()))
        .collect();
    let mut body = raw[end + 4..].to_vec();
    if headers
        .get("transfer-encoding")
        .is_some_and(|v| v.contains("chunked"))
    {
        body = dechunk(&body);
    }
    Answer {
        status,
        headers,
        body,
    }
}

fn dechunk(mut data: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let Some(line_end) = data.windows(2).position(|w| w == b"\r\n") else {
            return out;
        };
        let size = usize::from_str_radix(
            String::from_utf8_lossy(&data[..line_end])
                .split(';')
                .next()
                .unwrap_or("0")
                .trim(),
            16,
        )
        .unwrap_or(0);
        if size == 0 {
            return out;
        }
        let start = line_end + 2;
        out.extend_from_slice(&data[start..start + size]);
        data = &data[start + size + 2..];
    }
}

/// A binary mesh (`ZSM1`) taken apart: the report, positions, normals, triangles.
pub struct WireMesh {
    pub report: serde_json::Value,
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[i16; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// Parses `ZSM1` as `docs/studio.md` lays it out, checking every length.
pub fn parse_mesh(bytes: &[u8]) -> WireMesh {
    assert_eq!(&bytes[..4], b"ZSM1", "magic");
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let j = word(4);
    assert_eq!(j % 4, 0, "the report is padded to 4 bytes");
    let report: serde_json::Value = serde_json::from_slice(&bytes[8..8 + j]).expect("report");
    let (v, t) = (word(8 + j), word(12 + j));
    let mut at = 16 + j;
    let f = |at: usize| f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    let positions: Vec<[f32; 3]> = (0..v)
        .map(|i| [f(at + 12 * i), f(at + 12 * i + 4), f(at + 12 * i + 8)])
        .collect();
    at += 12 * v;
    let s = |at: usize| i16::from_le_bytes(bytes[at..at + 2].try_into().unwrap());
    let normals: Vec<[i16; 3]> = (0..v)
        .map(|i| [s(at + 6 * i), s(at + 6 * i + 2), s(at + 6 * i + 4)])
        .collect();
    at += (6 * v).next_multiple_of(4);
    let triangles: Vec<[u32; 3]> = (0..t)
        .map(|i| {
            let w = |k: usize| word(at + 12 * i + 4 * k) as u32;
            [w(0), w(1), w(2)]
        })
        .collect();
    assert_eq!(bytes.len(), at + 12 * t, "nothing after the indices");
    assert_eq!(report["vertices"], v);
    assert_eq!(report["triangles"], t);
    WireMesh {
        report,
        positions,
        normals,
        triangles,
    }
}
