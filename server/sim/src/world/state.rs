//! A world's changing state as plain data (`WorldState`): every vehicle (its driver's
//! memory included), the simulated clock, the collisions so far, the sorted order and the
//! RNG. A `World` holds one and a snapshot is its encoding; equality, copies and serde are
//! derived, so they compare and carry exactly that. What a scenario fixes (road, bodies,
//! timing, IDM constants, each vehicle's name, style, driver parameters and prepared
//! physics step, each `gt` car's game, role and constants) is not in it, nor is the scene
//! drivers read (taken from the vehicles when it is read) or anything of the `Stepper`: a
//! state is restored onto a world freshly built from the same episode, and checked against
//! it.

use std::fmt;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{AgentCommand, Collision, Driver, Vehicle, World};
use crate::dynamics::within_state;
use crate::road::LaneId;

/// Everything of a `World` that changes as it runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorldState {
    /// Every vehicle, indexed by `VehicleId`.
    pub(super) vehicles: Vec<Vehicle>,
    /// Simulated time (s): `ticks` physics steps.
    pub(super) time: f64,
    pub(super) ticks: u64,
    pub(super) collisions: Vec<Collision>,
    /// The world's only source of randomness, seeded at creation.
    #[serde(with = "rng_position")]
    pub(super) rng: ChaCha8Rng,
    /// Vehicles by s, kept sorted every tick for the collision sweep.
    pub(super) order: Vec<u32>,
}

impl WorldState {
    /// No vehicles yet, at time zero, the randomness seeded with `seed`.
    pub(super) fn new(seed: u64) -> WorldState {
        WorldState {
            vehicles: Vec::new(),
            time: 0.0,
            ticks: 0,
            collisions: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            order: Vec::new(),
        }
    }

    /// Keeps `order` sorted by s: insertion sort, O(n) on the nearly sorted order of the
    /// last tick. `positions` is filled with each vehicle's s by id.
    pub(super) fn sort_along_road(&mut self, positions: &mut Vec<f64>) {
        positions.clear();
        positions.extend(self.vehicles.iter().map(|vehicle| vehicle.state.s));
        let order = &mut self.order;
        for i in 1..order.len() {
            let mut j = i;
            while j > 0 && positions[order[j - 1] as usize] > positions[order[j] as usize] {
                order.swap(j - 1, j);
                j -= 1;
            }
        }
    }
}

/// A ChaCha8 generator as serde carries it (`#[serde(with = "arena_sim::rng_position")]`):
/// its position (`RngState`), which reads back to a generator that draws the same numbers.
pub mod rng_position {
    use rand_chacha::ChaCha8Rng;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use super::RngState;

    /// Writes `rng`'s position.
    pub fn serialize<S: Serializer>(rng: &ChaCha8Rng, serializer: S) -> Result<S::Ok, S::Error> {
        RngState::of(rng).serialize(serializer)
    }

    /// A generator at the position read.
    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<ChaCha8Rng, D::Error> {
        RngState::deserialize(deserializer).map(|position| position.rng())
    }
}

/// A ChaCha8 generator's position: its seed, stream and word.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RngState {
    seed: [u8; 32],
    stream: u64,
    word: u128,
}

impl RngState {
    /// Where `rng` is.
    pub fn of(rng: &ChaCha8Rng) -> RngState {
        RngState { seed: rng.get_seed(), stream: rng.get_stream(), word: rng.get_word_pos() }
    }

    /// A generator at this position: it draws what the one it was taken of would have.
    pub fn rng(&self) -> ChaCha8Rng {
        let mut rng = ChaCha8Rng::from_seed(self.seed);
        rng.set_stream(self.stream);
        rng.set_word_pos(self.word);
        rng
    }
}

/// A `WorldState` that does not fit the world it is restored onto.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StateError {
    /// What does not fit, and where.
    pub what: String,
}

impl fmt::Display for StateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "invalid world state: {}", self.what)
    }
}

impl std::error::Error for StateError {}

fn invalid(what: impl Into<String>) -> StateError {
    StateError { what: what.into() }
}

impl World {
    /// The world's changing state, to restore later with `restore`.
    pub fn state(&self) -> &WorldState {
        &self.state
    }

    /// Puts `state` into this world, which must have been built from the same episode
    /// (the same vehicles, with the same kinds of driver, on the same road; their names,
    /// styles and constants are this world's, never the state's);
    /// from then on it runs exactly as the world `state` was taken of. A state that does
    /// not fit (it may come from outside the process) is refused, naming what does not,
    /// and the world is left as it was.
    pub fn restore(&mut self, state: WorldState) -> Result<(), StateError> {
        self.check(&state)?;
        self.state = state;
        self.scene_taken = None;
        Ok(())
    }

    fn check(&self, state: &WorldState) -> Result<(), StateError> {
        let n = self.state.vehicles.len();
        if state.vehicles.len() != n || state.order.len() != n {
            return Err(invalid(format!(
                "{} vehicles and {} sorted places, where this world has {n} vehicles",
                state.vehicles.len(),
                state.order.len()
            )));
        }
        let lanes = self.road().lane_count();
        let lane_ok = |lane: LaneId| (lane.0 as usize) < lanes;
        for (index, (ours, theirs)) in self.state.vehicles.iter().zip(&state.vehicles).enumerate() {
            let at = || format!("vehicle {index} ('{}')", self.setups[index].name);
            let same_driver = match (&ours.driver, &theirs.driver) {
                (Driver::Agent(_), Driver::Agent(_)) | (Driver::Idm, Driver::Idm) => Ok(()),
                (Driver::Gt(_), Driver::Gt(memory)) => memory.check(self.gt_of(index), lanes),
                _ => Err("another driver".to_string()),
            };
            same_driver.map_err(|e| invalid(format!("{}: {e}", at())))?;
            let lanes_used = [theirs.target_lane, theirs.lane_entry.lane].into_iter();
            if !lanes_used.chain(theirs.occupancy.iter().map(|o| o.lane)).all(lane_ok) {
                return Err(invalid(format!("{}: a lane the road (lanes 0..{lanes}) does not have", at())));
            }
            // A body is in three lanes at most (`collision::lanes_reached`), each once.
            let occupancy = &theirs.occupancy;
            let repeated = occupancy.iter().enumerate().any(|(k, o)| occupancy[..k].iter().any(|p| p.lane == o.lane));
            if occupancy.len() > 3 || repeated {
                return Err(invalid(format!("{}: {} lanes occupied, or one twice", at(), occupancy.len())));
            }
            if let Some(gap) = occupancy.iter().filter_map(|o| o.behind).find(|g| g.rear.0 as usize >= n) {
                return Err(invalid(format!(
                    "{}: entered a lane ahead of vehicle {}: there are {n}",
                    at(),
                    gap.rear.0
                )));
            }
            if !vehicle_numbers(theirs).all(within_state) {
                return Err(invalid(format!(
                    "{}: a number that is not finite, or past MAX_STATE_MAGNITUDE (its state, command, path or driver's \
                     memory)",
                    at()
                )));
            }
        }
        let mut seen = vec![false; n];
        for &place in &state.order {
            match seen.get_mut(place as usize) {
                Some(seen) if !*seen => *seen = true,
                _ => return Err(invalid("the sorted order is not an order of the vehicles")),
            }
        }
        if let Some(c) = state.collisions.iter().find(|c| c.rear.0 as usize >= n || c.front.0 as usize >= n) {
            return Err(invalid(format!("collision of vehicles {} and {}: there are {n}", c.rear.0, c.front.0)));
        }
        let time = state.ticks as f64 * self.params.physics_dt;
        if state.time.to_bits() != time.to_bits() && !(state.ticks == 0 && state.time == 0.0) {
            return Err(invalid(format!(
                "time {} s after {} ticks of {} s",
                state.time, state.ticks, self.params.physics_dt
            )));
        }
        Ok(())
    }
}

/// Every number a vehicle carries from one tick to the next: its state, what it is
/// commanded, its lateral path, its driver's memory and its lane entries. A number that is not finite
/// from outside would reach the dynamics and the MPC.
fn vehicle_numbers(vehicle: &Vehicle) -> impl Iterator<Item = f64> + '_ {
    let path = &vehicle.path;
    let own = [
        vehicle.target_speed,
        vehicle.command.accel,
        vehicle.command.preview,
        vehicle.longitudinal_accel,
        // Minus infinity until MOBIL is first consulted.
        if vehicle.last_lane_decision == f64::NEG_INFINITY { 0.0 } else { vehicle.last_lane_decision },
        path.from,
        path.to,
        path.start,
        path.duration,
    ];
    // A gt driver's memory is checked by `GtMemory::check`.
    let driver: Vec<f64> = match &vehicle.driver {
        Driver::Agent(AgentCommand::Direct(command)) => vec![command.accel, command.preview],
        Driver::Agent(AgentCommand::Track) | Driver::Idm | Driver::Gt(_) => Vec::new(),
    };
    let lane_entry = vehicle.lane_entry.at;
    let occupancy = vehicle.occupancy.iter().flat_map(|o| {
        let gap = o.behind.map(|g| [g.gap, g.speed, g.rear_speed, g.rear_accel]).into_iter().flatten();
        o.since.into_iter().chain(gap).chain(o.behind.and_then(|g| g.established))
    });
    vehicle
        .state
        .to_array()
        .into_iter()
        .chain(own)
        .chain(vehicle.ramp_from)
        .chain(lane_entry)
        .chain(driver)
        .chain(occupancy)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::builtin_scenario;

    fn advanced(name: &str, seconds: f64) -> World {
        let mut world = builtin_scenario(name).unwrap().unwrap().build(7);
        world.advance(seconds);
        world
    }

    #[test]
    fn a_restored_world_runs_on_as_the_original() {
        for name in ["highway-gt", "merge-random"] {
            let mut original = advanced(name, 3.0);
            let mut restored = builtin_scenario(name).unwrap().unwrap().build(99);
            restored.restore(original.state().clone()).unwrap();
            assert!(restored.state() == original.state(), "{name}");
            original.advance(4.0);
            restored.advance(4.0);
            assert!(restored.state() == original.state(), "{name}: the worlds parted");
        }
    }

    #[test]
    fn a_restore_takes_no_constants_from_the_state() {
        // A world whose gt car plans with other constants hands its state to one built
        // from the scenario: that one keeps the scenario's constants, and the two part.
        let mut tuned = advanced("merge-random", 0.0);
        let ec =
            (0..tuned.vehicles().len() as u32).map(crate::VehicleId).find(|&id| tuned.gt_setup(id).is_some()).unwrap();
        let mut params = tuned.gt_params(ec);
        params.decision.game.accel_step = 1.0;
        params.decision.prediction.samples = 2;
        tuned.set_gt_params(ec, params);
        tuned.advance(1.0);
        let mut restored = advanced("merge-random", 0.0);
        let scenario_params = restored.gt_params(ec);
        restored.restore(tuned.state().clone()).unwrap();
        assert!(restored.gt_params(ec) == scenario_params && scenario_params != params);
        tuned.advance(3.0);
        restored.advance(3.0);
        assert!(restored.state() != tuned.state(), "the constants never mattered: the test would not see them");
    }

    fn first_gt(state: &mut WorldState) -> &mut crate::GtMemory {
        let gt = state.vehicles.iter_mut().find_map(|v| match &mut v.driver {
            Driver::Gt(gt) => Some(gt),
            _ => None,
        });
        gt.expect("merge-random has a gt car")
    }

    /// In lane 0 since 1 s, `gap` m ahead of vehicle `rear`.
    fn entered_behind(rear: u32, gap: f64) -> crate::Occupancy {
        let behind = crate::EntryGap {
            rear: crate::VehicleId(rear),
            gap,
            speed: 20.0,
            rear_speed: 20.0,
            rear_accel: 0.0,
            established: None,
        };
        crate::Occupancy { lane: LaneId(0), since: Some(1.0), behind: Some(behind) }
    }

    #[test]
    fn a_state_that_does_not_fit_is_refused_and_the_world_left_as_it_was() {
        let world = advanced("merge-random", 1.0);
        let good = world.state().clone();
        type Spoil = Box<dyn Fn(&mut WorldState)>;
        let cases: Vec<(&str, Spoil)> = vec![
            ("vehicles", Box::new(|s| drop(s.vehicles.pop()))),
            (
                "another driver",
                Box::new(|s| {
                    let idm = matches!(s.vehicles[0].driver, Driver::Idm);
                    s.vehicles[0].driver =
                        if idm { Driver::Agent(super::super::AgentCommand::Track) } else { Driver::Idm };
                }),
            ),
            ("a lane the road", Box::new(|s| s.vehicles[1].target_lane = LaneId(9))),
            ("not finite", Box::new(|s| s.vehicles[1].state.vx = f64::NAN)),
            ("vehicle 1 ('", Box::new(|s| s.vehicles[1].command.preview = f64::INFINITY)),
            ("vehicle 1 ('", Box::new(|s| s.vehicles[1].path.duration = f64::NAN)),
            (
                "memory",
                Box::new(|s| {
                    let gt = s.vehicles.iter_mut().find_map(|v| match &mut v.driver {
                        Driver::Gt(gt) => Some(gt),
                        _ => None,
                    });
                    gt.expect("merge-random has a gt car").plan = vec![0.0, f64::NEG_INFINITY];
                }),
            ),
            ("a plan of 11 moves", Box::new(|s| first_gt(s).plan = vec![0.0; 11])),
            // Finite but past what the dynamics stay finite with (the restore fuzz target).
            ("MAX_STATE_MAGNITUDE", Box::new(|s| s.vehicles[0].state.vx = 1e180)),
            ("MAX_STATE_MAGNITUDE", Box::new(|s| s.vehicles[1].state.heading = -4e228)),
            ("MAX_STATE_MAGNITUDE", Box::new(|s| first_gt(s).preview = Some(1e10))),
            ("sorted order", Box::new(|s| s.order[0] = s.order[1])),
            (
                "collision of vehicles",
                Box::new(|s| {
                    s.collisions.push(Collision {
                        rear: crate::VehicleId(0),
                        front: crate::VehicleId(77),
                        at_fault: crate::AtFault::Rear,
                        entry_rule: crate::AtFault::Rear,
                    })
                }),
            ),
            ("time", Box::new(|s| s.time += 1.0)),
            ("a lane the road", Box::new(|s| s.vehicles[1].occupancy[0].lane = LaneId(9))),
            ("or one twice", Box::new(|s| s.vehicles[1].occupancy = vec![s.vehicles[1].occupancy[0]; 2])),
            ("or one twice", Box::new(|s| s.vehicles[1].occupancy = vec![entered_behind(0, 1.0); 4])),
            ("ahead of vehicle 77", Box::new(|s| s.vehicles[1].occupancy = vec![entered_behind(77, 1.0)])),
            ("vehicle 1 ('", Box::new(|s| s.vehicles[1].occupancy = vec![entered_behind(0, f64::NAN)])),
            (
                "not finite",
                Box::new(|s| {
                    let mut entry = entered_behind(0, 1.0);
                    entry.since = Some(f64::INFINITY);
                    s.vehicles[1].occupancy = vec![entry];
                }),
            ),
        ];
        for (needle, spoil) in cases {
            let mut bad = good.clone();
            spoil(&mut bad);
            let mut target = advanced("merge-random", 2.0);
            let before = target.state().clone();
            let error = target.restore(bad).unwrap_err().to_string();
            assert!(error.contains(needle), "'{needle}' not in: {error}");
            assert!(*target.state() == before, "{needle}: a refused state changed the world");
        }
    }
}
