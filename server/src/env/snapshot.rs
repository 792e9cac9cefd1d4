//! Env snapshots: the whole state of an env as bytes (`Env::snapshot`) and back
//! (`Env::restore`), so an episode can branch: restored into this env or a fresh one of
//! the same scenario and options, on this server or another of the same protocol
//! version, it continues bit for bit as the original would have.
//!
//! The bytes: 8 bytes `MAGIC`, the protocol version (u16, little-endian), the `Body`
//! in the protocol's codec, and a SHA3-256 of everything before it (so a truncated or
//! corrupted snapshot is told as such, not taken for another state). The body names the scenario and a SHA3-256 of the
//! resolved scenario (`Env::identity`: the text, inline or not, with its overrides
//! applied), and the options that change results; the episode is rebuilt from the
//! scenario and the reset's own inputs (the world's seed, the reset's overrides), and
//! only what changes as it runs comes from the bytes, checked against that rebuilt
//! world (`World::restore`). A snapshot from a client is untrusted input: every decode or
//! fit error is an `InvalidSnapshot` reply naming what did not fit, and the env is left
//! as it was. Solver scratch (the MPC's per-thread clarabel workspace, the world's
//! decision and fleet buffers, the step's scratch) is not in it: each is rewritten
//! before it is read, so it does not change results.

use arena_protocol::{AgentStart, ErrorCode, ErrorReply, PROTOCOL_VERSION};
use arena_sim::{GtSetup, Role, World, WorldState};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use sha3::Digest;

use super::{AgentState, Env, EnvState, error, explain, info, observation, overrides, recording};
use arena_protocol::bounds::MAX_SNAPSHOT_BYTES;

/// The first bytes of every snapshot.
pub const MAGIC: &[u8; 8] = b"ARENASNP";

/// Bytes before the body: the magic and the protocol version.
const HEADER: usize = MAGIC.len() + 2;

/// Bytes of the checksum after the body.
const CHECKSUM: usize = 32;

/// What a snapshot holds after its header: the scenario's identity, the options that
/// change results, and the env's and its world's state as they are.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Body {
    /// The scenario's name.
    scenario: String,
    /// SHA3-256 of the resolved scenario (`Env::identity`).
    hash: [u8; 32],
    /// The env options that change results, as `Env::options_text` writes them.
    options: String,
    env: EnvState,
    world: WorldState,
}

fn refused(message: impl Into<String>) -> ErrorReply {
    error(ErrorCode::InvalidSnapshot, message)
}

/// The first 8 hex digits of a hash, as messages show it.
fn short(hash: &[u8; 32]) -> String {
    hash[..4].iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA3-256 of the resolved scenario: its `Debug` text, which writes every field (floats
/// as the shortest text that reads back to the same bits) in declaration order, its
/// source (file name, text, overrides) included.
pub fn identity(scenario: &arena_sim::Scenario) -> [u8; 32] {
    sha3::Sha3_256::digest(format!("{scenario:?}").as_bytes()).into()
}

impl Env {
    /// The env options that change what a step returns, as a snapshot names them.
    fn options_text(&self) -> String {
        let actions: Vec<String> = self.agents.iter().map(|a| format!("{}={}", a.name, a.action)).collect();
        let expert = self.expert.map_or("none".to_string(), |g| format!("{g:?}").to_lowercase());
        let policy = self.policy.map_or("none".to_string(), |p| p.to_string());
        format!(
            "observation {}, max_cycles {}, actions [{}], expert {expert}, policy {policy}, diagnostics {}",
            self.observation,
            self.max_cycles,
            actions.join(", "),
            self.diagnostics
        )
    }

    /// The env's whole state (docs/protocol.md, "Snapshots"); refused before a reset.
    pub fn snapshot(&self) -> Result<Vec<u8>, ErrorReply> {
        let world =
            self.world.as_ref().ok_or_else(|| error(ErrorCode::NotReset, "snapshot before reset: call reset first"))?;
        let body = Body {
            scenario: self.scenario.name.clone(),
            hash: self.identity,
            options: self.options_text(),
            env: self.state.clone(),
            world: world.state().clone(),
        };
        let mut bytes = Vec::with_capacity(4096);
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&PROTOCOL_VERSION.to_le_bytes());
        bytes.extend_from_slice(&arena_protocol::encode(&body));
        let checksum = sha3::Sha3_256::digest(&bytes);
        bytes.extend_from_slice(&checksum);
        if bytes.len() > MAX_SNAPSHOT_BYTES {
            return Err(error(
                ErrorCode::PayloadTooLarge,
                format!(
                    "this env's snapshot has {} bytes, more than the {MAX_SNAPSHOT_BYTES} a restore may carry",
                    bytes.len()
                ),
            ));
        }
        Ok(bytes)
    }

    /// Puts a snapshot's state into this env, which then continues exactly as the env it
    /// was taken of would have; returns the agents live in it with their observations and
    /// infos as a reset does (the infos' episode figures are zero, as on a reset, and
    /// computing them changes nothing of the state). A snapshot that is not one, is of
    /// another protocol version, scenario or options, or does not fit is refused with
    /// `InvalidSnapshot` naming what, and the env stays as it was.
    pub fn restore(&mut self, bytes: &[u8]) -> Result<Vec<AgentStart>, ErrorReply> {
        let Body { env: state, world: world_state, .. } = self.read(bytes)?;
        arena_protocol::bounds::check_reset_overrides(&state.overrides)
            .map_err(|e| refused(format!("the snapshot's episode: {e}")))?;
        if state.cycles > self.max_cycles {
            return Err(refused(format!(
                "the snapshot's episode has taken {} steps, more than this env's max_cycles {}",
                state.cycles, self.max_cycles
            )));
        }
        let mut draws = ChaCha8Rng::seed_from_u64(state.world_seed);
        let mut episode = self
            .scenario
            .episode(&mut draws, &overrides::converted(&state.overrides))
            .map_err(|e| refused(format!("the snapshot's episode does not build: {e}")))?;
        if let Some(policy) = self.policy {
            super::drive_learners(&mut episode, policy);
        }
        let mut world = episode.build(state.world_seed);
        world
            .restore(world_state)
            .map_err(|e| refused(format!("snapshot of scenario '{}': {e}", self.scenario.name)))?;
        if state.agents.len() != self.agents.len() {
            return Err(refused(format!(
                "the snapshot has {} agents, this env {}",
                state.agents.len(),
                self.agents.len()
            )));
        }
        for (slot, agent) in self.agents.iter().zip(&state.agents) {
            if world.find(&slot.name) != Some(agent.vehicle) {
                return Err(refused(format!(
                    "the snapshot's agent vehicle {} is not this env's '{}'",
                    agent.vehicle.0, slot.name
                )));
            }
            let setup =
                self.expert.map(|game| GtSetup { game, role: Role::Leader, params: world.gt_params(agent.vehicle) });
            self.check_agent(&world, &episode, state.cycles, agent, setup.as_ref())
                .map_err(|e| refused(format!("the snapshot's agent '{}': {e}", slot.name)))?;
        }
        if self.recording {
            recording::check_fits(world.vehicles().len(), super::frames_per_step(&episode))?;
        }
        if self.explain {
            explain::check_fits(&world, super::frames_per_step(&episode) - 1)?;
        }
        if self.recording {
            self.recorder.restart(&world);
        }
        self.stepper = self.stepper_for_episode();
        self.episode = episode;
        self.state = state;
        let live: Vec<usize> = (0..self.agents.len()).filter(|&i| self.state.agents[i].live).collect();
        let starts = live
            .into_iter()
            .map(|i| {
                let (vehicle, action) = (self.state.agents[i].vehicle, self.agents[i].action);
                let observation = observation::observe(self.observation, world.scene(), vehicle, action);
                // The expert's memory and ladder move when its info is computed: kept as
                // they were, so the restored env steps as the original.
                let kept = self.state.agents[i].clone();
                let info = self.info(&mut world, i, &info::Outcome::start());
                self.state.agents[i] = kept;
                AgentStart { agent: self.agents[i].name.clone(), observation, info }
            })
            .collect();
        self.world = Some(world);
        Ok(starts)
    }

    /// Whether an agent's part of a snapshot could be one of this env after `cycles` steps
    /// of `episode` in `world`: an expert's memory one the expert this env makes (`setup`)
    /// could have, its episode's figures, its speeds. Nothing of it sets what a step costs.
    fn check_agent(
        &self,
        world: &World,
        episode: &arena_sim::Scenario,
        cycles: u32,
        state: &AgentState,
        setup: Option<&GtSetup>,
    ) -> Result<(), String> {
        let lanes = world.road().lane_count();
        match (&state.expert, setup) {
            (Some(memory), Some(setup)) => memory.check(setup, lanes).map_err(|e| format!("its expert: {e}"))?,
            (None, None) => {}
            _ => return Err("an expert's memory where the env has none, or none".into()),
        }
        let per_step = episode.control_periods_per_step();
        if let Some(stats) = &state.stats {
            stats.check(cycles, cycles as usize * per_step, lanes)?;
        }
        if ![state.aim, state.ladder].into_iter().all(|speed| speed.is_finite() && speed >= 0.0) {
            return Err(format!("speeds {} and {} that are not finite sizes", state.aim, state.ladder));
        }
        Ok(())
    }

    /// The body of `bytes`, checked against this env's protocol version, scenario and
    /// options.
    fn read(&self, bytes: &[u8]) -> Result<Body, ErrorReply> {
        if bytes.len() < HEADER || &bytes[..MAGIC.len()] != MAGIC {
            return Err(refused(format!(
                "{} bytes that are not an env snapshot (a snapshot begins with {:?}): pass the bytes \
                 `snapshot` returned, unchanged",
                bytes.len(),
                String::from_utf8_lossy(MAGIC)
            )));
        }
        let version = u16::from_le_bytes([bytes[MAGIC.len()], bytes[MAGIC.len() + 1]]);
        if version != PROTOCOL_VERSION {
            return Err(refused(format!(
                "a snapshot of protocol version {version}, this server speaks version {PROTOCOL_VERSION}: restore it \
                 on a server of version {version}"
            )));
        }
        let Some(split) = bytes.len().checked_sub(CHECKSUM).filter(|&split| split > HEADER) else {
            return Err(refused(format!("a snapshot of {} bytes is truncated: it cannot hold a state", bytes.len())));
        };
        if sha3::Sha3_256::digest(&bytes[..split])[..] != bytes[split..] {
            return Err(refused(format!(
                "the snapshot ({} bytes) is truncated or corrupted: its checksum does not match its contents; pass \
                 the bytes `snapshot` returned, unchanged",
                bytes.len()
            )));
        }
        let body: Body = arena_protocol::decode(&bytes[HEADER..split])
            .map_err(|e| refused(format!("the snapshot's contents do not decode: {e}")))?;
        let name = &self.scenario.name;
        if body.scenario != *name || body.hash != self.identity {
            return Err(refused(format!(
                "a snapshot of scenario '{}' (resolved content {}) cannot be restored into an env of scenario \
                 '{name}' (resolved content {}): create the env from the same scenario, text and overrides",
                body.scenario,
                short(&body.hash),
                short(&self.identity)
            )));
        }
        let options = self.options_text();
        if body.options != options {
            return Err(refused(format!(
                "a snapshot of an env with options ({}) cannot be restored into one with ({options}): create the \
                 env with the same options",
                body.options
            )));
        }
        Ok(body)
    }
}

#[cfg(test)]
mod tests {
    use arena_protocol::{CreateOptions, ErrorCode, Game, OptionValue, ResetOptions};

    use super::*;

    fn stepped(options: CreateOptions) -> Env {
        let (_, file, text) = arena_sim::BUILTIN_SCENARIOS.into_iter().find(|(n, ..)| *n == "merge").unwrap();
        let mut env = Env::from_text(file, text, &options, 1).unwrap();
        env.reset(Some(2), &ResetOptions::default()).unwrap();
        for _ in 0..5 {
            env.step(&[]).unwrap();
        }
        env
    }

    /// `snapshot` with its body changed by `spoil` and its checksum made again, as anyone
    /// can: the checksum tells damage, not forgery.
    fn forged(snapshot: &[u8], spoil: impl FnOnce(&mut Body)) -> Vec<u8> {
        let split = snapshot.len() - CHECKSUM;
        let mut body: Body = arena_protocol::decode(&snapshot[HEADER..split]).unwrap();
        spoil(&mut body);
        let mut bytes = snapshot[..HEADER].to_vec();
        bytes.extend_from_slice(&arena_protocol::encode(&body));
        let checksum = sha3::Sha3_256::digest(&bytes);
        bytes.extend_from_slice(&checksum);
        bytes
    }

    fn expert(body: &mut Body) -> &mut arena_sim::GtMemory {
        body.env.agents[0].expert.as_mut().expect("an env with an expert")
    }

    fn stats(body: &mut Body) -> &mut super::super::episode::EpisodeStats {
        body.env.agents[0].stats.as_mut().expect("figures after five steps")
    }

    #[test]
    fn a_forged_snapshot_brings_no_constant_no_unbounded_list_and_no_number_that_is_not_finite() {
        let mut env = stepped(CreateOptions { expert: Some(Game::Stackelberg), ..CreateOptions::default() });
        let snapshot = env.snapshot().unwrap();
        type Spoil = Box<dyn Fn(&mut Body)>;
        let cases: Vec<(&str, Spoil)> = vec![
            ("not finite", Box::new(|b| expert(b).preview = Some(f64::NAN))),
            ("not finite", Box::new(|b| expert(b).decision.cost = f64::INFINITY)),
            ("a plan of 100000 moves", Box::new(|b| expert(b).plan = vec![0.0; 100_000])),
            ("not finite", Box::new(|b| stats(b).total_reward = f64::NAN)),
            ("not finite", Box::new(|b| stats(b).speed_sum = f64::INFINITY)),
            ("no size", Box::new(|b| stats(b).min_gap = f64::NAN)),
            ("no size", Box::new(|b| stats(b).min_ttc = f64::NEG_INFINITY)),
            ("jerks", Box::new(|b| stats(b).jerks = vec![1.0; 10_000])),
            ("not a finite size", Box::new(|b| stats(b).jerks[0] = f64::NAN)),
            ("speeds", Box::new(|b| b.env.agents[0].aim = f64::NAN)),
            (
                "reset override list",
                Box::new(|b| b.env.overrides = vec![("k".into(), OptionValue::Bool(true)); 200_000]),
            ),
            ("reset override key", Box::new(|b| b.env.overrides = vec![("k".repeat(1 << 20), OptionValue::Int(1))])),
            ("max_cycles", Box::new(|b| b.env.cycles = u32::MAX)),
        ];
        for (needle, spoil) in cases {
            let bytes = forged(&snapshot, spoil);
            let error = env.restore(&bytes).unwrap_err();
            assert_eq!(error.code, ErrorCode::InvalidSnapshot, "{needle}: {error}");
            assert!(error.message.contains(needle), "'{needle}' not in: {}", error.message);
            assert!(env.snapshot().unwrap() == snapshot, "{needle}: a refused restore changed the env");
        }
        // Forged but true to the env: taken.
        let same = forged(&snapshot, |_| {});
        assert!(env.restore(&same).is_ok());
        assert!(env.step(&[]).is_ok());
    }
}
