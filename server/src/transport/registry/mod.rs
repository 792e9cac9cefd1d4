//! The server's envs and the handling of one request, independent of Zenoh: bytes in,
//! reply out. Owns the rules a remote client meets — protocol version, bounds, ownership
//! of envs, sequence numbers that make retries safe (`sequence`), env limits and
//! reclaiming — so each can be tested without a network and the queryable stays thin.
//! Batches of steps are `batch`'s.

mod batch;
mod sequence;

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, TryLockError};
use std::time::Instant;

use arena_protocol::{
    AgentStep, ClientId, ClientTag, CreateOptions, EnvId, ErrorCode, ErrorReply, MAX_MESSAGE_BYTES, PROTOCOL_VERSION,
    Reply, ReplyBody, Request, RequestBody, ResetReply, ScenarioSource, ServerInfo, StepReply, bounds, decode, encode,
    peek_version,
};

use super::limits::{Limits, ORPHAN_GRACE, Party, Shares};
use super::memory::resident_bytes;
use super::scenarios::Scenarios;
use crate::env::Env;
use batch::Single;
use sequence::{ReplyCache, Tombstones};

/// One env and what the server remembers about it.
struct Slot {
    env: Env,
    owner: ClientId,
    /// `owner.tag()`, what its liveliness token shows: computed once, read when clients leave.
    owner_tag: ClientTag,
    party: Party,
    created: Instant,
    replies: ReplyCache,
    last_used: Instant,
}

/// An env's decisions to make ahead once a reset's or a step's reply is sent
/// (`Registry::handle_then`, `Registry::decide_ahead`).
pub struct Ahead(Arc<Mutex<Slot>>);

/// Every env of one server.
pub struct Registry {
    server_id: String,
    scenarios: Scenarios,
    limits: Limits,
    envs: Mutex<HashMap<EnvId, Arc<Mutex<Slot>>>>,
    /// How many envs each party holds (kept with `envs`, under its lock, so a create
    /// checks the party's limit without visiting every env).
    shares: Mutex<Shares>,
    /// Clients by tag: `None` while their liveliness token is alive, else when it went.
    tokens: Mutex<HashMap<ClientTag, Option<Instant>>>,
    closed: Mutex<Tombstones>,
    /// Env steps taken, for `ServerInfo::steps`.
    steps: AtomicU64,
    /// Steps the envs of a batch, one thread per core; started by the first batch.
    batch_workers: std::sync::OnceLock<Option<rayon::ThreadPool>>,
    /// Single steps and resets being answered now: batch workers give way to them between
    /// envs, so a client's big batch does not hold up another client's step.
    singles: AtomicUsize,
    /// The kind of request whose next one panics (`inject_panic`).
    #[cfg(feature = "test-hooks")]
    panic_next: Mutex<Option<&'static str>>,
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic while holding a lock cannot leave an env half-stepped in a way later
    // requests could see wrongly: a request that panics inside an env closes it. Keep
    // serving.
    mutex.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn error(code: ErrorCode, message: impl Into<String>, env_usable: bool) -> ErrorReply {
    ErrorReply { code, message: message.into(), env_usable }
}

impl Registry {
    /// An empty registry for server `server_id`.
    pub fn new(server_id: String, scenarios: Scenarios, limits: Limits) -> Registry {
        Registry {
            server_id,
            scenarios,
            limits,
            envs: Mutex::new(HashMap::new()),
            shares: Mutex::new(Shares::default()),
            tokens: Mutex::new(HashMap::new()),
            closed: Mutex::new(Tombstones::default()),
            steps: AtomicU64::new(0),
            batch_workers: std::sync::OnceLock::new(),
            singles: AtomicUsize::new(0),
            #[cfg(feature = "test-hooks")]
            panic_next: Mutex::new(None),
        }
    }

    /// Makes the next request of `kind` ("create", "reset" or "step") panic inside the
    /// server, where a bug would: for the tests that show a panic is contained.
    #[cfg(feature = "test-hooks")]
    pub fn inject_panic(&self, kind: &'static str) {
        *lock(&self.panic_next) = Some(kind);
    }

    fn panic_if_injected(&self, _kind: &str) {
        #[cfg(feature = "test-hooks")]
        if lock(&self.panic_next).take_if(|next| *next == _kind).is_some() {
            panic!("a panic injected into {_kind} by a test");
        }
    }

    /// How many envs are alive.
    pub fn len(&self) -> usize {
        lock(&self.envs).len()
    }

    /// Whether no env is alive.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Answers one request, given as the bytes that arrived, from an unnamed user.
    pub fn handle(&self, bytes: &[u8]) -> Vec<u8> {
        self.handle_from(None, bytes)
    }

    /// Answers one request that came as `user` (named by its key, which only a site's
    /// access control makes trustworthy): its envs count against that user's limit.
    pub fn handle_from(&self, user: Option<&str>, bytes: &[u8]) -> Vec<u8> {
        self.handle_then(user, bytes).0
    }

    /// `handle_from`, and for a reset or a single step whose episode goes on, the work that
    /// may start once its reply is sent: the env's next decisions (`Env::decide_ahead`).
    pub fn handle_then(&self, user: Option<&str>, bytes: &[u8]) -> (Vec<u8>, Option<Ahead>) {
        let mut ahead = None;
        let body = self.answer(user, bytes, &mut ahead).unwrap_or_else(ReplyBody::Error);
        (encode(&Reply { version: PROTOCOL_VERSION, body }), ahead)
    }

    /// Makes `ahead`'s decisions (`Env::decide_ahead`) until a single step or reset is
    /// being answered: that request then waits for one decision at most, not for all of
    /// them. Call it off the thread that receives requests. It never waits for the env:
    /// one in use is being stepped (and a step's parallel decisions may need the very
    /// thread this runs on). A panic in it closes nothing: the env's next request meets
    /// whatever it left, as a step that panicked would.
    pub fn decide_ahead(&self, ahead: Ahead) {
        let answering = || self.singles.load(Ordering::SeqCst) > 0;
        let mut slot = match ahead.0.try_lock() {
            _ if answering() => return,
            Ok(slot) => slot,
            Err(TryLockError::Poisoned(poisoned)) => poisoned.into_inner(),
            Err(TryLockError::WouldBlock) => return,
        };
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| slot.env.decide_ahead(&answering)));
    }

    fn answer(&self, user: Option<&str>, bytes: &[u8], ahead: &mut Option<Ahead>) -> Result<ReplyBody, ErrorReply> {
        if bytes.len() > MAX_MESSAGE_BYTES {
            return Err(error(
                ErrorCode::PayloadTooLarge,
                format!("request of {} bytes exceeds the limit of {MAX_MESSAGE_BYTES}", bytes.len()),
                true,
            ));
        }
        let request: Request = decode(bytes).map_err(|e| match peek_version(bytes) {
            Some(version) if version != PROTOCOL_VERSION => wrong_version(version),
            _ => error(ErrorCode::MalformedRequest, format!("cannot decode the request: {e}"), true),
        })?;
        if request.version != PROTOCOL_VERSION {
            return Err(wrong_version(request.version));
        }
        bounds::check(&request).map_err(|e| error(ErrorCode::PayloadTooLarge, e.to_string(), true))?;
        let client = request.client;
        let party = Party::of(user, client);
        let _single = matches!(request.body, RequestBody::Step { .. } | RequestBody::Reset { .. })
            .then(|| Single::begin(&self.singles));
        match request.body {
            RequestBody::ServerInfo => Ok(ReplyBody::ServerInfo(self.info(&party))),
            RequestBody::CreateEnv { scenario, options } => self.create(client, party, scenario, &options),
            RequestBody::Reset { env: id, seq, seed, options } => {
                let reply = self.sequenced(client, id, seq, |env| {
                    self.panic_if_injected("reset");
                    let agents = env.reset(seed, &options)?;
                    Ok(ReplyBody::Reset(ResetReply { seq, agents, world: env.world_start().map(Box::new) }))
                });
                self.ahead_of_step(&reply, client, id, ahead);
                reply
            }
            RequestBody::Step { env: id, seq, actions } => {
                let reply =
                    self.sequenced(client, id, seq, |env| self.step_reply(env, seq, &actions).map(ReplyBody::Step));
                self.ahead_of_step(&reply, client, id, ahead);
                reply
            }
            RequestBody::StepBatch { steps } => {
                self.check_batch(&steps)?;
                Ok(ReplyBody::StepBatch(self.step_batch(client, &steps)))
            }
            RequestBody::Render { env, mode, follow } => {
                self.with_env(client, env, |slot| slot.env.render(mode, follow.as_deref()).map(ReplyBody::Render))
            }
            RequestBody::Statistics { env } => {
                self.with_env(client, env, |slot| Ok(ReplyBody::Statistics(slot.env.statistics())))
            }
            RequestBody::State { env } => self.with_env(client, env, |slot| slot.env.state().map(ReplyBody::State)),
            RequestBody::Specs { env } => self.with_env(client, env, |slot| Ok(ReplyBody::Specs(slot.env.specs()))),
            RequestBody::Close { env } => self.close(client, env),
            RequestBody::Record { env, on } => self.with_env(client, env, |slot| {
                slot.env.set_recording(on).map(|start| ReplyBody::Recording(start.map(Box::new)))
            }),
            RequestBody::Snapshot { env } => {
                self.with_env(client, env, |slot| slot.env.snapshot().map(ReplyBody::Snapshot))
            }
            RequestBody::Restore { env, seq, snapshot } => self.sequenced(client, env, seq, |env| {
                let agents = env.restore(&snapshot)?;
                Ok(ReplyBody::Reset(ResetReply { seq, agents, world: env.world_start().map(Box::new) }))
            }),
        }
    }

    /// Sets `ahead` to env `id`'s next decisions when `reply` leaves it waiting for a step:
    /// a reset, or a step whose episode goes on.
    fn ahead_of_step(
        &self,
        reply: &Result<ReplyBody, ErrorReply>,
        client: ClientId,
        id: EnvId,
        ahead: &mut Option<Ahead>,
    ) {
        let goes_on = match reply {
            Ok(ReplyBody::Step(step)) => !step.agents.is_empty(),
            Ok(ReplyBody::Reset(reset)) => !reset.agents.is_empty(),
            _ => false,
        };
        if goes_on {
            *ahead = self.slot(client, id).ok().map(Ahead);
        }
    }

    /// One env step, counted in `ServerInfo::steps` when it is taken.
    fn step_reply(
        &self,
        env: &mut Env,
        seq: u64,
        actions: &[(String, arena_protocol::Action)],
    ) -> Result<StepReply, ErrorReply> {
        self.panic_if_injected("step");
        let steps: Vec<AgentStep> = env.step(actions)?;
        self.steps.fetch_add(1, Ordering::Relaxed);
        let (world, explain) = (env.take_frames(), env.take_explanations());
        Ok(StepReply { seq, steps, agents: env.live_agents(), world, explain })
    }

    fn info(&self, party: &Party) -> ServerInfo {
        ServerInfo {
            server_id: self.server_id.clone(),
            version: env!("CARGO_PKG_VERSION").to_string(),
            protocol: PROTOCOL_VERSION,
            scenarios: self.scenarios.names(),
            envs: self.len() as u32,
            max_envs: self.limits.max_envs as u32,
            max_envs_per_client: self.limits.max_envs_per_client as u32,
            yours: lock(&self.shares).of(party) as u32,
            steps: self.steps.load(Ordering::Relaxed),
            cores: std::thread::available_parallelism().map_or(1, |n| n.get() as u32),
            rss_bytes: resident_bytes(),
        }
    }

    fn create(
        &self,
        owner: ClientId,
        party: Party,
        source: ScenarioSource,
        options: &CreateOptions,
    ) -> Result<ReplyBody, ErrorReply> {
        // Refused before any work: a full server parses and builds nothing.
        self.has_room(lock(&self.envs).len(), &party)?;
        let build = std::panic::AssertUnwindSafe(|| self.build(source, options));
        let env = std::panic::catch_unwind(build).unwrap_or_else(|_| {
            Err(error(ErrorCode::Internal, "creating this env panicked (a server bug); nothing was created", true))
        })?;
        let id = EnvId(rand::random::<u128>());
        let specs = env.specs();
        let mut envs = lock(&self.envs);
        // Again under the lock: another create may have taken the last place meanwhile.
        self.has_room(envs.len(), &party)?;
        lock(&self.shares).take(&party);
        let now = Instant::now();
        let slot = Slot {
            env,
            owner,
            owner_tag: owner.tag(),
            party,
            created: now,
            replies: ReplyCache::default(),
            last_used: now,
        };
        envs.insert(id, Arc::new(Mutex::new(slot)));
        Ok(ReplyBody::Created { env: id, specs })
    }

    /// The env a create asks for, built from its scenario and options.
    fn build(&self, source: ScenarioSource, options: &CreateOptions) -> Result<Env, ErrorReply> {
        self.panic_if_injected("create");
        let (file, text) = match &source {
            ScenarioSource::Named(name) => self.scenarios.get(name).ok_or_else(|| {
                let known = self.scenarios.names().join(", ");
                error(
                    ErrorCode::UnknownScenario,
                    format!("no scenario named '{name}' on this server; it has: {known}"),
                    true,
                )
            })?,
            ScenarioSource::Inline { file_name, text } => (file_name.as_str(), text.as_str()),
        };
        Env::from_text(file, text, options, rand::random::<u64>())
    }

    /// Whether one more env fits the server (holding `open`) and the party's share.
    fn has_room(&self, open: usize, party: &Party) -> Result<(), ErrorReply> {
        lock(&self.shares).room(&self.limits, open, party)
    }

    /// Counts `party`'s env as gone (called under the `envs` lock).
    fn release(&self, party: &Party) {
        lock(&self.shares).release(party);
    }

    fn slot(&self, client: ClientId, env: EnvId) -> Result<Arc<Mutex<Slot>>, ErrorReply> {
        let found = lock(&self.envs).get(&env).cloned();
        match found {
            // Another client's env looks exactly like one that does not exist.
            Some(slot) if lock(&slot).owner == client => Ok(slot),
            // Only its owner learns that a closed env existed; to anyone else it is unknown.
            None if lock(&self.closed).closed_for(&env, client) => {
                Err(error(ErrorCode::EnvClosed, format!("env {env} was closed; create a new one"), false))
            }
            _ => Err(error(ErrorCode::UnknownEnv, format!("no env {env} of yours on this server"), false)),
        }
    }

    /// Runs `f` on the client's env. A panic in it is that env's end, not the server's
    /// silence: the env, half changed, is closed and the client told at once.
    fn with_env(
        &self,
        client: ClientId,
        env: EnvId,
        f: impl FnOnce(&mut Slot) -> Result<ReplyBody, ErrorReply>,
    ) -> Result<ReplyBody, ErrorReply> {
        let slot = self.slot(client, env)?;
        let outcome = {
            let mut slot = lock(&slot);
            slot.last_used = Instant::now();
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(&mut slot)))
        };
        outcome.unwrap_or_else(|_| {
            let _ = self.close(client, env);
            let message = "this env panicked while answering (a server bug); it was closed: create a new one";
            Err(error(ErrorCode::Internal, message, false))
        })
    }

    /// Runs a mutating request on the client's env once per sequence number
    /// (`ReplyCache::once`).
    fn sequenced(
        &self,
        client: ClientId,
        env: EnvId,
        seq: u64,
        f: impl FnOnce(&mut Env) -> Result<ReplyBody, ErrorReply>,
    ) -> Result<ReplyBody, ErrorReply> {
        self.with_env(client, env, |slot| {
            let Slot { env, replies, .. } = slot;
            replies.once(seq, || f(env))
        })
    }

    fn close(&self, client: ClientId, env: EnvId) -> Result<ReplyBody, ErrorReply> {
        self.slot(client, env)?;
        let mut envs = lock(&self.envs);
        if let Some(slot) = envs.remove(&env) {
            self.release(&lock(&slot).party);
        }
        drop(envs);
        lock(&self.closed).insert(env, client);
        Ok(ReplyBody::Closed)
    }

    /// Notes that the client whose public tag is `client` has a live liveliness token.
    pub fn client_arrived(&self, client: ClientTag) {
        lock(&self.tokens).insert(client, None);
    }

    /// Notes that the token of the client whose public tag is `client` went at `now`.
    /// Its envs stay for `ORPHAN_GRACE`: a client whose link drops and comes back (Zenoh
    /// reconnects it and declares its token again) loses nothing; `reclaim_orphans`
    /// closes them if it stays away.
    pub fn client_left(&self, client: ClientTag, now: Instant) {
        lock(&self.tokens).insert(client, Some(now));
    }

    /// Closes the envs whose owner has shown no liveliness token for `ORPHAN_GRACE`:
    /// since it left, or since the env was created by an id that never showed one; returns
    /// how many. Ids cost nothing, so without this one session minting ids could hold
    /// every place of an open server until the idle timeout.
    pub fn reclaim_orphans(&self, now: Instant) -> usize {
        let tokens = lock(&self.tokens).clone();
        let away_too_long = |slot: &Slot| {
            let since = match tokens.get(&slot.owner_tag) {
                Some(None) => return false,
                Some(Some(left)) => (*left).max(slot.created),
                None => slot.created,
            };
            now.saturating_duration_since(since) >= ORPHAN_GRACE
        };
        let closed = self.retain(|slot| !away_too_long(slot));
        // Every env of a client gone this long was closed just now: forget it.
        lock(&self.tokens).retain(|_, left| left.is_none_or(|left| now.saturating_duration_since(left) < ORPHAN_GRACE));
        closed
    }

    /// Closes envs idle for longer than the limit; returns how many.
    pub fn reclaim_idle(&self, now: Instant) -> usize {
        let timeout = self.limits.idle_timeout;
        self.retain(|slot| now.saturating_duration_since(slot.last_used) < timeout)
    }

    fn retain(&self, keep: impl Fn(&Slot) -> bool) -> usize {
        let mut envs = lock(&self.envs);
        let before = envs.len();
        let mut closed = lock(&self.closed);
        envs.retain(|id, slot| {
            let slot = lock(slot);
            let kept = keep(&slot);
            if !kept {
                closed.insert(*id, slot.owner);
                self.release(&slot.party);
            }
            kept
        });
        before - envs.len()
    }
}

fn wrong_version(version: u16) -> ErrorReply {
    error(
        ErrorCode::WrongVersion,
        format!("request speaks protocol {version}, this server speaks {PROTOCOL_VERSION}; upgrade the older side"),
        true,
    )
}
