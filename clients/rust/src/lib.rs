//! Rust client of highway-arena: find servers by Zenoh liveliness, place envs across them,
//! and reset, step (one env or a batch in one round trip), render, read state, record
//! (reset and step replies then carry the world's frames) and close them, with timeouts
//! and safe retries.
//!
//! `Client` is async (it needs a tokio multi-thread runtime, as Zenoh does);
//! `blocking::Client` wraps it with its own runtime for callers that are not async, such
//! as the Python extension and the `arena` CLI.
//!
//! ```no_run
//! # async fn demo() -> Result<(), arena_client::ClientError> {
//! use arena_client::{Client, ScenarioSource, CreateOptions};
//! use arena_protocol::session::ConnectionFlags;
//! let client = Client::connect(&ConnectionFlags::default()).await?;
//! let server = client.pick_server().await?;
//! let mut env = client.create_env(&server, ScenarioSource::Named("merge".into()), CreateOptions::default()).await?;
//! env.reset(Some(0), vec![]).await?;
//! let reply = env.step(vec![]).await?;
//! println!("{:?}", reply.steps[0].reward);
//! env.close().await?;
//! client.close().await?;
//! # Ok(()) }
//! ```
#![warn(missing_docs)]

pub mod blocking;
mod fork;
pub mod placement;

pub use fork::forked;

use std::fmt;
use std::sync::Arc;
use std::time::{Duration, Instant};

pub use arena_protocol::{
    Action, AgentStart, AgentStep, BatchItem, BatchStep, CreateOptions, EndReason, EnvId, EnvSpecs, EnvStatistics,
    ErrorCode, ErrorReply, Frame, Info, InfoValue, MetaAction, Observation, OptionValue, RenderMode, ResetReply,
    ScenarioSource, ServerInfo, StepReply, WorldFrame, WorldStart,
};
use arena_protocol::{
    ClientId, PROTOCOL_VERSION, Reply, ReplyBody, Request, RequestBody, ResetOptions, decode, encode, keys,
    session::{ConnectionFlags, Role, login_user},
};
use zenoh::query::{ConsolidationMode, QueryTarget};

/// Occurs when a call to a server fails.
#[derive(Debug, Clone, PartialEq)]
pub enum ClientError {
    /// Occurs when the Zenoh session cannot be opened or a query cannot be sent.
    Zenoh(String),
    /// Occurs when no reply came within the timeout (after every retry).
    Timeout {
        /// What was asked.
        what: String,
        /// How long the client waited in all.
        waited: Duration,
    },
    /// Occurs when nothing answers on the server's key at all: the server stopped or
    /// restarted, and the envs it held are gone.
    ServerGone {
        /// The server's id.
        server: String,
        /// What was asked.
        what: String,
        /// How long the client tried (retries included).
        waited: Duration,
    },
    /// Occurs when no server answers under the prefix.
    NoServer {
        /// The prefix searched.
        prefix: String,
    },
    /// Occurs when the server refused the request; the reply says why.
    Server(ErrorReply),
    /// Occurs when a reply cannot be decoded (a server of another version, say).
    Protocol(String),
    /// Occurs in a child made by `fork()` of a process that had opened a Zenoh session:
    /// Zenoh's runtime threads are not in the child, so no session can work there.
    Forked {
        /// The process that opened the first session.
        parent: u32,
        /// This process.
        child: u32,
    },
}

impl fmt::Display for ClientError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ClientError::Zenoh(message) => write!(f, "zenoh: {message}"),
            ClientError::Timeout { what, waited } => write!(
                f,
                "no reply to {what} within {:.1} s; is an arena-server running and reachable? (start one with `arena-server`)",
                waited.as_secs_f64()
            ),
            ClientError::ServerGone { server, what, waited } => write!(
                f,
                "arena-server {server} is gone: nothing answered {what} on its key in {:.1} s (it stopped or \
                 restarted), so the envs it held no longer exist; create new ones",
                waited.as_secs_f64()
            ),
            ClientError::NoServer { prefix } => write!(
                f,
                "no arena-server found under prefix '{prefix}'; start one with `arena-server`, or point --connect (Python: connect=) at its endpoint"
            ),
            ClientError::Server(reply) => write!(f, "{reply}"),
            ClientError::Protocol(message) => write!(f, "protocol: {message}"),
            ClientError::Forked { parent, child } => write!(
                f,
                "process {child} was forked from process {parent} after that one opened a Zenoh session; Zenoh's \
                 runtime threads do not survive fork(), so no connection can be opened or used here: start worker \
                 processes with the 'spawn' (or 'forkserver') start method, or fork them before connecting"
            ),
        }
    }
}

impl std::error::Error for ClientError {}

/// Result of every client call.
pub type Result<T> = std::result::Result<T, ClientError>;

fn zenoh_error(e: impl fmt::Display) -> ClientError {
    ClientError::Zenoh(e.to_string())
}

/// Pause before asking again when nothing answered on a server's key at all: a route may
/// be settling, or this session's link coming back (Zenoh reconnects a dropped link in
/// tens of milliseconds); after every attempt so answered, the server is taken as gone.
const GONE_GRACE: Duration = Duration::from_millis(200);

struct Inner {
    session: zenoh::Session,
    prefix: String,
    /// The user the session logged in as, named in every request's key (`keys::user_rpc`).
    user: Option<String>,
    id: ClientId,
    timeout: Duration,
    retries: u32,
    /// Taken by `close`; servers close this client's envs when it disappears.
    token: std::sync::Mutex<Option<zenoh::liveliness::LivelinessToken>>,
}

/// A connection to the Zenoh network where arena-servers live. Cheap to clone.
#[derive(Clone)]
pub struct Client {
    inner: Arc<Inner>,
}

impl fmt::Debug for Client {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Client").field("id", &self.inner.id).field("prefix", &self.inner.prefix).finish()
    }
}

impl Client {
    /// Opens a Zenoh session as `flags` say (by default a peer connecting to
    /// tcp/127.0.0.1:7447 with multicast scouting off) and announces this client.
    pub async fn connect(flags: &ConnectionFlags) -> Result<Client> {
        let config = flags.zenoh_config(Role::Client).map_err(ClientError::Zenoh)?;
        let user = login_user(&config);
        fork::starting_zenoh()?;
        let session = zenoh::open(config).await.map_err(zenoh_error)?;
        Client::with_session(session, &flags.prefix, user, flags.timeout(), flags.retries).await
    }

    /// Uses an open session, logged in as `user` if its config names one (a site's
    /// access control lets a user ask only on keys that name it). `timeout` bounds each
    /// attempt; a sequenced call is retried `retries` times with the same sequence
    /// number, so it never steps twice.
    pub async fn with_session(
        session: zenoh::Session,
        prefix: &str,
        user: Option<String>,
        timeout: Duration,
        retries: u32,
    ) -> Result<Client> {
        let id = ClientId(rand::random::<u128>());
        // The token shows the id's tag, never the id: the id is what proves ownership.
        let token_key = keys::client_liveliness(prefix, &id.tag().to_string()).map_err(zenoh_error)?;
        let token = session.liveliness().declare_token(token_key).await.map_err(zenoh_error)?;
        let token = std::sync::Mutex::new(Some(token));
        let inner = Inner { session, prefix: prefix.to_string(), user, id, timeout, retries, token };
        Ok(Client { inner: Arc::new(inner) })
    }

    /// This client's id (its envs are reachable only with it).
    pub fn id(&self) -> ClientId {
        self.inner.id
    }

    /// Servers that are alive now, by id.
    pub async fn servers(&self) -> Result<Vec<String>> {
        let key = keys::servers_liveliness_wildcard(&self.inner.prefix).map_err(zenoh_error)?;
        let replies =
            self.inner.session.liveliness().get(key).timeout(self.inner.timeout).await.map_err(zenoh_error)?;
        let mut servers = Vec::new();
        while let Ok(reply) = replies.recv_async().await {
            if let Ok(sample) = reply.result()
                && let Some(id) = keys::server_id_from_liveliness(&self.inner.prefix, sample.key_expr().as_str())
            {
                servers.push(id);
            }
        }
        servers.sort();
        servers.dedup();
        Ok(servers)
    }

    /// The first server found, waiting up to the timeout for one to appear.
    pub async fn pick_server(&self) -> Result<String> {
        self.pick_server_within(self.inner.timeout).await
    }

    /// The first server found, waiting up to `wait` for one to appear.
    pub async fn pick_server_within(&self, wait: Duration) -> Result<String> {
        let deadline = Instant::now() + wait;
        loop {
            if let Some(server) = self.servers().await?.into_iter().next() {
                return Ok(server);
            }
            if Instant::now() >= deadline {
                return Err(ClientError::NoServer { prefix: self.inner.prefix.clone() });
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    /// What a server offers.
    pub async fn server_info(&self, server: &str) -> Result<ServerInfo> {
        match self.call(server, RequestBody::ServerInfo, true).await? {
            ReplyBody::ServerInfo(info) => Ok(info),
            other => Err(unexpected("ServerInfo", &other)),
        }
    }

    /// Creates an env on `server`. Not retried: a lost reply would leave an env behind,
    /// which the server reclaims when it idles out.
    pub async fn create_env(
        &self,
        server: &str,
        scenario: ScenarioSource,
        options: CreateOptions,
    ) -> Result<RemoteEnv> {
        match self.call(server, RequestBody::CreateEnv { scenario, options }, false).await? {
            ReplyBody::Created { env, specs } => Ok(RemoteEnv {
                client: self.clone(),
                server: server.to_string(),
                id: env,
                seq: 0,
                specs,
                closed: false,
            }),
            other => Err(unexpected("Created", &other)),
        }
    }

    /// Steps many envs of this client: one round trip per server, the servers' batches
    /// sent at once. Actions are given per env, in the order of `envs`; each env's result
    /// is its own (an env whose server is gone gets that error, the others step on).
    pub async fn step_batch(
        &self,
        envs: &mut [&mut RemoteEnv],
        actions: Vec<Vec<(String, Action)>>,
    ) -> Result<Vec<Result<StepReply>>> {
        if actions.len() != envs.len() {
            return Err(ClientError::Protocol(format!("{} envs but {} action sets", envs.len(), actions.len())));
        }
        // Envs grouped by server, each group in the order of `envs`.
        let mut groups: Vec<(String, Vec<usize>, Vec<BatchStep>)> = Vec::new();
        for (i, (env, actions)) in envs.iter_mut().zip(actions).enumerate() {
            env.seq += 1;
            let step = BatchStep { env: env.id, seq: env.seq, actions };
            match groups.iter_mut().find(|(server, ..)| *server == env.server) {
                Some((_, members, steps)) => {
                    members.push(i);
                    steps.push(step);
                }
                None => groups.push((env.server.clone(), vec![i], vec![step])),
            }
        }
        let mut results: Vec<Option<Result<StepReply>>> = envs.iter().map(|_| None).collect();
        let mut pending = tokio::task::JoinSet::new();
        let last = groups.pop();
        for (server, members, steps) in groups {
            let client = self.clone();
            pending.spawn(async move { (members, client.step_batch_on(&server, steps).await) });
        }
        // The last group (the only one, usually) is stepped here, without a task.
        if let Some((server, members, steps)) = last {
            scatter(&mut results, members, self.step_batch_on(&server, steps).await);
        }
        while let Some(done) = pending.join_next().await {
            let (members, outcome) = done.map_err(|e| ClientError::Protocol(format!("a batch task failed: {e}")))?;
            scatter(&mut results, members, outcome);
        }
        Ok(results.into_iter().map(|result| result.expect("every env is in one group")).collect())
    }

    /// One `StepBatch` round trip to `server`.
    async fn step_batch_on(&self, server: &str, steps: Vec<BatchStep>) -> Result<Vec<Result<StepReply>>> {
        let expected = steps.len();
        match self.call(server, RequestBody::StepBatch { steps }, true).await? {
            ReplyBody::StepBatch(items) if items.len() == expected => Ok(items
                .into_iter()
                .map(|item| match item {
                    BatchItem::Ok(reply) => Ok(reply),
                    BatchItem::Err(err) => Err(ClientError::Server(err)),
                })
                .collect()),
            ReplyBody::StepBatch(items) => {
                Err(ClientError::Protocol(format!("{expected} envs stepped but {} results came back", items.len())))
            }
            other => Err(unexpected("StepBatch", &other)),
        }
    }

    /// Every server alive and what it reports of itself (load included), under the id it
    /// was asked by; a server that does not answer is left out, but when servers are
    /// listed and none answers, the first error is returned (a server of another protocol
    /// version says so, rather than "no server").
    pub async fn server_infos(&self) -> Result<Vec<ServerInfo>> {
        let mut pending = tokio::task::JoinSet::new();
        for server in self.servers().await? {
            let client = self.clone();
            pending.spawn(async move {
                client.server_info(&server).await.map(|info| ServerInfo { server_id: server, ..info })
            });
        }
        let (mut infos, mut first_error) = (Vec::new(), None);
        while let Some(done) = pending.join_next().await {
            match done {
                Ok(Ok(info)) => infos.push(info),
                Ok(Err(error)) => {
                    first_error.get_or_insert(error);
                }
                Err(e) => {
                    first_error.get_or_insert(ClientError::Protocol(format!("a server info task failed: {e}")));
                }
            }
        }
        if let (true, Some(error)) = (infos.is_empty(), first_error) {
            return Err(error);
        }
        infos.sort_by(|a, b| a.server_id.cmp(&b.server_id));
        Ok(infos)
    }

    /// Where to create `count` new envs: each on the server with the fewest envs per
    /// core at that point (counting the ones placed before it; full servers skipped),
    /// ties to the fewest envs, then an order of this client's own (see
    /// `placement::spread`). Waits up to the timeout for a first server.
    pub async fn place(&self, count: usize) -> Result<Vec<String>> {
        self.pick_server().await?;
        let infos = self.server_infos().await?;
        if infos.is_empty() {
            return Err(ClientError::NoServer { prefix: self.inner.prefix.clone() });
        }
        let placed = placement::spread(&infos, count, self.inner.id.tag());
        if placed.len() < count {
            return Err(ClientError::Server(ErrorReply {
                code: ErrorCode::TooManyEnvs,
                message: format!(
                    "the {} server(s) found have room for {} more env(s), not {count} (each holds at most its \
                     --max-envs, and at most its --max-envs-per-client of yours): close envs you no longer need, \
                     or start another server",
                    infos.len(),
                    placed.len()
                ),
                env_usable: false,
            }));
        }
        Ok(placed)
    }

    /// Sends `body` to `server` and waits for its reply; with `retry`, resends the same
    /// bytes after each timeout.
    async fn call(&self, server: &str, body: RequestBody, retry: bool) -> Result<ReplyBody> {
        let what = request_name(&body);
        let request = Request { version: PROTOCOL_VERSION, client: self.inner.id, body };
        let bytes = encode(&request);
        let key = match &self.inner.user {
            Some(user) => keys::user_rpc(&self.inner.prefix, server, user),
            None => keys::server_rpc(&self.inner.prefix, server),
        }
        .map_err(zenoh_error)?;
        let attempts = if retry { self.inner.retries + 1 } else { 1 };
        let started = Instant::now();
        let mut unanswered = true;
        for _ in 0..attempts {
            let sent = Instant::now();
            if let Some(bytes) = self.get_once(&key, server, bytes.clone()).await? {
                let reply: Reply = decode(&bytes)
                    .map_err(|e| ClientError::Protocol(format!("cannot decode the reply to {what}: {e}")))?;
                return match reply.body {
                    ReplyBody::Error(err) => Err(ClientError::Server(err)),
                    body => Ok(body),
                };
            }
            // A get that ends well before its timeout found no queryable on the key.
            if sent.elapsed() < self.inner.timeout / 2 {
                tokio::time::sleep(GONE_GRACE).await;
            } else {
                unanswered = false;
            }
        }
        let waited = started.elapsed();
        if unanswered {
            return Err(ClientError::ServerGone { server: server.to_string(), what: what.to_string(), waited });
        }
        Err(ClientError::Timeout { what: what.to_string(), waited })
    }

    /// One Zenoh get answered by `server`'s session; `None` when it did not answer in
    /// time. Replies from any other session (one that declared a queryable on the
    /// server's key) are dropped, so nobody can answer in the server's place.
    async fn get_once(&self, key: &str, server: &str, payload: Vec<u8>) -> Result<Option<Vec<u8>>> {
        let replies = self
            .inner
            .session
            .get(key)
            .payload(payload)
            .target(QueryTarget::All)
            .consolidation(ConsolidationMode::None)
            .timeout(self.inner.timeout)
            .await
            .map_err(zenoh_error)?;
        // An error reply (Zenoh's own timeout among them) counts as no reply: the request
        // is retried like a missing one, and `call` says what happened in the end.
        // The server id is its session's Zenoh id (parsed once, not printed per reply).
        let expected = server.parse::<zenoh::session::ZenohId>().ok();
        while let Ok(reply) = replies.recv_async().await {
            let from_server = expected.is_some_and(|id| reply.replier_id().is_some_and(|replier| replier.zid() == id));
            if let (true, Ok(sample)) = (from_server, reply.result()) {
                return Ok(Some(sample.payload().to_bytes().into_owned()));
            }
        }
        Ok(None)
    }

    /// A raw Zenoh get on the server's echo key: sends `request_bytes` and asks for a
    /// reply of `reply_bytes`. `arena bench` compares this with a step round trip.
    pub async fn echo(&self, server: &str, request_bytes: usize, reply_bytes: u32) -> Result<Duration> {
        let key = keys::server_echo(&self.inner.prefix, server).map_err(zenoh_error)?;
        let mut payload = vec![0u8; request_bytes.max(4)];
        payload[..4].copy_from_slice(&reply_bytes.to_le_bytes());
        let started = Instant::now();
        match self.get_once(&key, server, payload).await? {
            Some(_) => Ok(started.elapsed()),
            None => Err(ClientError::Timeout { what: "echo".into(), waited: started.elapsed() }),
        }
    }

    /// Undeclares this client and closes its session, for every handle sharing it;
    /// servers then close its envs, 3 s later (the grace a dropped link has to come back;
    /// close the envs first to free their places at once). Closing twice is harmless.
    pub async fn close(&self) -> Result<()> {
        let token = self.inner.token.lock().map_or(None, |mut token| token.take());
        if let Some(token) = token {
            token.undeclare().await.map_err(zenoh_error)?;
        }
        if self.inner.session.is_closed() {
            return Ok(());
        }
        self.inner.session.close().await.map_err(zenoh_error)
    }
}

/// Puts a server's batch outcome in the places of its envs.
fn scatter(results: &mut [Option<Result<StepReply>>], members: Vec<usize>, outcome: Result<Vec<Result<StepReply>>>) {
    match outcome {
        Ok(replies) => members.into_iter().zip(replies).for_each(|(i, reply)| results[i] = Some(reply)),
        Err(error) => members.into_iter().for_each(|i| results[i] = Some(Err(error.clone()))),
    }
}

fn request_name(body: &RequestBody) -> &'static str {
    match body {
        RequestBody::ServerInfo => "server_info",
        RequestBody::CreateEnv { .. } => "create_env",
        RequestBody::Reset { .. } => "reset",
        RequestBody::Step { .. } => "step",
        RequestBody::StepBatch { .. } => "step_batch",
        RequestBody::Render { .. } => "render",
        RequestBody::State { .. } => "state",
        RequestBody::Specs { .. } => "specs",
        RequestBody::Close { .. } => "close",
        RequestBody::Record { .. } => "record",
        RequestBody::Snapshot { .. } => "snapshot",
        RequestBody::Restore { .. } => "restore",
        RequestBody::Statistics { .. } => "statistics",
    }
}

fn unexpected(wanted: &str, got: &ReplyBody) -> ClientError {
    ClientError::Protocol(format!("expected a {wanted} reply, got {got:?}"))
}

/// An env living on a server, created by this client.
#[derive(Debug)]
pub struct RemoteEnv {
    client: Client,
    server: String,
    id: EnvId,
    seq: u64,
    specs: EnvSpecs,
    closed: bool,
}

impl RemoteEnv {
    /// Its id on the server.
    pub fn id(&self) -> EnvId {
        self.id
    }

    /// The server it lives on.
    pub fn server(&self) -> &str {
        &self.server
    }

    /// Agents, spaces and timing, as the server described them at creation.
    pub fn specs(&self) -> &EnvSpecs {
        &self.specs
    }

    /// Starts an episode, with `overrides` of the scenario for it alone (dotted keys, as
    /// at creation).
    pub async fn reset(&mut self, seed: Option<u64>, overrides: Vec<(String, OptionValue)>) -> Result<ResetReply> {
        self.seq += 1;
        let body = RequestBody::Reset { env: self.id, seq: self.seq, seed, options: ResetOptions { overrides } };
        match self.client.call(&self.server, body, true).await? {
            ReplyBody::Reset(reply) => Ok(reply),
            other => Err(unexpected("Reset", &other)),
        }
    }

    /// Steps with the given actions (agents left out take the default action).
    pub async fn step(&mut self, actions: Vec<(String, Action)>) -> Result<StepReply> {
        self.seq += 1;
        self.step_with_seq(self.seq, actions).await
    }

    /// Steps with an explicit sequence number: repeating the last one returns the same
    /// reply without stepping again (what a retry does).
    pub async fn step_with_seq(&mut self, seq: u64, actions: Vec<(String, Action)>) -> Result<StepReply> {
        let body = RequestBody::Step { env: self.id, seq, actions };
        match self.client.call(&self.server, body, true).await? {
            ReplyBody::Step(reply) => Ok(reply),
            other => Err(unexpected("Step", &other)),
        }
    }

    /// A frame drawn by the server, following the vehicle named `follow` (any vehicle of
    /// the scenario), else the first learner.
    pub async fn render(&self, mode: RenderMode, follow: Option<&str>) -> Result<Frame> {
        let body = RequestBody::Render { env: self.id, mode, follow: follow.map(str::to_string) };
        match self.client.call(&self.server, body, true).await? {
            ReplyBody::Render(frame) => Ok(frame),
            other => Err(unexpected("Render", &other)),
        }
    }

    /// The global state.
    pub async fn state(&self) -> Result<Observation> {
        match self.client.call(&self.server, RequestBody::State { env: self.id }, true).await? {
            ReplyBody::State(state) => Ok(state),
            other => Err(unexpected("State", &other)),
        }
    }

    /// Turns recording on or off: while on, reset replies carry a `WorldStart` and step
    /// replies a `WorldFrame` per control period. Turned on after a reset, it returns the
    /// world now (road, vehicles, a frame), so a recording can begin mid-episode.
    pub async fn record(&self, on: bool) -> Result<Option<WorldStart>> {
        match self.client.call(&self.server, RequestBody::Record { env: self.id, on }, true).await? {
            ReplyBody::Recording(start) => Ok(start.map(|start| *start)),
            other => Err(unexpected("Recording", &other)),
        }
    }

    /// The env's whole state as bytes (docs/protocol.md, "Snapshots"): give them to
    /// `restore` on this env or another of the same scenario and options, on any server
    /// of this protocol version, to continue from here bit for bit.
    pub async fn snapshot(&self) -> Result<Vec<u8>> {
        match self.client.call(&self.server, RequestBody::Snapshot { env: self.id }, true).await? {
            ReplyBody::Snapshot(bytes) => Ok(bytes),
            other => Err(unexpected("Snapshot", &other)),
        }
    }

    /// Puts a snapshot's state into this env; the reply is a reset's, of the agents live
    /// in the snapshot. A snapshot of another scenario, options or protocol version, or
    /// damaged, is refused (`ErrorCode::InvalidSnapshot`) and the env stays as it was.
    pub async fn restore(&mut self, snapshot: Vec<u8>) -> Result<ResetReply> {
        self.seq += 1;
        let body = RequestBody::Restore { env: self.id, seq: self.seq, snapshot };
        match self.client.call(&self.server, body, true).await? {
            ReplyBody::Reset(reply) => Ok(reply),
            other => Err(unexpected("Reset", &other)),
        }
    }

    /// What the server spent on this env by its own clock: for each learner its built-in
    /// policy drives, the wall time of each step's decisions (docs/protocol.md,
    /// "Statistics").
    pub async fn statistics(&self) -> Result<EnvStatistics> {
        match self.client.call(&self.server, RequestBody::Statistics { env: self.id }, true).await? {
            ReplyBody::Statistics(statistics) => Ok(statistics),
            other => Err(unexpected("Statistics", &other)),
        }
    }

    /// Closes the env on the server. Closing twice is harmless here.
    pub async fn close(&mut self) -> Result<()> {
        if self.closed {
            return Ok(());
        }
        match self.client.call(&self.server, RequestBody::Close { env: self.id }, false).await {
            Ok(ReplyBody::Closed) | Err(ClientError::Server(ErrorReply { code: ErrorCode::EnvClosed, .. })) => {
                self.closed = true;
                Ok(())
            }
            Ok(other) => Err(unexpected("Closed", &other)),
            Err(e) => Err(e),
        }
    }
}
