//! The `gt` driver: reads a car's situation from the `Scene` (lead cars, adjacent cars,
//! lane ends, through the scene's neighbour queries), plays the game of its role, plans
//! Y_p with the MPC, commands the first step of the decision's ramp at the jerk bound
//! (`jerk`), and falls back to a safe command when the MPC fails. It returns a `GtStep`;
//! the world applies it. What the scenario fixes of it (`GtSetup`: game, role, constants)
//! the world keeps beside its state; its memory (`GtMemory`) is plain data kept in the
//! vehicle; the only scratch (the MPC's solver) does not affect results. Also the two
//! questions the env asks of any vehicle: `stage_cost` and `expert_decision`, each with
//! that vehicle's own parameters.

use serde::{Deserialize, Serialize};

use super::costs::{self, CostComponents};
use super::field::{self, Field, FieldParams, Obstacle};
use super::games::{
    Adjacent, Decision, DecisionParams, Game, GameExplained, LaneOption, Needs, Player, Profile, SideGame, Situation,
};
use super::jerk::{AccelRamp, Exemption, JerkParams};
use super::merge::UnderWay;
use super::mpc::{self, Mpc, MpcError, MpcParams, MpcProblem, MpcSolution};
use super::prediction::{self, Kinematics, SpeedBounds};
use super::safety::{self, SafetyOverride, SafetyParams};
use super::styles::CostWeights;
use crate::dynamics::{Command, LANE_CHANGE_DURATION};
use crate::road::{LaneChange, LaneId};
use crate::scene::{Car, DriverKind, Lead, Role, Scene, Status, VehicleId};

/// How a `gt` vehicle reads the world and what it does when planning fails.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct InteractionParams {
    /// Cars farther than this along the road (m) are not adjacent cars of a game. 60,
    /// chosen here: two seconds of closing at 30 m/s.
    pub interaction_range: f64,
    /// A neighbouring lane that ends within this many seconds of driving is not a
    /// lane-change target (s). 8, chosen here: a change takes 4.
    pub lane_end_time: f64,
    /// Braking of the fallback command (m/s^2), held within the acceleration bounds. 3,
    /// chosen here: firm, short of the bound, so a follower is not surprised.
    pub fallback_brake: f64,
}

impl Default for InteractionParams {
    fn default() -> Self {
        InteractionParams { interaction_range: 60.0, lane_end_time: 8.0, fallback_brake: 3.0 }
    }
}

/// Every constant of the game-theoretic (`gt`) driver.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct GtParams {
    /// Costs, prediction, games.
    pub decision: DecisionParams,
    /// Eq. (19)–(21).
    pub field: FieldParams,
    /// Eq. (22)–(29).
    pub mpc: MpcParams,
    /// Reading the world; the fallback.
    pub interaction: InteractionParams,
    /// The safety layer over the games' acceleration (docs/design.md, "Safety layer").
    #[serde(default)]
    pub safety: SafetyParams,
}

/// The most prediction samples a preset may ask for (the defaults take 6; calibration 3-10).
const MAX_SAMPLES: usize = 100;
/// The longest prediction horizon a preset may ask for (s; the defaults 3, calibration 1.5-5).
const MAX_HORIZON: f64 = 30.0;
/// The most acceleration steps of a game's grid (the defaults: 7 m/s^2 in 0.25 steps, 28).
const MAX_ACCEL_GRID: f64 = 200.0;

impl GtParams {
    /// Checks the constants a preset or a fit may set: `Err` names the first one out of
    /// its range (dotted path below `GtParams`) and says why.
    pub fn check(&self) -> Result<(), String> {
        let (c, p, g) = (&self.decision.costs, &self.decision.prediction, &self.decision.game);
        let positive = [
            ("decision.costs.kappa_v_log", c.kappa_v_log),
            ("decision.costs.kappa_s_log", c.kappa_s_log),
            ("decision.costs.kappa_v_lat", c.kappa_v_lat),
            ("decision.costs.kappa_s_lat", c.kappa_s_lat),
            ("decision.costs.kappa_ax", c.kappa_ax),
            ("decision.costs.kappa_ay", c.kappa_ay),
            ("decision.costs.epsilon", c.epsilon),
            ("decision.prediction.horizon", p.horizon),
            ("decision.game.accel_max", g.accel_max),
            ("decision.game.accel_step", g.accel_step),
            ("decision.jerk.max_jerk", self.decision.jerk.max_jerk),
            ("interaction.interaction_range", self.interaction.interaction_range),
        ];
        for (key, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(format!("{key} must be a number > 0, not {value}"));
            }
        }
        let non_negative = [
            ("decision.costs.lead_range", c.lead_range),
            ("decision.game.follower_tolerance", g.follower_tolerance),
            ("decision.game.speed_min", g.speed_min),
            ("mpc.lane_keeping_bound", self.mpc.lane_keeping_bound),
            ("mpc.return_step", self.mpc.return_step),
        ];
        for (key, value) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return Err(format!("{key} must be a number >= 0, not {value}"));
            }
        }
        if !(g.accel_min.is_finite() && g.accel_min < 0.0) {
            return Err(format!("decision.game.accel_min must be a number < 0, not {}", g.accel_min));
        }
        let m = &self.decision.merge;
        if !(m.min_duration.is_finite() && m.min_duration > 0.0 && m.min_duration <= LANE_CHANGE_DURATION) {
            return Err(format!(
                "decision.merge.min_duration must be a number in (0, {LANE_CHANGE_DURATION}] s, not {}",
                m.min_duration
            ));
        }
        for (key, value) in [
            ("decision.merge.response_lag", m.response_lag),
            ("decision.merge.end_margin", m.end_margin),
            ("decision.merge.stop_margin", m.stop_margin),
            ("decision.merge.crossing_speed", m.crossing_speed),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(format!("{key} must be a number >= 0, not {value}"));
            }
        }
        let safety = &self.safety;
        for (key, value) in [
            ("safety.response_time", safety.response_time),
            ("safety.brake", safety.brake),
            ("safety.lead_brake", safety.lead_brake),
            ("safety.gap_braking", safety.gap_braking),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(format!("{key} must be a number > 0, not {value}"));
            }
        }
        if !(safety.emergency_brake.is_finite() && safety.emergency_brake >= safety.brake) {
            return Err(format!(
                "safety.emergency_brake must be a number >= safety.brake ({}), not {}",
                safety.brake, safety.emergency_brake
            ));
        }
        for (key, value) in [
            ("safety.margin", safety.margin),
            ("safety.cut_in_time", safety.cut_in_time),
            ("safety.lateral_margin", safety.lateral_margin),
            ("safety.follower_response", safety.follower_response),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(format!("{key} must be a number >= 0, not {value}"));
            }
        }
        if p.samples == 0 {
            return Err("decision.prediction.samples must be at least 1".to_string());
        }
        // Upper bounds: a preset may come with a scenario file, and every decision's work
        // grows with these (a grid of 1e300 accelerations would never end).
        if p.samples > MAX_SAMPLES {
            return Err(format!("decision.prediction.samples must be at most {MAX_SAMPLES}, not {}", p.samples));
        }
        if p.horizon > MAX_HORIZON {
            return Err(format!("decision.prediction.horizon must be at most {MAX_HORIZON} s, not {}", p.horizon));
        }
        let grid = (g.accel_max - g.accel_min) / g.accel_step;
        if grid > MAX_ACCEL_GRID {
            return Err(format!(
                "decision.game's acceleration grid (accel_max - accel_min) / accel_step has {grid:.0} steps; \
                 at most {MAX_ACCEL_GRID}: raise accel_step"
            ));
        }
        Ok(())
    }
}

/// What the driver reports about its last plan.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Diagnostics {
    /// Why the last plan fell back to the safe command, if it did.
    pub fallback: Option<String>,
    /// Plans that fell back since the start.
    pub fallbacks: u32,
    /// Interior-point iterations of the last QP (0: no bound was active, solved directly).
    pub iterations: u32,
    /// Decisions the Nash search took without a pure equilibrium (it then keeps the
    /// current lane decision) since the start.
    pub inexact: u32,
    /// Control periods planned since the start.
    pub plans: u32,
    /// Interior-point iterations of every QP since the start.
    pub iterations_total: u64,
    /// How the safety layer lowered the last plan's acceleration, if it did.
    #[serde(default)]
    pub safety: Option<SafetyOverride>,
    /// Plans whose acceleration the safety layer lowered since the start.
    #[serde(default)]
    pub overrides: u32,
    /// Of those, the ones that braked harder than the games' a_min (emergencies).
    #[serde(default)]
    pub emergencies: u32,
    /// Commands since the start whose acceleration changed by more than the jerk bound
    /// allows because a lane change was aborted (exempt: docs/design.md, "Jerk").
    #[serde(default)]
    pub abort_jumps: u32,
    /// Commands since the start whose acceleration changed by more than the jerk bound
    /// allows because a safety override braked (emergency braking, exempt).
    #[serde(default)]
    pub emergency_jumps: u32,
}

/// What a scenario fixes of a `gt` driver: the game it plays, its role in it and its
/// constants. The world keeps it beside its state (`World::gt_setup`); it never changes
/// as the world runs, and no state from outside carries it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GtSetup {
    /// Nash or Stackelberg.
    pub game: Game,
    /// Leader or follower.
    pub role: Role,
    /// Its constants.
    pub params: GtParams,
}

/// A `gt` driver's memory: plain data, part of the world's state. A fresh driver's is the
/// default.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct GtMemory {
    /// The last decision.
    pub decision: Decision,
    /// u(k-1): the preview point of the last plan, once there is one (m).
    pub preview: Option<f64>,
    /// The last Delta u plan (the MPC's nominal path next time).
    pub plan: Vec<f64>,
    /// The full-width duration (s) of the lane change under way, when it was shortened
    /// to leave an ending lane in time (`merge`).
    #[serde(default)]
    pub pace: Option<f64>,
    /// When (simulated s) the lane change under way out of an ending lane is predicted to
    /// cross the lane line (`merge`).
    #[serde(default)]
    pub crossing_at: Option<f64>,
    /// The lane it is changing to when it plans in a place it does not drive
    /// (`World::expert_command`, a learner's vehicle), whose own target lane is the
    /// learner's; `None` where it drives.
    #[serde(default)]
    pub counterfactual_target: Option<LaneId>,
    /// What happened in the last plan.
    pub diagnostics: Diagnostics,
}

impl GtMemory {
    /// Every number it carries from one decision to the next.
    pub fn numbers(&self) -> impl Iterator<Item = f64> + '_ {
        let d = &self.decision;
        let memory = [self.preview, self.pace, self.crossing_at, d.response, d.duration, d.crossing];
        let decided = [d.accel, d.cost, d.predicted.safety, d.predicted.comfort, d.predicted.efficiency];
        memory.into_iter().flatten().chain(decided).chain(self.plan.iter().copied())
    }

    /// Whether this memory, read from outside (a snapshot), could be one a driver with
    /// `setup` (the one its scenario gives the car) came to: every number finite, a plan
    /// no longer than its MPC's, lanes the road (`lanes` wide) has. The setup itself is
    /// never taken from outside: it sets how much a decision costs.
    pub fn check(&self, setup: &GtSetup, lanes: usize) -> Result<(), String> {
        if !self.numbers().all(crate::dynamics::within_state) {
            return Err("a number that is not finite, or past MAX_STATE_MAGNITUDE, in its driver's memory".into());
        }
        let horizon = setup.params.mpc.control_horizon;
        if self.plan.len() > horizon.max(1) {
            return Err(format!("a plan of {} moves, where its MPC plans {horizon}", self.plan.len()));
        }
        if self.counterfactual_target.is_some_and(|lane| lane.0 as usize >= lanes) {
            return Err(format!("a lane the road (lanes 0..{lanes}) does not have"));
        }
        Ok(())
    }
}

/// One control period's output of a `gt` driver, before the world applies it.
#[derive(Debug, Clone, PartialEq)]
pub struct GtStep {
    /// a_x and Y_p to apply.
    pub command: Command,
    /// A lane change to start (or, on fallback, the current lane to return to).
    pub change_to: Option<LaneId>,
    /// Whether the world ramps the acceleration over the period from the last command to
    /// `command.accel` (the jerk bound); false: it applies at once (an exempt command, or
    /// the bound off).
    pub ramp: bool,
    /// The driver's new memory.
    pub memory: GtMemory,
}

fn kinematics(car: &Car) -> Kinematics {
    Kinematics { s: car.state.s, d: car.state.d, speed: car.speed() }
}

fn lead_kinematics(lead: Lead) -> Kinematics {
    Kinematics { s: lead.s, d: lead.d, speed: lead.speed }
}

/// v_max of eq. (14)–(15) for `car` in `lane`: the lane's speed limit, or the speed its
/// driver aims for if lower.
fn speed_limit(scene: &Scene, car: &Car, lane: LaneId) -> f64 {
    scene.road.speed_limit(lane).min(car.target_speed)
}

fn player(scene: &Scene, car: &Car, lane: LaneId, params: &GtParams) -> Player {
    Player {
        now: kinematics(car),
        accel: car.accel,
        weights: CostWeights::for_style(car.style),
        bounds: SpeedBounds { min: params.decision.game.speed_min, max: speed_limit(scene, car, lane) },
    }
}

/// A neighbouring lane EC may change to, with its adjacent car: `None` when the lane
/// does not exist or ends too soon.
fn side_option(
    scene: &Scene,
    id: VehicleId,
    side: LaneChange,
    params: &GtParams,
) -> Option<(LaneOption, Option<VehicleId>)> {
    let car = scene.car(id);
    let ego = kinematics(car);
    let lane = scene.lane_beside(car.lane, side)?;
    let ahead = scene.road.lane_end(lane) - ego.s;
    let ends_soon = ahead < ego.speed.max(10.0) * params.interaction.lane_end_time;
    if scene.road.lane_end(lane) < scene.road.length() && (ends_soon || !scene.road.worth_entering(car.lane, lane)) {
        return None;
    }
    if car.lane_change().sigma() != side.sigma() && !gap_open(scene, id, lane, params) {
        return None;
    }
    let ac = scene.nearest(lane, ego.s, params.interaction.interaction_range, &[id]);
    let adjacent = ac.map(|ac| {
        let others = [id, ac.id];
        let ac_lead = scene.lead_car(lane, ac.state.s, &others).map(lead_kinematics);
        Adjacent {
            player: player(scene, ac, lane, params),
            leader: scene.leader(lane, ac.state.s, &others).map(lead_kinematics),
            lead: ac_lead,
        }
    });
    let exclude: Vec<VehicleId> = [Some(id), ac.map(|ac| ac.id)].into_iter().flatten().collect();
    let option = LaneOption {
        sigma: side.sigma(),
        centre: scene.road.lane_center(lane),
        speed_limit: speed_limit(scene, car, lane),
        leader: None,
        lead: scene.lead_car(lane, ego.s, &exclude).map(lead_kinematics),
        adjacent,
    };
    Some((option, ac.map(|ac| ac.id)))
}

/// Whether car `id` may start a lane change into `lane`. On the open road: the gap there
/// asks no one to brake harder than `gap_braking`, and the car behind it keeps RSS's
/// distance with a driver's response time (`follower_response`, `safety`). Out of a lane
/// that ends, where the car must leave and may wait for no better gap: the gap asks no
/// one to brake harder than the games' firmest braking (-a_min), what they count on a
/// yielding car doing; `merge` and the games decide the rest.
fn gap_open(scene: &Scene, id: VehicleId, lane: LaneId, params: &GtParams) -> bool {
    let car = scene.car(id);
    let safety = &params.safety;
    if !safety.enabled {
        return true;
    }
    let braking = safety::gap_braking(scene, id, lane, safety);
    match scene.road.lane_end(car.lane) >= scene.road.length() {
        true => braking <= safety.gap_braking && safety::follower_keeps_distance(scene, id, lane, safety),
        false => braking <= -params.decision.game.accel_min,
    }
}

/// Whether car `id`, changing lanes on the open road, gives its change up: the gap it goes
/// into asks someone to brake harder than the games' firmest braking (-a_min), and the
/// lane it leaves asks less. Before it crosses the line only: past it, it is in the lane.
fn gives_up(scene: &Scene, id: VehicleId, params: &GtParams) -> bool {
    let car = scene.car(id);
    let safety = &params.safety;
    let open_road = scene.road.lane_end(car.lane) >= scene.road.length();
    if !safety.enabled || !open_road || car.target_lane == car.lane {
        return false;
    }
    let into = safety::gap_braking(scene, id, car.target_lane, safety);
    into > -params.decision.game.accel_min && safety::gap_braking(scene, id, car.lane, safety) < into
}

/// Car `id`'s situation with its own lane as its only option: the game a follower without
/// a partner plays, and a car that gives its lane change up.
fn own_lane_only(scene: &Scene, id: VehicleId, params: &GtParams) -> Situation {
    let (mut own, _) = situation(scene, id, params);
    own.sides = [None, None];
    own.committed = None;
    own
}

/// What car `id` decides back in its own lane, alone (eq. 15 with no side).
fn keep_alone(scene: &Scene, id: VehicleId, params: &GtParams) -> Decision {
    own_lane_only(scene, id, params).decide(Game::Nash, &params.decision)
}

/// Car `id`'s situation as the EC of a game, and the adjacent car of each side.
pub fn situation(scene: &Scene, id: VehicleId, params: &GtParams) -> (Situation, [Option<VehicleId>; 2]) {
    situation_timed(scene, id, params, None)
}

/// `situation`, with the lane change under way (if any) timed as `under_way` says.
fn situation_timed(
    scene: &Scene,
    id: VehicleId,
    params: &GtParams,
    under_way: Option<UnderWay>,
) -> (Situation, [Option<VehicleId>; 2]) {
    let car = scene.car(id);
    let keep = LaneOption {
        sigma: 0,
        centre: scene.road.lane_center(car.lane),
        speed_limit: speed_limit(scene, car, car.lane),
        leader: scene.leader(car.lane, car.state.s, &[id]).map(lead_kinematics),
        lead: scene.lead_car(car.lane, car.state.s, &[id]).map(lead_kinematics),
        adjacent: None,
    };
    let left = side_option(scene, id, LaneChange::Left, params);
    let right = side_option(scene, id, LaneChange::Right, params);
    let committed = Some(car.lane_change().sigma()).filter(|&c| c != 0);
    let end = scene.road.lane_end(car.lane);
    let situation = Situation {
        ego: player(scene, car, car.lane, params),
        keep,
        sides: [left.map(|(o, _)| o), right.map(|(o, _)| o)],
        committed,
        lane_end: (end < scene.road.length()).then_some(end - car.state.s),
        under_way: under_way.filter(|_| committed.is_some()),
        lateral_speed: car.state.vx * car.state.heading.sin() + car.state.vy * car.state.heading.cos(),
        lane_width: scene.road.lane_width(),
        car_length: scene.vehicle.length,
        period: scene.control_dt,
    };
    (situation, [left.and_then(|(_, ac)| ac), right.and_then(|(_, ac)| ac)])
}

/// Eq. (10)–(14) for car `id` as it is now, with the AV constants `params`: sigma is the
/// lane change it is making (target lane against current lane), a_x its commanded
/// acceleration, a_y its measured lateral acceleration less the road's centripetal
/// part. Lane ends count as stopped lead cars in eq. (11), as in the games.
pub fn stage_cost(scene: &Scene, id: VehicleId, params: &GtParams) -> CostComponents {
    let c = &params.decision.costs;
    let car = scene.car(id);
    let ego = kinematics(car);
    let sigma = car.lane_change().sigma();
    let longitudinal = scene
        .leader(car.lane, ego.s, &[id])
        .map_or(0.0, |leader| costs::longitudinal_safety(c, scene.vehicle.length, ego, lead_kinematics(leader)));
    let lateral = match sigma {
        0 => 0.0,
        _ => scene
            .nearest(car.target_lane, ego.s, params.interaction.interaction_range, &[id])
            .map_or(0.0, |ac| costs::lateral_safety(c, scene.vehicle.length, ego, kinematics(ac))),
    };
    let centripetal = car.state.vx * car.state.vx * scene.road.curvature(ego.s);
    let lateral_accel = car.state.lateral_accel(&scene.vehicle) - centripetal;
    let lead = scene.lead_car(car.target_lane, ego.s, &[id]).map(lead_kinematics);
    let v_bar = costs::target_speed(c, ego, speed_limit(scene, car, car.target_lane), lead);
    CostComponents {
        safety: costs::safety(sigma, longitudinal, lateral),
        comfort: costs::comfort(c, sigma, car.accel, lateral_accel),
        efficiency: costs::efficiency(ego.speed, v_bar),
    }
}

/// What the built-in AV with constants `params` would decide in car `id`'s place, as
/// the EC of `game`: its acceleration and lane choice.
pub fn expert_decision(scene: &Scene, id: VehicleId, game: Game, params: &GtParams) -> Decision {
    situation(scene, id, params).0.decide(game, &params.decision)
}

/// The leader or learner in an adjacent lane a follower answers: the nearest within range.
fn partner(scene: &Scene, id: VehicleId, params: &GtParams) -> Option<VehicleId> {
    let me = scene.car(id);
    let range = params.interaction.interaction_range;
    let plays = |other: &&Car| {
        other.id != id
            && other.status == Status::Driving
            && other.lane.0.abs_diff(me.lane.0) == 1
            && matches!(other.driver, DriverKind::Gt(Role::Leader) | DriverKind::Agent)
    };
    scene
        .around(me.state.s, range)
        .filter(plays)
        .map(|other| (other.id, (other.state.s - me.state.s).abs()))
        .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
        .map(|(other, _)| other)
}

/// What a leader (or learner) decided this period: its acceleration and the lane change
/// it is making or has just decided. One that has not announced (it no longer drives)
/// is read from its last command.
fn observed(scene: &Scene, id: VehicleId) -> (f64, LaneChange) {
    let car = scene.car(id);
    car.decided.unwrap_or((car.accel, car.lane_change()))
}

/// What a follower plays: alone (no partner in play: the best for itself, as the EC of
/// its own lane's game), or its part of the side game against its partner. Returned by
/// value once per decision: boxing the larger variant would allocate on the driving path.
#[allow(clippy::large_enum_variant)]
enum Followed {
    Alone(Situation),
    Answer {
        partner: VehicleId,
        side: i8,
        view: Situation,
        game: SideGame,
        /// Its action is the column: AC's equilibrium part (Nash) or best reply (Stackelberg).
        profile: Profile,
    },
}

/// The game a follower plays: its part of the side game against its partner (Nash),
/// its best response to the partner's decision of this period (Stackelberg), or, with no
/// partner in play, the game of its own lane alone.
fn follow_game(scene: &Scene, id: VehicleId, game: Game, params: &GtParams) -> Followed {
    let alone = || Followed::Alone(own_lane_only(scene, id, params));
    let Some(partner) = partner(scene, id, params) else { return alone() };
    let (view, adjacent) = situation(scene, partner, params);
    let side = LaneChange::between(scene.car(partner).lane, scene.car(id).lane);
    if adjacent[usize::from(side == LaneChange::Right)] != Some(id) {
        return alone();
    }
    let side = side.sigma();
    let (side_game, profile) = match game {
        Game::Nash => {
            let side_game = view.side_game(side, &params.decision, Needs::Nash);
            if side_game.ec_actions.is_empty() {
                return alone();
            }
            let profile = side_game.nash(); // eq. (15b) / (16e–f)
            (side_game, profile)
        }
        Game::Stackelberg => {
            let (accel, change) = observed(scene, partner);
            let sigma = if change.sigma() == side { side } else { 0 };
            let me = player(scene, scene.car(id), scene.car(id).lane, params);
            let grid = params.decision.game.grid(me.now.speed, me.bounds, scene.control_dt, &params.decision.jerk);
            let side_game = view.side_game_with(side, vec![(accel, sigma)], grid, &params.decision, Needs::Replies);
            let col = side_game.table.best_reply(0); // eq. (17b)
            (side_game, Profile { row: 0, col, exact: true })
        }
    };
    Followed::Answer { partner, side, view, game: side_game, profile }
}

/// A follower's acceleration: the column of the game it plays (`follow_game`), or alone
/// the Nash decision of its own lane's game.
fn follow(scene: &Scene, id: VehicleId, game: Game, params: &GtParams) -> Decision {
    match follow_game(scene, id, game, params) {
        Followed::Alone(own) => own.decide(Game::Nash, &params.decision),
        Followed::Answer { game, profile, .. } => {
            let accel = game.ac_actions[profile.col];
            Decision { accel, lane_change: LaneChange::Keep, exact: true, ..Decision::default() }
        }
    }
}

/// The field car `id` plans in: the other cars near it and the road's lines (edges
/// one-sided when `one_sided`). Keeping `keeping` lane, only the cars ahead and beside,
/// and the lines of that lane (`field::lane_lines`): a car closing from behind is not
/// steered away from, and the road's field is least at the lane's centre.
fn field_around(scene: &Scene, id: VehicleId, params: &FieldParams, one_sided: bool, keeping: Option<LaneId>) -> Field {
    let me = scene.car(id).state.s;
    let length = scene.vehicle.length;
    let obstacles = scene
        .around(me, params.range)
        .filter(|car| car.id != id && (keeping.is_none() || car.state.s > me - length))
        .map(|car| Obstacle { s: car.state.s, d: car.state.d, heading: car.state.heading, speed: car.speed() })
        .collect();
    let lines = match keeping {
        Some(lane) => field::lane_lines(&scene.road, lane, me, params),
        None => field::road_lines(&scene.road, params, one_sided),
    };
    Field::new(*params, scene.vehicle.width, obstacles, lines)
}

/// Where Y_p may go (low, high; m): between the centres of the lane the car is in
/// (`from`) and the one it keeps or changes to (`to`), widened by the lane-keeping bound;
/// a preview point outside that band (an aborted change, an offset the field asked for)
/// moves back into it by at least `max_step` a period, the pace of a lane change. So no
/// plan drifts away from both lanes, and every offset is pulled back, never amplified.
fn lane_band(from: f64, to: f64, previous_preview: f64, params: &MpcParams) -> (f64, f64) {
    let low = from.min(to) - params.lane_keeping_bound;
    let high = from.max(to) + params.lane_keeping_bound;
    (low.min(previous_preview + params.max_step), high.max(previous_preview - params.max_step))
}

/// Plans Y_p toward `target` lane for car `id`, driven by `setup` with `memory`, at
/// acceleration `accel` (held from now) with `mpc`.
pub fn plan_motion(
    scene: &Scene,
    id: VehicleId,
    (setup, memory): (&GtSetup, &GtMemory),
    accel: f64,
    target: LaneId,
    mpc: Option<&mut Mpc>,
) -> Result<MpcSolution, MpcError> {
    let ramp = AccelRamp::step(accel);
    plan_motion_with(scene, id, (&setup.params, memory), &setup.params.mpc, ramp, target, mpc)
}

/// `plan_motion` with the MPC's constants `mpc_params` (a shortened lane change moves its
/// preview point faster), a_x along `accel`.
fn plan_motion_with(
    scene: &Scene,
    id: VehicleId,
    (params, memory): (&GtParams, &GtMemory),
    mpc_params: &MpcParams,
    accel: AccelRamp,
    target: LaneId,
    mpc: Option<&mut Mpc>,
) -> Result<MpcSolution, MpcError> {
    let car = scene.car(id);
    let keeping = (target == car.lane).then_some(target);
    let field = field_around(scene, id, &params.field, params.decision.merge.enabled, keeping);
    let road = &scene.road;
    let w = road.lane_width();
    let rightmost = road.lane_center(LaneId(road.lane_count() as u32 - 1));
    let margin = mpc_params.preview_margin;
    let previous_preview = memory.preview.unwrap_or(car.preview);
    let band = lane_band(road.lane_center(car.lane), road.lane_center(target), previous_preview, mpc_params);
    let preview_bounds = ((rightmost - margin.min(w)).max(band.0), margin.min(w).min(band.1));
    let problem = MpcProblem {
        state: car.state,
        accel,
        previous_preview,
        target: road.lane_center(target),
        curvature: road.curvature(car.state.s),
        vehicle: &scene.vehicle,
        driver: &car.driver_params,
        dt: scene.control_dt,
        field: &field,
        nominal: &memory.plan,
        preview_bounds,
    };
    match mpc {
        Some(mpc) => mpc.solve(&problem, mpc_params),
        None => mpc::solve(&problem, mpc_params),
    }
}

/// What car `id`, driven by `setup` with `memory`, decides this period in its role.
pub fn decide(scene: &Scene, id: VehicleId, setup: &GtSetup, memory: &GtMemory) -> Decision {
    match setup.role {
        Role::Leader => leader_situation(scene, id, setup, memory).0.decide(setup.game, &setup.params.decision),
        Role::Follower => follow(scene, id, setup.game, &setup.params),
    }
}

/// A leader's situation, its lane change under way timed from the driver's memory, with
/// the adjacent car of each side.
fn leader_situation(
    scene: &Scene,
    id: VehicleId,
    setup: &GtSetup,
    memory: &GtMemory,
) -> (Situation, [Option<VehicleId>; 2]) {
    let pace = memory.pace.unwrap_or(LANE_CHANGE_DURATION);
    let under_way = UnderWay { pace, crossing_in: memory.crossing_at.map(|t| t - scene.time) };
    situation_timed(scene, id, &setup.params, Some(under_way))
}

/// A game-theoretic car's decision of one control period explained (issue 27): the game
/// it played, from the same scene and memory as the decision, recomputed only when asked.
#[derive(Debug, Clone, PartialEq)]
pub struct Explanation {
    /// The car that decided.
    pub vehicle: VehicleId,
    /// Simulated time of the decision (s).
    pub time: f64,
    /// Nash or Stackelberg.
    pub game: Game,
    /// Leader (the game's EC) or follower (its AC; alone: EC of its own lane's game).
    pub role: Role,
    /// The game's EC: the car itself, or the leader a follower answers.
    pub ec: VehicleId,
    /// The AC of each side's game (left, right), where there is one.
    pub adjacent: [Option<VehicleId>; 2],
    /// The tables, the equilibria, the side chosen, the predicted paths.
    pub played: GameExplained,
    /// What the driver then decided (after the safety layer and any fallback).
    pub decision: Decision,
    /// How the safety layer lowered the games' acceleration, if it did.
    pub safety: Option<SafetyOverride>,
    /// Whether the MPC failed and the driver fell back to the safe command.
    pub fallback: bool,
}

/// Explains the decision `step` that car `id`, driven by `setup` with `memory` (its memory
/// before the decision), took from `scene`: the decision's game recomputed from the same
/// situation, so `step` is unchanged whether or not anyone asks.
pub fn explain(scene: &Scene, id: VehicleId, setup: &GtSetup, memory: &GtMemory, step: &GtStep) -> Explanation {
    let d = &setup.params.decision;
    let (ec, adjacent, played) = match setup.role {
        Role::Leader => {
            let (situation, adjacent) = leader_situation(scene, id, setup, memory);
            (id, adjacent, situation.explain(setup.game, d))
        }
        Role::Follower => match follow_game(scene, id, setup.game, &setup.params) {
            Followed::Alone(own) => (id, [None, None], own.explain(Game::Nash, d)),
            Followed::Answer { partner, side, view, game, profile } => {
                let mut adjacent = [None, None];
                adjacent[usize::from(side == 1)] = Some(id);
                (partner, adjacent, view.explain_side(side, game, profile, d))
            }
        },
    };
    let diagnostics = &step.memory.diagnostics;
    Explanation {
        vehicle: id,
        time: scene.time,
        game: setup.game,
        role: setup.role,
        ec,
        adjacent,
        played,
        decision: step.memory.decision,
        safety: diagnostics.safety,
        fallback: diagnostics.fallback.is_some(),
    }
}

/// The acceleration to command this period for a car whose last command was `previous`,
/// towards `target` (docs/design.md, "Jerk"), and whether the world ramps to it: the
/// first step of the ramp at the jerk bound, or, for an exempt command, `target` at once,
/// counted in `diagnostics` when that leaves the bound `jerk`.
pub(super) fn command_accel(
    previous: f64,
    target: f64,
    dt: f64,
    exemption: Option<Exemption>,
    (jerk, diagnostics): (&JerkParams, &mut Diagnostics),
) -> (f64, bool) {
    let Some(exemption) = exemption else { return (jerk.ramp(previous, target).at(dt), jerk.enabled) };
    if (target - previous).abs() > jerk.step_limit(dt) {
        let d = diagnostics;
        match exemption {
            Exemption::Abort => d.abort_jumps += 1,
            Exemption::Emergency => d.emergency_jumps += 1,
        }
    }
    (target, false)
}

/// One control period of the `gt` driver of car `id`: decide, keep safe, plan, or fall
/// back, as `setup` says, from `memory` (the driver's before this period). Reads the
/// scene only; the world applies the returned step.
pub fn plan(scene: &Scene, id: VehicleId, setup: &GtSetup, memory: &GtMemory, mpc: Option<&mut Mpc>) -> GtStep {
    let car = scene.car(id);
    let params = &setup.params;
    let mut decision = decide(scene, id, setup, memory);
    let leads = setup.role == Role::Leader;
    if leads && !decision.aborted && gives_up(scene, id, params) {
        decision = Decision { aborted: true, ..keep_alone(scene, id, params) };
    }
    let starts = decision.lane_change != LaneChange::Keep && car.target_lane == car.lane && leads;
    let aborts = decision.aborted && car.target_lane != car.lane && leads;
    let target = if starts { scene.lane_beside(car.lane, decision.lane_change) } else { None };
    let target = if aborts { car.lane } else { target.unwrap_or(car.target_lane) };
    let mut next = GtMemory::clone(memory);
    // The safety layer, outside the games: it only lowers the acceleration they decided.
    let intent = safety::Intent {
        target,
        pace: decision.duration.or(memory.pace).unwrap_or(LANE_CHANGE_DURATION),
        lag: params.decision.merge.response_lag,
        accel: decision.accel,
        firm: -params.decision.game.accel_min,
        ramp_time: params.decision.jerk.ramp(decision.accel, params.decision.game.accel_min).duration(),
    };
    let limited = safety::limit(scene, id, &intent, &params.safety);
    if let Some(limited) = limited {
        decision.accel = limited.accel;
        next.diagnostics.overrides += 1;
        next.diagnostics.emergencies += u32::from(limited.emergency);
    }
    next.diagnostics.safety = limited;
    next.decision = decision;
    // The command ramps to the decision at the jerk bound unless exempt: an aborted lane
    // change and a safety override brake at once (the safe distance assumes a response
    // within `safety.response_time`).
    let exemption = match limited {
        _ if aborts => Some(Exemption::Abort),
        Some(_) => Some(Exemption::Emergency),
        None => None,
    };
    // What the driver remembers of a change under way (`merge`): its pace and when it
    // crosses the line.
    let under_way = (starts || car.target_lane != car.lane) && !aborts;
    next.pace = decision.duration.filter(|_| under_way);
    next.crossing_at = decision.crossing.filter(|_| under_way).map(|t| scene.time + t);
    next.diagnostics.inexact += u32::from(!decision.exact);
    // A shortened change (`merge`) moves the preview point as much faster: Delta u_max of
    // eq. (27) is sized for `LANE_CHANGE_DURATION`.
    let mut mpc_params = params.mpc;
    if let Some(duration) = decision.duration.filter(|&t| t < LANE_CHANGE_DURATION) {
        mpc_params.max_step *= LANE_CHANGE_DURATION / duration;
    }
    let previous_preview = memory.preview.unwrap_or(car.preview);
    if target == car.lane && (previous_preview - scene.road.lane_center(target)).abs() > params.mpc.lane_keeping_bound {
        mpc_params.max_step = mpc_params.max_step.max(params.mpc.return_step);
    }
    // Out of emergency braking (a command past the games' firmest), the brake is let go at
    // once to the games' firmest; from there the command ramps at the jerk bound, as any.
    // Ramping all the way up from -8 kept the car braking past -6 for half a second after
    // the danger had gone.
    let firm = -params.decision.game.accel_min;
    let released = exemption.is_none() && car.accel < -firm && decision.accel > car.accel;
    let from = if released { -firm } else { car.accel };
    let ramp = match exemption {
        Some(_) => AccelRamp::step(decision.accel),
        None => params.decision.jerk.ramp(from, decision.accel),
    };
    match plan_motion_with(scene, id, (params, memory), &mpc_params, ramp, target, mpc) {
        Ok(solution) => {
            next.preview = Some(solution.preview);
            next.plan = solution.plan;
            next.diagnostics.fallback = None;
            next.diagnostics.iterations = solution.iterations;
            next.diagnostics.iterations_total += u64::from(solution.iterations);
            next.diagnostics.plans += 1;
            let jerk = (&params.decision.jerk, &mut next.diagnostics);
            let (accel, mut ramp) = command_accel(from, decision.accel, scene.control_dt, exemption, jerk);
            if released && accel - car.accel > params.decision.jerk.step_limit(scene.control_dt) {
                (ramp, next.diagnostics.emergency_jumps) = (false, next.diagnostics.emergency_jumps + 1);
            }
            let command = Command { accel, preview: solution.preview };
            GtStep { command, change_to: (target != car.target_lane).then_some(target), ramp, memory: next }
        }
        Err(error) => fallback(scene, id, params, next, &error),
    }
}

/// The safe command: keep (or return to) the current lane, brake within bounds, the
/// braking reached at the jerk bound (at once under a safety override).
fn fallback(scene: &Scene, id: VehicleId, params: &GtParams, mut next: GtMemory, error: &MpcError) -> GtStep {
    let car = scene.car(id);
    let bounds = SpeedBounds { min: params.decision.game.speed_min, max: speed_limit(scene, car, car.lane) };
    let brake = (-params.interaction.fallback_brake).max(params.decision.game.accel_min);
    let mut accel = prediction::feasible_accel(brake, car.state.vx, bounds, scene.control_dt);
    // The safety layer's braking, if harder (`plan` has lowered the decision's).
    if next.diagnostics.safety.is_some() {
        accel = accel.min(next.decision.accel);
    }
    let preview = scene.road.lane_center(car.lane);
    next.decision = Decision { accel, lane_change: LaneChange::Keep, exact: false, ..next.decision };
    next.preview = Some(preview);
    next.plan.clear();
    next.pace = None;
    next.crossing_at = None;
    next.diagnostics.fallback = Some(error.to_string());
    next.diagnostics.fallbacks += 1;
    next.diagnostics.iterations = 0;
    next.diagnostics.plans += 1;
    let change_to = (car.target_lane != car.lane).then_some(car.lane);
    let exemption = next.diagnostics.safety.map(|_| Exemption::Emergency);
    let jerk = (&params.decision.jerk, &mut next.diagnostics);
    let (accel, ramp) = command_accel(car.accel, accel, scene.control_dt, exemption, jerk);
    GtStep { command: Command { accel, preview }, change_to, ramp, memory: next }
}
