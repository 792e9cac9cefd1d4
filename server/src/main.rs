//! `arena-server`: hosts highway-arena envs over Zenoh until SIGINT or SIGTERM, or, with
//! `--route-only`, routes a site's servers and clients without hosting envs.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use arena_protocol::session::{ConnectionFlags, Mode, Role, guard_server_keys};
use arena_server::transport::{Limits, Scenarios, Server};
use clap::Parser;

/// mimalloc: the game-theoretic cars' decisions allocate and free small buffers on two
/// threads at once, where glibc's malloc took 12 % of a highway-gt step
/// (docs/performance.md, "Issue 25, second round"). `transport::memory` hands its freed
/// pages back.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Hosts highway-arena envs over Zenoh. With no flags it listens as a Zenoh peer on
/// tcp/127.0.0.1:7447 with multicast scouting off; clients connect to that endpoint.
#[derive(Debug, Parser)]
#[command(name = "arena-server", version, about, long_about = None)]
struct Args {
    #[command(flatten)]
    connection: ConnectionFlags,
    /// Most envs alive at once; further creates are refused with TooManyEnvs. An env keeps
    /// at most about 40 MiB between requests (docs/reliability.md, "Bounded cost"): the
    /// default fits a 24 GiB machine.
    #[arg(long, default_value_t = Limits::default().max_envs)]
    max_envs: usize,
    /// Most envs one party may hold at once; further creates are refused with TooManyEnvs.
    /// Under a site's access control (deploy/auth/) a party is a logged-in user, however
    /// many client ids it uses. On an open server it is a client id, and ids cost nothing:
    /// there one session can still fill the server while it runs (envs of clients that
    /// show no liveliness token are closed within seconds, the rest when they leave).
    #[arg(long, default_value_t = Limits::default().max_envs_per_client)]
    max_envs_per_client: usize,
    /// Seconds an env may stay untouched before it is closed.
    #[arg(long, default_value_t = 600.0)]
    idle_timeout: f64,
    /// A folder of extra scenario files (*.toml), each served under the `name` it
    /// declares, beside the built-in ones (a same-named one replaces a built-in). A bad
    /// file stops the server with the file and the error.
    #[arg(long)]
    scenarios: Option<PathBuf>,
    /// Only route for others (Zenoh router mode, implied): host no envs and announce no server.
    /// The meeting point of a deployment whose servers and clients connect to it.
    #[arg(long)]
    route_only: bool,
}

/// Prints a line to stdout, ignoring a stdout that has gone (a closed pipe must not
/// stop a server).
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

fn main() -> anyhow::Result<()> {
    let mut args = Args::parse();
    if !(args.idle_timeout.is_finite() && args.idle_timeout > 0.0) {
        anyhow::bail!("--idle-timeout must be a positive number of seconds, not {}", args.idle_timeout);
    }
    if args.max_envs == 0 || args.max_envs_per_client == 0 {
        anyhow::bail!(
            "--max-envs and --max-envs-per-client must be at least 1 (a server that can hold no env serves nothing)"
        );
    }
    if args.route_only {
        match args.connection.mode {
            None => args.connection.mode = Some(Mode::Router),
            Some(Mode::Router) => {}
            Some(_) => anyhow::bail!("--route-only needs --mode router (a peer or client does not route for others)"),
        }
    }
    let runtime =
        tokio::runtime::Builder::new_multi_thread().enable_all().build().context("cannot start the tokio runtime")?;
    runtime.block_on(async { if args.route_only { route(args).await } else { serve(args).await } })
}

async fn open_session(args: &Args) -> anyhow::Result<zenoh::Session> {
    let mut config = args.connection.zenoh_config(Role::Server).map_err(anyhow::Error::msg)?;
    // A peer server is its clients' meeting point: nobody else may serve its keys there.
    // (A config file, or a router, brings its own access control: deploy/auth/.)
    let peer = matches!(args.connection.mode, None | Some(Mode::Peer));
    if peer && !args.route_only && args.connection.zenoh_config.is_none() {
        guard_server_keys(&mut config, &args.connection.prefix).map_err(anyhow::Error::msg)?;
    }
    zenoh::open(config).await.map_err(|e| {
        let hint = if args.connection.connect.is_empty() {
            String::new()
        } else {
            format!(
                " (connecting to {}: is the router running there, and does it ask for credentials, \
                 --zenoh-config deploy/auth/server.json5?)",
                args.connection.connect.join(", ")
            )
        };
        anyhow::anyhow!("cannot open the Zenoh session{hint}: {e}")
    })
}

/// Where the banner says the session is reachable: what it listens on, else what it
/// connected to.
fn reachable(args: &Args) -> String {
    let listen = args.connection.endpoints(Role::Server);
    match (listen.is_empty(), args.connection.connect.is_empty()) {
        (false, _) => format!("serving on {}", listen.join(", ")),
        (true, false) => format!("serving through {}", args.connection.connect.join(", ")),
        (true, true) => "serving where its Zenoh config says".to_string(),
    }
}

async fn route(args: Args) -> anyhow::Result<()> {
    let session = open_session(&args).await?;
    let listen = args.connection.endpoints(Role::Server);
    let at = if listen.is_empty() { "where its Zenoh config says".to_string() } else { listen.join(", ") };
    say!("arena-server {} routing only (zenoh id {}) on {at}", env!("CARGO_PKG_VERSION"), session.zid());
    say!("stop with Ctrl-C");
    shutdown_signal().await;
    session.close().await.map_err(|e| anyhow::anyhow!("closing the session failed: {e}"))
}

async fn serve(args: Args) -> anyhow::Result<()> {
    let scenarios = Scenarios::load(args.scenarios.as_deref()).map_err(anyhow::Error::msg)?;
    let session = open_session(&args).await?;
    let limits = Limits {
        max_envs: args.max_envs,
        max_envs_per_client: args.max_envs_per_client,
        idle_timeout: Duration::from_secs_f64(args.idle_timeout),
    };
    let server = Server::start(session, &args.connection.prefix, scenarios.clone(), limits)
        .await
        .map_err(|e| anyhow::anyhow!("cannot declare the server: {e}"))?;
    say!("arena-server {} (server id {}) {}", env!("CARGO_PKG_VERSION"), server.id(), reachable(&args));
    say!("scenarios: {}", scenarios.names().join(", "));
    say!("connect from another terminal:");
    let endpoint = (args.connection.endpoints(Role::Server).into_iter().chain(args.connection.connect.iter().cloned()))
        .next()
        .unwrap_or_else(|| "ENDPOINT".to_string());
    // Through a router (this server only connected), clients are Zenoh clients too; with
    // a config file, they need one of their own (credentials).
    let through_router = args.connection.endpoints(Role::Server).is_empty();
    let (cli_extra, py_extra) = match (through_router, args.connection.zenoh_config.is_some()) {
        (false, _) => (String::new(), String::new()),
        (true, false) => (" --mode client".to_string(), ", mode='client'".to_string()),
        (true, true) => (
            " --mode client --zenoh-config CLIENT.json5".to_string(),
            ", mode='client', zenoh_config='CLIENT.json5'".to_string(),
        ),
    };
    say!("  arena play --scenario merge --connect {endpoint}{cli_extra}");
    say!(
        "  python -c \"import highway_arena; env = highway_arena.parallel_env('merge', connect='{endpoint}'{py_extra}); print(env.reset(seed=0))\""
    );
    say!("stop with Ctrl-C");
    shutdown_signal().await;
    say!("arena-server: shutting down ({} env(s) open)", server.registry().len());
    server.close().await.map_err(|e| anyhow::anyhow!("closing the session failed: {e}"))?;
    Ok(())
}

async fn shutdown_signal() {
    let interrupt = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut terminate) => {
                tokio::select! {
                    _ = interrupt => {}
                    _ = terminate.recv() => {}
                }
            }
            Err(_) => {
                let _ = interrupt.await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = interrupt.await;
    }
}
