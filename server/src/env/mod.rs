//! The multi-agent episode on top of a world, with PettingZoo Parallel semantics:
//! `possible_agents` are the scenario's learner-driven vehicles; `reset` builds a fresh
//! world from a seed; `step` applies every live agent's action, advances the world by
//! one env step, and reports observations, rewards, terminations, truncations and infos
//! for every agent that was live before it. Agents that finish leave at once and never
//! return. Nothing here reads a clock: the same seed and actions give the same bits.

mod action;
mod episode;
mod observation;
mod render;
mod reward;

use arena_protocol::InfoValue;
use arena_protocol::{
    Action, ActionType, BuiltinPolicy, CreateOptions, EnvSpecs, ErrorCode, ErrorReply, Frame, Info, Observation,
    ObservationKind, OptionValue, RenderMode,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use arena_sim::dynamics::Style;
use arena_sim::gt::{Game, GtDriver, expert_decision, plan};
use arena_sim::scenario::{ActionKind, DriverSpec, Scenario};
use arena_sim::scene::Role;
use arena_sim::world::{Driver, Status, VehicleId, World};

pub use observation::{KINEMATICS_FEATURES, KINEMATICS_VEHICLES};

/// One agent's results of a step, in the order of the agents that were live before it.
#[derive(Debug, Clone, PartialEq)]
pub struct AgentStep {
    /// The agent's name.
    pub agent: String,
    /// What it observes after the step.
    pub observation: Observation,
    /// Minus the paper's cost J (eq. 9) over the step, minus the collision penalty on
    /// the step the agent crashes or leaves the road.
    pub reward: f64,
    /// Crashed, left the road or reached its end.
    pub terminated: bool,
    /// The episode reached `max_cycles`.
    pub truncated: bool,
    /// Cost components and vehicle facts.
    pub info: Info,
}

/// The result of `reset`: per possible agent, its first observation and info.
pub type ResetOutcome = Vec<(String, Observation, Info)>;

/// A learner's vehicle.
#[derive(Debug, Clone)]
struct AgentSlot {
    name: String,
    vehicle: VehicleId,
    action: ActionType,
    live: bool,
    /// The memory of the built-in AV planning in this agent's place (its last preview
    /// point and MPC plan), for continuous expert actions.
    expert: Option<Box<GtDriver>>,
    /// The figures of its episode so far.
    stats: Option<episode::EpisodeStats>,
    /// The speed its scenario has it aim for (m/s), fixed for the episode: the reward's
    /// yardstick of progress (an action that lowers the target speed does not lower it).
    aim: f64,
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
    expert: Option<Game>,
    /// The built-in driver of every learner, when the server drives them.
    policy: Option<BuiltinPolicy>,
    /// Whether infos carry the game-theoretic cars' solver counts.
    diagnostics: bool,
    seeds: ChaCha8Rng,
    world: Option<World>,
    agents: Vec<AgentSlot>,
    cycles: u32,
    /// Buffers of `step`, kept so a step allocates only what its reply carries.
    scratch: StepScratch,
}

/// What `step` works in, per agent slot or per live agent.
#[derive(Debug, Clone, Default)]
struct StepScratch {
    chosen: Vec<Option<Action>>,
    applied: Vec<bool>,
    live_before: Vec<usize>,
    driving_before: Vec<bool>,
    vehicles: Vec<VehicleId>,
    costs: Vec<reward::StepCost>,
}

/// The largest RGB frame (bytes) a render reply carries: the message limit less room for
/// the envelope.
const MAX_FRAME_BYTES: usize = arena_protocol::MAX_MESSAGE_BYTES - 64 * 1024;

fn error(code: ErrorCode, message: impl Into<String>) -> ErrorReply {
    ErrorReply { code, message: message.into(), env_usable: true }
}

impl Env {
    /// An env over `scenario`, not yet reset. `entropy` seeds the seeds of resets that do
    /// not give one (the server passes the env id).
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
        let agents = scenario
            .agents()
            .map(|spec| AgentSlot {
                name: spec.name.clone(),
                // Found in the world at each reset (`Scenario::build` orders vehicles by name).
                vehicle: VehicleId(0),
                action: options.action_type.unwrap_or(match spec.driver {
                    DriverSpec::Agent(ActionKind::Continuous) => ActionType::Continuous,
                    _ => ActionType::Meta,
                }),
                live: false,
                expert: None,
                stats: None,
                aim: 0.0,
            })
            .collect();
        Ok(Env {
            episode: scenario.clone(),
            scenario,
            observation: options.observation.unwrap_or(ObservationKind::Kinematics),
            max_cycles,
            render_size,
            expert: options.expert.map(game),
            policy: options.policy,
            diagnostics: options.diagnostics,
            seeds: ChaCha8Rng::seed_from_u64(entropy),
            world: None,
            agents,
            cycles: 0,
            scratch: StepScratch::default(),
        })
    }

    /// The world, once reset.
    #[cfg(test)]
    pub(crate) fn world(&self) -> Option<&World> {
        self.world.as_ref()
    }

    /// Names of the agents live now.
    pub fn live_agents(&self) -> Vec<String> {
        self.agents.iter().filter(|a| a.live).map(|a| a.name.clone()).collect()
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
    /// `overrides.<dotted key>` values), builds its world from the seed. Any other option
    /// is refused, naming it, and the env stays as it was.
    pub fn reset(&mut self, seed: Option<u64>, options: &[(String, OptionValue)]) -> Result<ResetOutcome, ErrorReply> {
        let overrides = episode_overrides(options)?;
        let mut seeds = match seed {
            Some(seed) => ChaCha8Rng::seed_from_u64(seed),
            None => self.seeds.clone(),
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
        let mut world = episode.build(world_seed);
        self.seeds = seeds;
        self.episode = episode;
        self.cycles = 0;
        for agent in &mut self.agents {
            agent.live = true;
            agent.vehicle = world.find(&agent.name).unwrap_or(agent.vehicle);
            agent.expert =
                self.expert.map(|game| Box::new(GtDriver::new(game, Role::Leader, world.gt_params(agent.vehicle))));
            agent.stats = Some(episode::EpisodeStats::start(&world, agent.vehicle));
            agent.aim = world.vehicle(agent.vehicle).target_speed;
        }
        let outcome = self
            .agents
            .iter_mut()
            .map(|agent| {
                let observation = observation::observe(self.observation, world.scene(), agent.vehicle, agent.action);
                let mut info = reward::info(&world, agent.vehicle, None);
                add_expert(&mut info, &mut world, agent);
                if self.diagnostics {
                    add_diagnostics(&mut info, &world);
                }
                (agent.name.clone(), observation, info)
            })
            .collect();
        self.world = Some(world);
        Ok(outcome)
    }

    /// One env step. Every action is checked before any is applied, so a refused step
    /// leaves the env as it was.
    pub fn step(&mut self, actions: &[(String, Action)]) -> Result<Vec<AgentStep>, ErrorReply> {
        let Some(world) = self.world.as_mut() else {
            return Err(error(ErrorCode::NotReset, "step before reset: call reset first"));
        };
        if !self.agents.iter().any(|a| a.live) {
            return Err(error(ErrorCode::AgentNotLive, "every agent has finished this episode: call reset"));
        }
        if let (Some(policy), Some((name, _))) = (self.policy, actions.first()) {
            return Err(error(
                ErrorCode::InvalidAction,
                format!(
                    "agent '{name}' is driven by the server's built-in policy {policy} (the env's `policy` \
                     option): send steps without actions"
                ),
            ));
        }
        let StepScratch { chosen, applied, live_before, driving_before, vehicles, costs } = &mut self.scratch;
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
            if !agent.live {
                return Err(error(ErrorCode::AgentNotLive, format!("agent '{name}' has finished this episode")));
            }
            action::check(action, agent.action)
                .map_err(|(code, message)| error(code, format!("agent '{name}': {message}")))?;
            if chosen[index].replace(action.clone()).is_some() {
                return Err(error(ErrorCode::InvalidAction, format!("agent '{name}' has two actions in one step")));
            }
        }
        applied.clear();
        applied.resize(self.agents.len(), true);
        for ((agent, action), applied) in self.agents.iter().zip(chosen.iter()).zip(applied.iter_mut()) {
            if agent.live && self.policy.is_none() {
                *applied = action::apply(world, agent.vehicle, action.as_ref(), agent.action);
            }
        }
        live_before.clear();
        live_before.extend((0..self.agents.len()).filter(|&i| self.agents[i].live));
        driving_before.clear();
        driving_before
            .extend(live_before.iter().map(|&i| world.vehicle(self.agents[i].vehicle).status == Status::Driving));
        vehicles.clear();
        vehicles.extend(live_before.iter().map(|&i| self.agents[i].vehicle));
        let started = world.time();
        reward::advance(world, vehicles, self.episode.step_dt, costs);
        self.cycles += 1;
        let truncated = self.cycles >= self.max_cycles;
        let mut results = Vec::with_capacity(live_before.len());
        for (k, &i) in live_before.iter().enumerate() {
            let agent = &mut self.agents[i];
            let vehicle = world.vehicle(agent.vehicle);
            let crashed_now = driving_before[k] && matches!(vehicle.status, Status::Crashed | Status::OffRoad);
            let terminated = vehicle.status != Status::Driving;
            let reward = reward::reward(&self.episode.reward, self.max_cycles, &costs[k], agent.aim, crashed_now);
            let mut info = reward::info(world, agent.vehicle, Some(&costs[k]));
            info.values.push(("action_applied".to_string(), InfoValue::Bool(applied[i])));
            let stats = agent.stats.get_or_insert_with(|| episode::EpisodeStats::start(world, agent.vehicle));
            stats.record(world, agent.vehicle, started, reward, &costs[k]);
            if terminated || truncated {
                let reason = if terminated { reward::end_reason(world, agent.vehicle) } else { "time_limit" };
                info.values.push(("end_reason".to_string(), InfoValue::Str(reason.to_string())));
                info.values.extend(stats.finish(world, agent.vehicle, &self.episode.goal, reason));
            } else {
                add_expert(&mut info, world, agent);
            }
            if self.diagnostics {
                add_diagnostics(&mut info, world);
            }
            results.push(AgentStep {
                agent: agent.name.clone(),
                observation: observation::observe(self.observation, world.scene(), agent.vehicle, agent.action),
                reward,
                terminated,
                truncated: truncated && !terminated,
                info,
            });
        }
        for (k, &i) in live_before.iter().enumerate() {
            self.agents[i].live = !(results[k].terminated || results[k].truncated);
        }
        Ok(results)
    }

    /// The global view: every vehicle's kinematics, in a fixed order.
    pub fn state(&self) -> Result<Observation, ErrorReply> {
        let world =
            self.world.as_ref().ok_or_else(|| error(ErrorCode::NotReset, "state before reset: call reset first"))?;
        Ok(observation::state(world, &self.scenario))
    }

    /// A picture of the road around the first agent.
    pub fn render(&self, mode: RenderMode) -> Result<Frame, ErrorReply> {
        let world =
            self.world.as_ref().ok_or_else(|| error(ErrorCode::NotReset, "render before reset: call reset first"))?;
        let focus = self.agents.first().map(|a| a.vehicle);
        Ok(match mode {
            RenderMode::RgbArray => render::rgb(world, focus, self.render_size),
            RenderMode::Ansi => Frame::Ansi(render::ansi(world, focus)),
        })
    }
}

/// On request, every game-theoretic car's solver counts since the episode began, keyed
/// `gt.<car>.<count>`, cars in the world's order (named ones by name, then traffic). No timings: infos are bit-reproducible, so
/// decision times live in the benchmarks (docs/performance.md).
fn add_diagnostics(info: &mut Info, world: &World) {
    for vehicle in world.vehicles() {
        let Driver::Gt(gt) = &vehicle.driver else { continue };
        let d = &gt.diagnostics;
        let counts = [
            ("plans", i64::from(d.plans)),
            ("qp_iterations", i64::from(d.iterations)),
            ("qp_iterations_total", i64::try_from(d.iterations_total).unwrap_or(i64::MAX)),
            ("fallbacks", i64::from(d.fallbacks)),
            ("inexact", i64::from(d.inexact)),
        ];
        for (count, value) in counts {
            info.values.push((format!("gt.{}.{count}", vehicle.name), InfoValue::I64(value)));
        }
    }
}

fn game(game: arena_protocol::Game) -> Game {
    match game {
        arena_protocol::Game::Nash => Game::Nash,
        arena_protocol::Game::Stackelberg => Game::Stackelberg,
    }
}

/// Hands every learner's vehicle of `episode` to `policy`: the same world as a scenario
/// file with that driver, so a `gt` policy drives exactly as `arena paper`'s EC does.
fn drive_learners(episode: &mut Scenario, policy: BuiltinPolicy) {
    for vehicle in episode.vehicles.iter_mut().filter(|v| matches!(v.driver, DriverSpec::Agent(_))) {
        vehicle.driver = match policy {
            BuiltinPolicy::Gt { style, game: g } => {
                if let Some(style) = style {
                    vehicle.style = match style {
                        arena_protocol::Style::Aggressive => Style::Aggressive,
                        arena_protocol::Style::Normal => Style::Normal,
                        arena_protocol::Style::Conservative => Style::Conservative,
                    };
                }
                DriverSpec::Gt { game: game(g), role: Role::Leader, params: Default::default() }
            }
            BuiltinPolicy::Idm => DriverSpec::Idm,
        };
    }
}

/// On request, what the built-in AV would do in the agent's place: `expert_action` in
/// the agent's own action space, and the game's `expert_accel` and `expert_sigma`. For a
/// continuous agent the action is the AV's whole command (its acceleration and the
/// preview point its MPC plans, relative to the current lane), planned with the memory
/// the AV would have had in this place, so replaying it drives as the AV drives; for a
/// meta agent it is the meta action that best reproduces the AV's decision.
fn add_expert(info: &mut Info, world: &mut World, agent: &mut AgentSlot) {
    let Some(memory) = agent.expert.as_mut() else { return };
    let id = agent.vehicle;
    let (decision, action) = match agent.action {
        ActionType::Meta => {
            let decision = expert_decision(world.scene(), id, memory.game, &memory.params);
            let vehicle = world.vehicle(id);
            let (lane, target, s) = (vehicle.target_lane, vehicle.target_speed, vehicle.state.s);
            let mask = action::meta_mask(world.road(), lane, target, s);
            let limit = world.road().speed_limit(lane);
            let meta = action::meta_equivalent(&decision, mask, vehicle.state.vx, target, limit);
            (decision, InfoValue::I64(i64::from(meta)))
        }
        ActionType::Continuous => {
            let step = plan(world.scene(), id, memory, None);
            let road = world.road();
            let centre = road.lane_center(world.current_lane(id));
            let accel = (step.command.accel / action::CONTINUOUS_ACCEL_SCALE).clamp(-1.0, 1.0);
            let offset = ((step.command.preview - centre) / road.lane_width()).clamp(-1.0, 1.0);
            let decision = step.driver.decision;
            **memory = step.driver;
            (decision, InfoValue::F64s(vec![accel, offset]))
        }
    };
    info.values.push(("expert_action".to_string(), action));
    info.values.push(("expert_accel".to_string(), InfoValue::F64(decision.accel)));
    info.values.push(("expert_sigma".to_string(), InfoValue::I64(i64::from(decision.lane_change.sigma()))));
}

#[cfg(test)]
mod tests;

/// The scenario overrides of a reset's options: every key must be `overrides.<dotted
/// key>` (`overrides.vehicle.ac.speed`); any other is refused with its name.
fn episode_overrides(options: &[(String, OptionValue)]) -> Result<Vec<(String, toml::Value)>, ErrorReply> {
    let mut overrides = Vec::with_capacity(options.len());
    for (key, value) in options {
        let Some(path) = key.strip_prefix("overrides.").filter(|path| !path.is_empty()) else {
            return Err(error(
                ErrorCode::InvalidOption,
                format!(
                    "unknown reset option '{key}': the reset options are overrides.<dotted scenario key> \
                     (e.g. overrides.vehicle.ac.speed)"
                ),
            ));
        };
        let value = match value {
            OptionValue::Bool(b) => toml::Value::Boolean(*b),
            OptionValue::Int(i) => toml::Value::Integer(*i),
            OptionValue::Float(f) => toml::Value::Float(*f),
            OptionValue::Str(s) => toml::Value::String(s.clone()),
        };
        overrides.push((path.to_string(), value));
    }
    Ok(overrides)
}
