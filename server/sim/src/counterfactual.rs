//! Was a collision avoidable, and by whom (issue 46): counterfactual replays of a world.
//! This module owns the `Recorder`, which keeps, while an episode runs, a ring of copies of
//! the world (one a control period, enough for the longest lead and one period more) and
//! each learner car's commands of each period; the reference drivers a car is put under
//! (`Reference`); and the verdict on one collision (`verdict`, `Verdict`): for each of its
//! two cars, for each lead k of `LEADS`, for each reference driver, the world of k seconds
//! before is restored, that car alone is put under the reference driver, and the rest is
//! run closed loop (built-in drivers decide anew, learners replay their recorded commands)
//! to the collision's time plus `HORIZON`. It steps worlds through `world`'s API alone
//! (`Stepper`, `World::replace_driver`); nothing below it knows of it.
//! docs/evaluation.md, "Was it avoidable (issue 46)", has the method, its cost and what a
//! verdict does and does not say.

use std::collections::VecDeque;

use crate::dynamics::{Command, LateralPath, Style};
use crate::gt::{Game, GtParams, GtSetup};
use crate::road::LaneId;
use crate::scene::{Role, Status, VehicleId};
use crate::world::{AgentCommand, Collision, Driver, Stepper, World};

/// How long before the collision (s) the replays start: 1, 2 and 3, issue 46's. A replay
/// from earlier than the first copy the recorder holds starts from that copy (an episode's
/// first seconds), and a lead that falls on the same copy as a shorter one is not run again.
pub const LEADS: [f64; 3] = [1.0, 2.0, 3.0];

/// A car avoided the collision if it has none until this long (s) after the original
/// one: 5, issue 46's (and the stress suite's `REPLAY_HORIZON`).
pub const HORIZON: f64 = 5.0;

/// The braking of `Reference::Brake` (m/s^2): the AV's emergency braking
/// (`SafetyParams::emergency_brake`, 8), the hardest any driver of this world brakes.
pub const REFERENCE_BRAKE: f64 = -8.0;

/// A driver a car of a collision is put under in a replay.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Reference {
    /// The game-theoretic AV in this style and game, a leader, with the default constants
    /// (`GtParams::default()`), its memory fresh at the replay's start; the car takes the
    /// style (Table I's steering, Table III's costs).
    Gt(Style, Game),
    /// IDM + MOBIL with the world's constants, at the car's own target speed and style.
    Idm,
    /// Braking at `REFERENCE_BRAKE` from the replay's start until stopped, steering as it
    /// was: a learner along its recorded preview points, any other car along the lateral
    /// path it had (a lane change under way goes on).
    Brake,
}

impl Reference {
    /// Every reference driver, in the order a verdict tries and lists them: the six AV
    /// variants (styles aggressive, normal, conservative; Nash before Stackelberg), IDM,
    /// braking.
    pub const ALL: [Reference; 8] = [
        Reference::Gt(Style::Aggressive, Game::Nash),
        Reference::Gt(Style::Aggressive, Game::Stackelberg),
        Reference::Gt(Style::Normal, Game::Nash),
        Reference::Gt(Style::Normal, Game::Stackelberg),
        Reference::Gt(Style::Conservative, Game::Nash),
        Reference::Gt(Style::Conservative, Game::Stackelberg),
        Reference::Idm,
        Reference::Brake,
    ];

    /// A short name: `gt-normal-nash`, `idm`, `brake`.
    pub fn name(&self) -> String {
        match self {
            Reference::Gt(style, game) => format!("gt-{style:?}-{game:?}").to_lowercase(),
            Reference::Idm => "idm".into(),
            Reference::Brake => "brake".into(),
        }
    }
}

/// What a learner's car was asked to do for one control period, as the world held it when
/// the period began: its command, target lane and speed, and lateral path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LearnerCommand {
    /// The learner's car.
    pub id: VehicleId,
    /// Its driver's command.
    pub command: AgentCommand,
    /// Its target lane.
    pub target_lane: LaneId,
    /// Its target speed (m/s).
    pub target_speed: f64,
    /// The lateral path it previews (meta actions).
    pub path: LateralPath,
}

/// One control period as the recorder keeps it.
#[derive(Debug, Clone)]
struct Entry {
    world: World,
    commands: Vec<LearnerCommand>,
}

/// A collision and the simulated time (s) of the tick that found it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crash {
    /// When (s).
    pub time: f64,
    /// The collision.
    pub collision: Collision,
}

/// The ring a verdict replays from, kept while an episode runs: a copy of the world at the
/// start of each control period (after the learners' commands of the period are set,
/// before its first tick), and those commands. It holds `LEADS`' longest lead and two
/// periods more (32 copies at 10 Hz). Each `record` clones the world (its vehicles, their
/// gt memories and collision notes, the scene) and drops the oldest copy: 5 us for the
/// stress suite's adversarial worlds of 37 cars and 11 us for its dense ones of 81
/// (measured in release), against about 0.5 ms a period of their drivers takes.
#[derive(Debug, Clone)]
pub struct Recorder {
    ring: VecDeque<Entry>,
    capacity: usize,
}

impl Recorder {
    /// A recorder for worlds deciding every `control_dt` seconds.
    pub fn new(control_dt: f64) -> Recorder {
        let longest = LEADS.iter().copied().fold(0.0, f64::max);
        let capacity = (longest / control_dt).ceil() as usize + 2;
        Recorder { ring: VecDeque::with_capacity(capacity), capacity }
    }

    /// Keeps `world` as it is at the start of a control period, its learners' commands set.
    pub fn record(&mut self, world: &World) {
        if self.ring.len() == self.capacity {
            self.ring.pop_front();
        }
        let commands = learner_commands(world);
        self.ring.push_back(Entry { world: world.clone(), commands });
    }

    /// Records `world` and runs one control period of it: the collisions found, with their
    /// times.
    pub fn period(&mut self, world: &mut World, stepper: &mut Stepper) -> Vec<Crash> {
        self.record(world);
        let mut crashes = Vec::new();
        for _ in 0..world.params().substeps_per_control() {
            let seen = world.collisions().len();
            stepper.tick(world);
            let time = world.time();
            crashes.extend(world.collisions()[seen..].iter().map(|&collision| Crash { time, collision }));
        }
        crashes
    }

    /// Copies held.
    pub fn len(&self) -> usize {
        self.ring.len()
    }

    /// Whether no copy is held yet.
    pub fn is_empty(&self) -> bool {
        self.ring.is_empty()
    }

    /// The simulated time (s) of the oldest copy held.
    pub fn earliest(&self) -> Option<f64> {
        self.ring.front().map(|entry| entry.world.time())
    }
}

fn learner_commands(world: &World) -> Vec<LearnerCommand> {
    world
        .vehicles()
        .iter()
        .enumerate()
        .filter_map(|(i, vehicle)| match vehicle.driver {
            Driver::Agent(command) => Some(LearnerCommand {
                id: VehicleId(i as u32),
                command,
                target_lane: vehicle.target_lane,
                target_speed: vehicle.target_speed,
                path: vehicle.path,
            }),
            _ => None,
        })
        .collect()
}

/// A (reference driver, lead) that avoided the collision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Avoided {
    /// The driver.
    pub reference: Reference,
    /// How long before the collision (s) the replay started: the lead of `LEADS` it was
    /// for, or, if the episode was younger than that, the time from the recorder's first
    /// copy to the collision.
    pub lead: f64,
    /// When (simulated s) the copy it started from was taken: the latest at or before the
    /// collision's time minus `lead` (up to a control period earlier), or the recorder's
    /// earliest if the episode was younger than that.
    pub start: f64,
}

/// What the replays of one car of a collision gave.
#[derive(Debug, Clone, PartialEq)]
pub struct PartyVerdict {
    /// The car.
    pub id: VehicleId,
    /// Every (driver, lead) under which it had no collision until `HORIZON` after the
    /// original one, by lead then in `Reference::ALL`'s order.
    pub avoided: Vec<Avoided>,
    /// Replays run for it.
    pub replays: u32,
    /// Simulated seconds of them.
    pub simulated: f64,
}

impl PartyVerdict {
    /// Whether some reference driver avoided the collision in its place.
    pub fn avoidable(&self) -> bool {
        !self.avoided.is_empty()
    }

    /// The longest lead from which some driver avoided it (s): how early it had to act.
    pub fn earliest(&self) -> Option<f64> {
        self.avoided.iter().map(|a| a.lead).reduce(f64::max)
    }

    /// Whether `reference` avoided it from some lead.
    pub fn avoided_by(&self, reference: Reference) -> bool {
        self.avoided.iter().any(|a| a.reference == reference)
    }

    /// The drivers that avoided it, each once, with the longest lead each did it from (s):
    /// `brake@2 idm@3`, `idm@1.16` in an episode's first seconds; `none`.
    pub fn describe(&self) -> String {
        let parts: Vec<String> = Reference::ALL
            .iter()
            .filter_map(|&r| {
                let lead = self.avoided.iter().filter(|a| a.reference == r).map(|a| a.lead).reduce(f64::max)?;
                Some(format!("{}@{}", r.name(), seconds(lead)))
            })
            .collect();
        if parts.is_empty() { "none".into() } else { parts.join(" ") }
    }
}

/// `lead` as a note gives it: whole seconds bare (`3`), others to 0.01 s (`1.16`).
fn seconds(lead: f64) -> String {
    if lead == lead.round() { format!("{lead:.0}") } else { format!("{lead:.2}") }
}

/// Who could have avoided a collision.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Avoidability {
    /// The rear car alone (some reference driver in its place avoided it).
    Rear,
    /// The front car alone.
    Front,
    /// Either.
    Both,
    /// Neither, under any reference driver from any lead.
    Neither,
}

/// The counterfactual verdict on one collision.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// When the collision was found (s).
    pub time: f64,
    /// The rear car's replays (`Collision::rear`).
    pub rear: PartyVerdict,
    /// The front car's.
    pub front: PartyVerdict,
}

impl Verdict {
    /// Who could have avoided it.
    pub fn avoidability(&self) -> Avoidability {
        match (self.rear.avoidable(), self.front.avoidable()) {
            (true, true) => Avoidability::Both,
            (true, false) => Avoidability::Rear,
            (false, true) => Avoidability::Front,
            (false, false) => Avoidability::Neither,
        }
    }

    /// The replays of car `id`, if it is in the collision.
    pub fn of(&self, id: VehicleId) -> Option<&PartyVerdict> {
        [&self.rear, &self.front].into_iter().find(|p| p.id == id)
    }

    /// Replays run in all.
    pub fn replays(&self) -> u32 {
        self.rear.replays + self.front.replays
    }
}

/// The verdict on `crash`, one of the world's collisions found at `crash.time`, from the
/// copies `recorder` holds (it must have recorded every period up to the crash's). For each
/// of its two cars, for each lead of `LEADS` (the latest copy at or before the collision's
/// time minus the lead), for each driver of `Reference::ALL`: the copy is restored, the car
/// is put under the driver, and the world runs closed loop, its other learners replaying
/// their recorded commands (holding the last one recorded past the crash's period), every
/// built-in driver deciding anew, on one thread; the car avoided the collision if it has no
/// collision, and stays on the road, until `crash.time + HORIZON`. Every replay is run, so
/// the verdict lists every driver that avoids it; each stops as soon as the car collides
/// or leaves the road, so the cost is at most 2 x 3 x 8 = 48 replays of lead + `HORIZON`
/// seconds, less for the ones that fail. The same recorder and crash give the same
/// verdict, bit for bit.
pub fn verdict(recorder: &Recorder, crash: &Crash) -> Verdict {
    let [rear, front] = [crash.collision.rear, crash.collision.front].map(|id| party(recorder, crash.time, id));
    Verdict { time: crash.time, rear, front }
}

fn party(recorder: &Recorder, time: f64, id: VehicleId) -> PartyVerdict {
    let ring = &recorder.ring;
    let mut verdict = PartyVerdict { id, avoided: Vec::new(), replays: 0, simulated: 0.0 };
    let mut starts: Vec<usize> = Vec::new();
    for lead in LEADS {
        let start = ring.iter().rposition(|e| e.world.time() <= time - lead + 1e-9).unwrap_or(0);
        if ring.is_empty() || starts.contains(&start) {
            continue;
        }
        starts.push(start);
        if ring[start].world.vehicle(id).status != Status::Driving {
            continue;
        }
        let from = ring[start].world.time();
        let lead = if from <= time - lead + 1e-9 { lead } else { time - from };
        for reference in Reference::ALL {
            let (avoided, simulated) = replay(ring, start, id, reference, time + HORIZON);
            verdict.replays += 1;
            verdict.simulated += simulated;
            if avoided {
                verdict.avoided.push(Avoided { reference, lead, start: from });
            }
        }
    }
    verdict
}

/// Runs the world of `ring[start]` with car `id` under `reference` until `until` (s):
/// whether the car had no collision and stayed on the road, and the seconds simulated.
fn replay(ring: &VecDeque<Entry>, start: usize, id: VehicleId, reference: Reference, until: f64) -> (bool, f64) {
    let mut world = ring[start].world.clone();
    put(&mut world, id, reference);
    let braking = reference == Reference::Brake;
    let (avoided, simulated, _) = run_from(ring, start, world, id, braking, until, |world| {
        if braking {
            brake(world, id);
        }
    });
    (avoided, simulated)
}

/// Runs `world`, the copy `ring[start]` with car `id` put under another driver, a control
/// period at a time until `until` (s), its learners replaying their recorded commands
/// (car `id`'s too if `own_commands`), then `each_period` at the start of each period:
/// whether car `id` had no collision and stayed on the road, the seconds simulated, and
/// the world where it stopped (at the car's collision, off the road, or at `until`).
fn run_from(
    ring: &VecDeque<Entry>,
    start: usize,
    mut world: World,
    id: VehicleId,
    own_commands: bool,
    until: f64,
    mut each_period: impl FnMut(&mut World),
) -> (bool, f64, World) {
    let began = world.time();
    let mut stepper = Stepper::new();
    stepper.set_decision_threads(1);
    let seen = world.collisions().len();
    let substeps = world.params().substeps_per_control();
    let mut period = start;
    loop {
        if period > start {
            let commands = &ring[period.min(ring.len() - 1)].commands;
            for command in commands.iter().filter(|c| c.id != id || own_commands) {
                replay_command(&mut world, command);
            }
        }
        each_period(&mut world);
        for _ in 0..substeps {
            stepper.tick(&mut world);
            if world.collisions()[seen..].iter().any(|c| c.other(id).is_some()) {
                let simulated = world.time() - began;
                return (false, simulated, world);
            }
        }
        let simulated = world.time() - began;
        match world.vehicle(id).status {
            Status::OffRoad => return (false, simulated, world),
            Status::Exited => return (true, simulated, world),
            Status::Driving | Status::Crashed => {}
        }
        if world.time() >= until - 1e-9 {
            return (true, simulated, world);
        }
        period += 1;
    }
}

/// Puts car `id` of `world` under `reference` (`Reference::Brake` keeps its driver, and
/// `brake` replaces its command each period).
fn put(world: &mut World, id: VehicleId, reference: Reference) {
    let own = world.style(id);
    match reference {
        Reference::Gt(style, game) => {
            let setup = GtSetup { game, role: Role::Leader, params: GtParams::default() };
            world.replace_driver(id, Driver::Gt(Box::default()), Some(setup), style);
        }
        Reference::Idm => world.replace_driver(id, Driver::Idm, None, own),
        Reference::Brake => {}
    }
}

/// `Reference::Brake`'s command for the coming period: `REFERENCE_BRAKE`, and the preview
/// point of a learner's recorded command or of the car's lateral path.
fn brake(world: &mut World, id: VehicleId) {
    let (time, preview_time) = (world.time(), world.driver_params(id).preview_time);
    let vehicle = world.vehicle(id);
    let preview = match vehicle.driver {
        Driver::Agent(AgentCommand::Direct(command)) => command.preview,
        _ => vehicle.path.preview(time, preview_time),
    };
    let own = world.style(id);
    let driver = Driver::Agent(AgentCommand::Direct(Command { accel: REFERENCE_BRAKE, preview }));
    world.replace_driver(id, driver, None, own);
}

/// Sets a learner's recorded command again, if the car is still a learner's and drives.
fn replay_command(world: &mut World, command: &LearnerCommand) {
    let vehicle = world.vehicle(command.id);
    if vehicle.status != Status::Driving || !matches!(vehicle.driver, Driver::Agent(_)) {
        return;
    }
    let same = vehicle.driver == Driver::Agent(command.command)
        && vehicle.target_lane == command.target_lane
        && vehicle.target_speed == command.target_speed
        && vehicle.path == command.path;
    if !same {
        let vehicle = world.vehicle_mut(command.id);
        vehicle.driver = Driver::Agent(command.command);
        vehicle.target_lane = command.target_lane;
        vehicle.target_speed = command.target_speed;
        vehicle.path = command.path;
    }
}

#[cfg(test)]
mod tests;
