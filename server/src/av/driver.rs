//! The `gt` driver: reads a vehicle's situation from the world (lead cars, adjacent cars,
//! lane ends), plays the game of its role, plans Y_p with the MPC, and falls back to a
//! safe command when the MPC fails. Its state lives in the vehicle as plain data; the
//! only scratch (the MPC's solver) lives outside the world and does not affect results.
//! Also the two questions the env asks of any vehicle: `stage_cost` and `expert_decision`.

use serde::{Deserialize, Serialize};

use super::costs::{self, CostComponents};
use super::field::{self, Field, FieldParams, Obstacle};
use super::games::{Adjacent, Decision, DecisionParams, Game, LaneOption, Player, Situation};
use super::mpc::{self, Mpc, MpcError, MpcParams, MpcProblem, MpcSolution};
use super::prediction::{self, Kinematics, SpeedBounds};
use super::styles::CostWeights;
use crate::dynamics::Command;
use crate::road::LaneId;
use crate::world::{Driver, Status, Vehicle, VehicleId, World};

/// How a `gt` vehicle reads the world and what it does when planning fails.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GtParams {
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

impl Default for GtParams {
    fn default() -> Self {
        GtParams { interaction_range: 60.0, lane_end_time: 8.0, fallback_brake: 3.0 }
    }
}

/// Every constant of the game-theoretic AV.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct AvParams {
    /// Costs, prediction, games.
    pub decision: DecisionParams,
    /// Eq. (19)–(21).
    pub field: FieldParams,
    /// Eq. (22)–(29).
    pub mpc: MpcParams,
    /// Reading the world; the fallback.
    pub gt: GtParams,
}

/// What a `gt` vehicle does in its game.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Decides its acceleration and lane (the paper's EC).
    #[default]
    Leader,
    /// Keeps its lane and only chooses its acceleration, answering the nearest leader
    /// (or learner) in an adjacent lane: its part of the Nash equilibrium, or its best
    /// response to the leader's decision under Stackelberg (the paper's AC).
    Follower,
}

/// What the driver reports about its last plan.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Diagnostics {
    /// Why the last plan fell back to the safe command, if it did.
    pub fallback: Option<String>,
    /// Plans that fell back since the start.
    pub fallbacks: u32,
    /// Interior-point iterations of the last QP.
    pub iterations: u32,
}

/// A `gt` driver's settings and memory: plain data, part of the world's state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GtDriver {
    /// Nash or Stackelberg.
    pub game: Game,
    /// Leader or follower.
    pub role: Role,
    /// Its constants.
    pub params: AvParams,
    /// The last decision.
    pub decision: Decision,
    /// u(k-1): the preview point of the last plan, once there is one (m).
    pub preview: Option<f64>,
    /// The last Delta u plan (the MPC's nominal path next time).
    pub plan: Vec<f64>,
    /// What happened in the last plan.
    pub diagnostics: Diagnostics,
}

impl GtDriver {
    /// A fresh driver.
    pub fn new(game: Game, role: Role, params: AvParams) -> GtDriver {
        GtDriver {
            game,
            role,
            params,
            decision: Decision::default(),
            preview: None,
            plan: Vec::new(),
            diagnostics: Diagnostics::default(),
        }
    }
}

/// One control period's output of a `gt` driver, before it is written to the world.
#[derive(Debug, Clone, PartialEq)]
pub struct GtStep {
    /// a_x and Y_p to apply.
    pub command: Command,
    /// A lane change to start (or, on fallback, the current lane to return to).
    pub change_to: Option<LaneId>,
    /// The driver's new memory.
    pub driver: GtDriver,
}

fn kinematics(vehicle: &Vehicle) -> Kinematics {
    Kinematics { s: vehicle.state.s, d: vehicle.state.d, speed: vehicle.state.lane_speed() }
}

fn in_lane(world: &World, index: usize, lane: LaneId) -> bool {
    let vehicle = &world.vehicles[index];
    vehicle.on_road() && (vehicle.target_lane == lane || world.current_lane(VehicleId(index as u32)) == lane)
}

/// The nearest car in `lane` ahead of `s` (strictly ahead, or level and later in order),
/// other than `exclude`.
fn car_ahead(world: &World, lane: LaneId, s: f64, exclude: &[VehicleId]) -> Option<(VehicleId, Kinematics)> {
    (0..world.vehicles.len())
        .filter(|&i| !exclude.contains(&VehicleId(i as u32)) && in_lane(world, i, lane))
        .map(|i| (VehicleId(i as u32), kinematics(&world.vehicles[i])))
        .filter(|(_, k)| k.s >= s)
        .min_by(|a, b| a.1.s.total_cmp(&b.1.s))
}

/// The car in `lane` nearest to `s` along the road within `range`, other than `exclude`.
fn nearest_car(
    world: &World,
    lane: LaneId,
    s: f64,
    range: f64,
    exclude: &[VehicleId],
) -> Option<(VehicleId, Kinematics)> {
    (0..world.vehicles.len())
        .filter(|&i| !exclude.contains(&VehicleId(i as u32)) && in_lane(world, i, lane))
        .map(|i| (VehicleId(i as u32), kinematics(&world.vehicles[i])))
        .filter(|(_, k)| (k.s - s).abs() <= range)
        .min_by(|a, b| (a.1.s - s).abs().total_cmp(&(b.1.s - s).abs()))
}

/// The end of `lane` as a stopped car just past it (DESIGN.md: a lane end enters eq. 11
/// as the paper's lead car does), if the lane ends ahead of `s`.
fn lane_end(world: &World, lane: LaneId) -> Option<Kinematics> {
    let end = world.road.lane_end(lane);
    (end < world.road.length()).then(|| Kinematics {
        s: end + world.vehicle_params.length / 2.0,
        d: world.road.lane_center(lane),
        speed: 0.0,
    })
}

/// The nearer of a lead car and the lane's end: the lead obstacle of eq. (11).
fn lead_obstacle(world: &World, lane: LaneId, car: Option<Kinematics>) -> Option<Kinematics> {
    match (car, lane_end(world, lane)) {
        (Some(car), Some(end)) => Some(if car.s <= end.s { car } else { end }),
        (car, end) => car.or(end),
    }
}

/// v_max of eq. (14)–(15) for vehicle `id` in `lane`: the lane's speed limit, or the
/// speed its driver aims for (`Vehicle::target_speed`) if lower.
fn speed_limit(world: &World, id: VehicleId, lane: LaneId) -> f64 {
    world.road.speed_limit(lane).min(world.vehicle(id).target_speed)
}

fn player(world: &World, id: VehicleId, lane: LaneId, params: &AvParams) -> Player {
    let vehicle = world.vehicle(id);
    Player {
        now: kinematics(vehicle),
        weights: CostWeights::for_style(vehicle.style),
        bounds: SpeedBounds { min: params.decision.game.speed_min, max: speed_limit(world, id, lane) },
    }
}

/// The lane `id` is changing to, relative to where it is: -1, 0 or 1.
fn changing(world: &World, id: VehicleId) -> i8 {
    let (current, target) = (world.current_lane(id).0 as i64, world.vehicle(id).target_lane.0 as i64);
    (target - current).signum() as i8
}

/// A neighbouring lane EC may change to, with its adjacent car: `None` when the lane
/// does not exist or ends too soon.
fn side_option(world: &World, id: VehicleId, sigma: i8, params: &AvParams) -> Option<(LaneOption, Option<VehicleId>)> {
    let ego = kinematics(world.vehicle(id));
    let lane = world.current_lane(id).0 as i64 + i64::from(sigma);
    if !world.road.has_lane(lane) {
        return None;
    }
    let lane = LaneId(lane as u32);
    let ahead = world.road.lane_end(lane) - ego.s;
    if world.road.lane_end(lane) < world.road.length() && ahead < ego.speed.max(10.0) * params.gt.lane_end_time {
        return None;
    }
    let ac = nearest_car(world, lane, ego.s, params.gt.interaction_range, &[id]);
    let adjacent = ac.map(|(ac_id, ac_now)| {
        let others = [id, ac_id];
        let ac_lead = car_ahead(world, lane, ac_now.s, &others).map(|(_, k)| k);
        Adjacent {
            player: player(world, ac_id, lane, params),
            leader: lead_obstacle(world, lane, ac_lead),
            lead: ac_lead,
        }
    });
    let exclude: Vec<VehicleId> = [Some(id), ac.map(|(i, _)| i)].into_iter().flatten().collect();
    let lead = car_ahead(world, lane, ego.s, &exclude).map(|(_, k)| k);
    let option = LaneOption {
        sigma,
        centre: world.road.lane_center(lane),
        speed_limit: speed_limit(world, id, lane),
        leader: None,
        lead,
        adjacent,
    };
    Some((option, ac.map(|(i, _)| i)))
}

/// Vehicle `id`'s situation as the EC of a game, and the adjacent car of each side.
pub fn situation(world: &World, id: VehicleId, params: &AvParams) -> (Situation, [Option<VehicleId>; 2]) {
    let current = world.current_lane(id);
    let ego = kinematics(world.vehicle(id));
    let lead = car_ahead(world, current, ego.s, &[id]).map(|(_, k)| k);
    let keep = LaneOption {
        sigma: 0,
        centre: world.road.lane_center(current),
        speed_limit: speed_limit(world, id, current),
        leader: lead_obstacle(world, current, lead),
        lead,
        adjacent: None,
    };
    let left = side_option(world, id, -1, params);
    let right = side_option(world, id, 1, params);
    let committed = Some(changing(world, id)).filter(|&c| c != 0);
    let situation = Situation {
        ego: player(world, id, current, params),
        keep,
        sides: [left.map(|(o, _)| o), right.map(|(o, _)| o)],
        committed,
        lane_width: world.road.lane_width(),
        period: world.params.control_dt,
    };
    (situation, [left.and_then(|(_, ac)| ac), right.and_then(|(_, ac)| ac)])
}

/// Eq. (10)–(14) for vehicle `id` as it is now: sigma is the lane change it is making
/// (target lane against current lane), a_x its commanded acceleration, a_y its measured
/// lateral acceleration less the road's centripetal part. Lane ends count as stopped
/// lead cars in eq. (11), as in the games.
pub fn stage_cost(world: &World, id: VehicleId) -> CostComponents {
    let params = AvParams::default();
    let c = &params.decision.costs;
    let vehicle = world.vehicle(id);
    let ego = kinematics(vehicle);
    let sigma = changing(world, id);
    let (current, target) = (world.current_lane(id), vehicle.target_lane);
    let longitudinal = lead_obstacle(world, current, car_ahead(world, current, ego.s, &[id]).map(|(_, k)| k))
        .map_or(0.0, |leader| costs::longitudinal_safety(c, ego, leader));
    let lateral = match sigma {
        0 => 0.0,
        _ => nearest_car(world, target, ego.s, params.gt.interaction_range, &[id])
            .map_or(0.0, |(_, ac)| costs::lateral_safety(c, ego, ac)),
    };
    let centripetal = vehicle.state.vx * vehicle.state.vx * world.road.curvature(ego.s);
    let lateral_accel = vehicle.state.lateral_accel(&world.vehicle_params) - centripetal;
    let lead = car_ahead(world, target, ego.s, &[id]).map(|(_, k)| k);
    let v_bar = costs::target_speed(c, ego, speed_limit(world, id, target), lead);
    CostComponents {
        safety: costs::safety(sigma, longitudinal, lateral),
        comfort: costs::comfort(c, sigma, vehicle.command.accel, lateral_accel),
        efficiency: costs::efficiency(ego.speed, v_bar),
    }
}

/// What the built-in AV would decide in vehicle `id`'s place (as the EC of `game`, with
/// the default parameters): its acceleration and lane choice.
pub fn expert_decision(world: &World, id: VehicleId, game: Game) -> Decision {
    let params = AvParams::default();
    situation(world, id, &params).0.decide(game, &params.decision)
}

/// The leader or learner in an adjacent lane a follower answers: the nearest within range.
fn partner(world: &World, id: VehicleId, params: &AvParams) -> Option<VehicleId> {
    let me = kinematics(world.vehicle(id));
    let lane = world.current_lane(id).0 as i64;
    (0..world.vehicles.len())
        .map(|i| VehicleId(i as u32))
        .filter(|&other| other != id && world.vehicle(other).status == Status::Driving)
        .filter(|&other| (world.current_lane(other).0 as i64 - lane).abs() == 1)
        .filter(|&other| match &world.vehicle(other).driver {
            Driver::Gt(gt) => gt.role == Role::Leader,
            Driver::Agent(_) => true,
            Driver::Idm => false,
        })
        .map(|other| (other, (world.vehicle(other).state.s - me.s).abs()))
        .filter(|&(_, distance)| distance <= params.gt.interaction_range)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(other, _)| other)
}

/// What a leader (or learner) is doing: its last decision if it is a `gt` leader, else
/// its commanded acceleration; and the lane change it is making or has just decided.
fn observed(world: &World, id: VehicleId) -> (f64, i8) {
    let vehicle = world.vehicle(id);
    let under_way = changing(world, id);
    match &vehicle.driver {
        Driver::Gt(gt) => (gt.decision.accel, if under_way != 0 { under_way } else { gt.decision.sigma }),
        _ => (vehicle.command.accel, under_way),
    }
}

/// A follower's acceleration: its part of the side game against its partner (Nash), its
/// best response to the partner's observed decision (Stackelberg), or, with no partner
/// in play, the best for itself alone.
fn follow(world: &World, id: VehicleId, game: Game, params: &AvParams) -> Decision {
    let alone = || {
        let (mut own, _) = situation(world, id, params);
        own.sides = [None, None];
        own.committed = None;
        own.decide(Game::Nash, &params.decision)
    };
    let Some(partner) = partner(world, id, params) else { return alone() };
    let (view, adjacent) = situation(world, partner, params);
    let side: i8 = if world.current_lane(id) < world.current_lane(partner) { -1 } else { 1 };
    if adjacent[usize::from(side > 0)] != Some(id) {
        return alone();
    }
    let accel = match game {
        Game::Nash => {
            let side_game = view.side_game(side, &params.decision);
            if side_game.ec_actions.is_empty() {
                return alone();
            }
            let profile = side_game.table.nash(); // eq. (15b) / (16e–f)
            side_game.ac_actions[profile.col]
        }
        Game::Stackelberg => {
            let (accel, sigma) = observed(world, partner);
            let sigma = if sigma == side { side } else { 0 };
            let me = player(world, id, world.current_lane(id), params);
            let grid = params.decision.game.grid(me.now.speed, me.bounds, world.params.control_dt);
            let side_game = view.side_game_with(side, vec![(accel, sigma)], grid, &params.decision);
            side_game.ac_actions[side_game.table.best_reply(0)] // eq. (17b)
        }
    };
    Decision { accel, sigma: 0, exact: true, ..Decision::default() }
}

/// The field vehicle `id` plans in: the other cars near it and the road's lines.
fn field_around(world: &World, id: VehicleId, params: &FieldParams) -> Field {
    let me = world.vehicle(id).state.s;
    let obstacles = world
        .vehicles
        .iter()
        .enumerate()
        .filter(|&(i, v)| i != id.0 as usize && v.on_road() && (v.state.s - me).abs() <= params.range)
        .map(|(_, v)| Obstacle { s: v.state.s, d: v.state.d, heading: v.state.heading, speed: v.state.lane_speed() })
        .collect();
    Field { params: *params, obstacles, lines: field::road_lines(&world.road, params) }
}

/// Plans Y_p toward `target` lane for vehicle `id` at acceleration `accel` with `mpc`.
pub fn plan_motion(
    world: &World,
    id: VehicleId,
    accel: f64,
    target: LaneId,
    params: &AvParams,
    mpc: Option<&mut Mpc>,
) -> Result<MpcSolution, MpcError> {
    let vehicle = world.vehicle(id);
    let Driver::Gt(gt) = &vehicle.driver else {
        return Err(MpcError::Setup("vehicle is not driven by gt".into()));
    };
    let field = field_around(world, id, &params.field);
    let w = world.road.lane_width();
    let rightmost = world.road.lane_center(LaneId(world.road.lane_count() as u32 - 1));
    let margin = params.mpc.preview_margin;
    let problem = MpcProblem {
        state: vehicle.state,
        accel,
        previous_preview: gt.preview.unwrap_or(vehicle.command.preview),
        target: world.road.lane_center(target),
        curvature: world.road.curvature(vehicle.state.s),
        vehicle: &world.vehicle_params,
        driver: &vehicle.driver_params,
        dt: world.params.control_dt,
        field: &field,
        nominal: &gt.plan,
        preview_bounds: (rightmost - margin.min(w), margin.min(w)),
    };
    match mpc {
        Some(mpc) => mpc.solve(&problem, &params.mpc),
        None => mpc::solve(&problem, &params.mpc),
    }
}

/// One control period of the `gt` driver of vehicle `id`: decide, plan, or fall back.
/// Reads the world only; `drive` writes the result.
pub fn plan(world: &World, id: VehicleId, mpc: Option<&mut Mpc>) -> GtStep {
    let vehicle = world.vehicle(id);
    let Driver::Gt(gt) = &vehicle.driver else {
        let command = Command { accel: 0.0, preview: vehicle.command.preview };
        return GtStep {
            command,
            change_to: None,
            driver: GtDriver::new(Game::Nash, Role::Leader, AvParams::default()),
        };
    };
    let params = gt.params;
    let current = world.current_lane(id);
    let decision = match gt.role {
        Role::Leader => situation(world, id, &params).0.decide(gt.game, &params.decision),
        Role::Follower => follow(world, id, gt.game, &params),
    };
    let starts = decision.sigma != 0 && vehicle.target_lane == current && gt.role == Role::Leader;
    let target =
        if starts { LaneId((current.0 as i64 + i64::from(decision.sigma)) as u32) } else { vehicle.target_lane };
    let mut driver = GtDriver::clone(gt);
    driver.decision = decision;
    match plan_motion(world, id, decision.accel, target, &params, mpc) {
        Ok(solution) => {
            driver.preview = Some(solution.preview);
            driver.plan = solution.plan;
            driver.diagnostics.fallback = None;
            driver.diagnostics.iterations = solution.iterations;
            let command = Command { accel: decision.accel, preview: solution.preview };
            GtStep { command, change_to: starts.then_some(target), driver }
        }
        Err(error) => fallback(world, id, driver, &error),
    }
}

/// The safe command: keep (or return to) the current lane, brake within bounds.
fn fallback(world: &World, id: VehicleId, mut driver: GtDriver, error: &MpcError) -> GtStep {
    let vehicle = world.vehicle(id);
    let current = world.current_lane(id);
    let params = &driver.params;
    let bounds = SpeedBounds { min: params.decision.game.speed_min, max: speed_limit(world, id, current) };
    let brake = (-params.gt.fallback_brake).max(params.decision.game.accel_min);
    let accel = prediction::feasible_accel(brake, vehicle.state.vx, bounds, world.params.control_dt);
    let preview = world.road.lane_center(current);
    driver.decision = Decision { accel, sigma: 0, exact: false, ..driver.decision };
    driver.preview = Some(preview);
    driver.plan.clear();
    driver.diagnostics.fallback = Some(error.to_string());
    driver.diagnostics.fallbacks += 1;
    driver.diagnostics.iterations = 0;
    let change_to = (vehicle.target_lane != current).then_some(current);
    GtStep { command: Command { accel, preview }, change_to, driver }
}

/// Runs the `gt` driver of vehicle `id` for this control period and writes its command,
/// lane change and memory into the world. Returns the acceleration to apply.
pub fn drive(world: &mut World, id: VehicleId) -> f64 {
    let step = plan(world, id, None);
    if let Some(lane) = step.change_to {
        world.change_lane(id, lane);
    }
    let vehicle = world.vehicle_mut(id);
    vehicle.command.preview = step.command.preview;
    vehicle.driver = Driver::Gt(Box::new(step.driver));
    step.command.accel
}
