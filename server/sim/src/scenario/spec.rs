//! The validated parts a `Scenario` is made of: its named vehicles and who drives them,
//! its random traffic, its reward's constants and a learner's goal. Plain data, checked
//! once by `validate`; the env, `arena eval` and `build` read them and check nothing.

use serde::Deserialize;

use crate::dynamics::Style;
use crate::gt::{Game, GtParams};
use crate::road::LaneId;
use crate::scene::Role;
use crate::world::{VehicleId, World};

/// How a learner drives its vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ActionKind {
    /// Discrete 5: lane left, idle, lane right, faster, slower.
    #[default]
    Meta,
    /// Acceleration and lateral preview target.
    Continuous,
}

/// A named vehicle, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleSpec {
    /// Unique name.
    pub name: String,
    /// Lane it starts in.
    pub lane: LaneId,
    /// Start position along the road (m).
    pub s: f64,
    /// Start offset (m).
    pub d: f64,
    /// Start speed (m/s).
    pub speed: f64,
    /// Speed its driver aims for (m/s).
    pub target_speed: f64,
    /// Driving style.
    pub style: Style,
    /// Who drives it.
    pub driver: DriverSpec,
}

/// Who drives a named vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
// A spec is built once per scenario and copied into a driver: the size of the `Gt`
// variant (its constants, by value so the spec stays plain `Copy` data) costs nothing.
#[allow(clippy::large_enum_variant)]
pub enum DriverSpec {
    /// A learner, through the env.
    Agent(ActionKind),
    /// IDM + MOBIL.
    Idm,
    /// The game-theoretic AV of `gt`.
    Gt {
        /// Nash or Stackelberg.
        game: Game,
        /// Leader (the paper's EC) or follower (its AC).
        role: Role,
        /// Its constants: the defaults, or the preset its `params` names, with its
        /// `follower_tolerance` (eq. 17b) if given.
        params: GtParams,
    },
}

/// Random IDM traffic placed like highway-env's `Vehicle.create_random`.
#[derive(Debug, Clone, PartialEq)]
pub struct TrafficSpec {
    /// How many vehicles.
    pub count: u32,
    /// highway-env's `vehicles_density`.
    pub density: f64,
    /// Initial speed range (m/s); each car's target speed is its initial speed.
    pub speed: [f64; 2],
    /// Lanes to place cars in.
    pub lanes: Vec<LaneId>,
    /// Style of their steering.
    pub style: Style,
    /// Where the traffic starts (m along the road): the first car goes one spacing ahead
    /// of it, and the named vehicles stay out of the stretch it fills in its lanes
    /// (`validate`). `None`: ahead of the frontmost named vehicle, as highway-env places
    /// traffic ahead of the ego car.
    pub start: Option<f64>,
    /// How many of them the game-theoretic AV drives, spread evenly through the traffic
    /// (every `count / gt.count`-th car), and how.
    pub gt: Option<GtTraffic>,
}

impl TrafficSpec {
    /// highway-env's spacing along the road between one car and the next one placed ahead
    /// of it (centre to centre, in any lane), before its U(0.9, 1.1) factor: `(12 + speed)
    /// x exp(-5/40 x lanes) / density` for a car at `speed` (m/s) on a road of `lanes`
    /// lanes (m).
    pub fn spacing(&self, speed: f64, lanes: usize) -> f64 {
        (12.0 + speed) * (-5.0 / 40.0 * lanes as f64).exp() / self.density
    }

    /// The most road the traffic can fill from where it starts (m): `count` spacings at
    /// the top speed, each at its U(0.9, 1.1) factor's top.
    pub fn reach(&self, lanes: usize) -> f64 {
        f64::from(self.count) * self.spacing(self.speed[1], lanes) * 1.1
    }

    /// The traffic's density as placed, in vehicles per km per lane of `self.lanes`: one
    /// car per mean spacing (the speed range's middle), spread over its lanes.
    pub fn vehicles_per_km_per_lane(&self, lanes: usize) -> f64 {
        let mean = self.spacing((self.speed[0] + self.speed[1]) / 2.0, lanes);
        1000.0 / (mean * self.lanes.len() as f64)
    }
}

/// The game-theoretic cars among random traffic.
#[derive(Debug, Clone, PartialEq)]
pub struct GtTraffic {
    /// How many.
    pub count: u32,
    /// Their games: one, or several the cars take in turn (`driver`).
    pub games: Vec<Game>,
    /// Their styles: one, or several the cars take in turn (`driver`).
    pub styles: Vec<Style>,
    /// Leader or follower.
    pub role: Role,
}

impl GtTraffic {
    /// The style and game of the `k`-th game-theoretic car of the traffic (from 0, in the
    /// order they are placed): every (style, game) pair in turn, styles outer and games
    /// inner, so 6 cars of three styles and two games drive all six pairs once.
    pub fn driver(&self, k: u32) -> (Style, Game) {
        let (styles, games) = (self.styles.len().max(1), self.games.len().max(1));
        let pair = k as usize % (styles * games);
        (self.styles[pair / games], self.games[pair % games])
    }
}

/// How the env turns the paper's cost J into a reward (docs/rewards.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RewardSpec {
    /// J_0 of r = J_0 / (J_0 + J): the cost at which a step earns half the most.
    pub cost_scale: f64,
    /// What a step at full risk costs (the env's `risk`: 1 at contact, 0 beyond a 1.5 s
    /// time to collision, a 0.5 s headway and 1 m of sideways clearance): a step earns
    /// J_0 / (J_0 + J) x progress - risk_weight x risk. 0 turns the term off.
    pub risk_weight: f64,
    /// What reaching the scenario's goal (`Goal::reached`) is worth: paid on the step an
    /// agent reaches it, taken back on a step that leaves it (potential-based shaping, Ng
    /// et al. 1999: over an episode it sums to goal_bonus x (reached at the end - reached
    /// at the start), whatever the path). 0 turns it off.
    pub goal_bonus: f64,
    /// The reward of the step an agent crashes or leaves the road; `None`: minus
    /// ((1 + risk_weight) times the episode length in steps + 2 x goal_bonus), below any
    /// episode without a crash.
    pub crash: Option<f64>,
    /// The reward of the step that ends an episode as a failure: the time limit reached
    /// short of a goal that must be reached (`Goal::fail_at_time_limit`); `None`: the crash
    /// reward. Between the crash reward and 0, so a crash stays the worst.
    pub failure: Option<f64>,
}

impl RewardSpec {
    /// J_0 by default: what the normal style pays in efficiency alone 11 m/s off its
    /// target speed (0.2 x 11.2^2); calm driving costs a few units and earns about 0.8
    /// (docs/rewards.md).
    pub const DEFAULT_COST_SCALE: f64 = 25.0;
    /// The risk weight by default (docs/rewards.md, "Risk": the smallest round weight
    /// under which a policy that passes cars side by side returns less than the AV;
    /// overtake and overtake-random set 15, where at 10 PPO's squeeze still out-earned the
    /// AV against IDM opponents).
    pub const DEFAULT_RISK_WEIGHT: f64 = 10.0;
    /// The goal bonus by default (docs/rewards.md, "Goal").
    pub const DEFAULT_GOAL_BONUS: f64 = 0.0;

    /// The crash reward for episodes of `max_cycles` steps: `crash`, else minus
    /// ((1 + risk_weight) x max_cycles + 2 x goal_bonus), less than any episode without a
    /// crash returns (each of its steps earns at least -risk_weight, a crash episode's
    /// others at most 1, and the goal's payments add up to between -goal_bonus and
    /// goal_bonus at any step).
    pub fn crash_reward(&self, max_cycles: u32) -> f64 {
        self.crash.unwrap_or(-((1.0 + self.risk_weight) * f64::from(max_cycles) + 2.0 * self.goal_bonus))
    }

    /// The reward of the step that fails at the time limit (`failure`), else the crash
    /// reward.
    pub fn failure_reward(&self, max_cycles: u32) -> f64 {
        self.failure.unwrap_or_else(|| self.crash_reward(max_cycles))
    }
}

/// What a learner's episode must achieve to count as a success (`arena eval`, the
/// `episode_success` info): end without a crash, off the road or past its lane's end, and
/// then in one of `lanes` (if any are given) ahead of every vehicle of `ahead_of`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Goal {
    /// Lanes the learner must end in; empty: any.
    pub lanes: Vec<LaneId>,
    /// Vehicles the learner must end ahead of (greater s).
    pub ahead_of: Vec<String>,
    /// Whether an episode that reaches the time limit short of the goal fails as a crash
    /// does: terminated (not truncated), paid `RewardSpec::failure_reward` (by default the
    /// crash reward). Without it, stopping short
    /// of a lane end and waiting out the clock risks nothing and returns more than a merge
    /// that goes wrong, a local optimum PPO settles in (docs/scenarios.md, "Versions").
    pub fail_at_time_limit: bool,
}

impl Goal {
    /// Whether vehicle `id` of `world` is where the goal asks, now: in one of `lanes` (if
    /// any) and ahead of every vehicle of `ahead_of`. An episode succeeds if it ends on
    /// the road (the time limit or the road's end) with this true.
    pub fn reached(&self, world: &World, id: VehicleId) -> bool {
        let s = world.vehicle(id).state.s;
        let in_lane = self.lanes.is_empty() || self.lanes.contains(&world.current_lane(id));
        in_lane
            && self.ahead_of.iter().all(|name| world.find(name).is_none_or(|other| s > world.vehicle(other).state.s))
    }
}
