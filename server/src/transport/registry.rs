//! The server's envs and the handling of one request, independent of Zenoh: bytes in,
//! reply out. Owns the rules a remote client meets — protocol version, size limit,
//! ownership of envs, sequence numbers that make retries safe, env limits and
//! reclaiming — so each can be tested without a network and the queryable stays thin.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use arena_protocol::{
    BatchItem, BatchStep, ClientId, ClientTag, CreateOptions, EnvId, ErrorCode, ErrorReply, MAX_MESSAGE_BYTES,
    OptionValue, PROTOCOL_VERSION, Reply, ReplyBody, Request, RequestBody, ResetReply, ScenarioSource, ServerInfo,
    StepReply, bounds, decode, encode, peek_version,
};

use rayon::prelude::*;

use crate::env::Env;
use arena_sim::scenario::{BUILTIN, Scenario};

/// How much a server takes on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Most envs alive at once.
    pub max_envs: usize,
    /// Most envs one party may hold at once: an authenticated user (the user named by the
    /// key a request came on), else a client id.
    pub max_envs_per_client: usize,
    /// An env nobody touched for this long is closed.
    pub idle_timeout: Duration,
}

impl Default for Limits {
    fn default() -> Self {
        Limits { max_envs: 1024, max_envs_per_client: 256, idle_timeout: Duration::from_secs(600) }
    }
}

/// Who an env counts against in `Limits::max_envs_per_client`: the user a site's access
/// control let the request through as (the last chunk of its key), else its client id.
/// An open server cannot tell parties apart better than this: ids cost nothing.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
enum Party {
    User(String),
    Client(ClientId),
}

impl Party {
    fn of(user: Option<&str>, client: ClientId) -> Party {
        user.map_or(Party::Client(client), |user| Party::User(user.to_string()))
    }
}

/// How long an env's owner has for its liveliness token to reach the server after the
/// create: envs of a client without a token are closed after this (`reclaim_orphans`).
pub const ORPHAN_GRACE: Duration = Duration::from_secs(3);

/// One env and what the server remembers about it.
struct Slot {
    env: Env,
    owner: ClientId,
    /// `owner.tag()`, what its liveliness token shows: computed once, read when clients leave.
    owner_tag: ClientTag,
    party: Party,
    created: Instant,
    /// The last mutating request's sequence number and its reply.
    last: Option<(u64, ReplyBody)>,
    last_used: Instant,
}

/// Scenario texts the server can create envs from, by name.
#[derive(Debug, Clone, Default)]
pub struct Scenarios {
    entries: Vec<(String, String, String)>,
}

impl Scenarios {
    /// The built-in scenarios plus every `*.toml` in `dir`, each served under the `name`
    /// its file declares (a name in `dir` replaces a built-in one). A folder that cannot
    /// be read, a file that does not load, or two files of one name are an error that
    /// names the file and what is wrong.
    pub fn load(dir: Option<&std::path::Path>) -> Result<Scenarios, String> {
        let mut entries: Vec<(String, String, String)> =
            BUILTIN.iter().map(|(name, file, text)| (name.to_string(), file.to_string(), text.to_string())).collect();
        let Some(dir) = dir else { return Ok(Scenarios { entries }) };
        let listing =
            std::fs::read_dir(dir).map_err(|e| format!("cannot read the scenario folder {}: {e}", dir.display()))?;
        let mut paths: Vec<_> =
            listing.flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|e| e == "toml")).collect();
        paths.sort();
        let mut seen: Vec<(String, std::path::PathBuf)> = Vec::new();
        for path in paths {
            let scenario = Scenario::load(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            if let Some((_, other)) = seen.iter().find(|(name, _)| *name == scenario.name) {
                return Err(format!(
                    "{} and {} both declare name = \"{}\"; scenario names must be unique",
                    other.display(),
                    path.display(),
                    scenario.name
                ));
            }
            let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            let file = path.file_name().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
            entries.retain(|(n, ..)| *n != scenario.name);
            entries.push((scenario.name.clone(), file, text));
            seen.push((scenario.name, path));
        }
        Ok(Scenarios { entries })
    }

    /// Scenario names, sorted.
    pub fn names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.entries.iter().map(|(n, ..)| n.clone()).collect();
        names.sort();
        names
    }

    fn get(&self, name: &str) -> Option<(&str, &str)> {
        self.entries.iter().find(|(n, ..)| n == name).map(|(_, file, text)| (file.as_str(), text.as_str()))
    }
}

/// Every env of one server.
pub struct Registry {
    server_id: String,
    scenarios: Scenarios,
    limits: Limits,
    envs: Mutex<HashMap<EnvId, Arc<Mutex<Slot>>>>,
    /// How many envs each party holds (kept with `envs`, under its lock, so a create
    /// checks the party's limit without visiting every env).
    held: Mutex<HashMap<Party, usize>>,
    /// Tags of the clients whose liveliness tokens are alive now.
    live: Mutex<HashSet<ClientTag>>,
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

/// Ids of recently closed envs, so a late request gets `EnvClosed` rather than
/// `UnknownEnv`; bounded, oldest forgotten first, so a long-lived server does not grow.
#[derive(Default)]
struct Tombstones {
    owners: HashMap<EnvId, ClientId>,
    order: std::collections::VecDeque<EnvId>,
}

impl Tombstones {
    const CAPACITY: usize = 1 << 16;

    fn insert(&mut self, id: EnvId, owner: ClientId) {
        if self.owners.insert(id, owner).is_none() {
            self.order.push_back(id);
        }
        while self.order.len() > Self::CAPACITY {
            if let Some(old) = self.order.pop_front() {
                self.owners.remove(&old);
            }
        }
    }

    /// Whether `id` was an env of `client` that has been closed.
    fn closed_for(&self, id: &EnvId, client: ClientId) -> bool {
        self.owners.get(id) == Some(&client)
    }
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic while holding a lock cannot leave an env half-stepped in a way later
    // requests could see wrongly: steps validate before they mutate. Keep serving.
    mutex.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The longest a batch worker waits, before each env, for single requests to be answered.
const GIVE_WAY_AT_MOST: Duration = Duration::from_millis(2);

/// The batch pool: as many threads as cores; `None` (batches step on the caller's
/// thread) if no thread can be started.
fn batch_workers() -> Option<rayon::ThreadPool> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    rayon::ThreadPoolBuilder::new().num_threads(threads).thread_name(|i| format!("batch-{i}")).build().ok()
}

/// Counts a single request as being answered for as long as it lives.
struct Single<'a>(&'a AtomicUsize);

impl<'a> Single<'a> {
    fn begin(count: &'a AtomicUsize) -> Single<'a> {
        count.fetch_add(1, Ordering::SeqCst);
        Single(count)
    }
}

impl Drop for Single<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

fn error(code: ErrorCode, message: impl Into<String>, env_usable: bool) -> ErrorReply {
    ErrorReply { code, message: message.into(), env_usable }
}

fn to_toml(value: &OptionValue) -> toml::Value {
    match value {
        OptionValue::Bool(b) => toml::Value::Boolean(*b),
        OptionValue::Int(i) => toml::Value::Integer(*i),
        OptionValue::Float(f) => toml::Value::Float(*f),
        // A string that is a TOML value ("{ kind = \"idm\" }", "[1, 2]") is taken as one,
        // so tables can be overridden too; anything else is a plain string.
        OptionValue::Str(s) => format!("v = {s}")
            .parse::<toml::Table>()
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(s.clone())),
    }
}

impl Registry {
    /// An empty registry for server `server_id`.
    pub fn new(server_id: String, scenarios: Scenarios, limits: Limits) -> Registry {
        Registry {
            server_id,
            scenarios,
            limits,
            envs: Mutex::new(HashMap::new()),
            held: Mutex::new(HashMap::new()),
            live: Mutex::new(HashSet::new()),
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
        let body = self.answer(user, bytes).unwrap_or_else(ReplyBody::Error);
        encode(&Reply { version: PROTOCOL_VERSION, body })
    }

    fn answer(&self, user: Option<&str>, bytes: &[u8]) -> Result<ReplyBody, ErrorReply> {
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
            RequestBody::Reset { env, seq, seed, options } => self.sequenced(client, env, seq, |slot| {
                self.panic_if_injected("reset");
                let outcome = slot.env.reset(seed, &options)?;
                let mut observations = Vec::with_capacity(outcome.len());
                let mut infos = Vec::with_capacity(outcome.len());
                for (agent, observation, info) in outcome {
                    observations.push((agent.clone(), observation));
                    infos.push((agent, info));
                }
                Ok(ReplyBody::Reset(ResetReply { seq, observations, infos }))
            }),
            RequestBody::Step { env, seq, actions } => self
                .sequenced(client, env, seq, |slot| self.step_reply(&mut slot.env, seq, &actions).map(ReplyBody::Step)),
            RequestBody::StepBatch { steps } => {
                self.check_batch(&steps)?;
                Ok(ReplyBody::StepBatch(self.step_batch(client, &steps)))
            }
            RequestBody::Render { env, mode } => {
                self.with_env(client, env, |slot| slot.env.render(mode).map(ReplyBody::Render))
            }
            RequestBody::State { env } => self.with_env(client, env, |slot| slot.env.state().map(ReplyBody::State)),
            RequestBody::Specs { env } => self.with_env(client, env, |slot| Ok(ReplyBody::Specs(slot.env.specs()))),
            RequestBody::Close { env } => self.close(client, env),
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
        let reply = step_reply(env, seq, actions)?;
        self.steps.fetch_add(1, Ordering::Relaxed);
        Ok(reply)
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
            yours: self.held_by(party) as u32,
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
        *lock(&self.held).entry(party.clone()).or_default() += 1;
        let now = Instant::now();
        let slot = Slot { env, owner, owner_tag: owner.tag(), party, created: now, last: None, last_used: now };
        envs.insert(id, Arc::new(Mutex::new(slot)));
        Ok(ReplyBody::Created { env: id, specs })
    }

    /// The env a create asks for, built from its scenario and options.
    fn build(&self, source: ScenarioSource, options: &CreateOptions) -> Result<Env, ErrorReply> {
        self.panic_if_injected("create");
        let overrides: Vec<(String, toml::Value)> =
            options.overrides.iter().map(|(k, v)| (k.clone(), to_toml(v))).collect();
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
        let scenario = Scenario::parse(file, text, &overrides)
            .map_err(|e| error(ErrorCode::InvalidScenario, e.to_string(), true))?;
        Env::new(scenario, options, rand::random::<u64>())
    }

    fn held_by(&self, party: &Party) -> usize {
        lock(&self.held).get(party).copied().unwrap_or(0)
    }

    /// Whether one more env fits the server (holding `open`) and the party's share.
    fn has_room(&self, open: usize, party: &Party) -> Result<(), ErrorReply> {
        let limits = &self.limits;
        if open >= limits.max_envs {
            let message =
                format!("this server holds its limit of {} envs; close one or use another server", limits.max_envs);
            return Err(error(ErrorCode::TooManyEnvs, message, true));
        }
        if self.held_by(party) >= limits.max_envs_per_client {
            let who = match party {
                Party::User(user) => format!("user '{user}'"),
                Party::Client(_) => "this client".to_string(),
            };
            let message = format!(
                "{who} holds its limit of {} envs on this server (--max-envs-per-client); close one first",
                limits.max_envs_per_client
            );
            return Err(error(ErrorCode::TooManyEnvs, message, true));
        }
        Ok(())
    }

    /// Counts `party`'s env as gone (called under the `envs` lock).
    fn release(&self, party: &Party) {
        let mut held = lock(&self.held);
        if let Some(count) = held.get_mut(party) {
            *count -= 1;
            if *count == 0 {
                held.remove(party);
            }
        }
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

    /// Runs a mutating request once per sequence number: a retry of the last one gets
    /// the cached reply, an older one is refused.
    fn sequenced(
        &self,
        client: ClientId,
        env: EnvId,
        seq: u64,
        f: impl FnOnce(&mut Slot) -> Result<ReplyBody, ErrorReply>,
    ) -> Result<ReplyBody, ErrorReply> {
        self.with_env(client, env, |slot| Self::once_per_seq(slot, seq, f))
    }

    fn once_per_seq(
        slot: &mut Slot,
        seq: u64,
        f: impl FnOnce(&mut Slot) -> Result<ReplyBody, ErrorReply>,
    ) -> Result<ReplyBody, ErrorReply> {
        match &slot.last {
            Some((last, cached)) if *last == seq => return Ok(cached.clone()),
            Some((last, _)) if seq < *last => {
                return Err(error(
                    ErrorCode::StaleSequence,
                    format!("sequence number {seq} is older than the last one, {last}"),
                    true,
                ));
            }
            _ => {}
        }
        let body = f(slot).unwrap_or_else(ReplyBody::Error);
        slot.last = Some((seq, body.clone()));
        Ok(body)
    }

    /// A batch names each env once and no more envs than one client may hold, so its
    /// reply (one result per env) stays bounded whatever a request asks.
    fn check_batch(&self, steps: &[BatchStep]) -> Result<(), ErrorReply> {
        let most = self.limits.max_envs_per_client.min(self.limits.max_envs);
        if steps.len() > most {
            return Err(error(
                ErrorCode::MalformedRequest,
                format!(
                    "a batch of {} steps is more than the {most} envs a client may hold on this server",
                    steps.len()
                ),
                true,
            ));
        }
        let mut envs: Vec<EnvId> = steps.iter().map(|step| step.env).collect();
        envs.sort_unstable();
        if let Some(pair) = envs.windows(2).find(|pair| pair[0] == pair[1]) {
            return Err(error(
                ErrorCode::MalformedRequest,
                format!("env {} appears twice in one batch: step each env once per batch", pair[0]),
                true,
            ));
        }
        Ok(())
    }

    /// Sleeps while single requests are being answered (up to `GIVE_WAY_AT_MOST`), so
    /// the cores go to them first. Before that, the worker yields its core once: a Zenoh
    /// thread woken by a single request that has not reached the server yet runs then,
    /// not when the scheduler would next preempt a busy worker (milliseconds later).
    fn give_way(&self) {
        std::thread::yield_now();
        let started = Instant::now();
        while self.singles.load(Ordering::SeqCst) > 0 && started.elapsed() < GIVE_WAY_AT_MOST {
            std::thread::sleep(Duration::from_micros(50));
        }
    }

    fn step_batch(&self, client: ClientId, steps: &[BatchStep]) -> Vec<BatchItem> {
        let one = |step: &BatchStep| -> BatchItem {
            let body = self.sequenced(client, step.env, step.seq, |slot| {
                self.step_reply(&mut slot.env, step.seq, &step.actions).map(ReplyBody::Step)
            });
            match body {
                Ok(ReplyBody::Step(step)) => BatchItem::Ok(step),
                Ok(ReplyBody::Error(err)) | Err(err) => BatchItem::Err(err),
                // The seq last answered a reset of this env: report it, step nothing.
                Ok(_) => BatchItem::Err(error(
                    ErrorCode::StaleSequence,
                    format!("sequence number {} was used by a reset of this env", step.seq),
                    true,
                )),
            }
        };
        let guarded = |step: &BatchStep| {
            self.give_way();
            one(step)
        };
        match self.batch_workers.get_or_init(batch_workers) {
            Some(workers) if steps.len() >= 4 && workers.current_num_threads() > 1 => {
                workers.install(|| steps.par_iter().map(guarded).collect())
            }
            _ => steps.iter().map(guarded).collect(),
        }
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
        lock(&self.live).insert(client);
    }

    /// Closes every env of the client whose public tag is `client` (its liveliness token
    /// is gone); returns how many.
    pub fn drop_client(&self, client: ClientTag) -> usize {
        lock(&self.live).remove(&client);
        self.retain(|slot| slot.owner_tag != client)
    }

    /// Closes the envs whose owner has shown no liveliness token within `ORPHAN_GRACE`
    /// of creating them; returns how many. Ids cost nothing, so without this one session
    /// minting ids could hold every place of an open server until the idle timeout.
    pub fn reclaim_orphans(&self, now: Instant) -> usize {
        let live = lock(&self.live).clone();
        self.retain(|slot| live.contains(&slot.owner_tag) || now.saturating_duration_since(slot.created) < ORPHAN_GRACE)
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

/// This process's resident memory (Linux: /proc/self/statm's second field, in pages of
/// 4 KiB); 0 elsewhere.
fn resident_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    statm.split_whitespace().nth(1).and_then(|pages| pages.parse::<u64>().ok()).map_or(0, |pages| pages * 4096)
}

fn wrong_version(version: u16) -> ErrorReply {
    error(
        ErrorCode::WrongVersion,
        format!("request speaks protocol {version}, this server speaks {PROTOCOL_VERSION}; upgrade the older side"),
        true,
    )
}

fn step_reply(env: &mut Env, seq: u64, actions: &[(String, arena_protocol::Action)]) -> Result<StepReply, ErrorReply> {
    let steps = env.step(actions)?;
    let mut reply = StepReply {
        seq,
        observations: Vec::with_capacity(steps.len()),
        rewards: Vec::with_capacity(steps.len()),
        terminations: Vec::with_capacity(steps.len()),
        truncations: Vec::with_capacity(steps.len()),
        infos: Vec::with_capacity(steps.len()),
        agents: env.live_agents(),
    };
    for step in steps {
        reply.observations.push((step.agent.clone(), step.observation));
        reply.rewards.push((step.agent.clone(), step.reward));
        reply.terminations.push((step.agent.clone(), step.terminated));
        reply.truncations.push((step.agent.clone(), step.truncated));
        reply.infos.push((step.agent, step.info));
    }
    Ok(reply)
}
