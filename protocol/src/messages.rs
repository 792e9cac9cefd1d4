//! Every request and reply, as serde types. Maps are `Vec<(key, value)>` in a fixed
//! order (agents in `possible_agents` order), so encodings are deterministic.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::ErrorReply;
use crate::explain::DecisionExplained;
use crate::info::Info;
use crate::names::named;
use crate::options::CreateOptions;
use crate::spaces::Space;
use crate::world::{WorldFrame, WorldStart};

macro_rules! hex_id {
    ($name:ident, $what:literal) => {
        #[doc = concat!("A 128-bit ", $what, " id, shown as 32 hex digits.")]
        #[repr(transparent)]
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
        pub struct $name(pub u128);

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{:032x}", self.0)
            }
        }

        impl FromStr for $name {
            type Err = std::num::ParseIntError;
            fn from_str(text: &str) -> Result<Self, Self::Err> {
                u128::from_str_radix(text, 16).map($name)
            }
        }
    };
}

hex_id!(EnvId, "env");
hex_id!(ClientId, "client");
hex_id!(ClientTag, "public client");

impl ClientId {
    /// What this client shows the world: its liveliness token carries the tag, never the
    /// id, because the id is what proves ownership of its envs. The tag is the first 128
    /// bits (big-endian) of SHA3-256 over the id's 16 bytes, big-endian; it cannot be
    /// turned back into the id.
    pub fn tag(&self) -> ClientTag {
        use sha3::Digest;
        let digest = sha3::Sha3_256::digest(self.0.to_be_bytes());
        let mut first = [0u8; 16];
        first.copy_from_slice(&digest[..16]);
        ClientTag(u128::from_be_bytes(first))
    }
}

/// Everything a client asks. `version` is first, so any version can read it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Request {
    /// `PROTOCOL_VERSION` of the sender.
    pub version: u16,
    /// Who asks: envs answer only the client that created them.
    pub client: ClientId,
    /// What is asked.
    pub body: RequestBody,
}

impl Request {
    /// A request of this crate's `PROTOCOL_VERSION`.
    pub fn new(client: ClientId, body: RequestBody) -> Request {
        Request { version: crate::PROTOCOL_VERSION, client, body }
    }
}

/// The requests.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum RequestBody {
    /// Version, scenarios and load of the server.
    ServerInfo,
    /// A new env from a scenario.
    CreateEnv {
        /// Which scenario.
        scenario: ScenarioSource,
        /// Overrides and env options.
        options: CreateOptions,
    },
    /// Start an episode.
    Reset {
        /// The env.
        env: EnvId,
        /// Sequence number (see `Step`).
        seq: u64,
        /// Seed of the episode; none continues the env's seed stream.
        seed: Option<u64>,
        /// What this episode changes of the scenario.
        options: ResetOptions,
    },
    /// One env step.
    Step {
        /// The env.
        env: EnvId,
        /// Grows by one per reset or step; resending the last one returns the cached
        /// reply without stepping again; an older one gets `StaleSequence`.
        seq: u64,
        /// Actions of live agents; an agent left out takes the default action.
        actions: Vec<(String, Action)>,
    },
    /// Steps of many envs of this client, in one round trip.
    StepBatch {
        /// One entry per env.
        steps: Vec<BatchStep>,
    },
    /// A picture of the env.
    Render {
        /// The env.
        env: EnvId,
        /// Which picture.
        mode: RenderMode,
        /// The vehicle the picture follows, by its scenario name (an agent's name for a
        /// learner) (version 9); `None` follows the first live learner, else the first
        /// vehicle.
        follow: Option<String>,
    },
    /// The global state.
    State {
        /// The env.
        env: EnvId,
    },
    /// The env's specs again.
    Specs {
        /// The env.
        env: EnvId,
    },
    /// Close the env.
    Close {
        /// The env.
        env: EnvId,
    },
    /// Turn recording on or off (version 7): while on, reset replies carry a
    /// `WorldStart` and step replies a `WorldFrame` per control period. Setting what is
    /// already set changes nothing, so a resent request is harmless.
    Record {
        /// The env.
        env: EnvId,
        /// On or off.
        on: bool,
    },
    /// The env's whole state as bytes (version 7): its world (every vehicle, every
    /// driver's memory, the RNG, the clock), its agents and their episodes' figures, its
    /// seed stream; named by scenario, a hash of the resolved scenario and the protocol
    /// version (docs/protocol.md, "Snapshots").
    Snapshot {
        /// The env.
        env: EnvId,
    },
    /// Puts a `Snapshot`'s state into the env (version 7), which then continues exactly
    /// as the env the snapshot was taken of would have. Sequenced as `Reset` is; the reply
    /// is a `Reset` reply of the agents live in the snapshot.
    Restore {
        /// The env.
        env: EnvId,
        /// Sequence number (see `Step`).
        seq: u64,
        /// The bytes a `Snapshot` reply carried, at most `bounds::MAX_SNAPSHOT_BYTES`.
        snapshot: Vec<u8>,
    },
    /// What the env's server spent on it (version 9), measured by the server's clock:
    /// never part of an observation or an info, which stay the same bits on every run.
    Statistics {
        /// The env.
        env: EnvId,
    },
}

/// One env's step within a `StepBatch`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BatchStep {
    /// The env.
    pub env: EnvId,
    /// Its sequence number.
    pub seq: u64,
    /// Its actions.
    pub actions: Vec<(String, Action)>,
}

/// Where a scenario comes from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ScenarioSource {
    /// A scenario the server has, by name ("merge").
    Named(String),
    /// A scenario file's text sent by the client, validated exactly as files are.
    Inline {
        /// Name used in error messages ("mine.toml").
        file_name: String,
        /// The TOML text.
        text: String,
    },
}

/// Options of `Reset`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ResetOptions {
    /// (dotted key, value) overrides of the scenario for this episode only, applied after
    /// its `[vary]` draws and read exactly as `CreateOptions::overrides` are.
    pub overrides: Vec<(String, OptionValue)>,
}

/// A driver the server has, in a learner's place.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BuiltinPolicy {
    /// The game-theoretic AV of the paper as a leader; `style` none keeps the learner's.
    Gt {
        /// Driving style (Tables I and III), or the learner's own.
        style: Option<Style>,
        /// The game it plays.
        game: Game,
    },
    /// IDM for speed and MOBIL for lane changes, in the learner's style.
    Idm,
}

impl BuiltinPolicy {
    /// The forms `FromStr` takes, for help texts and error messages:
    /// `gt:<aggressive|normal|conservative>:<nash|stackelberg>`, `expert`, `idm`.
    pub fn forms() -> [String; 3] {
        let gt = format!("gt:<{}>:<{}>", Style::ALL.map(Style::name).join("|"), Game::ALL.map(Game::name).join("|"));
        [gt, "expert".into(), "idm".into()]
    }
}

impl fmt::Display for BuiltinPolicy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BuiltinPolicy::Gt { style: None, game: Game::Stackelberg } => f.write_str("expert"),
            BuiltinPolicy::Gt { style, game } => {
                let style = style.map_or("own", Style::name);
                write!(f, "gt:{style}:{}", game.name())
            }
            BuiltinPolicy::Idm => f.write_str("idm"),
        }
    }
}

impl FromStr for BuiltinPolicy {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, String> {
        let unknown = || {
            let [gt, expert, idm] = Self::forms();
            let stackelberg = Game::Stackelberg;
            format!(
                "unknown built-in policy '{text}': the built-in policies are {gt}, {expert} (gt in the learner's own \
                 style, {stackelberg}), {idm}"
            )
        };
        match text.split(':').collect::<Vec<_>>().as_slice() {
            ["expert"] => Ok(BuiltinPolicy::Gt { style: None, game: Game::Stackelberg }),
            ["idm"] => Ok(BuiltinPolicy::Idm),
            ["gt", style, game] => {
                let style = style.parse::<Style>().map_err(|_| unknown())?;
                let game = game.parse::<Game>().map_err(|_| unknown())?;
                Ok(BuiltinPolicy::Gt { style: Some(style), game })
            }
            _ => Err(unknown()),
        }
    }
}

/// The paper's driving styles (Tables I and III), from the most to the least aggressive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Style {
    /// Large safety margin traded for speed.
    Aggressive,
    /// Between the two.
    Normal,
    /// Keeps its distance.
    Conservative,
}

named!(Style, "style", { Aggressive => "aggressive", Normal => "normal", Conservative => "conservative" });

/// The game the built-in AV plays when asked for `expert` infos.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Game {
    /// Nash equilibrium, eq. (15)-(16).
    Nash,
    /// Stackelberg equilibrium, eq. (17)-(18).
    Stackelberg,
}

named!(Game, "game", { Nash => "nash", Stackelberg => "stackelberg" });

/// A value of an option or override.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum OptionValue {
    /// A boolean.
    Bool(bool),
    /// An integer.
    Int(i64),
    /// A float.
    Float(f64),
    /// A string.
    Str(String),
}

/// How agents act.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ActionType {
    /// Discrete 5: lane left, idle, lane right, faster, slower.
    Meta,
    /// Box 2 in [-1, 1]: acceleration (times 6 m/s^2), preview offset from the lane
    /// centre (times the lane width).
    Continuous,
}

named!(ActionType, "action type", { Meta => "meta", Continuous => "continuous" });

/// What agents observe.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ObservationKind {
    /// The kinematics matrix.
    Kinematics,
    /// A Dict of the kinematics matrix and an `action_mask`.
    KinematicsWithMask,
}

named!(ObservationKind, "observation", { Kinematics => "kinematics", KinematicsWithMask => "kinematics_with_mask" });

/// highway-env's meta actions, Discrete(`MetaAction::ALL.len()`): on the wire (`Action::Meta`)
/// and in masks each is its code, the declaration order.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum MetaAction {
    /// Change to the lane on the left.
    LaneLeft = 0,
    /// Keep lane and target speed.
    Idle = 1,
    /// Change to the lane on the right.
    LaneRight = 2,
    /// Next higher target speed.
    Faster = 3,
    /// Next lower target speed.
    Slower = 4,
}

named!(MetaAction, "meta action", {
    LaneLeft => "lane_left", Idle => "idle", LaneRight => "lane_right", Faster => "faster", Slower => "slower",
});

impl MetaAction {
    /// Its code: the index of its place in Discrete(`ALL.len()`).
    pub fn code(self) -> u32 {
        self as u32
    }

    /// The meta action of a code, if there is one.
    pub fn from_code(code: u32) -> Option<MetaAction> {
        Self::ALL.get(usize::try_from(code).ok()?).copied()
    }
}

/// One agent's action.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Action {
    /// A meta action's code (`MetaAction::code`), 0 ..= 4.
    Meta(u32),
    /// [acceleration, lateral preview target], each in [-1, 1]: the server scales them to
    /// m/s^2 (times 6) and to an offset from the current lane's centre (times the lane
    /// width, positive to the left), fed to the driver model.
    Continuous([f32; 2]),
}

/// Picture kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RenderMode {
    /// Top-down RGB, height x width x 3 uint8.
    RgbArray,
    /// Text.
    Ansi,
}

/// Every reply. `version` is first.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Reply {
    /// `PROTOCOL_VERSION` of the server.
    pub version: u16,
    /// The answer.
    pub body: ReplyBody,
}

impl Reply {
    /// A reply of this crate's `PROTOCOL_VERSION`.
    pub fn new(body: ReplyBody) -> Reply {
        Reply { version: crate::PROTOCOL_VERSION, body }
    }
}

/// The replies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ReplyBody {
    /// To `ServerInfo`.
    ServerInfo(ServerInfo),
    /// To `CreateEnv`.
    Created {
        /// The new env's id: keep it secret, it is the only key to the env.
        env: EnvId,
        /// Its specs.
        specs: EnvSpecs,
    },
    /// To `Reset`.
    Reset(ResetReply),
    /// To `Step`.
    Step(StepReply),
    /// To `StepBatch`, one item per env in request order.
    StepBatch(Vec<BatchItem>),
    /// To `Render`.
    Render(Frame),
    /// To `State`.
    State(Observation),
    /// To `Specs`.
    Specs(EnvSpecs),
    /// To `Close`.
    Closed,
    /// To anything that failed.
    Error(ErrorReply),
    /// To `Record`: turned on after a reset, the world now (road, vehicles, a frame), so
    /// a recording can begin mid-episode; `None` when turned off or before any reset.
    Recording(Option<Box<WorldStart>>),
    /// To `Snapshot`: the env's state (version 7), for `Restore`.
    Snapshot(Vec<u8>),
    /// To `Statistics` (version 9).
    Statistics(EnvStatistics),
}

/// What a server spent on one env, by its own clock (`RequestBody::Statistics`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct EnvStatistics {
    /// For each agent the server's built-in policy drives (`CreateOptions::policy`), in
    /// `possible_agents` order: the wall time the server spent deciding for it in each
    /// step it drove it (every control period of the step, the decision and the
    /// controller), in microseconds, oldest first, since the env was created; at most
    /// the newest `EnvStatistics::kept_per_agent` steps.
    pub decision_micros: Vec<(String, Vec<f32>)>,
}

impl EnvStatistics {
    /// Most steps kept per agent: 20 000 (80 KB), chosen here, a hundred episodes of
    /// 200 steps.
    pub const MAX_STEPS: usize = 20_000;
    /// Most samples kept per env over all its agents: 2^18 (1 MiB), so that an env of
    /// many learners (a client's inline scenario) holds and sends a bounded amount.
    pub const MAX_SAMPLES: usize = 1 << 18;

    /// Steps kept per agent in an env of `agents` learners.
    pub fn kept_per_agent(agents: usize) -> usize {
        (Self::MAX_SAMPLES / agents.max(1)).clamp(1, Self::MAX_STEPS)
    }
}

/// One env's result within a batch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum BatchItem {
    /// It stepped.
    Ok(StepReply),
    /// It did not.
    Err(ErrorReply),
}

/// What a server is and holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ServerInfo {
    /// Its id.
    pub server_id: String,
    /// Its crate version.
    pub version: String,
    /// Its protocol version.
    pub protocol: u16,
    /// Scenario names it can create envs from.
    pub scenarios: Vec<String>,
    /// Envs alive now.
    pub envs: u32,
    /// Most envs it holds.
    pub max_envs: u32,
    /// Most envs one party (an authenticated user, else a client id) may hold.
    pub max_envs_per_client: u32,
    /// Envs the asking party holds on this server now (so placement skips a server where
    /// it is at `max_envs_per_client`).
    pub yours: u32,
    /// Env steps it has taken since it started (batched ones included): its load, with
    /// `cores`, for clients that place envs.
    pub steps: u64,
    /// CPU cores it may use.
    pub cores: u32,
    /// Its resident memory (bytes; 0 where the system does not say), for soak runs.
    pub rss_bytes: u64,
}

/// Agents, spaces and timing of an env.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnvSpecs {
    /// Every agent that can appear, in a fixed order.
    pub possible_agents: Vec<String>,
    /// Observation space per agent.
    pub observation_spaces: Vec<(String, Space)>,
    /// Action space per agent.
    pub action_spaces: Vec<(String, Space)>,
    /// Space of `State`.
    pub state_space: Space,
    /// Simulated seconds per step.
    pub dt: f64,
    /// Steps per episode before every agent is truncated.
    pub max_cycles: u32,
    /// Frames per simulated second (1 / dt, at least 1).
    pub render_fps: u32,
    /// Render modes offered.
    pub render_modes: Vec<RenderMode>,
}

/// An n-dimensional array, row-major.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tensor {
    /// Dimensions.
    pub shape: Vec<u32>,
    /// Elements.
    pub data: TensorData,
}

/// Typed elements of a tensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum TensorData {
    /// float32.
    F32(Vec<f32>),
    /// uint8.
    U8(Vec<u8>),
    /// int8.
    I8(Vec<i8>),
    /// int64.
    I64(Vec<i64>),
}

impl TensorData {
    /// Number of elements.
    pub fn len(&self) -> usize {
        match self {
            TensorData::F32(v) => v.len(),
            TensorData::U8(v) => v.len(),
            TensorData::I8(v) => v.len(),
            TensorData::I64(v) => v.len(),
        }
    }

    /// Whether there are no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl Tensor {
    /// A tensor whose shape and data agree, or `None`.
    pub fn new(shape: Vec<u32>, data: TensorData) -> Option<Tensor> {
        let count = shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d as usize))?;
        (count == data.len()).then_some(Tensor { shape, data })
    }
}

/// An observation or a state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Observation {
    /// One array.
    Tensor(Tensor),
    /// Named arrays (a Gymnasium Dict), keys sorted.
    Dict(Vec<(String, Tensor)>),
}

/// One agent at the start of an episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AgentStart {
    /// Its name.
    pub agent: String,
    /// What it observes.
    pub observation: Observation,
    /// Its info (`info::SCHEMA` keys, zero where nothing happened yet).
    pub info: Info,
}

/// The reply to `Reset`: one row per possible agent, in `possible_agents` order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResetReply {
    /// The request's sequence number.
    pub seq: u64,
    /// Per agent.
    pub agents: Vec<AgentStart>,
    /// While recording: the road, the vehicles and the first frame (version 7).
    pub world: Option<Box<WorldStart>>,
}

/// One agent's results of a step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AgentStep {
    /// Its name.
    pub agent: String,
    /// What it observes after the step.
    pub observation: Observation,
    /// Its reward for the step (docs/rewards.md).
    pub reward: f64,
    /// Its episode ended in this step (crash, off the road, end of road or lane).
    pub terminated: bool,
    /// Its episode reached `max_cycles` in this step (never with `terminated`).
    pub truncated: bool,
    /// Its info, the same keys in the same order on every step (`info::SCHEMA`).
    pub info: Info,
}

/// The reply to `Step`: one row per agent live before the step, in `possible_agents`
/// order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepReply {
    /// The request's sequence number.
    pub seq: u64,
    /// Per agent live before the step.
    pub steps: Vec<AgentStep>,
    /// Agents live after the step.
    pub agents: Vec<String>,
    /// While recording: the world at the end of each control period of the step (and at
    /// its end, if that falls between two), in time order; empty otherwise (version 7).
    pub world: Vec<WorldFrame>,
    /// With `CreateOptions::explain`: every game-theoretic decision of the step, in time
    /// order, cars by index; empty otherwise (version 8).
    pub explain: Vec<DecisionExplained>,
}

/// A rendered frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Frame {
    /// height x width x 3 bytes, row-major.
    Rgb {
        /// Rows.
        height: u32,
        /// Columns.
        width: u32,
        /// RGB bytes.
        pixels: Vec<u8>,
    },
    /// A text picture.
    Ansi(String),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::EndReason;
    use crate::PROTOCOL_VERSION;
    use crate::codec::{decode, encode, peek_version};
    use crate::error::ErrorCode;
    use crate::info::InfoValue;
    use crate::spaces::DType;
    use crate::world::{
        CollisionEvent, DriverInfo, Fault, GtRole, LaneGeometry, RoadGeometry, VehicleFrame, VehicleInfo,
    };

    fn frame(time: f64) -> WorldFrame {
        let vehicle = VehicleFrame {
            x: 12.5,
            y: -3.5,
            heading: 0.01,
            s: 12.0,
            d: -3.5,
            speed: 22.0,
            accel: -0.5,
            lane: 1,
            target_lane: 0,
            end: EndReason::Running,
        };
        WorldFrame {
            time,
            vehicles: vec![vehicle, VehicleFrame { end: EndReason::LaneEnd, lane: 2, ..vehicle }],
            collisions: vec![CollisionEvent { time, rear: 0, front: 1, at_fault: Fault::Both, x: 1.0, y: -2.0 }],
        }
    }

    fn world_start() -> Box<WorldStart> {
        let lane = LaneGeometry {
            centre: vec![[0.0, 0.0], [100.0, 0.0]],
            left: vec![[0.0, 2.0], [100.0, 2.0]],
            right: vec![[0.0, -2.0], [100.0, -2.0]],
            end: 100.0,
            ends_early: true,
            speed_limit: 25.0,
        };
        let info = |name: &str, driver| VehicleInfo {
            name: name.into(),
            learner: driver == DriverInfo::Learner,
            driver,
            style: Style::Aggressive,
            length: 5.0,
            width: 2.0,
        };
        Box::new(WorldStart {
            road: RoadGeometry { length: 1000.0, lane_width: 4.0, lanes: vec![lane] },
            vehicles: vec![
                info("ego", DriverInfo::Learner),
                info("ac", DriverInfo::Gt { game: Game::Nash, role: GtRole::Follower }),
                info("t0", DriverInfo::Idm),
            ],
            frame: frame(0.0),
        })
    }

    fn observation() -> Observation {
        Observation::Dict(vec![
            ("action_mask".into(), Tensor::new(vec![5], TensorData::I8(vec![1, 1, 0, 1, 0])).unwrap()),
            ("observation".into(), Tensor::new(vec![2, 2], TensorData::F32(vec![0.5, -0.25, 1.0, 0.0])).unwrap()),
        ])
    }

    fn specs() -> EnvSpecs {
        let space = Space::Box { low: vec![-1.0; 4], high: vec![1.0; 4], shape: vec![2, 2], dtype: DType::F32 };
        EnvSpecs {
            possible_agents: vec!["ego".into(), "b".into()],
            observation_spaces: vec![("ego".into(), space.clone()), ("b".into(), space.clone())],
            action_spaces: vec![
                ("ego".into(), Space::Discrete { n: 5, start: 0 }),
                (
                    "b".into(),
                    Space::Box { low: vec![-6.0, -4.0], high: vec![6.0, 4.0], shape: vec![2], dtype: DType::F32 },
                ),
            ],
            state_space: Space::Dict(vec![("x".into(), space)]),
            dt: 0.1,
            max_cycles: 200,
            render_fps: 10,
            render_modes: vec![RenderMode::RgbArray, RenderMode::Ansi],
        }
    }

    fn step_reply() -> StepReply {
        let info = Info {
            values: vec![
                ("cost".into(), InfoValue::F64(2.0)),
                ("crashed".into(), InfoValue::Bool(true)),
                ("lane".into(), InfoValue::I64(1)),
                ("expert_action".into(), InfoValue::F64s(vec![0.5, -1.0])),
            ],
        };
        let b_observation = Observation::Tensor(Tensor::new(vec![1], TensorData::I64(vec![-9])).unwrap());
        StepReply {
            seq: 3,
            steps: vec![
                AgentStep {
                    agent: "ego".into(),
                    observation: observation(),
                    reward: -1.5,
                    terminated: false,
                    truncated: true,
                    info,
                },
                AgentStep {
                    agent: "b".into(),
                    observation: b_observation,
                    reward: 0.25,
                    terminated: true,
                    truncated: false,
                    info: Info::default(),
                },
            ],
            agents: vec![],
            world: vec![],
            explain: vec![],
        }
    }

    fn explained_step_reply() -> StepReply {
        use crate::explain::{DecisionExplained, GameTable, PathPoint};
        let point = PathPoint { t: 0.5, x: 1.0, y: -2.0, speed: 20.0 };
        let table = GameTable {
            side: -1,
            adjacent: Some(1),
            ec_actions: vec![(-1.0, 0), (0.5, -1)],
            ac_actions: vec![0.0, 1.0],
            ec_costs: vec![1.0, 1.0, 2.0, 3.0],
            ac_costs: vec![0.5, 0.25, 4.0, 5.0],
            pruned: vec![false, true],
            row: 0,
            col: 1,
            exact: true,
            cost: 1.0,
        };
        let decision = DecisionExplained {
            time: 1.5,
            vehicle: 0,
            game: Game::Stackelberg,
            role: crate::world::GtRole::Leader,
            ec: 0,
            tables: vec![table],
            chosen: Some(0),
            games_accel: -1.0,
            accel: -1.0,
            sigma: 0,
            safety: false,
            fallback: true,
            planned: vec![point, point],
            predicted: vec![],
        };
        StepReply { explain: vec![decision], ..step_reply() }
    }

    fn recorded_step_reply() -> StepReply {
        StepReply { world: vec![frame(0.1), frame(0.2)], agents: vec!["ego".into()], ..step_reply() }
    }

    /// Every create option set through `CREATE_OPTIONS`, none left at its default: a new
    /// option is in the round trips without a word here.
    fn every_option_set() -> CreateOptions {
        use crate::{CREATE_OPTIONS, Given, OptionKind};
        let mut options = CreateOptions::default();
        for option in CREATE_OPTIONS {
            let given = match option.kind {
                OptionKind::Flag => Given::Flag(true),
                OptionKind::Count => Given::Count(9),
                OptionKind::Pair => Given::Pair(10, 20),
                OptionKind::Choice(names) => Given::Name(names().pop().unwrap()),
                OptionKind::Overrides => Given::Overrides(vec![("x".into(), OptionValue::Str("y".into()))]),
                OptionKind::Names => Given::Names(vec!["speed".into()]),
            };
            (option.set)(&mut options, given).unwrap();
        }
        assert_eq!(
            (options.action_type, options.observation, options.expert, options.render_size),
            (
                Some(ActionType::Continuous),
                Some(ObservationKind::KinematicsWithMask),
                Some(Game::Stackelberg),
                Some((10, 20))
            )
        );
        options
    }

    fn requests() -> Vec<RequestBody> {
        let env = EnvId(0xdead_beef_u128 << 64 | 7);
        vec![
            RequestBody::ServerInfo,
            RequestBody::CreateEnv {
                scenario: ScenarioSource::Named("merge".into()),
                options: CreateOptions {
                    overrides: vec![
                        ("vehicle.ac.speed".into(), OptionValue::Float(18.0)),
                        ("x".into(), OptionValue::Str("y".into())),
                    ],
                    policy: Some(BuiltinPolicy::Gt { style: Some(Style::Conservative), game: Game::Nash }),
                    ..every_option_set()
                },
            },
            RequestBody::CreateEnv {
                scenario: ScenarioSource::Inline { file_name: "a.toml".into(), text: "name = 'a'".into() },
                options: CreateOptions {
                    action_type: Some(ActionType::Meta),
                    observation: Some(ObservationKind::Kinematics),
                    expert: Some(Game::Nash),
                    ..CreateOptions::default()
                },
            },
            RequestBody::CreateEnv { scenario: ScenarioSource::Named("x".into()), options: CreateOptions::default() },
            RequestBody::Reset {
                env,
                seq: 1,
                seed: Some(42),
                options: ResetOptions {
                    overrides: vec![("k".into(), OptionValue::Bool(true)), ("i".into(), OptionValue::Int(-3))],
                },
            },
            RequestBody::Reset { env, seq: u64::MAX, seed: None, options: ResetOptions::default() },
            RequestBody::Step {
                env,
                seq: 2,
                actions: vec![
                    ("ego".into(), Action::Meta(MetaAction::Faster.code())),
                    ("b".into(), Action::Continuous([0.5, -1.0])),
                ],
            },
            RequestBody::StepBatch {
                steps: vec![
                    BatchStep { env, seq: 4, actions: vec![] },
                    BatchStep { env: EnvId(1), seq: 5, actions: vec![("ego".into(), Action::Meta(0))] },
                ],
            },
            RequestBody::Render { env, mode: RenderMode::RgbArray, follow: None },
            RequestBody::Render { env, mode: RenderMode::Ansi, follow: Some("ac".into()) },
            RequestBody::Statistics { env },
            RequestBody::State { env },
            RequestBody::Specs { env },
            RequestBody::Close { env },
            RequestBody::Record { env, on: true },
            RequestBody::Record { env, on: false },
            RequestBody::Snapshot { env },
            RequestBody::Restore { env, seq: 9, snapshot: vec![0, 1, 255, 7] },
        ]
    }

    fn replies() -> Vec<ReplyBody> {
        let error = ErrorReply { code: ErrorCode::InvalidAction, message: "component 0".into(), env_usable: true };
        vec![
            ReplyBody::ServerInfo(ServerInfo {
                server_id: "s".into(),
                version: "0.1.0".into(),
                protocol: 1,
                scenarios: vec!["merge".into(), "overtake".into()],
                envs: 2,
                max_envs: 9,
                max_envs_per_client: 3,
                yours: 1,
                steps: 1 << 40,
                cores: 2,
                rss_bytes: 12 << 20,
            }),
            ReplyBody::Created { env: EnvId(5), specs: specs() },
            ReplyBody::Reset(ResetReply {
                seq: 1,
                agents: vec![AgentStart { agent: "ego".into(), observation: observation(), info: Info::default() }],
                world: None,
            }),
            ReplyBody::Reset(ResetReply { seq: 2, agents: vec![], world: Some(world_start()) }),
            ReplyBody::Step(step_reply()),
            ReplyBody::Step(recorded_step_reply()),
            ReplyBody::Step(explained_step_reply()),
            ReplyBody::StepBatch(vec![BatchItem::Ok(step_reply()), BatchItem::Err(error.clone())]),
            ReplyBody::Render(Frame::Rgb { height: 1, width: 2, pixels: vec![1, 2, 3, 4, 5, 6] }),
            ReplyBody::Render(Frame::Ansi("..@..".into())),
            ReplyBody::State(observation()),
            ReplyBody::State(Observation::Tensor(Tensor::new(vec![1, 2], TensorData::U8(vec![0, 255])).unwrap())),
            ReplyBody::Specs(specs()),
            ReplyBody::Closed,
            ReplyBody::Error(error),
            ReplyBody::Recording(Some(world_start())),
            ReplyBody::Recording(None),
            ReplyBody::Snapshot(vec![1, 2, 3]),
            ReplyBody::Snapshot(vec![]),
            ReplyBody::Statistics(EnvStatistics::default()),
            ReplyBody::Statistics(EnvStatistics { decision_micros: vec![("ego".into(), vec![12.5, 40.0])] }),
        ]
    }

    #[test]
    fn built_in_policies_are_named_as_the_cli_and_python_spell_them() {
        let expected = [
            ("expert", BuiltinPolicy::Gt { style: None, game: Game::Stackelberg }),
            ("idm", BuiltinPolicy::Idm),
            ("gt:aggressive:nash", BuiltinPolicy::Gt { style: Some(Style::Aggressive), game: Game::Nash }),
            (
                "gt:conservative:stackelberg",
                BuiltinPolicy::Gt { style: Some(Style::Conservative), game: Game::Stackelberg },
            ),
        ];
        for (name, policy) in expected {
            assert_eq!(name.parse::<BuiltinPolicy>(), Ok(policy));
            assert_eq!(policy.to_string(), name);
        }
        for bad in ["gt:normal", "gt:calm:nash", "gt:normal:pareto", "idle", "", "idm:normal"] {
            let error = bad.parse::<BuiltinPolicy>().unwrap_err();
            assert!(error.contains(&format!("'{bad}'")) && error.contains("gt:<aggressive"), "{error}");
        }
    }

    #[test]
    fn every_request_round_trips_and_leads_with_its_version() {
        for body in requests() {
            for version in [PROTOCOL_VERSION, 250, 251, u16::MAX] {
                let request = Request { version, client: ClientId(u128::MAX), body: body.clone() };
                let bytes = encode(&request);
                assert_eq!(decode::<Request>(&bytes).as_ref(), Ok(&request));
                assert_eq!(peek_version(&bytes), Some(version), "{request:?}");
            }
        }
    }

    #[test]
    fn every_reply_round_trips_and_leads_with_its_version() {
        for body in replies() {
            for version in [PROTOCOL_VERSION, 300] {
                let reply = Reply { version, body: body.clone() };
                let bytes = encode(&reply);
                assert_eq!(decode::<Reply>(&bytes).as_ref(), Ok(&reply));
                assert_eq!(peek_version(&bytes), Some(version), "{reply:?}");
            }
        }
    }

    #[test]
    fn skipped_cells_travel_as_nan() {
        let mut reply = explained_step_reply();
        reply.explain[0].tables[0].ec_costs[3] = f64::NAN;
        let ReplyBody::Step(back) = decode::<Reply>(&encode(&Reply::new(ReplyBody::Step(reply)))).unwrap().body else {
            panic!("not a step reply")
        };
        let costs = &back.explain[0].tables[0].ec_costs;
        assert!(costs[3].is_nan() && costs[..3] == [1.0, 1.0, 2.0], "{costs:?}");
    }

    #[test]
    fn statistics_stay_bounded_however_many_learners_an_env_has() {
        assert_eq!(EnvStatistics::kept_per_agent(1), EnvStatistics::MAX_STEPS);
        assert_eq!(EnvStatistics::kept_per_agent(0), EnvStatistics::MAX_STEPS);
        assert_eq!(EnvStatistics::kept_per_agent(1000), 262);
        assert_eq!(EnvStatistics::kept_per_agent(1 << 20), 1, "every agent keeps its latest step");
    }

    #[test]
    fn every_variant_is_covered_by_the_round_trips() {
        // Variant indexes in the fixtures: requests 0..=12, replies 0..=12 (the byte after
        // the one-byte version and, for requests, the client id).
        let request_variants: std::collections::BTreeSet<u8> =
            requests().into_iter().map(|body| encode(&Request::new(ClientId(1), body))[2]).collect();
        assert_eq!(request_variants, (0..=12).collect());
        let reply_variants: std::collections::BTreeSet<u8> =
            replies().into_iter().map(|body| encode(&Reply::new(body))[1]).collect();
        assert_eq!(reply_variants, (0..=12).collect());
    }

    #[test]
    fn a_request_for_the_wrong_envelope_does_not_decode_as_it() {
        // A Reply is not a Request: the decoder must not silently accept it.
        let bytes = encode(&Reply::new(ReplyBody::Closed));
        assert!(decode::<Request>(&bytes).is_err());
    }

    #[test]
    fn a_client_tag_is_the_first_half_of_sha3_256_of_the_id() {
        // Python: hashlib.sha3_256((1).to_bytes(16, "big")).hexdigest()[:32]
        assert_eq!(ClientId(1).tag().to_string(), "f1232a8cea9ae1d59147fcde30471108");
        assert_ne!(ClientId(2).tag(), ClientId(1).tag());
    }

    #[test]
    fn ids_print_and_parse_as_32_hex_digits() {
        let id = EnvId(0xabc);
        assert_eq!(id.to_string(), "00000000000000000000000000000abc");
        assert_eq!(id.to_string().parse::<EnvId>(), Ok(id));
        let max = ClientId(u128::MAX);
        assert_eq!(max.to_string(), "f".repeat(32));
        assert_eq!(max.to_string().parse::<ClientId>(), Ok(max));
        assert!("xyz".parse::<ClientId>().is_err());
        assert!("1".repeat(33).parse::<EnvId>().is_err(), "more than 128 bits");
    }

    #[test]
    fn tensors_refuse_a_shape_that_disagrees_with_their_data() {
        assert!(Tensor::new(vec![2, 3], TensorData::F32(vec![0.0; 6])).is_some());
        assert!(Tensor::new(vec![3], TensorData::F32(vec![0.0; 2])).is_none());
        assert!(Tensor::new(vec![], TensorData::U8(vec![7])).is_some(), "a scalar has one element");
        assert!(Tensor::new(vec![u32::MAX, u32::MAX, u32::MAX], TensorData::U8(vec![])).is_none(), "overflow");
        assert!(Tensor::new(vec![0, 4], TensorData::I64(vec![])).is_some());
    }

    #[test]
    fn meta_action_codes_follow_the_documented_order() {
        assert_eq!(MetaAction::ALL.map(MetaAction::code), [0, 1, 2, 3, 4]);
        assert_eq!(MetaAction::ALL.map(MetaAction::name), ["lane_left", "idle", "lane_right", "faster", "slower"]);
        assert_eq!(MetaAction::from_code(4), Some(MetaAction::Slower));
        assert_eq!(MetaAction::from_code(5), None);
    }
}
