//! The stress suite of issue 43 (docs/baselines.md, "Stress suite (issue 43)"): its
//! families (the scenarios of scenarios/stress/ and how the learner's car drives in each),
//! one episode of a family measured at every control period, the replays that tell an
//! avoidable collision from another, and the table of a family's episodes. Shared by
//! `examples/stress.rs` (the suite, 100 seeds a family) and `tests/stress.rs` (a fixed
//! subset that asserts the targets), so both measure alike.

use std::collections::VecDeque;

use arena_sim::{
    AgentCommand, AtFault, Avoidability, CUT_IN_WINDOW, Collision, Command, Crash, DRIFT_SPEED, Driver, Ending,
    FULL_PACE_SPEED, Forced, Game, LANE_CHANGE_DURATION, LaneId, LateralPath, Recorder, Scenario, Status, Stepper,
    Style, VehicleId, Verdict, World,
};

use crate::highway_gt;

/// Simulated seconds per episode: the families' 40 env steps of 1 s.
pub const SECONDS: f64 = 40.0;
/// Braking harder than this (m/s^2, a gt car's commanded acceleration) is counted: IDM
/// traffic brakes at most this hard (`IdmParams::accel_limit`).
pub const HARD_BRAKING: f64 = -6.0;
/// Hard braking is justified by a car (or a lane's end) in or entering the braking car's
/// path within this time to collision (s), issue 43's target 3. The time to collision is
/// the braking car's had it held its speed, the car ahead keeping its acceleration (the
/// modified TTC of Ozbay et al. 2008): a car ahead that brakes closes the gap sooner than
/// its speed alone says.
pub const PHANTOM_TTC: f64 = 2.0;
/// A car whose body is less than this (m) beside the gt car's is in its path, whatever
/// lanes their centres are in (RSS's lateral margin mu; a gt car leaving a lane still
/// sweeps part of it).
pub const PATH_MARGIN: f64 = 0.5;
/// A gt car further than this (m) from its target lane's centre, in that lane, drifts
/// outside a lane change: once its target has been unchanged for `LANE_CHANGE_DURATION`
/// of lane-change time (paced as a lane change's path is, below `FULL_PACE_SPEED`) and
/// its centre crossed into the lane at least half of that before (the second half of a
/// lane change's path, from the line to the centre: a change held up before the line
/// still settles after it).
pub const DRIFT_BOUND: f64 = 0.5;
/// A replay starts from the world this long (s) before the collision it replays...
pub const REPLAY_LEAD: f64 = 1.0;
/// ... and the collision counts as avoided if the car at fault has none until this long
/// (s) after the original one.
pub const REPLAY_HORIZON: f64 = 5.0;
/// The braking a replay forces (m/s^2).
pub const REPLAY_BRAKING: f64 = -6.0;
/// Every file's learner.
pub const LEARNER: &str = "ego_0";
/// Copies of the episode kept, one a control period: more than `REPLAY_LEAD` of them.
const RING: usize = 12;

/// How the learner's car drives in a family.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Learner {
    /// IDM + MOBIL, as the traffic does.
    Idm,
    /// A script that pushes the gt cars (`Adversary`).
    Script(Attack),
}

/// What a scripted learner does to the gt cars (issue 43, "scripted adversarial learners").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Attack {
    /// Cuts in ahead of a gt car and brakes.
    CutIn,
    /// Drifts towards a gt car's target lane while it changes lanes.
    Drift,
    /// Accelerates to close the gap behind a gt car that has just changed into its lane.
    CloseGap,
}

/// A stress family: a scenario of scenarios/stress/ and how the learner's car drives in it.
#[derive(Debug, Clone, Copy)]
pub struct Family {
    /// Its name on the command line and in the table.
    pub name: &'static str,
    /// The scenario file, in scenarios/stress/.
    pub file: &'static str,
    /// The file's text, compiled in.
    pub text: &'static str,
    /// Who drives the learner's car.
    pub learner: Learner,
    /// The gt car whose merge is counted (the on-ramp families).
    pub merger: Option<&'static str>,
}

macro_rules! stress_file {
    ($file:literal) => {
        ($file, include_str!(concat!("../../../../scenarios/stress/", $file)))
    };
}

const fn family(
    name: &'static str,
    (file, text): (&'static str, &'static str),
    learner: Learner,
    merger: Option<&'static str>,
) -> Family {
    Family { name, file, text, learner, merger }
}

/// Every family of the suite, in the table's order.
pub const FAMILIES: [Family; 11] = [
    family("gt16", stress_file!("gt16.toml"), Learner::Idm, None),
    family("half-gt", stress_file!("half-gt.toml"), Learner::Idm, None),
    family("dense-normal-stackelberg", stress_file!("dense-normal-stackelberg.toml"), Learner::Idm, None),
    family("dense-aggressive-nash", stress_file!("dense-aggressive-nash.toml"), Learner::Idm, None),
    family("dense-conservative", stress_file!("dense-conservative.toml"), Learner::Idm, None),
    family("fast-aggressive-nash", stress_file!("fast-aggressive-nash.toml"), Learner::Idm, None),
    family("on-ramp", stress_file!("on-ramp.toml"), Learner::Idm, Some("merger")),
    family("on-ramp-dense", stress_file!("on-ramp-dense.toml"), Learner::Idm, Some("merger")),
    family("adversarial-cut-in", stress_file!("adversarial.toml"), Learner::Script(Attack::CutIn), None),
    family("adversarial-drift", stress_file!("adversarial.toml"), Learner::Script(Attack::Drift), None),
    family("adversarial-close-gap", stress_file!("adversarial.toml"), Learner::Script(Attack::CloseGap), None),
];

/// The family called `name`, or an error naming the families there are.
pub fn find_family(name: &str) -> Result<&'static Family, String> {
    FAMILIES.iter().find(|f| f.name == name).ok_or_else(|| {
        let names: Vec<&str> = FAMILIES.iter().map(|f| f.name).collect();
        format!("unknown family '{name}'; the families are {}", names.join(", "))
    })
}

impl Family {
    /// Its scenario, the learner's car on IDM + MOBIL unless a script drives it.
    pub fn scenario(&self) -> Scenario {
        // The learner's car on IDM as an override of the file, not an edit of the parsed
        // scenario: an episode of a file with `[vary]` is parsed again from its text and
        // overrides, and an edit would be lost (the learner then tracked its speed blind).
        let idm = toml::Value::Table(toml::map::Map::from_iter([("kind".to_string(), "idm".into())]));
        let overrides = match self.learner {
            Learner::Idm => vec![(format!("vehicle.{LEARNER}.driver"), idm)],
            Learner::Script(_) => Vec::new(),
        };
        Scenario::parse(self.file, self.text, &overrides).unwrap_or_else(|e| panic!("{e}"))
    }

    /// Whether a script pushes the gt cars.
    pub fn is_adversarial(&self) -> bool {
        matches!(self.learner, Learner::Script(_))
    }

    /// Its traffic's density as placed, vehicles per km per lane of the traffic's lanes.
    pub fn density(&self) -> f64 {
        let scenario = self.scenario();
        let traffic = scenario.traffic.as_ref().expect("every stress family has traffic");
        traffic.vehicles_per_km_per_lane(scenario.road.lane_count())
    }
}

/// How collisions are attributed: the field of `Collision` a rule is read from, named in
/// the table.
#[derive(Clone, Copy)]
pub struct Rule {
    /// The field's name.
    pub field: &'static str,
    /// Who is at fault by it.
    pub fault: fn(&Collision) -> AtFault,
}

/// The attribution of docs/design.md, "Collision attribution", as the world gives it now.
pub const NEW_RULE: Rule = Rule { field: "at_fault", fault: |c| c.at_fault };
/// afc5fa6's rule (a lane changer at fault while it crosses and for `CUT_IN_WINDOW`
/// after it enters the lane), which the world keeps as `Collision::entry_rule` beside the
/// new one.
pub const ENTRY_RULE: Rule = Rule { field: "entry_rule", fault: |c| c.entry_rule };

impl Rule {
    /// The gt cars at fault in `collision` by this rule.
    pub fn gt_at_fault(&self, world: &World, collision: &Collision) -> Vec<VehicleId> {
        let at_fault = match (self.fault)(collision) {
            AtFault::Rear => vec![collision.rear],
            AtFault::Front => vec![collision.front],
            AtFault::Both => vec![collision.rear, collision.front],
        };
        at_fault.into_iter().filter(|&id| is_gt(world, id)).collect()
    }
}

fn is_gt(world: &World, id: VehicleId) -> bool {
    world.gt_setup(id).is_some()
}

/// How an on-ramp's merging car did in one episode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Merge {
    /// Its style and game, drawn for the episode.
    pub style: Style,
    /// See `style`.
    pub game: Game,
    /// Whether its centre reached a through lane while it drove.
    pub merged: bool,
    /// Whether it was at fault in a collision (`NEW_RULE`).
    pub at_fault: bool,
    /// How it stopped driving, if it did.
    pub ending: Option<Ending>,
}

/// What one episode of a family gave. Counts of car-episodes count each gt car once
/// however often it did the thing.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Episode {
    /// The reset seed.
    pub seed: u64,
    /// Collisions in the world.
    pub collisions: u32,
    /// Those with a gt car in them.
    pub involving_gt: u32,
    /// Those with a gt car at fault by `NEW_RULE`.
    pub gt_at_fault: u32,
    /// Those with a gt car at fault by `ENTRY_RULE`.
    pub gt_at_fault_entry: u32,
    /// Those of `gt_at_fault` that a gt car at fault avoids when replayed from
    /// `REPLAY_LEAD` before, forced to return to the lane it came from or to brake at
    /// `REPLAY_BRAKING` (`avoidable`).
    pub avoidable: u32,
    /// Cars that drove past the end of their lane, all of them and gt cars.
    pub lane_end: u32,
    /// See `lane_end`.
    pub lane_end_gt: u32,
    /// Cars that left the road over an edge, all of them and gt cars.
    pub off_road: u32,
    /// See `off_road`.
    pub off_road_gt: u32,
    /// gt car-episodes with a command below `HARD_BRAKING`...
    pub hard_braking: u32,
    /// ... and those of them with such a command at a moment no car was in or entering
    /// its path within `PHANTOM_TTC` (`threatened`).
    pub phantom: u32,
    /// gt car-episodes that drifted past `DRIFT_BOUND` outside a lane change.
    pub drift: u32,
    /// The largest such offset of any gt car (m), drifting or not.
    pub max_drift: f64,
    /// Lane changes gt cars began...
    pub changes: u32,
    /// ... and those they aborted: the target lane set back to the one left before the
    /// car's centre crossed into the new one.
    pub aborts: u32,
    /// The merge, on an on-ramp.
    pub merge: Option<Merge>,
    /// Attacks the scripted learner began.
    pub attacks: u32,
    /// Collisions with a gt car or the learner's car in them, judged by counterfactual
    /// replays (`arena_sim::verdict`: each car under every reference driver from 1, 2 and
    /// 3 s before, avoided if it has no collision until 5 s after)...
    pub verdicts: u32,
    /// ... those that only the rear car, only the front car, either, or neither could
    /// have avoided...
    pub by_rear: u32,
    /// See `by_rear`.
    pub by_front: u32,
    /// See `by_rear`.
    pub by_both: u32,
    /// See `by_rear`.
    pub by_neither: u32,
    /// ... those where the responsibility rule (`NEW_RULE`) puts a car at fault that no
    /// reference driver in its place avoids...
    pub fault_unavoidable: u32,
    /// ... and those where it does not put at fault the one car a reference driver in
    /// whose place avoids it (the other car could not).
    pub blameless_avoider: u32,
    /// The replays run for them, and the CPU time (s, this thread's) they took in all, and
    /// the most one collision's took.
    pub replays: u32,
    /// See `replays`.
    pub verdict_cpu: f64,
    /// See `replays`.
    pub verdict_cpu_max: f64,
    /// What happened worth reading, in time order: collisions, the first phantom braking
    /// and drift of each car.
    pub notes: Vec<String>,
}

/// A collision and the simulated time (s) it was found at.
pub type Timed = (f64, Collision);

/// An episode as it runs: the world, the learner's script and the collisions so far with
/// the time of each. Copied every control period for the replays.
#[derive(Debug, Clone)]
struct Sim {
    world: World,
    learner: VehicleId,
    script: Option<Adversary>,
    crashes: Vec<Timed>,
}

impl Sim {
    /// One control period: the script acts, `recorder` (if any) keeps the world with the
    /// script's command, then the world ticks; `sample` reads it after the period's first
    /// tick, when every driver's decision of the period is applied, with each car's
    /// command before it (what the period's decisions saw).
    fn period(
        &mut self,
        stepper: &mut Stepper,
        recorder: Option<&mut Recorder>,
        mut sample: impl FnMut(&World, &[f64]),
    ) {
        if let Some(script) = &mut self.script {
            script.act(&mut self.world, self.learner);
        }
        if let Some(recorder) = recorder {
            recorder.record(&self.world);
        }
        let decided_on: Vec<f64> = self.world.vehicles().iter().map(|v| v.command.accel).collect();
        for tick in 0..self.world.params().substeps_per_control() {
            let seen = self.world.collisions().len();
            stepper.tick(&mut self.world);
            let time = self.world.time();
            self.crashes.extend(self.world.collisions()[seen..].iter().map(|&c| (time, c)));
            if tick == 0 {
                sample(&self.world, &decided_on);
            }
        }
    }

    /// Whether vehicle `id` is in a collision after the first `seen`.
    fn crashed_since(&self, seen: usize, id: VehicleId) -> bool {
        self.crashes[seen..].iter().any(|(_, c)| c.other(id).is_some())
    }
}

/// One stepper for a run, deciding on one thread (the bits are the same on any number).
fn stepper() -> Stepper {
    let mut stepper = Stepper::new();
    stepper.set_decision_threads(1);
    stepper
}

/// What the sampling keeps of one gt car through an episode.
#[derive(Debug, Clone)]
struct Track {
    id: VehicleId,
    /// Its target lane at the last sample, and since when.
    target: LaneId,
    target_since: f64,
    /// Lane-change time since then: simulated time at the pace a lane change's path keeps
    /// (`FULL_PACE_SPEED`): a car stopped in a queue halfway across is still changing.
    paced_since_target: f64,
    /// The same clock since its centre last crossed into its target lane (finishing a
    /// change, or coming back from one given up past the line).
    paced_since_crossing: f64,
    /// The lane its centre was in at the last sample.
    here: Option<LaneId>,
    /// The lane change under way (from, to) until its centre crosses into `to`.
    change: Option<(LaneId, LaneId)>,
    /// Each lane change it began: when, and the lane it left.
    begun: Vec<(f64, LaneId)>,
    hard_braking: bool,
    phantom: bool,
    drift: bool,
    max_drift: f64,
    changes: u32,
    aborts: u32,
}

impl Track {
    fn new(world: &World, id: VehicleId) -> Track {
        Track {
            id,
            target: world.vehicle(id).target_lane,
            target_since: f64::NEG_INFINITY,
            paced_since_target: f64::INFINITY,
            paced_since_crossing: f64::INFINITY,
            here: None,
            change: None,
            begun: Vec::new(),
            hard_braking: false,
            phantom: false,
            drift: false,
            max_drift: 0.0,
            changes: 0,
            aborts: 0,
        }
    }

    fn sample(&mut self, world: &World, seen: &[f64], notes: &mut Vec<String>) {
        let vehicle = world.vehicle(self.id);
        if vehicle.status != Status::Driving {
            return;
        }
        let (road, time) = (world.road(), world.time());
        let here = road.lane_at(vehicle.state.s, vehicle.state.d);
        if vehicle.target_lane != self.target {
            match self.change {
                Some((from, _)) if vehicle.target_lane == from => {
                    self.aborts += 1;
                    self.change = None;
                }
                _ => {
                    let from = here.unwrap_or(self.target);
                    self.changes += 1;
                    self.change = Some((from, vehicle.target_lane));
                    self.begun.push((time, from));
                }
            }
            self.target = vehicle.target_lane;
            self.target_since = time;
            self.paced_since_target = 0.0;
        }
        if self.change.is_some_and(|(_, to)| here == Some(to)) {
            self.change = None;
        }
        if here == Some(self.target) && self.here.is_some_and(|before| before != self.target) {
            self.paced_since_crossing = 0.0;
        }
        self.here = here;
        let paced = world.params().control_dt * (vehicle.state.lane_speed() / FULL_PACE_SPEED).clamp(0.0, 1.0);
        self.paced_since_target += paced;
        self.paced_since_crossing += paced;
        let settled = self.paced_since_target >= LANE_CHANGE_DURATION - 1e-9
            && self.paced_since_crossing >= LANE_CHANGE_DURATION / 2.0 - 1e-9;
        if here == Some(self.target) && settled {
            let offset = (vehicle.state.d - road.lane_center(self.target)).abs();
            self.max_drift = self.max_drift.max(offset);
            if offset > DRIFT_BOUND && !self.drift {
                self.drift = true;
                notes.push(format!(
                    "t={time:5.2} {} drifts {offset:.2} m off lane {}'s centre",
                    world.name(self.id),
                    self.target.0
                ));
            }
        }
        if vehicle.command.accel < HARD_BRAKING - 1e-9 {
            self.hard_braking = true;
            if !self.phantom && !threatened(world, seen, self.id) {
                self.phantom = true;
                let nearest = in_path(world, seen, self.id).into_iter().min_by(|a, b| a.1.total_cmp(&b.1));
                let ahead = nearest.map_or("nothing ahead".to_string(), |(car, gap, closing, _)| {
                    let what = car.map_or("its lane's end", |car| world.name(car));
                    format!("nearest in its path {what}, {gap:.1} m ahead closing at {closing:.1} m/s")
                });
                let reason = match &vehicle.driver {
                    Driver::Gt(memory) => match memory.diagnostics.safety {
                        Some(o) => {
                            let other = world.vehicle(o.car);
                            format!(
                                "; the safety layer braked for {} at {:+.1} m, {:+.2} m across, {:.1} m/s, {:?}",
                                world.name(o.car),
                                other.state.s - vehicle.state.s,
                                other.state.d - vehicle.state.d,
                                other.state.lane_speed(),
                                other.status
                            )
                        }
                        None => format!("; no safety override, decided {:+.2}", memory.decision.accel),
                    },
                    _ => String::new(),
                };
                notes.push(format!(
                    "t={time:5.2} {} brakes at {:.2} m/s^2 at {:.1} m/s, nothing within {PHANTOM_TTC} s in its path \
                     ({ahead}{reason})",
                    world.name(self.id),
                    vehicle.command.accel,
                    vehicle.state.lane_speed()
                ));
            }
        }
    }

    /// The lane car `id` came from as of `time`: the one its last lane change begun by
    /// then left, if that began within a lane change and `CUT_IN_WINDOW` of it; else the
    /// lane it was in.
    fn origin(&self, world: &World, time: f64) -> LaneId {
        let recent =
            |&&(at, _): &&(f64, LaneId)| at <= time + 1e-9 && time - at <= LANE_CHANGE_DURATION + CUT_IN_WINDOW;
        match self.begun.iter().rev().find(|begun| begun.0 <= time + 1e-9) {
            Some(begun) if recent(&begun) => begun.1,
            _ => world.current_lane(self.id),
        }
    }
}

/// Whether something is in or entering gt car `id`'s path (the lane it is in and its
/// target lane) within `PHANTOM_TTC` of time to collision ahead of it, or level with it:
/// a car whose centre, target lane or body (straddling a lane line) is in the path, whose
/// body is within `PATH_MARGIN` beside the gt car's, or
/// that moves sideways towards the gt car faster than `DRIFT_SPEED` from within one and a
/// half lane widths of it; or the end of a lane of the path, as a stopped car. A car
/// ahead keeps the harder braking of its command now and `seen`'s (each car's command when
/// the period's decisions were taken).
pub fn threatened(world: &World, seen: &[f64], id: VehicleId) -> bool {
    in_path(world, seen, id)
        .iter()
        .any(|&(_, gap, closing, lead_accel)| time_to_collision(gap, closing, lead_accel) < PHANTOM_TTC)
}

/// When a gap of `gap` m closing at `closing` m/s closes if the car ahead keeps `lead_accel`
/// (m/s^2, until it stops) and the car behind its speed: infinite if it never does.
pub fn time_to_collision(gap: f64, closing: f64, lead_accel: f64) -> f64 {
    if gap <= 0.0 {
        return 0.0;
    }
    // gap(t) = gap - closing t + lead_accel t^2 / 2, while the car ahead moves.
    let (a, b, c) = (0.5 * lead_accel, -closing, gap);
    if a.abs() < 1e-12 {
        return if closing > 0.0 { gap / closing } else { f64::INFINITY };
    }
    let discriminant = b * b - 4.0 * a * c;
    if discriminant < 0.0 {
        return f64::INFINITY;
    }
    let root = discriminant.sqrt();
    [(-b - root) / (2.0 * a), (-b + root) / (2.0 * a)].into_iter().filter(|&t| t > 0.0).fold(f64::INFINITY, f64::min)
}

/// What is in or entering gt car `id`'s path ahead of it (see `threatened`): each car
/// (`None`: a lane's end) with its bumper gap (m) and closing speed (m/s).
fn in_path(world: &World, seen: &[f64], id: VehicleId) -> Vec<(Option<VehicleId>, f64, f64, f64)> {
    let (road, length) = (world.road(), world.vehicle_params().length);
    let me = world.vehicle(id);
    let (s, d, speed) = (me.state.s, me.state.d, me.state.lane_speed());
    let path = [road.lane_at(s, d).unwrap_or(me.target_lane), me.target_lane];
    let ends = path.iter().map(|&lane| (None, road.lane_end(lane) - s - length / 2.0, speed, 0.0));
    let cars = world.vehicles().iter().enumerate().filter_map(|(j, other)| {
        if j == id.0 as usize || !other.on_road() || other.state.s < s {
            return None;
        }
        let state = &other.state;
        let lane = road.lane_at(state.s, state.d).unwrap_or(other.target_lane);
        let lateral_speed = state.vx * state.heading.sin() + state.vy * state.heading.cos();
        let towards =
            lateral_speed * (d - state.d).signum() > DRIFT_SPEED && (d - state.d).abs() < 1.5 * road.lane_width();
        let reach = 0.5 * (road.lane_width() + world.vehicle_params().width);
        let body_in = path.iter().any(|&lane| (state.d - road.lane_center(lane)).abs() < reach);
        let beside = (state.d - d).abs() < world.vehicle_params().width + PATH_MARGIN;
        let entering = path.contains(&lane) || path.contains(&other.target_lane) || towards || body_in || beside;
        // Braking as it does now, or as it did when the gt car decided (an IDM car
        // alternating between -6 and +0.6 m/s^2 is braking half the time).
        let lead_accel = if state.lane_speed() > 0.0 { other.command.accel.min(seen[j]) } else { 0.0 };
        entering.then(|| (Some(VehicleId(j as u32)), state.s - s - length, speed - state.lane_speed(), lead_accel))
    });
    ends.chain(cars).collect()
}

/// One episode of `family` (its `scenario`, built once by the caller) from reset seed
/// `seed`, `SECONDS` long, measured at every control period; every collision with a gt car
/// at fault is replayed (`avoidable`).
pub fn run(family: &Family, scenario: &Scenario, seed: u64) -> Episode {
    let world = highway_gt::world(scenario, seed);
    let learner = world.find(LEARNER).expect("every stress family has a learner's car, ego_0");
    let script = match family.learner {
        Learner::Script(attack) => Some(Adversary::new(&world, learner, attack)),
        Learner::Idm => None,
    };
    let merger = family.merger.map(|name| world.find(name).unwrap_or_else(|| panic!("{}: no '{name}'", family.name)));
    let mut tracks: Vec<Track> = (0..world.vehicles().len() as u32)
        .map(VehicleId)
        .filter(|&id| is_gt(&world, id))
        .map(|id| Track::new(&world, id))
        .collect();
    let mut sim = Sim { world, learner, script, crashes: Vec::new() };
    let mut episode = Episode { seed, ..Episode::default() };
    let (mut ring, mut stepper, mut judged, mut merged) = (VecDeque::with_capacity(RING), stepper(), 0, false);
    let mut recorder = Recorder::new(sim.world.params().control_dt);
    while sim.world.time() < SECONDS - 1e-9 {
        if ring.len() == RING {
            ring.pop_front();
        }
        ring.push_back(sim.clone());
        let notes = &mut episode.notes;
        sim.period(&mut stepper, Some(&mut recorder), |world, seen| {
            tracks.iter_mut().for_each(|track| track.sample(world, seen, notes));
            merged |= merger.is_some_and(|id| in_through_lane(world, id));
        });
        while judged < sim.crashes.len() {
            let (time, collision) = sim.crashes[judged];
            judged += 1;
            episode.judge(&sim.world, &ring, &recorder, &tracks, time, collision);
        }
    }
    episode.count_endings(&sim.world);
    for track in &tracks {
        episode.hard_braking += u32::from(track.hard_braking);
        episode.phantom += u32::from(track.phantom);
        episode.drift += u32::from(track.drift);
        episode.max_drift = episode.max_drift.max(track.max_drift);
        episode.changes += track.changes;
        episode.aborts += track.aborts;
    }
    episode.attacks = sim.script.as_ref().map_or(0, |script| script.attacks);
    episode.merge = merger.map(|id| {
        let world = &sim.world;
        let game = world.gt_setup(id).expect("the merger is a gt car").game;
        let at_fault = sim.crashes.iter().any(|(_, c)| NEW_RULE.gt_at_fault(world, c).contains(&id));
        Merge { style: world.style(id), game, merged, at_fault, ending: world.ending(id) }
    });
    episode
}

/// Whether vehicle `id` drives with its centre in a lane that runs the road's length.
fn in_through_lane(world: &World, id: VehicleId) -> bool {
    let (vehicle, road) = (world.vehicle(id), world.road());
    vehicle.status == Status::Driving
        && road.lane_at(vehicle.state.s, vehicle.state.d).is_some_and(|lane| road.lane_end(lane) >= road.length())
}

impl Episode {
    /// Counts `collision`, found at `time`, and replays it for each gt car at fault.
    fn judge(
        &mut self,
        world: &World,
        ring: &VecDeque<Sim>,
        recorder: &Recorder,
        tracks: &[Track],
        time: f64,
        collision: Collision,
    ) {
        self.collisions += 1;
        let (rear, front) = (collision.rear, collision.front);
        self.involving_gt += u32::from(is_gt(world, rear) || is_gt(world, front));
        let at_fault = NEW_RULE.gt_at_fault(world, &collision);
        self.gt_at_fault_entry += u32::from(!ENTRY_RULE.gt_at_fault(world, &collision).is_empty());
        let mut verdict = String::new();
        if !at_fault.is_empty() {
            self.gt_at_fault += 1;
            let avoided = at_fault.iter().any(|&id| {
                let track = tracks.iter().find(|t| t.id == id).expect("every gt car is tracked");
                avoidable(ring, id, time, |world, start| track.origin(world, start))
            });
            self.avoidable += u32::from(avoided);
            verdict = if avoided { " [gt at fault, avoidable]".into() } else { " [gt at fault]".into() };
        }
        let who = |id: VehicleId| match world.gt_setup(id) {
            Some(setup) => format!("{} (gt {:?} {:?})", world.name(id), world.style(id), setup.game),
            None => world.name(id).to_string(),
        };
        let learner = world.find(LEARNER);
        let judged = is_gt(world, rear) || is_gt(world, front) || learner.is_some_and(|l| collision.other(l).is_some());
        if judged {
            let began = cpu_seconds();
            let counterfactual = arena_sim::verdict(recorder, &Crash { time, collision });
            let spent = cpu_seconds() - began;
            verdict += &self.count_verdict(&collision, &counterfactual, spent);
        }
        self.notes.push(format!(
            "t={time:5.2} {} into {}: {:?} at fault{verdict}",
            who(rear),
            who(front),
            (NEW_RULE.fault)(&collision)
        ));
    }

    /// Counts `counterfactual`, the verdict on `collision` that took `spent` CPU seconds,
    /// beside the responsibility rule's: what the note says of it.
    fn count_verdict(&mut self, collision: &Collision, counterfactual: &Verdict, spent: f64) -> String {
        self.verdicts += 1;
        self.replays += counterfactual.replays();
        self.verdict_cpu += spent;
        self.verdict_cpu_max = self.verdict_cpu_max.max(spent);
        let class = counterfactual.avoidability();
        match class {
            Avoidability::Rear => self.by_rear += 1,
            Avoidability::Front => self.by_front += 1,
            Avoidability::Both => self.by_both += 1,
            Avoidability::Neither => self.by_neither += 1,
        }
        let (disagreement, why) = disagreement(collision, counterfactual);
        match disagreement {
            Some(Disagreement::FaultUnavoidable) => self.fault_unavoidable += 1,
            Some(Disagreement::BlamelessAvoider) => self.blameless_avoider += 1,
            None => {}
        }
        format!(
            " [avoidable by {class:?}: rear {}, front {}; {} replays, {spent:.2} CPU s{}]",
            counterfactual.rear.describe(),
            counterfactual.front.describe(),
            counterfactual.replays(),
            why.map_or(String::new(), |why| format!("; disagrees with the rule: {why}"))
        )
    }

    fn count_endings(&mut self, world: &World) {
        for id in (0..world.vehicles().len() as u32).map(VehicleId) {
            let gt = u32::from(is_gt(world, id));
            match world.ending(id) {
                Some(Ending::LaneEnd) => (self.lane_end, self.lane_end_gt) = (self.lane_end + 1, self.lane_end_gt + gt),
                Some(Ending::OffRoad) => (self.off_road, self.off_road_gt) = (self.off_road + 1, self.off_road_gt + gt),
                _ => {}
            }
        }
    }
}

/// How a counterfactual verdict disagrees with the responsibility rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Disagreement {
    /// A car at fault that no reference driver in its place avoids.
    FaultUnavoidable,
    /// A car not at fault that alone could have avoided it (the car at fault could not).
    BlamelessAvoider,
}

/// How `verdict` disagrees with `collision`'s responsibility rule, if it does, and why.
pub fn disagreement(collision: &Collision, verdict: &Verdict) -> (Option<Disagreement>, Option<String>) {
    let parties = [(collision.rear, &verdict.rear, "rear"), (collision.front, &verdict.front, "front")];
    for (id, party, name) in parties {
        if collision.is_at_fault(id) && !party.avoidable() {
            return (
                Some(Disagreement::FaultUnavoidable),
                Some(format!("the {name} car is at fault, unavoidable for it")),
            );
        }
    }
    let only = match verdict.avoidability() {
        Avoidability::Rear => Some((collision.rear, "rear")),
        Avoidability::Front => Some((collision.front, "front")),
        _ => None,
    };
    match only {
        Some((id, name)) if !collision.is_at_fault(id) => (
            Some(Disagreement::BlamelessAvoider),
            Some(format!("the {name} car is not at fault, the only one that could avoid it")),
        ),
        _ => (None, None),
    }
}

/// CPU time this thread has used (s), from /proc/thread-self/stat (Linux; 10 ms ticks);
/// 0 elsewhere.
pub fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/thread-self/stat") else { return 0.0 };
    // The fields after the command's closing parenthesis: state is the 3rd, utime and
    // stime the 14th and 15th.
    let rest = stat.rsplit_once(')').map_or("", |(_, rest)| rest);
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| fields.get(i).and_then(|f| f.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

/// Whether gt car `id`, at fault in a collision at `time`, avoids it when the episode is
/// replayed from the copy in `ring` taken `REPLAY_LEAD` before (the earliest one if the
/// collision came sooner), everything closed loop (the script plays again), with the car
/// forced (`World::force`) to return to the lane it came from (`origin` of the copy's
/// world and time) and, separately, to brake at `REPLAY_BRAKING`: avoided if either
/// replay has no collision of the car until `REPLAY_HORIZON` after `time`.
fn avoidable(ring: &VecDeque<Sim>, id: VehicleId, time: f64, origin: impl Fn(&World, f64) -> LaneId) -> bool {
    let start = ring.iter().rev().find(|sim| sim.world.time() <= time - REPLAY_LEAD + 1e-9).unwrap_or(&ring[0]);
    let back = origin(&start.world, start.world.time());
    [Forced::ReturnToLane(back), Forced::Brake(REPLAY_BRAKING)].into_iter().any(|forced| {
        let mut sim = start.clone();
        let seen = sim.crashes.len();
        sim.world.force(id, forced);
        let mut stepper = stepper();
        while sim.world.time() < time + REPLAY_HORIZON - 1e-9 && !sim.crashed_since(seen, id) {
            sim.period(&mut stepper, None, |_, _| {});
        }
        !sim.crashed_since(seen, id)
    })
}

/// Replays `family`'s episode `seed` unforced from the copy taken `REPLAY_LEAD` before its
/// first collision, to `REPLAY_HORIZON` after it: the collisions of the replay with their
/// times, against the episode's. The two agree when copies replay exactly (`World` is
/// plain data, the stepper holds none, the script is cloned with the world).
pub fn replay_first_collision(family: &Family, scenario: &Scenario, seed: u64) -> Option<(Vec<Timed>, Vec<Timed>)> {
    let world = highway_gt::world(scenario, seed);
    let learner = world.find(LEARNER)?;
    let script = match family.learner {
        Learner::Script(attack) => Some(Adversary::new(&world, learner, attack)),
        Learner::Idm => None,
    };
    let mut sim = Sim { world, learner, script, crashes: Vec::new() };
    let (mut ring, mut stepper) = (VecDeque::with_capacity(RING), stepper());
    while sim.world.time() < SECONDS - 1e-9 && sim.crashes.is_empty() {
        if ring.len() == RING {
            ring.pop_front();
        }
        ring.push_back(sim.clone());
        sim.period(&mut stepper, None, |_, _| {});
    }
    let time = sim.crashes.first()?.0;
    let start: &Sim = ring.iter().rev().find(|s| s.world.time() <= time - REPLAY_LEAD + 1e-9).unwrap_or(&ring[0]);
    let (mut original, mut replay) = (sim, start.clone());
    for run in [&mut original, &mut replay] {
        let mut stepper = self::stepper();
        while run.world.time() < time + REPLAY_HORIZON - 1e-9 {
            run.period(&mut stepper, None, |_, _| {});
        }
    }
    Some((original.crashes, replay.crashes))
}

// The scripted learner.

/// The speed the script passes gt cars at (m/s): the adversarial road's limit.
const CRUISE: f64 = 30.0;
/// How the script brakes after cutting in (m/s^2), and for how long (s).
const ATTACK_BRAKING: f64 = -6.0;
const BRAKE_TIME: f64 = 2.0;
/// How the script accelerates into a gap (m/s^2; the issue saw 2-6), and for how long (s).
const CLOSING_ACCEL: f64 = 4.0;
const CLOSE_TIME: f64 = 4.0;
/// How long a cut-in's lateral path takes (s): faster than a lane change.
const CUT_IN_TIME: f64 = 3.0;
/// How long a drift's lateral path takes (s): slower than a lane change.
const DRIFT_TIME: f64 = 6.0;
/// How long the script drives calmly after an attack (s).
const REST: f64 = 6.0;
/// How near (m along the road) the gt car it seeks must be before it takes the lane the
/// attack needs; further off it takes the lane with the most room ahead.
const REACH: f64 = 60.0;

/// The learner's car driven by a script that pushes the gt cars (`Attack`), through the
/// world's API as a learner's continuous actions are: its target lane
/// (`World::set_target_lane`) and a direct command (`World::command_agent`): an
/// acceleration, and the preview point of its own lateral path. It follows traffic with
/// IDM, seeks a gt car to attack and attacks when it can. Plain data, copied with the
/// world, so a replay plays it again.
#[derive(Debug, Clone)]
pub struct Adversary {
    attack: Attack,
    /// The lane it keeps or is changing to, and its lateral path there.
    lane: LaneId,
    path: LateralPath,
    phase: Phase,
    /// The gt car it is getting into position on.
    mark: Option<VehicleId>,
    /// Attacks begun.
    attacks: u32,
    /// No attack before this time (s).
    rest_until: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    /// Getting into position on a gt car (`mark`), following traffic.
    Seek,
    /// Changing into a gt car's lane ahead of it, since `since` (s).
    CutIn { since: f64 },
    /// Braking after a cut-in.
    Brake { until: f64 },
    /// Drifting towards the lane `gt` is changing to, level with it.
    Drift { gt: VehicleId, until: f64 },
    /// Accelerating into the gap behind `gt`.
    Close { gt: VehicleId, until: f64 },
}

impl Adversary {
    /// Its script for the learner's car `id` of `world`, keeping its lane at first.
    pub fn new(world: &World, id: VehicleId, attack: Attack) -> Adversary {
        let lane = world.current_lane(id);
        let path = LateralPath::hold(world.road().lane_center(lane));
        Adversary { attack, lane, path, phase: Phase::Seek, mark: None, attacks: 0, rest_until: 0.0 }
    }

    /// Commands car `id` for the coming control period.
    pub fn act(&mut self, world: &mut World, id: VehicleId) {
        if world.vehicle(id).status != Status::Driving {
            return;
        }
        let time = world.time();
        self.phase = self.next_phase(world, id, time);
        let accel = self.accel(world, id);
        let preview = self.path.preview(time, world.driver_params(id).preview_time);
        world.set_target_lane(id, self.lane);
        world.command_agent(id, AgentCommand::Direct(Command { accel, preview }));
    }

    fn next_phase(&mut self, world: &World, id: VehicleId, time: f64) -> Phase {
        let gone = |gt: VehicleId| world.vehicle(gt).status != Status::Driving;
        match self.phase {
            Phase::Seek if time >= self.rest_until => match self.trigger(world, id, time) {
                Some(phase) => {
                    self.attacks += 1;
                    phase
                }
                None => {
                    self.position(world, id, time);
                    Phase::Seek
                }
            },
            Phase::Seek => {
                self.position(world, id, time);
                Phase::Seek
            }
            Phase::CutIn { since } if world.current_lane(id) == self.lane || time - since > CUT_IN_TIME => {
                Phase::Brake { until: time + BRAKE_TIME }
            }
            Phase::Brake { until } | Phase::Drift { until, .. } | Phase::Close { until, .. } if time >= until => {
                self.rest_until = time + REST;
                Phase::Seek
            }
            Phase::Drift { gt, .. } | Phase::Close { gt, .. } if gone(gt) => {
                self.rest_until = time + REST;
                Phase::Seek
            }
            phase => phase,
        }
    }

    /// The attack that can begin now, if one can, with its lateral path set.
    fn trigger(&mut self, world: &World, id: VehicleId, time: f64) -> Option<Phase> {
        let length = world.vehicle_params().length;
        let me = world.vehicle(id).state;
        let mine = world.current_lane(id);
        if mine != self.lane {
            return None;
        }
        let gt_cars = (0..world.vehicles().len() as u32)
            .map(VehicleId)
            .filter(|&g| is_gt(world, g) && world.vehicle(g).status == Status::Driving);
        let beside = |a: LaneId, b: LaneId| a.0.abs_diff(b.0) == 1;
        match self.attack {
            Attack::CutIn => {
                // Level or just ahead of a gt car keeping the lane beside, with room ahead.
                let target = gt_cars
                    .filter(|&g| {
                        let (car, lane) = (world.vehicle(g), world.current_lane(g));
                        let gap = me.s - car.state.s - length;
                        car.target_lane == lane
                            && beside(lane, mine)
                            && (3.0..25.0).contains(&gap)
                            && clear_ahead(world, id, lane, 10.0)
                    })
                    .min_by(|&a, &b| world.vehicle(b).state.s.total_cmp(&world.vehicle(a).state.s))?;
                self.steer(world, id, world.current_lane(target), CUT_IN_TIME);
                Some(Phase::CutIn { since: time })
            }
            Attack::Drift => {
                // A gt car level with it changing into the lane beside.
                let (gt, lane) = gt_cars
                    .filter_map(|g| {
                        let car = world.vehicle(g);
                        let changing = car.target_lane != world.current_lane(g);
                        let level = (car.state.s - me.s).abs() < 40.0;
                        (changing && level && beside(car.target_lane, mine)).then_some((g, car.target_lane))
                    })
                    .min_by(|a, b| {
                        let distance = |g: VehicleId| (world.vehicle(g).state.s - me.s).abs();
                        distance(a.0).total_cmp(&distance(b.0))
                    })?;
                self.steer(world, id, lane, DRIFT_TIME);
                Some(Phase::Drift { gt, until: time + DRIFT_TIME })
            }
            Attack::CloseGap => {
                // A gt car up to 60 m ahead that is changing into its lane or entered it
                // in the last 3 s.
                let gt = gt_cars
                    .filter(|&g| {
                        let car = world.vehicle(g);
                        let gap = car.state.s - me.s - length;
                        let entering = world.current_lane(g) != mine
                            || car.lane_entry.at.is_some_and(|at| car.lane_entry.lane == mine && time - at < 3.0);
                        car.target_lane == mine && entering && (3.0..60.0).contains(&gap)
                    })
                    .min_by(|&a, &b| world.vehicle(a).state.s.total_cmp(&world.vehicle(b).state.s))?;
                Some(Phase::Close { gt, until: time + CLOSE_TIME })
            }
        }
    }

    /// Picks the nearest gt car to attack and changes one lane towards where the attack
    /// needs it: beside that car's lane (cut in, close the gap) or two lanes off (drift),
    /// once it is within `REACH`; until then it changes to the lane beside with the most
    /// room ahead, to get through the traffic.
    fn position(&mut self, world: &World, id: VehicleId, time: f64) {
        let me = world.vehicle(id).state;
        let mine = world.current_lane(id);
        let offset = self.offset();
        self.mark = (0..world.vehicles().len() as u32)
            .map(VehicleId)
            .filter(|&g| is_gt(world, g) && world.vehicle(g).status == Status::Driving)
            .filter(|&g| (-100.0..200.0).contains(&(world.vehicle(g).state.s - me.s)))
            .min_by(|&a, &b| {
                let off = |g: VehicleId| (world.vehicle(g).state.s - me.s - offset).abs();
                off(a).total_cmp(&off(b))
            });
        if mine != self.lane || !self.path.finished(time) {
            return;
        }
        let lanes = world.road().lane_count() as i64;
        let here = i64::from(mine.0);
        let room = |lane: i64| room_ahead(world, id, LaneId(lane as u32));
        let roomiest = |lanes: Vec<i64>| {
            lanes.into_iter().max_by(|&a, &b| room(a).total_cmp(&room(b)).then(b.abs_diff(here).cmp(&a.abs_diff(here))))
        };
        let beside_mark = self.mark.filter(|&g| (world.vehicle(g).state.s - me.s).abs() < REACH).and_then(|mark| {
            let theirs = i64::from(world.current_lane(mark).0);
            let lanes_off = |apart: &[i64]| -> Vec<i64> {
                apart.iter().map(|k| theirs + k).filter(|lane| (0..lanes).contains(lane)).collect()
            };
            let mut candidates = if self.attack == Attack::Drift { lanes_off(&[2, -2]) } else { Vec::new() };
            if candidates.is_empty() {
                candidates = lanes_off(&[1, -1]);
            }
            roomiest(candidates)
        });
        // Blocked by a car close ahead, or with no gt car near: the lane beside with more room.
        let around = || {
            let best = roomiest([here - 1, here + 1].into_iter().filter(|lane| (0..lanes).contains(lane)).collect());
            best.filter(|&lane| room(lane) > room(here) + 20.0)
        };
        let wanted = match beside_mark {
            Some(lane) if lane != here => Some(lane),
            Some(_) if room(here) > 30.0 => None,
            _ => around(),
        };
        let Some(wanted) = wanted.filter(|&lane| lane != here) else { return };
        let next = LaneId((here + (wanted - here).signum()) as u32);
        if lane_free(world, id, next) {
            self.steer(world, id, next, LANE_CHANGE_DURATION);
        }
    }

    /// Where a gt car should be against it for its attack (m along the road, its centre
    /// from the script's car's): behind to cut in ahead of it, level to drift, ahead to
    /// close the gap behind it.
    fn offset(&self) -> f64 {
        match self.attack {
            Attack::CutIn => -17.0,
            Attack::Drift => 0.0,
            Attack::CloseGap => 35.0,
        }
    }

    /// The acceleration of the coming period.
    fn accel(&self, world: &World, id: VehicleId) -> f64 {
        let me = world.vehicle(id).state;
        // Where to be along the road against a gt car: ahead to cut in, level to drift,
        // behind to close a gap.
        let hover = |gt: VehicleId, ahead: f64| {
            let car = world.vehicle(gt).state;
            car.lane_speed() + (0.4 * (ahead - (me.s - car.s))).clamp(-4.0, 6.0)
        };
        let lanes = [world.current_lane(id), self.lane];
        match self.phase {
            Phase::Seek => {
                let speed = self.mark.map_or(CRUISE, |gt| hover(gt, -self.offset()));
                follow(world, id, lanes, speed.min(CRUISE))
            }
            Phase::CutIn { .. } => follow(world, id, lanes, me.lane_speed()),
            Phase::Brake { .. } => ATTACK_BRAKING,
            Phase::Drift { gt, .. } => follow(world, id, lanes, hover(gt, 0.0).min(CRUISE)),
            Phase::Close { .. } => CLOSING_ACCEL,
        }
    }

    /// A lateral path from where the car is to `lane`'s centre over `duration`.
    fn steer(&mut self, world: &World, id: VehicleId, lane: LaneId, duration: f64) {
        let from = world.vehicle(id).state.d;
        self.lane = lane;
        self.path = LateralPath { from, to: world.road().lane_center(lane), start: world.time(), duration };
    }
}

/// Whether no car of `lane` (by position or target) is within `room` m (bumper to bumper)
/// ahead of car `id`, or level with it.
fn clear_ahead(world: &World, id: VehicleId, lane: LaneId, room: f64) -> bool {
    let (me, length) = (world.vehicle(id).state, world.vehicle_params().length);
    !world.vehicles().iter().enumerate().any(|(j, other)| {
        let in_lane = world.road().lane_at(other.state.s, other.state.d) == Some(lane) || other.target_lane == lane;
        let gap = other.state.s - me.s;
        j != id.0 as usize && other.on_road() && in_lane && gap > -length && gap < length + room
    })
}

/// How far ahead of car `id` (m, centre to centre) the nearest car of `lane` is (by
/// position or target); infinite on a free lane.
fn room_ahead(world: &World, id: VehicleId, lane: LaneId) -> f64 {
    let me = world.vehicle(id).state;
    world
        .vehicles()
        .iter()
        .enumerate()
        .filter(|&(j, other)| j != id.0 as usize && other.on_road() && other.state.s > me.s)
        .filter(|(_, other)| {
            world.road().lane_at(other.state.s, other.state.d) == Some(lane) || other.target_lane == lane
        })
        .map(|(_, other)| other.state.s - me.s)
        .fold(f64::INFINITY, f64::min)
}

/// Whether car `id` can change into `lane`: nobody there within 12 m ahead, nor behind
/// within 15 m plus 2 s of its closing speed.
fn lane_free(world: &World, id: VehicleId, lane: LaneId) -> bool {
    let me = world.vehicle(id).state;
    !world.vehicles().iter().enumerate().any(|(j, other)| {
        let in_lane = world.road().lane_at(other.state.s, other.state.d) == Some(lane) || other.target_lane == lane;
        let gap = other.state.s - me.s;
        let behind = 15.0 + 2.0 * (other.state.lane_speed() - me.lane_speed()).max(0.0);
        j != id.0 as usize && other.on_road() && in_lane && gap > -behind && gap < 12.0
    })
}

/// IDM's acceleration (the world's constants) for car `id` aiming at `speed`, behind the
/// nearest car ahead in any of `lanes` (by position or target).
fn follow(world: &World, id: VehicleId, lanes: [LaneId; 2], speed: f64) -> f64 {
    let (idm, length) = (world.idm(), world.vehicle_params().length);
    let me = world.vehicle(id).state;
    let v = me.lane_speed();
    let leader = world
        .vehicles()
        .iter()
        .enumerate()
        .filter(|&(j, other)| j != id.0 as usize && other.on_road() && other.state.s > me.s)
        .filter(|(_, other)| {
            let lane = world.road().lane_at(other.state.s, other.state.d).unwrap_or(other.target_lane);
            lanes.contains(&lane) || lanes.contains(&other.target_lane)
        })
        .min_by(|a, b| a.1.state.s.total_cmp(&b.1.state.s));
    let free = 1.0 - (v.max(0.0) / speed.max(1.0)).powf(idm.exponent);
    let interaction = leader.map_or(0.0, |(_, other)| {
        let gap = (other.state.s - me.s).max(1e-3);
        let approach = v - other.state.lane_speed();
        let desired = idm.jam_distance(length)
            + v * idm.time_headway
            + v * approach / (2.0 * (idm.max_accel * idm.comfortable_decel).sqrt());
        (desired.max(0.0) / gap).powi(2)
    });
    (idm.max_accel * (free - interaction)).clamp(-idm.accel_limit, idm.accel_limit)
}

// The table.

/// A family's episodes added up.
#[derive(Debug, Clone, Default)]
pub struct Summary {
    /// Episodes run.
    pub episodes: u32,
    /// The sums of `Episode`'s counts.
    pub total: Episode,
    /// Each merge, on an on-ramp.
    pub merges: Vec<Merge>,
}

impl Summary {
    /// Adds `episode`.
    pub fn add(&mut self, episode: &Episode) {
        let t = &mut self.total;
        self.episodes += 1;
        t.collisions += episode.collisions;
        t.involving_gt += episode.involving_gt;
        t.gt_at_fault += episode.gt_at_fault;
        t.gt_at_fault_entry += episode.gt_at_fault_entry;
        t.avoidable += episode.avoidable;
        t.lane_end += episode.lane_end;
        t.lane_end_gt += episode.lane_end_gt;
        t.off_road += episode.off_road;
        t.off_road_gt += episode.off_road_gt;
        t.hard_braking += episode.hard_braking;
        t.phantom += episode.phantom;
        t.drift += episode.drift;
        t.max_drift = t.max_drift.max(episode.max_drift);
        t.changes += episode.changes;
        t.aborts += episode.aborts;
        t.attacks += episode.attacks;
        t.verdicts += episode.verdicts;
        t.by_rear += episode.by_rear;
        t.by_front += episode.by_front;
        t.by_both += episode.by_both;
        t.by_neither += episode.by_neither;
        t.fault_unavoidable += episode.fault_unavoidable;
        t.blameless_avoider += episode.blameless_avoider;
        t.replays += episode.replays;
        t.verdict_cpu += episode.verdict_cpu;
        t.verdict_cpu_max = t.verdict_cpu_max.max(episode.verdict_cpu_max);
        self.merges.extend(episode.merge);
    }
}

/// The table's header (markdown), its columns those of `row`.
pub fn header() -> String {
    let entry = format!("gt at fault, old rule (`{}`)", ENTRY_RULE.field);
    let columns = [
        "family",
        "veh/km/lane",
        "episodes",
        "world collisions",
        "involving gt",
        &format!("gt at fault (`{}`)", NEW_RULE.field),
        &entry,
        "gt at fault, avoidable",
        "lane end (all / gt)",
        "off road (all / gt)",
        "gt braking < -6 m/s² (car-episodes)",
        "of those phantom",
        "gt drift > 0.5 m (car-episodes; max m)",
        "gt changes aborted / begun",
        "merged",
        "attacks",
        "judged (gt or learner in it)",
        "avoidable by rear / front / both / neither",
        "rule vs verdict: at fault, unavoidable / not at fault, only avoider",
        "replays",
        "CPU s per judged collision (mean; max)",
    ];
    let rule = vec!["---"; columns.len()];
    format!("| {} |\n|{}|", columns.join(" | "), rule.join("|"))
}

/// `family`'s row of the table.
pub fn row(family: &Family, density: f64, summary: &Summary) -> String {
    let t = &summary.total;
    let merged = if family.merger.is_some() {
        let n = summary.merges.iter().filter(|m| m.merged).count();
        format!("{n}/{} ({:.0} %)", summary.merges.len(), percent(n, summary.merges.len()))
    } else {
        "–".to_string()
    };
    let attacks = if family.is_adversarial() { t.attacks.to_string() } else { "–".to_string() };
    let cells = [
        family.name.to_string(),
        format!("{density:.1}"),
        summary.episodes.to_string(),
        t.collisions.to_string(),
        t.involving_gt.to_string(),
        t.gt_at_fault.to_string(),
        t.gt_at_fault_entry.to_string(),
        t.avoidable.to_string(),
        format!("{} / {}", t.lane_end, t.lane_end_gt),
        format!("{} / {}", t.off_road, t.off_road_gt),
        t.hard_braking.to_string(),
        t.phantom.to_string(),
        format!("{}; {:.2}", t.drift, t.max_drift),
        format!("{} / {}", t.aborts, t.changes),
        merged,
        attacks,
        t.verdicts.to_string(),
        format!("{} / {} / {} / {}", t.by_rear, t.by_front, t.by_both, t.by_neither),
        format!("{} / {}", t.fault_unavoidable, t.blameless_avoider),
        t.replays.to_string(),
        if t.verdicts == 0 {
            "–".to_string()
        } else {
            format!("{:.2}; {:.2}", t.verdict_cpu / f64::from(t.verdicts), t.verdict_cpu_max)
        },
    ];
    format!("| {} |", cells.join(" | "))
}

fn percent(n: usize, of: usize) -> f64 {
    100.0 * n as f64 / of.max(1) as f64
}

/// The merges of the on-ramp families by the merging car's style and game (markdown).
pub fn merge_table(summaries: &[(&Family, Summary)]) -> Option<String> {
    let on_ramps: Vec<_> = summaries.iter().filter(|(f, _)| f.merger.is_some()).collect();
    if on_ramps.is_empty() {
        return None;
    }
    let mut out = String::from(
        "| family | style | game | episodes | merged | merging car at fault | past the ramp's end / off road |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for (family, summary) in on_ramps {
        for style in [Style::Aggressive, Style::Normal, Style::Conservative] {
            for game in [Game::Nash, Game::Stackelberg] {
                let cell: Vec<&Merge> = summary.merges.iter().filter(|m| m.style == style && m.game == game).collect();
                let count = |f: fn(&Merge) -> bool| cell.iter().filter(|m| f(m)).count();
                let merged = count(|m| m.merged);
                out += &format!(
                    "| {} | {} | {} | {} | {merged} ({:.0} %) | {} | {} / {} |\n",
                    family.name,
                    lower(style),
                    lower(game),
                    cell.len(),
                    percent(merged, cell.len()),
                    count(|m| m.at_fault),
                    count(|m| m.ending == Some(Ending::LaneEnd)),
                    count(|m| m.ending == Some(Ending::OffRoad)),
                );
            }
        }
    }
    Some(out)
}

fn lower(value: impl std::fmt::Debug) -> String {
    format!("{value:?}").to_lowercase()
}

/// The CSV's header; `csv_row` writes one episode under it.
pub const CSV_HEADER: &str = "family,seed,collisions,involving_gt,gt_at_fault,gt_at_fault_entry_rule,\
     gt_at_fault_avoidable,lane_end,lane_end_gt,off_road,off_road_gt,gt_hard_braking,gt_phantom_braking,gt_drift,\
     gt_max_drift_m,gt_lane_changes,gt_aborted_changes,attacks,merger_style,merger_game,merged,merger_at_fault,\
     merger_ending,judged,avoidable_by_rear,avoidable_by_front,avoidable_by_both,avoidable_by_neither,\
     at_fault_unavoidable,not_at_fault_only_avoider,replays,verdict_cpu_s,verdict_cpu_max_s";

/// `episode` of `family` as a line of the CSV (no newline).
pub fn csv_row(family: &Family, e: &Episode) -> String {
    let merge = match e.merge {
        Some(m) => format!(
            "{},{},{},{},{}",
            lower(m.style),
            lower(m.game),
            u8::from(m.merged),
            u8::from(m.at_fault),
            m.ending.map_or(String::new(), lower)
        ),
        None => ",,,,".to_string(),
    };
    format!(
        "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:.3},{},{},{},{merge},{},{},{},{},{},{},{},{},{:.3},{:.3}",
        family.name,
        e.seed,
        e.collisions,
        e.involving_gt,
        e.gt_at_fault,
        e.gt_at_fault_entry,
        e.avoidable,
        e.lane_end,
        e.lane_end_gt,
        e.off_road,
        e.off_road_gt,
        e.hard_braking,
        e.phantom,
        e.drift,
        e.max_drift,
        e.changes,
        e.aborts,
        e.attacks,
        e.verdicts,
        e.by_rear,
        e.by_front,
        e.by_both,
        e.by_neither,
        e.fault_unavoidable,
        e.blameless_avoider,
        e.replays,
        e.verdict_cpu,
        e.verdict_cpu_max,
    )
}
