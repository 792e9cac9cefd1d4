//! The Zenoh side of the server: one session, a liveliness token that lets clients find
//! this server, one queryable that feeds every request to the `Registry` (with the user
//! its key names), a liveliness subscriber that follows clients coming and going (the
//! envs of one that is gone are closed), and a sweeper for idle envs and for envs whose
//! client never showed a token.
//! Closing drains: the requests being answered finish and are replied to; later ones are
//! told `ShuttingDown` at once, so no client waits out its timeout on a server that left.
//! Memory freed when clients leave is handed back to the system here (`memory::return_freed_memory`).
//! Once a reset's or a step's reply is sent, the env's next decisions are made on the
//! decision pool's thread (`Registry::decide_ahead`).
//! Zenoh's threads only receive: each request is computed on the runtime's blocking pool,
//! queued by its sender (`dispatch`), so a busy env never holds up another client.

mod dispatch;
mod limits;
mod memory;
mod registry;
mod scenarios;

use std::sync::{Arc, RwLock};
use std::time::{Duration, Instant};

use arena_protocol::{
    ClientId, ClientTag, ErrorCode, ErrorReply, PROTOCOL_VERSION, Reply, ReplyBody, encode, keys, peek_client,
};
use zenoh::Wait;
use zenoh::sample::SampleKind;

pub use limits::{ENV_KEPT_MIB_AT_MOST, Limits, ORPHAN_GRACE};
pub use registry::{Ahead, MAX_CLIENT_TAGS, Registry};
pub use scenarios::Scenarios;

use dispatch::Dispatch;
use limits::Party;
use memory::return_freed_memory;

/// How long a closing server keeps answering `ShuttingDown` after the requests in flight
/// are answered, so requests already on their way get an answer, not a timeout.
pub const SHUTDOWN_GRACE: Duration = Duration::from_millis(100);

/// The largest echo reply (bytes): more than any single-env step reply `arena bench`
/// compares it with (about 1 KB on highway.toml).
pub const ECHO_MAX_REPLY: usize = 64 * 1024;

/// How often freed memory is handed back when nothing was closed.
const TRIM_PERIOD: Duration = Duration::from_secs(5);

/// A running server. Dropping it undeclares everything; `close` also ends the session.
pub struct Server {
    session: zenoh::Session,
    server_id: String,
    registry: Arc<Registry>,
    /// Whether requests are answered (false once closing). Every answer holds it for
    /// reading, so taking it for writing waits for the answers in flight.
    accepting: Arc<RwLock<bool>>,
    _queryable: zenoh::query::Queryable<()>,
    _echo: zenoh::query::Queryable<()>,
    _token: zenoh::liveliness::LivelinessToken,
    _clients: zenoh::pubsub::Subscriber<()>,
    sweeper: tokio::task::JoinHandle<()>,
}

impl Server {
    /// Declares the server on `session` under `prefix`. Must run inside a tokio
    /// multi-thread runtime (Zenoh needs one).
    pub async fn start(
        session: zenoh::Session,
        prefix: &str,
        scenarios: Scenarios,
        limits: Limits,
    ) -> zenoh::Result<Server> {
        // The session's own id, so clients can check who answered (`Reply::replier_id`).
        let server_id = session.zid().to_string();
        let registry = Arc::new(Registry::new(server_id.clone(), scenarios, limits));

        let rpc = keys::server_rpc_queryable(prefix, &server_id)?;
        let (rpc_prefix, rpc_server) = (prefix.to_string(), server_id.clone());
        let handler = Arc::clone(&registry);
        let accepting = Arc::new(RwLock::new(true));
        let gate = Arc::clone(&accepting);
        let shutting_down = encode(&Reply {
            version: PROTOCOL_VERSION,
            body: ReplyBody::Error(ErrorReply {
                code: ErrorCode::ShuttingDown,
                message: format!(
                    "arena-server {server_id} is shutting down; its envs end with it: create new ones on another \
                     server, or on this one once it is started again"
                ),
                env_usable: false,
            }),
        });
        // One party computes at most as many requests at once as there are cores.
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let dispatch = Arc::new(Dispatch::new(tokio::runtime::Handle::current(), cores));
        let queryable = session
            .declare_queryable(rpc)
            .callback(move |query| {
                let bytes = query.payload().map(|p| p.to_bytes().into_owned()).unwrap_or_default();
                let user = keys::rpc_user(&rpc_prefix, &rpc_server, query.key_expr().as_str());
                // Undecodable requests share one queue: answering them costs a decode.
                let party = Party::of(user.as_deref(), peek_client(&bytes).unwrap_or(ClientId(0)));
                let (handler, gate, shutting_down) = (Arc::clone(&handler), Arc::clone(&gate), shutting_down.clone());
                dispatch.run(party, move || {
                    let open = gate.read().unwrap_or_else(|poisoned| poisoned.into_inner());
                    let (answer, ahead) =
                        if *open { handler.handle_then(user.as_deref(), &bytes) } else { (shutting_down, None) };
                    if let Err(e) = query.reply(query.key_expr().clone(), answer).wait() {
                        eprintln!("arena-server: could not send a reply: {e}");
                    }
                    drop(query);
                    drop(open);
                    // While the reply travels and the client picks its next actions, this
                    // env's next decisions are made on another thread: the next request
                    // stops them.
                    if let Some(ahead) = ahead {
                        let registry = Arc::clone(&handler);
                        crate::env::beside_decisions(move || registry.decide_ahead(ahead));
                    }
                });
            })
            .await?;

        // A raw reply of the size the request asks for (its first 4 bytes, u32 LE,
        // capped at `ECHO_MAX_REPLY`): `arena bench` measures Zenoh itself with it. The
        // cap keeps a 4-byte request from asking for megabytes (amplification).
        let echo = session
            .declare_queryable(keys::server_echo(prefix, &server_id)?)
            .callback(|query| {
                let bytes = query.payload().map(|p| p.to_bytes().into_owned()).unwrap_or_default();
                let asked = bytes.get(..4).and_then(|b| b.try_into().ok()).map_or(0, u32::from_le_bytes) as usize;
                let reply = vec![0u8; asked.min(ECHO_MAX_REPLY)];
                if let Err(e) = query.reply(query.key_expr().clone(), reply).wait() {
                    eprintln!("arena-server: could not send an echo reply: {e}");
                }
            })
            .await?;

        let token = session.liveliness().declare_token(keys::server_liveliness(prefix, &server_id)?).await?;

        let watcher = Arc::clone(&registry);
        let prefix_owned = prefix.to_string();
        let clients = session
            .liveliness()
            .declare_subscriber(keys::clients_liveliness_wildcard(prefix)?)
            .history(true)
            .callback(move |sample| {
                let tag = keys::client_tag_from_liveliness(&prefix_owned, sample.key_expr().as_str());
                let Some(client) = tag.and_then(|tag| tag.parse::<ClientTag>().ok()) else { return };
                match sample.kind() {
                    SampleKind::Put => watcher.client_arrived(client),
                    SampleKind::Delete => watcher.client_left(client, Instant::now()),
                }
            })
            .await?;

        let sweeper_registry = Arc::clone(&registry);
        let (sweeper_session, sweeper_prefix) = (session.clone(), prefix.to_string());
        // Every second at most, so envs of clients that showed no token are gone within
        // `ORPHAN_GRACE` + 1 s.
        let period = (limits.idle_timeout / 4).clamp(Duration::from_millis(100), Duration::from_secs(1));
        let sweeper = tokio::spawn(async move {
            let mut last_trim = Instant::now();
            loop {
                tokio::time::sleep(period).await;
                let now = Instant::now();
                let mut asked = tokio::task::JoinSet::new();
                for owner in sweeper_registry.unseen_owners(now) {
                    let (session, prefix) = (sweeper_session.clone(), sweeper_prefix.clone());
                    asked.spawn(async move { token_alive(&session, &prefix, owner).await.then_some(owner) });
                }
                while let Some(answer) = asked.join_next().await {
                    if let Ok(Some(owner)) = answer {
                        sweeper_registry.client_arrived(owner);
                    }
                }
                let idle = sweeper_registry.reclaim_idle(now);
                let orphans = sweeper_registry.reclaim_orphans(now);
                // Zenoh's idle connection threads exit about 10 s after a burst of
                // clients; what they freed is handed back every few seconds.
                if idle + orphans > 0 || now.duration_since(last_trim) >= TRIM_PERIOD {
                    return_freed_memory();
                    last_trim = now;
                }
                if idle > 0 {
                    eprintln!("arena-server: closed {idle} idle env(s)");
                }
                if orphans > 0 {
                    eprintln!(
                        "arena-server: closed {orphans} env(s) of clients gone, or never seen, for {} s (no liveliness \
                         token)",
                        ORPHAN_GRACE.as_secs()
                    );
                }
            }
        });

        Ok(Server {
            session,
            server_id,
            registry,
            accepting,
            _queryable: queryable,
            _echo: echo,
            _token: token,
            _clients: clients,
            sweeper,
        })
    }

    /// This server's id (the last part of its liveliness key).
    pub fn id(&self) -> &str {
        &self.server_id
    }

    /// Its envs.
    pub fn registry(&self) -> &Registry {
        &self.registry
    }

    /// Stops being found, answers the requests in flight and refuses later ones with
    /// `ShuttingDown`, then undeclares everything and closes the session.
    pub async fn close(self) -> zenoh::Result<()> {
        self.sweeper.abort();
        let Server { session, accepting, _queryable, _echo, _token, _clients, .. } = self;
        _token.undeclare().await?;
        // Waits for every answer being computed (they hold the lock for reading).
        let drained = tokio::task::spawn_blocking(move || {
            *accepting.write().unwrap_or_else(|poisoned| poisoned.into_inner()) = false;
        });
        drained.await.map_err(|e| format!("draining the requests in flight: {e}"))?;
        // Requests already on their way are told ShuttingDown rather than met by silence.
        tokio::time::sleep(SHUTDOWN_GRACE).await;
        _queryable.undeclare().await?;
        _echo.undeclare().await?;
        _clients.undeclare().await?;
        session.close().await
    }
}

/// How long the sweeper waits for a client's liveliness token to answer.
const TOKEN_QUERY_TIMEOUT: Duration = Duration::from_millis(500);

/// Whether the client tagged `owner` has a liveliness token now, asked of the network:
/// for an owner the registry has no record of (`Registry::unseen_owners`).
async fn token_alive(session: &zenoh::Session, prefix: &str, owner: ClientTag) -> bool {
    let Ok(key) = keys::client_liveliness(prefix, &owner.to_string()) else { return false };
    let Ok(replies) = session.liveliness().get(key).timeout(TOKEN_QUERY_TIMEOUT).await else { return false };
    replies.recv_async().await.is_ok_and(|reply| reply.result().is_ok())
}
