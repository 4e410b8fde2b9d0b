//! `zeroset studio`: the interactive restoration loop of the restoration paper's §6 — a page in
//! the user's browser, served by this binary on 127.0.0.1, where a box mask is placed and moved
//! on the surface, α or the coarse resolution is moved, and the restored surface is shown live.
//!
//! - [`session`]: the input, the committed restorations with undo/redo, previews, saving;
//!   every restoration is [`Restoration::restore`](crate::restore::Restoration), the code of
//!   `zeroset restore`, so a saved field is byte-identical to the CLI's.
//! - [`http`]: the HTTP API (`docs/studio.md`) and its guard (token, host, origin, size).
//! - [`json`]: a restoration's JSON form; [`wire`]: the binary mesh and point formats;
//!   [`assets`]: the embedded page and three.js.

mod assets;
mod http;
mod json;
mod session;
mod wire;

use std::io::Write as _;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use anyhow::{Context as _, bail};
use clap::Args;

use crate::restore::Source;

/// Shown after `zeroset studio --help`.
pub const EXAMPLES: &str = "\
Examples:
  # restore the sample bunny in the browser; Save writes no_ears.zsf (and no_ears.ply)
  zeroset studio samples/bunny_2k.xyzn -o no_ears.zsf
  # on a remote machine: forward the port, open the printed address locally
  ssh -L 7878:127.0.0.1:7878 host   # then, on the host:
  zeroset studio scan.ply -o fixed.zsf --no-browser
  # a finer restoration grid (128 cells along each axis)
  zeroset studio field.zsf --grid 128,128,128 -o fixed.zsf";

/// How long requests in progress may finish after Ctrl-C.
const SHUTDOWN_GRACE: std::time::Duration = std::time::Duration::from_secs(2);

/// The port tried first, and how many after it when it is taken.
const DEFAULT_PORT: u16 = 7878;
const PORTS_TRIED: u16 = 21;

/// Arguments of `zeroset studio`.
#[derive(Debug, Args)]
pub struct StudioArgs {
    #[command(flatten)]
    pub source: Source,

    /// Where Save writes the restored field (.zsf, atomically; the mesh beside it as .ply).
    /// Without it Save is disabled.
    #[arg(short, long)]
    pub output: Option<PathBuf>,

    /// Overwrite an existing output (and its .ply).
    #[arg(long)]
    pub force: bool,

    /// The port (default 7878, or the next free one up to 7898); 0 picks any free port.
    #[arg(long)]
    pub port: Option<u16>,

    /// The address to listen on. Anything but a loopback address makes the studio reachable
    /// from other machines (anyone with the token can then use it); it warns.
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST))]
    pub host: IpAddr,

    /// Do not open a browser; just print the address.
    #[arg(long)]
    pub no_browser: bool,
}

/// Runs `zeroset studio` until Ctrl-C.
pub fn run(args: &StudioArgs) -> anyhow::Result<()> {
    if let Some(output) = &args.output {
        crate::output::check_output(output, &[&args.source.input], args.force, &["zsf"])?;
        // Save writes the mesh beside the field: never over the input, even with --force.
        let mesh = output.with_extension("ply");
        crate::output::check_output(&mesh, &[&args.source.input], args.force, &["ply"])
            .with_context(|| format!("the mesh Save writes beside {}", output.display()))?;
    }
    args.source.check_counts()?;
    let loaded = args.source.load()?;
    // The session holds the samples of two states at least (the input and a restoration) and
    // a preview: refuse a grid the machine cannot hold before sampling it.
    crate::restore::check_grid_memory(&loaded.grid, args.source.grid.is_some(), 3, 0)?;
    let description = loaded.description.clone();
    let session = session::Session::new(&args.source, loaded, args.output.clone());
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the server's runtime")?;
    runtime.block_on(serve(args, session, description))
}

async fn serve(
    args: &StudioArgs,
    session: session::Session,
    description: String,
) -> anyhow::Result<()> {
    let listener = bind(args.host, args.port).await?;
    let port = listener
        .local_addr()
        .context("reading the bound port")?
        .port();
    let token = token()?;
    let shown_host = match args.host {
        IpAddr::V6(ip) if ip.is_loopback() => "[::1]".to_owned(),
        ip if ip.is_unspecified() => "127.0.0.1".to_owned(),
        IpAddr::V6(ip) => format!("[{ip}]"),
        ip => ip.to_string(),
    };
    let url = format!("http://{shown_host}:{port}/?token={token}");
    // The first line of output is the address, as Jupyter prints it: scripts read it.
    outln!("zeroset studio: {url}");
    let counts = session.grid().counts();
    outln!("{description}");
    outln!(
        "restoration grid {}×{}×{} cells; {}",
        counts[0],
        counts[1],
        counts[2],
        match &args.output {
            Some(o) => format!("Save writes {}", o.display()),
            None => "Save is disabled (no -o OUT.zsf)".to_owned(),
        }
    );
    outln!("Ctrl-C stops the server.");
    std::io::stdout().flush().ok();
    let hosts = if args.host.is_loopback() {
        let mut hosts = vec![
            format!("{shown_host}:{port}"),
            format!("localhost:{port}"),
            format!("127.0.0.1:{port}"),
            format!("[::1]:{port}"),
        ];
        hosts.dedup();
        Some(hosts)
    } else {
        eprintln!(
            "warning: listening on {}: the studio is reachable from other machines; anyone \
             who has the address with its token can read the field and write the output",
            args.host
        );
        None
    };
    let app = Arc::new(http::App {
        session: Mutex::new(session),
        token,
        hosts,
    });
    let redirect = if args.no_browser {
        None
    } else {
        open_browser(&url)
    };
    // Ctrl-C lets requests in progress finish, but not for longer than SHUTDOWN_GRACE: a client
    // that keeps a connection half-open must not keep the server alive.
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let server = axum::serve(listener, http::router(app)).with_graceful_shutdown(async move {
        shutdown().await;
        let _ = stop.send(());
    });
    let deadline = async move {
        if stopped.await.is_ok() {
            tokio::time::sleep(SHUTDOWN_GRACE).await;
        } else {
            std::future::pending::<()>().await;
        }
    };
    tokio::select! {
        served = server => served.context("serving")?,
        () = deadline => {}
    }
    if let Some(path) = redirect {
        let _ = std::fs::remove_file(path);
    }
    outln!("zeroset studio stopped");
    Ok(())
}

/// Listens on `host:port`; without `--port`, on the first free port from 7878 on.
async fn bind(host: IpAddr, port: Option<u16>) -> anyhow::Result<tokio::net::TcpListener> {
    let ports: Vec<u16> = match port {
        Some(p) => vec![p],
        None => (DEFAULT_PORT..DEFAULT_PORT + PORTS_TRIED).collect(),
    };
    let mut last = None;
    for &p in &ports {
        match tokio::net::TcpListener::bind(SocketAddr::new(host, p)).await {
            Ok(listener) => return Ok(listener),
            Err(e) => last = Some(e),
        }
    }
    let e = last.map_or_else(|| "no port to try".to_owned(), |e| e.to_string());
    match port {
        Some(p) => bail!("cannot listen on {host}:{p}: {e} (choose another --port, or 0)"),
        None => bail!(
            "cannot listen on {host}:{DEFAULT_PORT}..{}: {e} (choose a --port, or 0)",
            DEFAULT_PORT + PORTS_TRIED - 1
        ),
    }
}

/// 128 random bits from the operating system, as 32 hex digits.
fn token() -> anyhow::Result<String> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes)
        .map_err(|e| anyhow::anyhow!("no randomness for the access token: {e}"))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Resolves on Ctrl-C (or SIGTERM on Unix).
async fn shutdown() {
    let interrupt = async {
        tokio::signal::ctrl_c().await.ok();
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        () = interrupt => {},
        () = terminate => {},
    }
}

/// Opens `url` in the desktop's browser; says so when there is none (an SSH session). The
/// browser is given a file that redirects to the address, readable by the user alone, not the
/// address itself: a browser's command line can be read by every user of the machine, and the
/// token is what keeps them out. Returns the file, to remove when the studio stops.
fn open_browser(url: &str) -> Option<PathBuf> {
    let (program, prefix): (&str, &[&str]) = if cfg!(target_os = "macos") {
        ("open", &[])
    } else if cfg!(windows) {
        ("cmd", &["/C", "start", ""])
    } else {
        if std::env::var_os("DISPLAY").is_none() && std::env::var_os("WAYLAND_DISPLAY").is_none() {
            outln!(
                "no display here: open the address above in a browser (--no-browser hides this)"
            );
            return None;
        }
        ("xdg-open", &[])
    };
    let redirect = match redirect_file(url) {
        Ok(path) => path,
        Err(e) => {
            outln!("could not write the browser's start page ({e}): open the address above");
            return None;
        }
    };
    let opened = std::process::Command::new(program)
        .args(prefix)
        .arg(&redirect)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn();
    if let Err(e) = opened {
        outln!("could not start a browser ({program}: {e}): open the address above");
    }
    Some(redirect)
}

/// A page that sends the browser to `url`, in the user's runtime directory (or the temporary
/// one), created with permissions for the user alone.
fn redirect_file(url: &str) -> std::io::Result<PathBuf> {
    let dir = std::env::var_os("XDG_RUNTIME_DIR")
        .map(PathBuf::from)
        .filter(|d| d.is_dir())
        .unwrap_or_else(std::env::temp_dir);
    let path = dir.join(format!("zeroset-studio-{}.html", std::process::id()));
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut file = options.open(&path)?;
    writeln!(
        file,
        "<!doctype html><meta charset=\"utf-8\"><meta http-equiv=\"refresh\" content=\"0;url={url}\">\
         <title>zeroset studio</title><a href=\"{url}\">zeroset studio</a>"
    )?;
    Ok(path)
}
