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
use std::sync::atomic::Ordering;
use std::sync::{Arc, PoisonError};
use std::time::Duration;

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
const SHUTDOWN_GRACE: Duration = Duration::from_secs(2);

/// How long a client may take to send a request's headers, and how long a kept-alive
/// connection may wait idle for its next request: connections opened and left silent (or fed a
/// byte at a time) are closed instead of piling up until the process has no file left.
const HEADER_TIMEOUT: Duration = Duration::from_secs(10);

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

    /// The address to listen on (an IP address, or localhost). Anything but a loopback address
    /// makes the studio reachable from other machines (anyone with the token can then use it);
    /// it warns.
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST), value_parser = parse_host)]
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
    let counts = loaded.grid.counts();
    if counts.iter().product::<usize>() > LARGE_GRID {
        // The address is printed once the server answers; say what the wait is for.
        eprintln!(
            "sampling the field on the {}×{}×{} restoration grid...",
            counts[0], counts[1], counts[2]
        );
    }
    let session = session::Session::new(&args.source, loaded, args.output.clone());
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the server's runtime")?;
    let app = runtime.block_on(serve(args, session, description))?;
    // A save in progress finishes (its files are written whole or not at all); any other
    // computation still running is left behind: its answer has nowhere to go.
    if app.saving.load(Ordering::SeqCst) {
        outln!("finishing the save in progress...");
        drop(app.session.lock().unwrap_or_else(PoisonError::into_inner));
    }
    runtime.shutdown_background();
    outln!("zeroset studio stopped");
    Ok(())
}

/// Grids of more cells than this take long enough to sample that startup says so.
const LARGE_GRID: usize = 1 << 22;

/// `--host`: an IP address, or `localhost` (127.0.0.1).
fn parse_host(text: &str) -> Result<IpAddr, String> {
    if text.eq_ignore_ascii_case("localhost") {
        return Ok(IpAddr::V4(Ipv4Addr::LOCALHOST));
    }
    text.parse()
        .map_err(|_| format!("{text:?} is not an IP address (e.g. 127.0.0.1, ::1, 0.0.0.0)"))
}

async fn serve(
    args: &StudioArgs,
    session: session::Session,
    description: String,
) -> anyhow::Result<Arc<http::App>> {
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
            SocketAddr::new(args.host, port)
        );
        None
    };
    let app = Arc::new(http::App::new(session, token, hosts));
    let redirect = if args.no_browser {
        None
    } else {
        open_browser(&url)
    };
    // Ctrl-C (or SIGTERM) refuses new computations and lets requests in progress finish, but
    // not for longer than SHUTDOWN_GRACE; a second one stops the process at once.
    let stop = {
        let app = app.clone();
        async move {
            shutdown().await;
            app.stopping.store(true, Ordering::SeqCst);
            tokio::spawn(async {
                shutdown().await;
                eprintln!("zeroset studio: stopped at once (second signal)");
                std::process::exit(130);
            });
        }
    };
    serve_connections(listener, http::router(app.clone()), stop).await;
    if let Some(path) = redirect {
        let _ = std::fs::remove_file(path);
    }
    Ok(app)
}

/// Serves HTTP/1 connections on `listener` until `stop` resolves, each with the
/// [`HEADER_TIMEOUT`]; then lets those open finish their requests for up to
/// [`SHUTDOWN_GRACE`].
async fn serve_connections(
    listener: tokio::net::TcpListener,
    router: axum::Router,
    stop: impl Future<Output = ()>,
) {
    use hyper_util::rt::{TokioIo, TokioTimer};
    use hyper_util::service::TowerToHyperService;

    let (closing, closed) = tokio::sync::watch::channel(false);
    let mut connections = tokio::task::JoinSet::new();
    let mut stop = std::pin::pin!(stop);
    loop {
        let stream = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((stream, _)) => stream,
                Err(_) => {
                    // Out of file descriptors, or a connection reset before it was accepted:
                    // wait a moment rather than spin.
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            () = &mut stop => break,
        };
        while connections.try_join_next().is_some() {}
        let service = TowerToHyperService::new(router.clone());
        let mut closed = closed.clone();
        connections.spawn(async move {
            let mut builder = hyper::server::conn::http1::Builder::new();
            builder
                .timer(TokioTimer::new())
                .header_read_timeout(HEADER_TIMEOUT);
            let mut connection =
                std::pin::pin!(builder.serve_connection(TokioIo::new(stream), service));
            tokio::select! {
                _ = connection.as_mut() => return,
                _ = closed.changed() => connection.as_mut().graceful_shutdown(),
            }
            let _ = connection.await;
        });
    }
    let _ = closing.send(true);
    let _ = tokio::time::timeout(SHUTDOWN_GRACE, async {
        while connections.join_next().await.is_some() {}
    })
    .await;
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
    let not_here =
        last.as_ref().map(std::io::Error::kind) == Some(std::io::ErrorKind::AddrNotAvailable);
    let e = last.map_or_else(|| "no port to try".to_owned(), |e| e.to_string());
    if not_here {
        bail!("cannot listen on {host}: {e} (--host must be an address of this machine)");
    }
    match port {
        Some(p) => bail!(
            "cannot listen on {}: {e} (choose another --port, or 0)",
            SocketAddr::new(host, p)
        ),
        None => bail!(
            "cannot listen on {host} ports {DEFAULT_PORT}..{}: {e} (choose a --port, or 0)",
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
pub(crate) async fn shutdown() {
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
