//! The multi-agent episode on top of a world, with PettingZoo Parallel semantics:
//! `possible_agents` are the scenario's learner-driven vehicles; `reset` builds a fresh
//! world from a seed; `step` applies every live agent's action, advances the world by
//! one env step, and reports each agent that was live before it. Agents that finish leave
//! at once and never return. Nothing here reads a clock: the same seed and actions give
//! the same bits.
//!
//! A step runs in phases, as highway-env's `AbstractEnv.step` does, each in its own
//! module: check and apply the actions (`action`), simulate (`simulate`: the world's
//! ticks and the costs sampled on the way), then per agent observe (`observation`),
//! reward (`reward`), terminate (`episode`) and info (`info`). While recording is on,
//! `recording` assembles the world's frames for the reply (the simulate phase takes one
//! per control period). `snapshot` saves the whole state as bytes and restores it.

mod action;
mod episode;
mod explain;
mod info;
mod observation;
mod overrides;
mod recording;
mod render;
mod reward;
mod risk;
mod simulate;
mod snapshot;

use std::collections::VecDeque;

use arena_protocol::{
    Action, ActionType, AgentStart, AgentStep, BuiltinPolicy, CreateOptions, DecisionExplained, EndReason, EnvSpecs,
    EnvStatistics, ErrorCode, ErrorReply, Frame, Observation, ObservationKind, RenderMode, ResetOptions, WorldFrame,
    WorldStart,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use arena_sim::Role;
use arena_sim::Style;
use arena_sim::{ActionKind, DriverSpec, Scenario};
use arena_sim::{Game, GtMemory};
use arena_sim::{Status, Stepper, VehicleId, World};

/// Where a server runs `Env::decide_ahead` once a reply is on its way: the decision pool's
/// thread, still warm from the step (`arena_sim::beside_decisions`).
pub use arena_sim::beside_decisions;
pub use episode::MAX_AGENT_PERIODS;
pub use observation::{KINEMATICS_FEATURES, KINEMATICS_VEHICLES};

/// A learner, as its env was created: its vehicle's name and its action space.
#[derive(Debug, Clone)]
struct AgentSlot {
    name: String,
    action: ActionType,
}

/// What changes of a learner as an episode runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct AgentState {
    /// Its vehicle in this episode's world.
    vehicle: VehicleId,
    live: bool,
    /// The memory of the built-in AV planning in this agent's place (its last preview
    /// point and MPC plan), for continuous expert actions. Its game is the env's
    /// `expert`, its constants the vehicle's (`World::gt_params`): not state.
    expert: Option<Box<GtMemory>>,
    /// The figures of its episode so far.
    stats: Option<episode::EpisodeStats>,
    /// The speed its scenario has it aim for (m/s), fixed for the episode: the reward's
    /// yardstick of progress (an action that lowers the target speed does not lower it).
    aim: f64,
    /// When the AV drives it (`policy`), the target speed a learner playing the meta
    /// labels of `expert_action` would have (m/s); they are chosen against it.
    ladder: f64,
}

impl AgentState {
    /// Before its first reset.
    fn idle() -> AgentState {
        AgentState { vehicle: VehicleId(0), live: false, expert: None, stats: None, aim: 0.0, ladder: 0.0 }
    }
}

/// Everything of an env that changes as it runs but its world (whose state is the
/// world's own, `arena_sim::WorldState`): plain data, compared and encoded as it is. A
/// snapshot is this and the world's state, with the scenario's identity.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct EnvState {
    /// The current episode's world seed and reset overrides: its scenario (its `[vary]`
    /// draws) and its built world are made again from them.
    world_seed: u64,
    overrides: Vec<(String, arena_protocol::OptionValue)>,
    /// The env's seed stream, for resets without a seed.
    #[serde(with = "arena_sim::rng_position")]
    seeds: ChaCha8Rng,
    /// Steps taken in this episode.
    cycles: u32,
    /// Per agent, in the order of `Env::agents`.
    agents: Vec<AgentState>,
}

/// A PettingZoo-Parallel env over one scenario.
#[derive(Debug, Clone)]
pub struct Env {
    /// The scenario as created; each episode draws its own from it (`Scenario::episode`).
    scenario: Scenario,
    /// The current episode's scenario.
    episode: Scenario,
    observation: ObservationKind,
    max_cycles: u32,
    render_size: (u32, u32),
    /// Metres across an RGB frame (`render::window`).
    render_window: f64,
    expert: Option<Game>,
    /// The built-in driver of every learner, when the server drives them.
    policy: Option<BuiltinPolicy>,
    /// Whether infos carry the game-theoretic cars' solver counts.
    diagnostics: bool,
    /// The only info keys replies carry (`info::kept_keys`); `None`: all.
    info_keys: Option<Vec<String>>,
    /// Whether replies carry the world's frames (`recording`).
    recording: bool,
    recorder: recording::Recorder,
    world: Option<World>,
    /// What advances `world` and is not part of it (arena_sim::Stepper): scratch, the
    /// decision pool's hand-off, the decisions made ahead, the decision clock and the
    /// explanations. A new one each episode; dropping it changes no result.
    stepper: Stepper,
    agents: Vec<AgentSlot>,
    /// What changes as an episode runs, but the world.
    state: EnvState,
    /// Buffers of `step`, kept so a step allocates only what its reply carries.
    scratch: StepScratch,
    /// Whether step replies explain the game-theoretic decisions (`explain`).
    explain: bool,
    /// SHA3-256 of the resolved scenario, which snapshots name (`snapshot`).
    identity: [u8; 32],
    /// Per agent, the server's wall time deciding for it in each step its built-in
    /// `policy` drove it (µs), the newest `EnvStatistics::kept_per_agent`: the
    /// `Statistics` reply, never an info.
    decision_micros: Vec<VecDeque<f32>>,
}

/// What `step` works in, per agent slot or per live agent.
#[derive(Debug, Clone, Default)]
struct StepScratch {
    chosen: Vec<Option<Action>>,
    applied: Vec<bool>,
    live_before: Vec<usize>,
    driving_before: Vec<bool>,
    /// Per live agent, whether it was at the scenario's goal before the step.
    reached_before: Vec<bool>,
    vehicles: Vec<VehicleId>,
    costs: Vec<simulate::StepCost>,
    /// Per live agent, the acceleration commanded in each control period of the step.
    accels: Vec<Vec<f64>>,
    /// Simulated time when the step began.
    started: f64,
}

// A step carries one action per learner: the scenario's bound on learners is the
// protocol's on a step's actions.
const _: () = assert!(arena_sim::MAX_LEARNERS == arena_protocol::bounds::MAX_ACTIONS);

/// The largest RGB frame (bytes) a render reply carries: the message limit less room for
/// the envelope.
const MAX_FRAME_BYTES: usize = arena_protocol::MAX_MESSAGE_BYTES - 64 * 1024;

fn error(code: ErrorCode, message: impl Into<String>) -> ErrorReply {
    ErrorReply { code, message: message.into(), env_usable: true }
}

impl Env {
    /// An env over `scenario`, not yet reset (`options.overrides` are `from_text`'s).
    /// `entropy` seeds the seeds of resets that do not give one.
    pub fn new(scenario: Scenario, options: &CreateOptions, entropy: u64) -> Result<Env, ErrorReply> {
        if scenario.agents().next().is_none() {
            return Err(error(
                ErrorCode::InvalidScenario,
                format!(
                    "scenario '{}' has no learner: give one [[vehicle]] driver = {{ kind = \"agent\" }} (an env \
                     steps the learners' vehicles; scenarios without one are for `arena paper` and the world alone)",
                    scenario.name
                ),
            ));
        }
        let max_cycles = options.max_cycles.unwrap_or(scenario.max_cycles);
        if max_cycles == 0 {
            return Err(error(ErrorCode::InvalidScenario, "max_cycles must be at least 1"));
        }
        let mut driven = scenario.clone();
        if let Some(policy) = options.policy {
            drive_learners(&mut driven, policy);
        }
        episode_fits(&driven, max_cycles, options.expert.is_some())?;
        if let (Some(expert), Some(policy @ BuiltinPolicy::Gt { game: driving, .. })) = (options.expert, options.policy)
            && expert != driving
        {
            return Err(error(
                ErrorCode::InvalidScenario,
                format!(
                    "expert {expert} with policy {policy}: when the AV drives the learners, the expert keys are \
                     that driver's own actions; ask for expert {driving} (or leave expert out)"
                ),
            ));
        }
        let render_size = options.render_size.unwrap_or((300, 600));
        if !(16..=4096).contains(&render_size.0) || !(16..=4096).contains(&render_size.1) {
            return Err(error(
                ErrorCode::InvalidScenario,
                format!("render_size {render_size:?} must be within 16..=4096"),
            ));
        }
        let frame_bytes = u64::from(render_size.0) * u64::from(render_size.1) * 3;
        if frame_bytes > MAX_FRAME_BYTES as u64 {
            return Err(error(
                ErrorCode::InvalidScenario,
                format!(
                    "render_size {render_size:?} makes frames of {frame_bytes} bytes, more than a reply may carry \
                     ({MAX_FRAME_BYTES} of the {} byte message limit); ask for at most about 2300 x 2300",
                    arena_protocol::MAX_MESSAGE_BYTES
                ),
            ));
        }
        let render_window =
            render::window(options.render_window, render_size.1).map_err(|e| error(ErrorCode::InvalidScenario, e))?;
        let info_keys = options
            .info_keys
            .as_deref()
            .map(|asked| info::kept_keys(asked, options.expert.is_some(), options.diagnostics))
            .transpose()
            .map_err(|e| error(ErrorCode::InvalidOption, e))?;
        let agents = scenario
            .agents()
            .map(|spec| AgentSlot {
                name: spec.name.clone(),
                action: options.action_type.unwrap_or(match spec.driver {
                    DriverSpec::Agent(ActionKind::Continuous) => ActionType::Continuous,
                    _ => ActionType::Meta,
                }),
            })
            .collect::<Vec<_>>();
        let state = EnvState {
            world_seed: 0,
            overrides: Vec::new(),
            seeds: ChaCha8Rng::seed_from_u64(entropy),
            cycles: 0,
            // Each agent's vehicle is found in the world at each reset (`Scenario::build`
            // orders vehicles by name).
            agents: vec![AgentState::idle(); agents.len()],
        };
        Ok(Env {
            identity: snapshot::identity(&scenario),
            decision_micros: Vec::new(),
            episode: scenario.clone(),
            scenario,
            observation: options.observation.unwrap_or(ObservationKind::Kinematics),
            max_cycles,
            render_size,
            render_window,
            expert: options.expert.map(game),
            policy: options.policy,
            diagnostics: options.diagnostics,
            info_keys,
            recording: options.record,
            recorder: recording::Recorder::default(),
            world: None,
            stepper: Stepper::new(),
            agents,
            state,
            scratch: StepScratch::default(),
            explain: options.explain,
        })
    }

    /// An env over the scenario file `text` (named `file` in errors) with the options'
    /// overrides applied, as a create asks for it.
    pub fn from_text(file: &str, text: &str, options: &CreateOptions, entropy: u64) -> Result<Env, ErrorReply> {
        let scenario = Scenario::parse(file, text, &overrides::converted(&options.overrides))
            .map_err(|e| error(ErrorCode::InvalidScenario, e.to_string()))?;
        Env::new(scenario, options, entropy)
    }

    /// The name its scenario declares.
    pub fn scenario_name(&self) -> &str {
        &self.scenario.name
    }

    /// The world, once reset.
    #[cfg(test)]
    pub(crate) fn world(&self) -> Option<&World> {
        self.world.as_ref()
    }

    /// Names of the agents live now.
    pub fn live_agents(&self) -> Vec<String> {
        let live = self.agents.iter().zip(&self.state.agents).filter(|(_, state)| state.live);
        live.map(|(agent, _)| agent.name.clone()).collect()
    }

    /// Spaces, timing and agents: everything a client needs before `reset`.
    pub fn specs(&self) -> EnvSpecs {
        let observation_space = observation::space(self.observation, &self.scenario);
        EnvSpecs {
            possible_agents: self.agents.iter().map(|a| a.name.clone()).collect(),
            observation_spaces: self.agents.iter().map(|a| (a.name.clone(), observation_space.clone())).collect(),
            action_spaces: self.agents.iter().map(|a| (a.name.clone(), action::space(a.action))).collect(),
            state_space: observation::state_space(&self.scenario),
            dt: self.scenario.step_dt,
            max_cycles: self.max_cycles,
            render_fps: (1.0 / self.scenario.step_dt).round().max(1.0) as u32,
            render_modes: vec![RenderMode::RgbArray, RenderMode::Ansi],
        }
    }

    /// Starts an episode: draws its scenario (the `[vary]` values, then the options'
    /// overrides), builds its world from the seed. A bad override is refused, naming it,
    /// and the env stays as it was.
    pub fn reset(&mut self, seed: Option<u64>, options: &ResetOptions) -> Result<Vec<AgentStart>, ErrorReply> {
        let overrides = overrides::converted(&options.overrides);
        let mut seeds = match seed {
            Some(seed) => ChaCha8Rng::seed_from_u64(seed),
            None => self.state.seeds.clone(),
        };
        let world_seed = seeds.next_u64();
        let mut draws = ChaCha8Rng::seed_from_u64(world_seed);
        let episode = self
            .scenario
            .episode(&mut draws, &overrides)
            .map_err(|e| error(ErrorCode::InvalidScenario, format!("reset: {e}")))?;
        let learners: Vec<&str> = episode.agents().map(|v| v.name.as_str()).collect();
        if learners != self.agents.iter().map(|a| a.name.as_str()).collect::<Vec<_>>() {
            return Err(error(
                ErrorCode::InvalidScenario,
                format!(
                    "reset: the episode's learners {learners:?} are not the env's; overrides may not change who learns"
                ),
            ));
        }
        let mut episode = episode;
        if let Some(policy) = self.policy {
            drive_learners(&mut episode, policy);
        }
        episode_fits(&episode, self.max_cycles, self.expert.is_some())
            .map_err(|e| error(e.code, format!("reset: {}", e.message)))?;
        let mut world = episode.build(world_seed);
        if self.recording {
            recording::check_fits(world.vehicles().len(), frames_per_step(&episode))?;
            self.recorder.restart(&world);
        }
        if self.explain {
            explain::check_fits(&world, frames_per_step(&episode) - 1)?;
        }
        self.stepper = self.stepper_for_episode();
        self.episode = episode;
        let periods = self.control_periods();
        let state = &mut self.state;
        (state.seeds, state.cycles) = (seeds, 0);
        (state.world_seed, state.overrides) = (world_seed, options.overrides.clone());
        for (slot, agent) in self.agents.iter().zip(&mut state.agents) {
            agent.live = true;
            agent.vehicle = world.find(&slot.name).unwrap_or(agent.vehicle);
            agent.expert = self.expert.map(|_| Box::default());
            agent.stats = Some(episode::EpisodeStats::start(&world, agent.vehicle, periods));
            agent.aim = world.vehicle(agent.vehicle).target_speed;
            agent.ladder = agent.aim;
        }
        let starts = (0..self.agents.len())
            .map(|i| {
                let (vehicle, action) = (self.state.agents[i].vehicle, self.agents[i].action);
                let observation = observation::observe(self.observation, world.scene(), vehicle, action);
                let info = self.info(&mut world, i, &info::Outcome::start());
                AgentStart { agent: self.agents[i].name.clone(), observation, info }
            })
            .collect();
        self.world = Some(world);
        Ok(starts)
    }

    /// A stepper for a new or restored episode, with what this env's options ask of it on:
    /// explained decisions, and the decision clock when the server drives the learners.
    fn stepper_for_episode(&self) -> Stepper {
        let mut stepper = Stepper::new();
        stepper.set_explain(self.explain);
        stepper.clock_decisions(self.policy.is_some());
        stepper
    }

    /// One env step, in phases: actions are checked (all before any is applied, so a
    /// refused step leaves the env as it was) and applied, the world simulated, and each
    /// agent live before the step observed, rewarded, terminated and told its info.
    pub fn step(&mut self, actions: &[(String, Action)]) -> Result<Vec<AgentStep>, ErrorReply> {
        self.check_actions(actions)?;
        self.apply_actions();
        self.simulate();
        self.clock_decisions();
        let mut world = self.world.take().expect("checked: reset before step");
        let steps = (0..self.scratch.live_before.len()).map(|k| self.agent_step(&mut world, k)).collect();
        self.world = Some(world);
        Ok(steps)
    }

    /// Makes the next step's first decisions now (`Stepper::decide_ahead`), while its
    /// actions are on their way, until `stop` says the next request has come: a server
    /// calls it once a reset's or a step's reply is sent. The next step takes them when
    /// its actions leave the vehicles as they were, and makes them again otherwise; its
    /// results are the same bits either way.
    pub fn decide_ahead(&mut self, stop: &(dyn Fn() -> bool + Sync)) {
        if self.state.agents.iter().any(|a| a.live)
            && let Some(world) = self.world.as_ref()
        {
            self.stepper.decide_ahead(world, stop);
        }
    }

    /// Checks `actions` and keeps each live agent's in `scratch.chosen`. An action for an
    /// agent that has finished is ignored, as PettingZoo's own conversions do; an unknown
    /// agent, an action outside its space or two for one agent refuse the step.
    fn check_actions(&mut self, actions: &[(String, Action)]) -> Result<(), ErrorReply> {
        if self.world.is_none() {
            return Err(error(ErrorCode::NotReset, "step before reset: call reset first"));
        }
        if !self.state.agents.iter().any(|a| a.live) {
            return Err(error(ErrorCode::AgentNotLive, "every agent has finished this episode: call reset"));
        }
        let chosen = &mut self.scratch.chosen;
        chosen.clear();
        chosen.resize(self.agents.len(), None);
        for (name, action) in actions {
            let Some(index) = self.agents.iter().position(|a| &a.name == name) else {
                let known = self.agents.iter().map(|a| a.name.as_str()).collect::<Vec<_>>().join(", ");
                return Err(error(
                    ErrorCode::UnknownAgent,
                    format!("no agent named '{name}'; the agents are: {known}"),
                ));
            };
            let agent = &self.agents[index];
            if !self.state.agents[index].live {
                continue;
            }
            if let Some(policy) = self.policy {
                return Err(error(
                    ErrorCode::InvalidAction,
                    format!(
                        "agent '{name}' is driven by the server's built-in policy {policy} (the env's `policy` \
                         option): send steps without actions"
                    ),
                ));
            }
            action::check(action, agent.action)
                .map_err(|(code, message)| error(code, format!("agent '{name}': {message}")))?;
            if chosen[index].replace(action.clone()).is_some() {
                return Err(error(ErrorCode::InvalidAction, format!("agent '{name}' has two actions in one step")));
            }
        }
        Ok(())
    }

    /// Writes each live agent's action (none: the default) into its vehicle's command,
    /// and notes who was live and driving before the step.
    fn apply_actions(&mut self) {
        let Some(world) = self.world.as_mut() else { return };
        let StepScratch { chosen, applied, live_before, driving_before, reached_before, vehicles, .. } =
            &mut self.scratch;
        applied.clear();
        applied.resize(self.agents.len(), true);
        let agents = &self.state.agents;
        for (((slot, agent), action), applied) in self.agents.iter().zip(agents).zip(chosen.iter()).zip(applied) {
            if agent.live && self.policy.is_none() {
                *applied = action::apply(world, agent.vehicle, action.as_ref(), slot.action);
            }
        }
        live_before.clear();
        live_before.extend((0..agents.len()).filter(|&i| agents[i].live));
        driving_before.clear();
        driving_before.extend(live_before.iter().map(|&i| world.vehicle(agents[i].vehicle).status == Status::Driving));
        reached_before.clear();
        reached_before.extend(live_before.iter().map(|&i| self.episode.goal.reached(world, agents[i].vehicle)));
        vehicles.clear();
        vehicles.extend(live_before.iter().map(|&i| agents[i].vehicle));
    }

    /// While recording, the road, the vehicles and the world now (a reset reply's).
    pub fn world_start(&self) -> Option<WorldStart> {
        let world = self.world.as_ref().filter(|_| self.recording)?;
        let learners: Vec<&str> = self.agents.iter().map(|a| a.name.as_str()).collect();
        Some(recording::start(world, &learners))
    }

    /// A reset or restore reply's world: while recording (`world_start`), and with
    /// `explain` too, where it names the vehicles the explanations point to by index.
    pub fn reset_world(&self) -> Option<WorldStart> {
        let world = self.world.as_ref().filter(|_| self.recording || self.explain)?;
        let learners: Vec<&str> = self.agents.iter().map(|a| a.name.as_str()).collect();
        Some(recording::start(world, &learners))
    }

    /// The frames the last step took while recording (a step reply's); empty otherwise.
    pub fn take_frames(&mut self) -> Vec<WorldFrame> {
        std::mem::take(&mut self.recorder.frames)
    }

    /// The game-theoretic decisions the last step took, explained (a step reply's); empty
    /// unless created with `explain`.
    pub fn take_explanations(&mut self) -> Vec<DecisionExplained> {
        match self.world.as_mut() {
            Some(world) if self.explain => explain::take(&mut self.stepper, world.road()),
            _ => Vec::new(),
        }
    }

    /// Turns recording on or off. Turned on after a reset, it returns the world now
    /// (`world_start`), so a recording can begin mid-episode. A world whose frames would
    /// not fit a reply is refused, and recording stays as it was.
    pub fn set_recording(&mut self, on: bool) -> Result<Option<WorldStart>, ErrorReply> {
        if on && let Some(world) = &self.world {
            recording::check_fits(world.vehicles().len(), frames_per_step(&self.episode))?;
            if !self.recording {
                self.recorder.restart(world);
            }
        }
        self.recording = on;
        self.recorder.frames.clear();
        Ok(self.world_start())
    }

    /// The most control periods an episode can have: `max_cycles` steps of `step_dt`.
    fn control_periods(&self) -> usize {
        self.max_cycles as usize * self.episode.control_periods_per_step()
    }

    /// Advances the world by one env step, sampling the live agents' costs.
    fn simulate(&mut self) {
        let Some(world) = self.world.as_mut() else { return };
        let StepScratch { vehicles, costs, accels, started, .. } = &mut self.scratch;
        *started = world.time();
        let recorder = self.recording.then_some(&mut self.recorder);
        simulate::advance(world, &mut self.stepper, vehicles, self.episode.step_dt, costs, accels, recorder);
        self.state.cycles += 1;
    }

    /// Notes the wall time the server's policy spent on each agent it drove this step.
    fn clock_decisions(&mut self) {
        if self.world.is_none() || self.policy.is_none() {
            return;
        }
        self.decision_micros.resize_with(self.agents.len(), VecDeque::new);
        let cap = EnvStatistics::kept_per_agent(self.agents.len());
        for &i in &self.scratch.live_before {
            let spent = self.stepper.take_decision_time(self.state.agents[i].vehicle);
            let kept = &mut self.decision_micros[i];
            if kept.len() >= cap {
                kept.pop_front();
            }
            kept.push_back(spent.as_secs_f64() as f32 * 1e6);
        }
    }

    /// What the server spent on this env (the `Statistics` reply).
    pub fn statistics(&self) -> EnvStatistics {
        let decision_micros = self
            .agents
            .iter()
            .zip(&self.decision_micros)
            .map(|(agent, kept)| (agent.name.clone(), kept.iter().copied().collect()))
            .collect();
        EnvStatistics { decision_micros }
    }

    /// The `k`-th agent live before the step: observed, rewarded, terminated, its info.
    fn agent_step(&mut self, world: &mut World, k: usize) -> AgentStep {
        let i = self.scratch.live_before[k];
        let cost = self.scratch.costs[k];
        let truncated = self.state.cycles >= self.max_cycles;
        let periods = self.control_periods();
        let (action, agent) = (self.agents[i].action, &mut self.state.agents[i]);
        let vehicle = world.vehicle(agent.vehicle);
        let crashed_now = self.scratch.driving_before[k] && matches!(vehicle.status, Status::Crashed | Status::OffRoad);
        let ended = episode::ended(world, agent.vehicle);
        let goal = reward::GoalChange {
            before: self.scratch.reached_before[k],
            after: self.episode.goal.reached(world, agent.vehicle),
        };
        // Out of time short of a goal that must be reached: a failure (by default paid as a crash).
        let failed = truncated && ended.is_none() && self.episode.goal.fail_at_time_limit && !goal.after;
        let reward = if failed {
            self.episode.reward.failure_reward(self.max_cycles)
        } else {
            reward::reward(&self.episode.reward, self.max_cycles, &cost, agent.aim, crashed_now, goal)
        };
        let stats = agent.stats.get_or_insert_with(|| episode::EpisodeStats::start(world, agent.vehicle, periods));
        stats.record(world, agent.vehicle, self.scratch.started, reward, &cost);
        stats.record_accels(&self.scratch.accels[k], world.params().control_dt);
        let end = ended.unwrap_or(if truncated { EndReason::TimeLimit } else { EndReason::Running });
        let figures = match end {
            EndReason::Running => episode::Figures::default(),
            end => stats.finish(world, agent.vehicle, &self.episode.goal, end),
        };
        agent.live = end == EndReason::Running;
        let observation = observation::observe(self.observation, world.scene(), agent.vehicle, action);
        let outcome = info::Outcome { cost: Some(&cost), applied: self.scratch.applied[i], end, figures };
        let info = self.info(world, i, &outcome);
        AgentStep {
            agent: self.agents[i].name.clone(),
            observation,
            reward,
            terminated: ended.is_some() || failed,
            truncated: truncated && ended.is_none() && !failed,
            info,
        }
    }

    /// Agent `i`'s info: the schema's keys, then those the env's options turn on; only
    /// `info_keys` of them if the env names some.
    fn info(&mut self, world: &mut World, i: usize, outcome: &info::Outcome) -> arena_protocol::Info {
        let (action, agent) = (self.agents[i].action, &mut self.state.agents[i]);
        let mut info = info::info(world, agent.vehicle, outcome);
        if let (Some(game), Some(memory)) = (self.expert, agent.expert.as_mut()) {
            let running = outcome.end == EndReason::Running;
            let expert = running.then(|| info::expert(world, agent.vehicle, action, (game, memory), &mut agent.ladder));
            info::add_expert(&mut info, action, expert);
        }
        if self.diagnostics {
            info::add_diagnostics(&mut info, world);
        }
        info::keep(&mut info, self.info_keys.as_deref());
        info
    }

    /// The global view: every vehicle's kinematics, in a fixed order.
    pub fn state(&self) -> Result<Observation, ErrorReply> {
        let world =
            self.world.as_ref().ok_or_else(|| error(ErrorCode::NotReset, "state before reset: call reset first"))?;
        Ok(observation::state(world, &self.scenario))
    }

    /// A picture of the road around the vehicle named `follow` (any vehicle of the
    /// scenario), else around the first agent.
    pub fn render(&self, mode: RenderMode, follow: Option<&str>) -> Result<Frame, ErrorReply> {
        let world =
            self.world.as_ref().ok_or_else(|| error(ErrorCode::NotReset, "render before reset: call reset first"))?;
        let focus = match follow {
            Some(name) => Some(world.find(name).ok_or_else(|| unknown_vehicle(world, name))?),
            None => self.state.agents.first().map(|a| a.vehicle),
        };
        Ok(match mode {
            RenderMode::RgbArray => {
                let end = focus.and_then(|id| self.end_shown(id));
                render::rgb(world, focus, end, self.render_size, self.render_window)
            }
            RenderMode::Ansi => Frame::Ansi(render::ansi(world, focus)),
        })
    }

    /// How vehicle `id`'s episode ended, as a frame shows it: the world's ending, else
    /// the time limit for an agent no longer live.
    fn end_shown(&self, id: VehicleId) -> Option<&'static str> {
        let world = self.world.as_ref()?;
        let out_of_time = self.state.agents.iter().any(|a| a.vehicle == id && !a.live);
        world.ending(id).map(render::ending_name).or(out_of_time.then_some(EndReason::TimeLimit.name()))
    }
}

/// Whether `max_cycles` steps of `episode` (its learners already handed to the env's
/// policy, if any) keep within what an env may cost, checked before anything is made in
/// proportion to them: `episode::MAX_AGENT_PERIODS`, and the scenario's bounds on
/// game-theoretic cars and decisions counting an expert's decision per learner and step.
fn episode_fits(episode: &Scenario, max_cycles: u32, expert: bool) -> Result<(), ErrorReply> {
    let refuse = |message: String| Err(error(ErrorCode::InvalidScenario, message));
    let per_step = episode.control_periods_per_step();
    let learners = episode.agents().count();
    let periods = f64::from(max_cycles) * (per_step * learners) as f64;
    if periods > episode::MAX_AGENT_PERIODS as f64 {
        return refuse(format!(
            "max_cycles {max_cycles} x {per_step} control periods per step x {learners} learner(s) is {periods} \
             periods an episode, more than the {} an env may hold (docs/protocol.md, \"Bounds\"): ask for fewer \
             steps, a shorter sim.step_dt or fewer learners",
            episode::MAX_AGENT_PERIODS
        ));
    }
    let gt_cars = episode.gt_cars();
    if gt_cars > arena_sim::MAX_GT_CARS {
        return refuse(format!(
            "{gt_cars} game-theoretic cars (the policy drives {learners} learner(s) as one), more than the {}: \
             fewer learners, or another policy",
            arena_sim::MAX_GT_CARS
        ));
    }
    let experts = if expert { learners } else { 0 };
    let decisions = episode.gt_decisions_per_step() + experts;
    if decisions > arena_sim::MAX_GT_DECISIONS_PER_STEP {
        return refuse(format!(
            "{decisions} game-theoretic decisions a step ({gt_cars} car(s) x {per_step} period(s), and {experts} \
             expert decision(s) for the learners), more than the {}: fewer game-theoretic cars or learners, a \
             shorter sim.step_dt, or no expert",
            arena_sim::MAX_GT_DECISIONS_PER_STEP
        ));
    }
    Ok(())
}

/// The refusal of a render that follows a vehicle the world does not have.
fn unknown_vehicle(world: &World, name: &str) -> ErrorReply {
    let names: Vec<&str> = world.setups().iter().map(|v| v.name.as_str()).collect();
    let shown = if names.len() > 20 {
        format!("{}, ... ({} in all)", names[..20].join(", "), names.len())
    } else {
        names.join(", ")
    };
    error(ErrorCode::InvalidOption, format!("render: no vehicle named '{name}' to follow; the vehicles are {shown}"))
}

/// The protocol's words for the model's own types, mapped once.
fn game(game: arena_protocol::Game) -> Game {
    match game {
        arena_protocol::Game::Nash => Game::Nash,
        arena_protocol::Game::Stackelberg => Game::Stackelberg,
    }
}

/// The model's style in the protocol's words.
fn style_of(style: Style) -> arena_protocol::Style {
    match style {
        Style::Aggressive => arena_protocol::Style::Aggressive,
        Style::Normal => arena_protocol::Style::Normal,
        Style::Conservative => arena_protocol::Style::Conservative,
    }
}

/// Frames a recorded step can take: one per control period, and one at its end.
fn frames_per_step(episode: &Scenario) -> usize {
    episode.control_periods_per_step() + 1
}

fn style(style: arena_protocol::Style) -> Style {
    match style {
        arena_protocol::Style::Aggressive => Style::Aggressive,
        arena_protocol::Style::Normal => Style::Normal,
        arena_protocol::Style::Conservative => Style::Conservative,
    }
}

/// Hands every learner's vehicle of `episode` to `policy`: the same world as a scenario
/// file with that driver, so a `gt` policy drives exactly as `arena paper`'s EC does.
fn drive_learners(episode: &mut Scenario, policy: BuiltinPolicy) {
    for vehicle in episode.vehicles.iter_mut().filter(|v| matches!(v.driver, DriverSpec::Agent(_))) {
        vehicle.driver = match policy {
            BuiltinPolicy::Gt { style: chosen, game: g } => {
                vehicle.style = chosen.map_or(vehicle.style, style);
                DriverSpec::Gt { game: game(g), role: Role::Leader, params: Default::default() }
            }
            BuiltinPolicy::Idm => DriverSpec::Idm,
        };
    }
}

#[cfg(test)]
mod tests;
