//! The server's envs and the handling of one request, independent of Zenoh: bytes in,
//! reply out. Owns the rules a remote client meets — protocol version, bounds, ownership
//! of envs, sequence numbers that make retries safe (`sequence`), env limits and
//! reclaiming — so each can be tested without a network and the queryable stays thin.
//! Batches of steps are `batch`'s.
//! What the server needs to know of an env without stepping it (owner, party, creation,
//! last use) lives beside the env's lock, never under it: the sweeper, `ServerInfo`,
//! create, close and the owner check never wait for an env that is busy.

mod batch;
mod sequence;

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, TryLockError};
use std::time::{Duration, Instant};

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

/// The most client tags remembered beyond those of envs' owners (about 50 bytes each):
/// a session declaring tokens in a loop grows the registry by no more than this.
pub const MAX_CLIENT_TAGS: usize = 4096;

/// One env and what the server remembers about it: who owns it, outside the env's lock.
struct Slot {
    owner: ClientId,
    /// `owner.tag()`, what its liveliness token shows: computed once, read when clients leave.
    owner_tag: ClientTag,
    party: Party,
    created: Instant,
    /// When a request last touched it, as nanoseconds since `Registry::epoch`.
    last_used: AtomicU64,
    work: Mutex<Work>,
}

/// What a request works on, under the env's lock.
struct Work {
    env: Env,
    replies: ReplyCache,
}

/// An env's decisions to make ahead once a reset's or a step's reply is sent
/// (`Registry::handle_then`, `Registry::decide_ahead`).
pub struct Ahead(Arc<Slot>);

/// Every env of one server.
pub struct Registry {
    server_id: String,
    scenarios: Scenarios,
    limits: Limits,
    /// The origin of every `Slot::last_used`.
    epoch: Instant,
    envs: Mutex<HashMap<EnvId, Arc<Slot>>>,
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
            epoch: Instant::now(),
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
        let mut work = match ahead.0.work.try_lock() {
            _ if answering() => return,
            Ok(work) => work,
            Err(TryLockError::Poisoned(poisoned)) => poisoned.into_inner(),
            Err(TryLockError::WouldBlock) => return,
        };
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work.env.decide_ahead(&answering)));
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
                    Ok(ReplyBody::Reset(ResetReply { seq, agents, world: env.reset_world().map(Box::new) }))
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
                self.with_env(client, env, |work| work.env.render(mode, follow.as_deref()).map(ReplyBody::Render))
            }
            RequestBody::Statistics { env } => {
                self.with_env(client, env, |work| Ok(ReplyBody::Statistics(work.env.statistics())))
            }
            RequestBody::State { env } => self.with_env(client, env, |work| work.env.state().map(ReplyBody::State)),
            RequestBody::Specs { env } => self.with_env(client, env, |work| Ok(ReplyBody::Specs(work.env.specs()))),
            RequestBody::Close { env } => self.close(client, env),
            RequestBody::Record { env, on } => self.with_env(client, env, |work| {
                work.env.set_recording(on).map(|start| ReplyBody::Recording(start.map(Box::new)))
            }),
            RequestBody::Snapshot { env } => {
                self.with_env(client, env, |work| work.env.snapshot().map(ReplyBody::Snapshot))
            }
            RequestBody::Restore { env, seq, snapshot } => self.sequenced(client, env, seq, |env| {
                let agents = env.restore(&snapshot)?;
                Ok(ReplyBody::Reset(ResetReply { seq, agents, world: env.reset_world().map(Box::new) }))
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
            owner,
            owner_tag: owner.tag(),
            party,
            created: now,
            last_used: AtomicU64::new(self.since_epoch(now)),
            work: Mutex::new(Work { env, replies: ReplyCache::default() }),
        };
        envs.insert(id, Arc::new(slot));
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
        let env = Env::from_text(file, text, options, rand::random::<u64>())?;
        if let ScenarioSource::Inline { file_name, .. } = &source {
            inline_named_as_declared(file_name, env.scenario_name())?;
        }
        Ok(env)
    }

    /// Whether one more env fits the server (holding `open`) and the party's share.
    fn has_room(&self, open: usize, party: &Party) -> Result<(), ErrorReply> {
        lock(&self.shares).room(&self.limits, open, party)
    }

    /// Counts `party`'s env as gone (called under the `envs` lock).
    fn release(&self, party: &Party) {
        lock(&self.shares).release(party);
    }

    /// `now` as a `Slot::last_used`.
    fn since_epoch(&self, now: Instant) -> u64 {
        now.saturating_duration_since(self.epoch).as_nanos().min(u128::from(u64::MAX)) as u64
    }

    fn slot(&self, client: ClientId, env: EnvId) -> Result<Arc<Slot>, ErrorReply> {
        let found = lock(&self.envs).get(&env).cloned();
        match found {
            // Another client's env looks exactly like one that does not exist.
            Some(slot) if slot.owner == client => Ok(slot),
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
        f: impl FnOnce(&mut Work) -> Result<ReplyBody, ErrorReply>,
    ) -> Result<ReplyBody, ErrorReply> {
        let slot = self.slot(client, env)?;
        slot.last_used.store(self.since_epoch(Instant::now()), Ordering::Relaxed);
        let outcome = {
            let mut work = lock(&slot.work);
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(&mut work)))
        };
        slot.last_used.store(self.since_epoch(Instant::now()), Ordering::Relaxed);
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
        self.with_env(client, env, |work| {
            let Work { env, replies } = work;
            replies.once(seq, || f(env))
        })
    }

    fn close(&self, client: ClientId, env: EnvId) -> Result<ReplyBody, ErrorReply> {
        self.slot(client, env)?;
        let mut envs = lock(&self.envs);
        let removed = envs.remove(&env);
        if let Some(slot) = &removed {
            self.release(&slot.party);
        }
        drop(envs);
        lock(&self.closed).insert(env, client);
        // A request still working on it holds it; the last one out drops it, off these locks.
        drop(removed);
        Ok(ReplyBody::Closed)
    }

    /// Notes that the client whose public tag is `client` has a live liveliness token.
    /// Tokens cost nothing to declare, so past `MAX_CLIENT_TAGS` the tags that own no
    /// env are forgotten: an owner whose tag was forgotten is looked up again
    /// (`unseen_owners`) before its envs could be taken for orphans.
    pub fn client_arrived(&self, client: ClientTag) {
        let mut tokens = lock(&self.tokens);
        tokens.insert(client, None);
        if tokens.len() > MAX_CLIENT_TAGS {
            let owners: std::collections::HashSet<ClientTag> =
                lock(&self.envs).values().map(|slot| slot.owner_tag).collect();
            tokens.retain(|tag, _| owners.contains(tag));
        }
    }

    /// How many client tags the registry remembers now (at most `MAX_CLIENT_TAGS` beyond
    /// the owners of envs).
    pub fn client_tags(&self) -> usize {
        lock(&self.tokens).len()
    }

    /// The owners of envs, created at least `ORPHAN_GRACE` before `now`, of whom no token
    /// was seen: before `reclaim_orphans` takes their envs, ask whether they are there
    /// (their arrival may have been forgotten under a flood of tokens).
    pub fn unseen_owners(&self, now: Instant) -> Vec<ClientTag> {
        let tokens = lock(&self.tokens);
        let envs = lock(&self.envs);
        let mut unseen: Vec<ClientTag> = envs
            .values()
            .filter(|slot| now.saturating_duration_since(slot.created) >= ORPHAN_GRACE)
            .map(|slot| slot.owner_tag)
            .filter(|tag| !tokens.contains_key(tag))
            .collect();
        unseen.sort_unstable();
        unseen.dedup();
        unseen
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
        let now = self.since_epoch(now);
        self.retain(|slot| Duration::from_nanos(now.saturating_sub(slot.last_used.load(Ordering::Relaxed))) < timeout)
    }

    /// Closes the envs `keep` refuses; never waits for an env's own lock, so an env busy
    /// with a long request delays no other client's.
    fn retain(&self, keep: impl Fn(&Slot) -> bool) -> usize {
        let mut gone = Vec::new();
        let mut envs = lock(&self.envs);
        let mut closed = lock(&self.closed);
        envs.retain(|id, slot| {
            let kept = keep(slot);
            if !kept {
                closed.insert(*id, slot.owner);
                self.release(&slot.party);
                gone.push(Arc::clone(slot));
            }
            kept
        });
        drop((closed, envs));
        gone.len()
    }
}

fn wrong_version(version: u16) -> ErrorReply {
    error(
        ErrorCode::WrongVersion,
        format!("request speaks protocol {version}, this server speaks {PROTOCOL_VERSION}; upgrade the older side"),
        true,
    )
}

/// An inline scenario is named by its file (`*.toml`, which only names it in messages) or
/// by the `name` its text declares: any other name would label an env, and the results
/// and recordings made with it, as a scenario its text is not.
fn inline_named_as_declared(given: &str, declared: &str) -> Result<(), ErrorReply> {
    if given == declared || given.ends_with(".toml") {
        return Ok(());
    }
    Err(error(
        ErrorCode::InvalidScenario,
        format!(
            "the scenario text declares name = \"{declared}\" but was sent as '{given}': send it as '{declared}' \
             (or as a file name ending in .toml), or change its name"
        ),
        true,
    ))
}
