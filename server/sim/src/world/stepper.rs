//! What advances a world and is not part of it: one tick's stages in order (keep the
//! vehicles sorted along the road, let the drivers decide at the control rate, integrate,
//! detect collisions), with the buffers they work in, the decision pool that takes the
//! game-theoretic cars' decisions in parallel, the decisions made ahead of their instant,
//! the explanations asked for and the wall-time clock. None of it is state: a stepper can
//! be dropped and a new one built at any tick, and the world runs on to the same bits
//! (rapier's `PhysicsPipeline` holds "only temporary data buffers" the same way).

use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use super::clock::{self, DecisionClock};
use super::pool::{self, Helpers};
use super::{AgentCommand, Decision, Driver, Forced, Status, VehicleId, World, collision};
use crate::dynamics;
use crate::gt;

/// How far sideways a preview point may lie from the car, per metre of road the driver
/// previews (v T_p): 0.4, chosen here: the slope a lane change's path asks for at
/// `FULL_PACE_SPEED` (its 1.9 m/s peak over 5 m/s), so that no path IDM or a learner's
/// meta action previews reaches it.
pub const PREVIEW_SLOPE: f64 = 0.4;

/// `preview` held where a driver steering towards it keeps the car, at `state` and
/// reaching `half_width` to either side, on the road: within `PREVIEW_SLOPE` of its
/// preview distance of it (at a standstill, straight ahead: a driver aiming a lane away
/// there holds the wheels at their lock and the car, creeping off, turns across the
/// lanes), then within the road's edges where it is (`Road::paved_band`), beside a lane's
/// end as along the road's outer edges, whatever its plan or path asks for.
fn held(
    road: &crate::road::Road,
    half_width: f64,
    state: &dynamics::VehicleState,
    preview_time: f64,
    preview: f64,
) -> f64 {
    let reach = PREVIEW_SLOPE * state.lane_speed().max(0.0) * preview_time;
    let (low, high) = road.paved_band(state.s, half_width);
    preview.max(state.d - reach).min(state.d + reach).max(low).min(high)
}

/// Advances worlds: scratch, threads, a clock and decisions made ahead, never state.
#[derive(Debug, Clone)]
pub struct Stepper {
    /// Each vehicle's s by id, refreshed every tick: the sort and the sweep read these 8
    /// bytes per vehicle rather than a whole `Vehicle` each.
    positions: Vec<f64>,
    /// One decision per vehicle, this control period's.
    decisions: Vec<Decision>,
    /// Threads for the game-theoretic cars' decisions (`set_decision_threads`).
    decision_threads: usize,
    /// The vehicles that move this step, in SIMD blocks, and their ids.
    fleet: dynamics::Fleet,
    moving: Vec<u32>,
    /// Whether each game-theoretic decision is explained (`set_explain`); never read by a
    /// decision.
    explain: bool,
    /// The decisions explained since `take_explanations` last emptied it.
    explanations: Vec<gt::Explanation>,
    /// Wall time spent deciding, per vehicle (`clock_decisions`).
    clock: DecisionClock,
    /// The coming control instant's decisions, made early (`decide_ahead`).
    pub(super) ahead: Option<Ahead>,
}

/// Decisions made ahead of their control instant, by vehicle, with the scene they were
/// made from: the tick takes them only if that scene is still the world's.
#[derive(Debug, Clone)]
pub(super) struct Ahead {
    scene: u64,
    pub(super) decided: Decided,
}

/// Decisions of one control instant, by vehicle (`None`: not decided there), with the
/// wall time each took.
type Decided = Vec<Option<(Decision, Duration)>>;

impl Default for Stepper {
    fn default() -> Stepper {
        Stepper::new()
    }
}

impl Stepper {
    /// A stepper deciding on every core of the machine.
    pub fn new() -> Stepper {
        Stepper {
            positions: Vec::new(),
            decisions: Vec::new(),
            decision_threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            fleet: dynamics::Fleet::default(),
            moving: Vec::new(),
            explain: false,
            explanations: Vec::new(),
            clock: DecisionClock::default(),
            ahead: None,
        }
    }

    /// One physics step of `world`.
    pub fn tick(&mut self, world: &mut World) {
        world.state.sort_along_road(&mut self.positions);
        if world.state.ticks.is_multiple_of(world.params.substeps_per_control()) {
            world.scene();
            world.note_lane_entries();
            self.decide(world);
        }
        self.integrate(world);
        self.detect_collisions(world);
        let state = &mut world.state;
        state.ticks += 1;
        state.time = state.ticks as f64 * world.params.physics_dt;
    }

    /// Advances `world` by the whole physics steps closest to `seconds`.
    pub fn advance(&mut self, world: &mut World, seconds: f64) {
        let steps = (seconds / world.params.physics_dt).round() as u64;
        for _ in 0..steps {
            self.tick(world);
        }
    }

    /// How many threads the game-theoretic cars of one control period may decide on
    /// (default: the machine's cores; 1 decides them in turn). The results are the same
    /// bits either way.
    pub fn set_decision_threads(&mut self, threads: usize) {
        self.decision_threads = threads.max(1);
    }

    /// Measure the wall time each driver spends deciding from now on
    /// (`take_decision_time`), or stop. Off by default; the decisions are the same bits
    /// either way.
    pub fn clock_decisions(&mut self, on: bool) {
        self.clock.switch(on);
    }

    /// The wall time vehicle `id`'s driver spent deciding since the last call (zero
    /// unless `clock_decisions` is on).
    pub fn take_decision_time(&mut self, id: VehicleId) -> Duration {
        self.clock.take(id.0 as usize)
    }

    /// Explain every game-theoretic decision from now on (`take_explanations`), or stop.
    /// Off by default; the decisions are the same bits either way.
    pub fn set_explain(&mut self, on: bool) {
        self.explain = on;
        if !on {
            self.explanations.clear();
        }
    }

    /// The decisions explained since the last call, in time order, cars by id.
    pub fn take_explanations(&mut self) -> Vec<gt::Explanation> {
        std::mem::take(&mut self.explanations)
    }

    /// Every driver picks its command for the coming control period from the scene:
    /// first everyone but the game-theoretic followers, then the followers, who read
    /// their leaders' decisions of this period. Then every decision is applied.
    fn decide(&mut self, world: &mut World) {
        let mut decisions = std::mem::take(&mut self.decisions);
        decisions.clear();
        let threads = self.decision_threads;
        let made = self.ahead.take().filter(|ahead| world.fresh_scene() == Some(ahead.scene));
        let mut leaders = match made {
            Some(Ahead { decided: mut made, .. }) => {
                // Made ahead, perhaps not all of them (`decide_ahead` stops when asked): the
                // rest now.
                let missing = |world: &World, index: usize| {
                    !world.is_follower(index) && made.get(index).is_none_or(Option::is_none)
                };
                let rest = self.in_parallel(world, missing, threads, &|| false);
                for (slot, decided) in made.iter_mut().zip(rest) {
                    if slot.is_none() {
                        *slot = decided;
                    }
                }
                made
            }
            None => self.in_parallel(world, |world, index| !world.is_follower(index), threads, &|| false),
        };
        let n = world.state.vehicles.len();
        for index in 0..n {
            let decision = match leaders.get_mut(index).and_then(Option::take) {
                Some((decided, spent)) => self.clocked(index, n, decided, spent),
                None if world.is_follower(index) => Decision::Accel(0.0),
                None => self.decide_clocked(world, index),
            };
            if let Some((accel, change)) = world.announced(index, &decision) {
                world.scene.record_decision(VehicleId(index as u32), accel, change);
            }
            decisions.push(decision);
        }
        let mut followers = self.in_parallel(world, |world, index| world.is_follower(index), threads, &|| false);
        for (index, decision) in decisions.iter_mut().enumerate() {
            if let Some((decided, spent)) = followers.get_mut(index).and_then(Option::take) {
                *decision = self.clocked(index, n, decided, spent);
            } else if world.is_follower(index) {
                *decision = self.decide_clocked(world, index);
            }
        }
        if self.explain {
            self.explain_decisions(world, &decisions);
        }
        for (index, decision) in decisions.drain(..).enumerate() {
            world.apply(VehicleId(index as u32), decision);
        }
        self.decisions = decisions;
    }

    /// Makes `world`'s coming control instant's decisions now, while it waits for its
    /// learners' actions (a server calls it once a step's reply is on its way), for every
    /// vehicle whose decision cannot read those actions: all but the learners and the
    /// game-theoretic followers, who read what the learners announce. They need the
    /// scene of this instant, taken already (an env samples its agents' costs from it at
    /// the end of each step); without it nothing is done.
    /// The instant's `tick` uses them when that scene is still the world's: every change
    /// to a vehicle (`add`, `restore`, each one between ticks) and every new scene make
    /// another, and a decision reads only the scene, its own vehicle and the world's time.
    /// So the world runs the same bits with or without them; a learner's action that
    /// changes its vehicle (a lane change, a new target speed or acceleration) only costs
    /// the work done ahead.
    /// It stops, keeping what it decided, when `stop` says so (the next request has come):
    /// the tick decides the rest.
    pub fn decide_ahead(&mut self, world: &World, stop: &(dyn Fn() -> bool + Sync)) {
        let at_instant = world.state.ticks.is_multiple_of(world.params.substeps_per_control());
        let Some(scene) = world.fresh_scene().filter(|_| at_instant) else {
            return;
        };
        if self.ahead.as_ref().is_some_and(|ahead| ahead.scene == scene) {
            return;
        }
        let pick = |world: &World, index: usize| {
            !world.is_follower(index) && !matches!(world.state.vehicles[index].driver, Driver::Agent(_))
        };
        // IDM traffic alone decides in a few microseconds: not worth a buffer.
        let n = world.state.vehicles.len();
        if !(0..n).any(|index| world.is_gt(index) && pick(world, index)) {
            return;
        }
        // One thread fewer than a tick uses: the reply's way out and the client's way back
        // run meanwhile and need a core. On two cores, one period's decisions made in turn
        // fit within the round trip of a client in Python (docs/performance.md).
        let mut decided = self.in_parallel(world, pick, self.decision_threads - 1, stop);
        if decided.is_empty() {
            // In turn, the game-theoretic cars first: they are most of the work.
            let mut order: Vec<usize> = (0..n).filter(|&index| pick(world, index)).collect();
            order.sort_by_key(|&index| !world.is_gt(index));
            decided = vec![None; n];
            for index in order {
                if stop() {
                    break;
                }
                decided[index] = Some(clock::timed(self.clock.on, || world.decide_one(index)));
            }
        }
        self.ahead = Some(Ahead { scene, decided });
    }

    /// Vehicle `index`'s decision, its wall time added to its clock when the clock is on.
    fn decide_clocked(&mut self, world: &World, index: usize) -> Decision {
        let (decision, spent) = clock::timed(self.clock.on, || world.decide_one(index));
        self.clocked(index, world.state.vehicles.len(), decision, spent)
    }

    /// Adds `spent` to vehicle `index`'s clock (of `vehicles`); returns `decision`.
    fn clocked(&mut self, index: usize, vehicles: usize, decision: Decision, spent: Duration) -> Decision {
        self.clock.note(index, vehicles, spent);
        decision
    }

    /// Explains the game-theoretic cars' `decisions` of this period from the scene they
    /// read and each driver's memory before it (`gt::explain`): the decisions do not
    /// change.
    fn explain_decisions(&mut self, world: &World, decisions: &[Decision]) {
        for (index, decision) in decisions.iter().enumerate() {
            if let (Decision::Gt(step), Driver::Gt(memory)) = (decision, &world.state.vehicles[index].driver) {
                let explained = gt::explain(&world.scene, VehicleId(index as u32), world.gt_of(index), memory, step);
                self.explanations.push(explained);
            }
        }
    }

    /// The decisions of the vehicles that `pick` selects, by vehicle, with the wall time
    /// each took: made on up to `threads` threads when two or more of them are
    /// game-theoretic cars (each decision reads the scene only, so the bits do not depend
    /// on the threads); empty otherwise, and the caller decides them in turn. No task starts
    /// once `stop` says so; those not started are `None`.
    fn in_parallel(
        &self,
        world: &World,
        pick: impl Fn(&World, usize) -> bool + Sync,
        threads: usize,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Decided {
        if threads < 2 {
            return Vec::new();
        }
        let vehicles = &world.state.vehicles;
        let is_gt = |i: usize| vehicles[i].status == Status::Driving && world.is_gt(i);
        // Counted before anything is collected: a world with fewer than two (IDM traffic)
        // allocates nothing here.
        let picked = |i: &usize| pick(world, *i);
        if (0..vehicles.len()).filter(|&i| is_gt(i)).filter(picked).nth(1).is_none() {
            return Vec::new();
        }
        let (mut gt, others): (Vec<usize>, Vec<usize>) = (0..vehicles.len()).filter(picked).partition(|&i| is_gt(i));
        // Every thread takes the next task when it is done with one: a game-theoretic car,
        // the cars slowest to decide last period first, then all the other vehicles at
        // once (IDM's decisions are cheap), so that no thread waits long for another's
        // last car.
        gt.sort_by_key(|&i| std::cmp::Reverse(self.clock.last(i)));
        let next = AtomicUsize::new(0);
        let decided: Vec<OnceLock<(Decision, Duration)>> = (0..vehicles.len()).map(|_| OnceLock::new()).collect();
        // The game-theoretic cars' times order the next period's tasks; the others' are
        // read only by a clock that is on.
        let decide = |index: usize, timed: bool| {
            let _ = decided[index].set(clock::timed(timed, || world.decide_one(index)));
        };
        let work = || {
            while !stop() {
                let task = next.fetch_add(1, Ordering::Relaxed);
                match gt.get(task) {
                    Some(&index) => decide(index, true),
                    None if task == gt.len() => others.iter().for_each(|&index| decide(index, self.clock.on)),
                    None => break,
                }
            }
        };
        // The calling thread decides too, beside helper threads: it does not sleep while
        // they wake. Within a pool (a batch env's worker), the helpers are that pool's;
        // otherwise the decision pool's, built once for the process (a thread spawned per
        // control period cost as much as a decision) with one thread fewer than the
        // cores, so no thread spins for work beside the two that decide. A panic in a
        // decision surfaces on this thread.
        let helpers = |pool: usize| threads.min(pool + 1).min(gt.len()) - 1;
        let count = Helpers::default();
        match pool::decision_pool() {
            Some(decision_pool) if rayon::current_thread_index().is_none() => {
                let helpers = helpers(decision_pool.current_num_threads());
                decision_pool.in_place_scope(|scope| pool::alongside(scope, helpers, &work, &count));
                pool::keep_warm(decision_pool);
            }
            _ => {
                let helpers = helpers(rayon::current_num_threads().saturating_sub(1));
                rayon::in_place_scope(|scope| pool::alongside(scope, helpers, &work, &count));
            }
        }
        decided.into_iter().map(OnceLock::into_inner).collect()
    }

    /// Integrates every vehicle on the road over one physics step, all of them together
    /// (`dynamics::Fleet`).
    fn integrate(&mut self, world: &mut World) {
        let World { scene, params, steps, setups, state, forced, .. } = world;
        let time = state.time;
        // Which step of its control period this is: a ramped acceleration is a linear
        // blend reaching the command at the period's last step.
        let per_control = params.substeps_per_control();
        let phase = state.ticks % per_control + 1;
        let road = &scene.road;
        let half_width = scene.vehicle.width / 2.0;
        let (fleet, moving) = (&mut self.fleet, &mut self.moving);
        fleet.clear();
        moving.clear();
        for (index, vehicle) in state.vehicles.iter_mut().enumerate() {
            let stopped_wreck = vehicle.status == Status::Crashed && vehicle.state.vx <= 0.0;
            if !vehicle.on_road() || stopped_wreck {
                continue;
            }
            // A gt car previews its plan's point, unless it is made to return to a lane
            // (`Forced::ReturnToLane`): then its path's, as every other driver.
            let returning = matches!(forced.get(index), Some(Some(Forced::ReturnToLane(_))));
            let preview_time = setups[index].driver_params.preview_time;
            vehicle.command.preview = match vehicle.driver {
                // A learner's continuous action steers where it says, off the road too:
                // the world then ends it there (`Status::OffRoad`), as its env expects.
                Driver::Agent(AgentCommand::Direct(command)) => command.preview,
                Driver::Gt(_) if !returning => {
                    held(road, half_width, &vehicle.state, preview_time, vehicle.command.preview)
                }
                _ => {
                    vehicle.path.pace(time, params.physics_dt, vehicle.state.lane_speed());
                    let preview = vehicle.path.preview(time, preview_time);
                    held(road, half_width, &vehicle.state, preview_time, preview)
                }
            };
            let mut command = vehicle.command;
            if let Some(from) = vehicle.ramp_from.filter(|_| phase < per_control) {
                command.accel = from + (command.accel - from) * (phase as f64 / per_control as f64);
            }
            vehicle.longitudinal_accel = vehicle.state.longitudinal_accel(command.accel);
            fleet.push(index as u64, &steps[index], &vehicle.state, command, road.curvature(vehicle.state.s));
            moving.push(index as u32);
        }
        fleet.step();
        for (k, &index) in moving.iter().enumerate() {
            let vehicle = &mut state.vehicles[index as usize];
            vehicle.state = fleet.state(k);
            self.positions[index as usize] = vehicle.state.s;
            if vehicle.state.s > road.length() {
                vehicle.status = Status::Exited;
            } else if vehicle.status == Status::Driving && road.lane_at(vehicle.state.s, vehicle.state.d).is_none() {
                vehicle.status = Status::OffRoad;
            }
        }
    }

    /// Oriented-box overlap between vehicles close along the road (a sweep over the
    /// sorted order: only pairs nearer than one body diagonal in s are tested).
    fn detect_collisions(&mut self, world: &mut World) {
        let body = world.scene.vehicle;
        let reach = body.length.hypot(body.width);
        let mut found = Vec::new();
        let (positions, state) = (&self.positions, &world.state);
        for (k, &i) in state.order.iter().enumerate() {
            for &j in &state.order[k + 1..] {
                if positions[j as usize] - positions[i as usize] > reach {
                    break;
                }
                let (a, b) = (&state.vehicles[i as usize], &state.vehicles[j as usize]);
                let both_crashed = a.status == Status::Crashed && b.status == Status::Crashed;
                // A box reaches sideways at most half its width plus half its length times
                // |sin(heading)| <= |heading|: most neighbours in the next lane fail this.
                let lateral_reach = body.width + body.length * (a.state.heading.abs() + b.state.heading.abs()) / 2.0;
                if a.on_road()
                    && b.on_road()
                    && !both_crashed
                    && (b.state.d - a.state.d).abs() <= lateral_reach
                    && world.boxes_overlap(a, b)
                {
                    let at_fault = collision::at_fault(&world.party(i as usize), &world.party(j as usize), state.time);
                    let entry_rule = collision::entry_rule(&world.approach(a), &world.approach(b), state.time);
                    found.push(super::Collision { rear: VehicleId(i), front: VehicleId(j), at_fault, entry_rule });
                }
            }
        }
        let state = &mut world.state;
        for collision in &found {
            state.vehicles[collision.rear.0 as usize].status = Status::Crashed;
            state.vehicles[collision.front.0 as usize].status = Status::Crashed;
        }
        state.collisions.extend(found);
    }
}
