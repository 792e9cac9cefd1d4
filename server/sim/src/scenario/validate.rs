//! The file as written (`file`) checked into a `Scenario`: timing, road, vehicles (on
//! the road, named once, not overlapping), traffic, reward, goal. Each refusal says which
//! key or vehicle is wrong and why; what passes here builds a world without a panic.

use std::collections::{HashMap, HashSet};

use super::bounds::{MAX_ROAD_EXTENT, MAX_SPEED};
use super::file::{
    DriverFile, GoalFile, GtTrafficFile, OriginFile, RewardFile, RoadFile, ScenarioFile, TrafficFile, VehicleFile,
};
use super::vary::validate_vary;
use super::{DriverSpec, Goal, GtTraffic, RewardSpec, Scenario, ScenarioErrorKind, TrafficSpec, VehicleSpec};
use crate::dynamics::VehicleParams;
use crate::gt::GtParams;
use crate::road::{LaneId, Pose, Road, Section};
use crate::world::WorldParams;

impl ScenarioFile {
    pub(super) fn validate(self) -> Result<Scenario, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        let sim = &self.sim;
        for (key, value) in
            [("sim.physics_dt", sim.physics_dt), ("sim.control_dt", sim.control_dt), ("sim.step_dt", sim.step_dt)]
        {
            if !(value.is_finite() && value > 0.0) {
                return Err(invalid(key, format!("must be a positive number of seconds, not {value}")));
            }
        }
        if sim.control_dt < sim.physics_dt || sim.step_dt < sim.physics_dt {
            return Err(invalid("sim.physics_dt", "must not exceed control_dt and step_dt".into()));
        }
        self.check_bounds()?;
        // The world ticks round(period / physics_dt) times per period: a step that does not
        // divide it would silently stretch the control period (0.04 s makes 0.12 s of 0.1 s).
        for (key, period) in [("sim.control_dt", sim.control_dt), ("sim.step_dt", sim.step_dt)] {
            let ticks = period / sim.physics_dt;
            if (ticks - ticks.round()).abs() > 1e-6 * ticks {
                let message = format!("must be a whole number of physics steps ({} s), not {ticks:.3}", sim.physics_dt);
                return Err(invalid(key, message));
            }
        }
        if sim.max_cycles == 0 {
            return Err(invalid("sim.max_cycles", "must be at least 1".into()));
        }
        let road = self.road.validate()?;
        let vehicles = self.vehicles.iter().map(|v| v.validate(&road)).collect::<Result<Vec<_>, _>>()?;
        check_names_and_overlaps(&vehicles, &road)?;
        let traffic = self.traffic.map(|t| t.validate(&road, &vehicles)).transpose()?;
        let goal = self.goal.validate(&road, &vehicles)?;
        let reward = self.reward.validate(sim.max_cycles, &goal)?;
        let vary = validate_vary(&self.vary)?;
        Ok(Scenario {
            name: self.name,
            description: self.description,
            road,
            world: WorldParams { physics_dt: sim.physics_dt, control_dt: sim.control_dt },
            step_dt: sim.step_dt,
            max_cycles: sim.max_cycles,
            vehicles,
            traffic,
            reward,
            goal,
            vary,
            source: Default::default(),
        })
    }
}

impl RewardFile {
    fn validate(&self, max_cycles: u32, goal: &Goal) -> Result<RewardSpec, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        if !(self.cost_scale.is_finite() && self.cost_scale > 0.0) {
            return Err(invalid("reward.cost_scale", format!("must be a positive number, not {}", self.cost_scale)));
        }
        if let Some(crash) = self.crash.filter(|c| !(c.is_finite() && *c < 0.0)) {
            return Err(invalid("reward.crash", format!("must be a negative number, not {crash}")));
        }
        if !(self.risk_weight.is_finite() && self.risk_weight >= 0.0) {
            return Err(invalid("reward.risk_weight", format!("must be 0 or more, not {}", self.risk_weight)));
        }
        if !(self.goal_bonus.is_finite() && self.goal_bonus >= 0.0) {
            return Err(invalid("reward.goal_bonus", format!("must be 0 or more, not {}", self.goal_bonus)));
        }
        let spec = RewardSpec {
            cost_scale: self.cost_scale,
            risk_weight: self.risk_weight,
            // A scenario without a goal (the highways) has nothing to pay it for, and its
            // crash reward stays -(1 + risk_weight) x max_cycles.
            goal_bonus: if goal.lanes.is_empty() && goal.ahead_of.is_empty() { 0.0 } else { self.goal_bonus },
            crash: self.crash,
            failure: self.failure,
        };
        // A failure at the time limit is no worse than a crash: a crash stays the worst.
        let crash = spec.crash_reward(max_cycles);
        if let Some(failure) = self.failure.filter(|f| !(f.is_finite() && *f <= 0.0 && *f >= crash)) {
            return Err(invalid(
                "reward.failure",
                format!("must be between the crash reward ({crash}) and 0, not {failure}"),
            ));
        }
        Ok(spec)
    }
}

impl GoalFile {
    fn validate(&self, road: &Road, vehicles: &[VehicleSpec]) -> Result<Goal, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        let mut lanes = Vec::with_capacity(self.lanes.len());
        for &lane in &self.lanes {
            if !road.has_lane(lane) {
                return Err(invalid(
                    "goal.lanes",
                    format!("lists lane {lane}, but the road's lanes are 0..={}", road.lane_count() - 1),
                ));
            }
            if lanes.contains(&LaneId(lane as u32)) {
                return Err(invalid("goal.lanes", format!("lists lane {lane} twice; list each lane once")));
            }
            lanes.push(LaneId(lane as u32));
        }
        // Each name once, and a set to look them up in: the list can be as long as the file.
        let names: HashSet<&str> = vehicles.iter().map(|v| v.name.as_str()).collect();
        let mut listed = HashSet::with_capacity(self.ahead_of.len());
        for name in &self.ahead_of {
            if !names.contains(name.as_str()) {
                return Err(invalid("goal.ahead_of", format!("names '{name}', which is no [[vehicle]] of the file")));
            }
            if !listed.insert(name.as_str()) {
                return Err(invalid("goal.ahead_of", format!("names '{name}' twice; name each vehicle once")));
            }
        }
        Ok(Goal { lanes, ahead_of: self.ahead_of.clone(), fail_at_time_limit: self.fail_at_time_limit })
    }
}

impl RoadFile {
    fn validate(&self) -> Result<Road, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        if !(1..=64).contains(&self.lanes) {
            return Err(invalid("road.lanes", format!("must be between 1 and 64, not {}", self.lanes)));
        }
        if !(self.lane_width.is_finite() && self.lane_width > 0.0) {
            return Err(invalid("road.lane_width", format!("must be positive, not {}", self.lane_width)));
        }
        if self.speed_limits.len() != self.lanes as usize {
            return Err(invalid(
                "road.speed_limits",
                format!("has {} entries but the road has {} lanes", self.speed_limits.len(), self.lanes),
            ));
        }
        if let Some(bad) = self.speed_limits.iter().find(|v| !(v.is_finite() && **v > 0.0 && **v <= MAX_SPEED)) {
            return Err(invalid(
                "road.speed_limits",
                format!("must be positive speeds in m/s of at most {MAX_SPEED} (MAX_SPEED), not {bad}"),
            ));
        }
        if self.sections.is_empty() {
            return Err(invalid("road.sections", "needs at least one section".into()));
        }
        let mut sections = Vec::with_capacity(self.sections.len());
        for (i, section) in self.sections.iter().enumerate() {
            if !(section.length.is_finite() && section.length > 0.0) {
                return Err(invalid(
                    &format!("road.sections[{i}].length"),
                    format!("must be positive, not {}", section.length),
                ));
            }
            sections.push(match section.radius {
                None => Section::Straight { length: section.length },
                Some(radius) if radius.is_finite() && radius.abs() > self.lane_width * self.lanes as f64 => {
                    Section::Arc { length: section.length, curvature: 1.0 / radius }
                }
                Some(radius) => {
                    return Err(invalid(
                        &format!("road.sections[{i}].radius"),
                        format!("{radius} m is tighter than the road is wide; lanes would fold over"),
                    ));
                }
            });
        }
        let length: f64 = sections.iter().map(Section::length).sum();
        let mut ends = Vec::new();
        for (i, end) in self.lane_ends.iter().enumerate() {
            if !(0..self.lanes).contains(&end.lane) {
                return Err(invalid(
                    &format!("road.lane_ends[{i}].lane"),
                    format!("{} does not exist (lanes 0..={})", end.lane, self.lanes - 1),
                ));
            }
            if !(end.s.is_finite() && end.s > 0.0 && end.s <= length) {
                return Err(invalid(
                    &format!("road.lane_ends[{i}].s"),
                    format!("{} is not on the road (0..{length})", end.s),
                ));
            }
            ends.push((LaneId(end.lane as u32), end.s));
        }
        let origin = self.origin()?;
        let width = self.lane_width * self.lanes as f64;
        for (key, extent) in [("road.sections", length), ("road.lane_width", width)] {
            if extent > MAX_ROAD_EXTENT {
                return Err(invalid(
                    key,
                    format!(
                        "makes the road {extent} m {}, more than the {MAX_ROAD_EXTENT} m a road may reach \
                         (MAX_ROAD_EXTENT); make it smaller",
                        if key == "road.sections" { "long" } else { "wide" }
                    ),
                ));
            }
        }
        Ok(Road::new(origin, sections, self.lane_width, self.speed_limits.clone(), &ends))
    }
}

impl RoadFile {
    /// Where the road starts: finite, and within `MAX_ROAD_EXTENT` of (0, 0).
    fn origin(&self) -> Result<Pose, ScenarioErrorKind> {
        let OriginFile { x, y, heading } = self.origin;
        for (key, value) in [("road.origin.x", x), ("road.origin.y", y)] {
            if !(value.is_finite() && value.abs() <= MAX_ROAD_EXTENT) {
                return Err(ScenarioErrorKind::Invalid {
                    key: key.to_string(),
                    message: format!(
                        "must be a number of metres within ±{MAX_ROAD_EXTENT} (MAX_ROAD_EXTENT), not {value}; \
                         place the road nearer (0, 0)"
                    ),
                });
            }
        }
        if !heading.is_finite() {
            return Err(ScenarioErrorKind::Invalid {
                key: "road.origin.heading".to_string(),
                message: format!("must be a number of radians, not {heading}"),
            });
        }
        Ok(Pose { x, y, heading })
    }
}

impl VehicleFile {
    fn validate(&self, road: &Road) -> Result<VehicleSpec, ScenarioErrorKind> {
        let vehicle = self.name.clone();
        let invalid = |field: &str, message: String| ScenarioErrorKind::Invalid {
            key: format!("vehicle '{}'.{field}", self.name),
            message,
        };
        if self.name.is_empty() || self.name.contains(|c: char| c.is_whitespace() || c == '/') {
            return Err(invalid("name", "must be non-empty, without spaces or '/'".into()));
        }
        if !(self.speed.is_finite() && (0.0..=MAX_SPEED).contains(&self.speed)) {
            return Err(invalid(
                "speed",
                format!("must be a speed in m/s from 0 to {MAX_SPEED} (MAX_SPEED), not {}", self.speed),
            ));
        }
        let target_speed = self.target_speed.unwrap_or(self.speed);
        if !(target_speed.is_finite() && target_speed > 0.0 && target_speed <= MAX_SPEED) {
            return Err(invalid(
                "target_speed",
                format!("must be positive and at most {MAX_SPEED} m/s (MAX_SPEED), not {target_speed}"),
            ));
        }
        let (s, d, lane) = match (self.lane, self.s, self.x, self.y) {
            (Some(lane), Some(s), None, None) => {
                if !road.has_lane(lane) {
                    return Err(ScenarioErrorKind::UnknownLane { vehicle, lane, lanes: road.lane_count() });
                }
                let lane = LaneId(lane as u32);
                (s, road.lane_center(lane), lane)
            }
            (None, None, Some(x), Some(y)) => {
                // The road's nearest point to NaN is its start: refuse it rather than place the car there.
                for (field, value) in [("x", x), ("y", y)] {
                    if !value.is_finite() {
                        return Err(invalid(field, format!("must be a number of metres, not {value}")));
                    }
                }
                let (s, d) = road.to_frenet(x, y);
                let lane = road.lane_at(s, d).ok_or_else(|| ScenarioErrorKind::OffRoad {
                    vehicle: vehicle.clone(),
                    detail: format!("({x}, {y}) is {d:.2} m from the reference line, outside every lane"),
                })?;
                (s, d, lane)
            }
            _ => return Err(invalid("position", "give either `lane` and `s`, or `x` and `y`".into())),
        };
        if !s.is_finite() || s < 0.0 || s > road.lane_end(lane) {
            return Err(ScenarioErrorKind::OffRoad {
                vehicle,
                detail: format!("s = {s} is outside lane {} (0..={})", lane.0, road.lane_end(lane)),
            });
        }
        let (style, driver) = match &self.driver {
            DriverFile::Agent { style, action } => (*style, DriverSpec::Agent(*action)),
            DriverFile::Idm { style } => (*style, DriverSpec::Idm),
            DriverFile::Gt { style, game, role, follower_tolerance, params } => {
                let mut constants = match params {
                    // Built-in names only: a scenario may come from a client, and must not
                    // make the server read its files.
                    Some(name) => {
                        let hint =
                            "(a scenario names built-in presets only; a preset file is for `arena paper --params`)";
                        crate::preset::Preset::builtin(name, hint)
                            .map_err(|e| invalid("driver.params", e.to_string()))?
                            .gt
                    }
                    None => GtParams::default(),
                };
                if let Some(tolerance) = *follower_tolerance {
                    if !(tolerance.is_finite() && tolerance >= 0.0) {
                        return Err(invalid(
                            "driver.follower_tolerance",
                            format!("must be a number >= 0, not {tolerance}"),
                        ));
                    }
                    constants.decision.game.follower_tolerance = tolerance;
                }
                (*style, DriverSpec::Gt { game: *game, role: *role, params: constants })
            }
        };
        Ok(VehicleSpec { name: self.name.clone(), lane, s, d, speed: self.speed, target_speed, style, driver })
    }
}

fn check_names_and_overlaps(vehicles: &[VehicleSpec], road: &Road) -> Result<(), ScenarioErrorKind> {
    let mut names = HashSet::with_capacity(vehicles.len());
    if let Some(twice) = vehicles.iter().find(|v| !names.insert(v.name.as_str())) {
        return Err(ScenarioErrorKind::DuplicateName(twice.name.clone()));
    }
    let poses: Vec<_> = vehicles
        .iter()
        .map(|v| {
            let pose = road.to_global(v.s, v.d, 0.0);
            (pose.x, pose.y, pose.heading)
        })
        .collect();
    match first_overlap(&poses, &VehicleParams::default()) {
        Some((i, j)) => {
            Err(ScenarioErrorKind::Overlap { first: vehicles[i].name.clone(), second: vehicles[j].name.clone() })
        }
        None => Ok(()),
    }
}

/// Two bodies (x, y, heading) that overlap, the first such pair (i < j) in order, in
/// about n log n time. Why none is missed: two overlapping boxes have centres at most
/// their two half-diagonals apart, so in a grid of cells a little wider than that, they
/// lie in the same or neighbouring cells; this holds in the global frame whatever the
/// road does (arcs, lanes' offsets, a road that crosses itself), where a window along s
/// would have to bound how far an arc brings distant s together. Each car is compared
/// with the cars of its 3 x 3 cells: the same pairs as every pair, less those too far
/// apart to touch, so the same first pair. Why it is fast: cars that do not overlap pack
/// at most `crowd` to a cell (their area fits in the cell widened by a half-diagonal on
/// every side); a cell holding more holds an overlapping pair among any `crowd` + 1 of
/// its cars, found among those (the pair may then differ from the first in order).
pub(super) fn first_overlap(poses: &[(f64, f64, f64)], body: &VehicleParams) -> Option<(usize, usize)> {
    let half = (body.length / 2.0, body.width / 2.0);
    // Metres to spare over the reach: coordinates stay within MAX_ROAD_EXTENT, where a
    // rounding is nanometres.
    let cell = 2.0 * half.0.hypot(half.1) + 0.1;
    let crowd = ((2.0 * cell).powi(2) / (body.length * body.width)) as usize;
    let key = |&(x, y, _): &(f64, f64, f64)| ((x / cell).floor() as i64, (y / cell).floor() as i64);
    let mut cells: HashMap<(i64, i64), Vec<usize>> = HashMap::with_capacity(poses.len());
    for (i, pose) in poses.iter().enumerate() {
        cells.entry(key(pose)).or_default().push(i);
    }
    let overlap = |i: usize, j: usize| crate::world::oriented_boxes_overlap(poses[i], poses[j], half);
    let first_among = |cars: &[usize]| {
        cars.iter().enumerate().find_map(|(k, &i)| cars[k + 1..].iter().find(|&&j| overlap(i, j)).map(|&j| (i, j)))
    };
    // Visited in a fixed order, so the same file names the same pair every time.
    let mut crowded: Vec<&Vec<usize>> = cells.values().filter(|cars| cars.len() > crowd).collect();
    crowded.sort_unstable();
    for cars in crowded {
        // The packing bound says the first crowd + 1 hold a pair; all of them if rounding
        // ever says otherwise.
        if let Some(pair) = first_among(&cars[..=crowd]).or_else(|| first_among(cars)) {
            return Some(pair);
        }
    }
    poses.iter().enumerate().find_map(|(i, pose)| {
        let (cx, cy) = key(pose);
        let near = (-1..=1).flat_map(|dx| (-1..=1).map(move |dy| (cx.saturating_add(dx), cy.saturating_add(dy))));
        let later = near.filter_map(|c| cells.get(&c)).flatten().filter(|&&j| j > i && overlap(i, j));
        later.min().map(|&j| (i, j))
    })
}

impl TrafficFile {
    fn validate(self, road: &Road, vehicles: &[VehicleSpec]) -> Result<TrafficSpec, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        if !(self.density.is_finite() && self.density > 0.0) {
            return Err(invalid("traffic.density", format!("must be positive, not {}", self.density)));
        }
        let [low, high] = self.speed;
        if !(low.is_finite() && high.is_finite() && 0.0 < low && low <= high && high <= MAX_SPEED) {
            return Err(invalid(
                "traffic.speed",
                format!("must be [low, high] with 0 < low <= high <= {MAX_SPEED} (MAX_SPEED), not [{low}, {high}]"),
            ));
        }
        let lanes = self.lanes.unwrap_or_else(|| (0..road.lane_count() as i64).collect());
        if lanes.is_empty() {
            return Err(invalid("traffic.lanes", "must name at least one lane".into()));
        }
        if let Some(&lane) = lanes.iter().find(|&&l| !road.has_lane(l)) {
            return Err(invalid(
                "traffic.lanes",
                format!("lane {lane} does not exist (lanes 0..={})", road.lane_count() - 1),
            ));
        }
        if let Some(start) = self.start.filter(|s| !(s.is_finite() && (0.0..road.length()).contains(s))) {
            return Err(invalid(
                "traffic.start",
                format!("must be a position on the road, 0 <= start < {} m, not {start}", road.length()),
            ));
        }
        let gt = match self.gt {
            Some(gt) => Some(gt.validate(self.count)?),
            None => None,
        };
        let traffic = TrafficSpec {
            gt,
            count: self.count,
            density: self.density,
            speed: self.speed,
            lanes: lanes.into_iter().map(|l| LaneId(l as u32)).collect(),
            style: self.style,
            start: self.start,
        };
        traffic.check_stretch(road, vehicles)?;
        Ok(traffic)
    }
}

impl GtTrafficFile {
    fn validate(self, traffic: u32) -> Result<GtTraffic, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        if self.count > traffic {
            return Err(invalid(
                "traffic.gt.count",
                format!("{} is more than the {traffic} cars of traffic", self.count),
            ));
        }
        if self.style.0.is_empty() {
            return Err(invalid("traffic.gt.style", "must name a style, or a list of at least one".into()));
        }
        if self.game.0.is_empty() {
            return Err(invalid("traffic.gt.game", "must name a game, or a list of at least one".into()));
        }
        Ok(GtTraffic { count: self.count, games: self.game.0, styles: self.style.0, role: self.role })
    }
}

impl TrafficSpec {
    /// Traffic with a `start` is placed without looking at the named vehicles: none may be
    /// in its lanes within a body length of the stretch it can fill (`reach`).
    fn check_stretch(&self, road: &Road, vehicles: &[VehicleSpec]) -> Result<(), ScenarioErrorKind> {
        let Some(start) = self.start else { return Ok(()) };
        let length = VehicleParams::default().length;
        let end = start + self.reach(road.lane_count());
        let inside = |v: &&VehicleSpec| self.lanes.contains(&v.lane) && start - length < v.s && v.s < end + length;
        match vehicles.iter().find(inside) {
            Some(vehicle) => Err(ScenarioErrorKind::Invalid {
                key: "traffic.start".to_string(),
                message: format!(
                    "vehicle '{}' is in lane {} at s = {} m, inside the stretch the traffic may fill in lanes {:?} \
                     (s {start:.0}..{end:.0} m, a body length either side); place it outside that stretch or in a \
                     lane traffic.lanes leaves out",
                    vehicle.name,
                    vehicle.lane.0,
                    vehicle.s,
                    self.lanes.iter().map(|l| l.0).collect::<Vec<_>>()
                ),
            }),
            None => Ok(()),
        }
    }
}
