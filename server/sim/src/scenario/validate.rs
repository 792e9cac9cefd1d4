//! The file as written (`file`) checked into a `Scenario`: timing, road, vehicles (on
//! the road, named once, not overlapping), traffic, reward, goal. Each refusal says which
//! key or vehicle is wrong and why; what passes here builds a world without a panic.

use super::file::{DriverFile, GoalFile, RewardFile, RoadFile, ScenarioFile, TrafficFile, VehicleFile};
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
        let traffic = self.traffic.map(|t| t.validate(&road)).transpose()?;
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
    fn validate(&self, _max_cycles: u32, goal: &Goal) -> Result<RewardSpec, ScenarioErrorKind> {
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
        Ok(RewardSpec {
            cost_scale: self.cost_scale,
            risk_weight: self.risk_weight,
            // A scenario without a goal (the highways) has nothing to pay it for, and its
            // crash reward stays -(1 + risk_weight) x max_cycles.
            goal_bonus: if goal.lanes.is_empty() && goal.ahead_of.is_empty() { 0.0 } else { self.goal_bonus },
            crash: self.crash,
        })
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
            lanes.push(LaneId(lane as u32));
        }
        if let Some(name) = self.ahead_of.iter().find(|name| !vehicles.iter().any(|v| &v.name == *name)) {
            return Err(invalid("goal.ahead_of", format!("names '{name}', which is no [[vehicle]] of the file")));
        }
        Ok(Goal { lanes, ahead_of: self.ahead_of.clone() })
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
        if let Some(bad) = self.speed_limits.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            return Err(invalid("road.speed_limits", format!("must be positive speeds in m/s, not {bad}")));
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
        let origin = Pose { x: self.origin.x, y: self.origin.y, heading: self.origin.heading };
        Ok(Road::new(origin, sections, self.lane_width, self.speed_limits.clone(), &ends))
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
        if !(self.speed.is_finite() && self.speed >= 0.0) {
            return Err(invalid("speed", format!("must be a speed >= 0 in m/s, not {}", self.speed)));
        }
        let target_speed = self.target_speed.unwrap_or(self.speed);
        if !(target_speed.is_finite() && target_speed > 0.0) {
            return Err(invalid("target_speed", format!("must be positive, not {target_speed}")));
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
    let body = VehicleParams::default();
    let half = (body.length / 2.0, body.width / 2.0);
    for (i, a) in vehicles.iter().enumerate() {
        for b in &vehicles[i + 1..] {
            if a.name == b.name {
                return Err(ScenarioErrorKind::DuplicateName(a.name.clone()));
            }
            let pa = road.to_global(a.s, a.d, 0.0);
            let pb = road.to_global(b.s, b.d, 0.0);
            if crate::world::oriented_boxes_overlap((pa.x, pa.y, pa.heading), (pb.x, pb.y, pb.heading), half) {
                return Err(ScenarioErrorKind::Overlap { first: a.name.clone(), second: b.name.clone() });
            }
        }
    }
    Ok(())
}

impl TrafficFile {
    fn validate(self, road: &Road) -> Result<TrafficSpec, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        if self.count > 10_000 {
            return Err(invalid("traffic.count", format!("{} is more than the 10000 a world supports", self.count)));
        }
        if !(self.density.is_finite() && self.density > 0.0) {
            return Err(invalid("traffic.density", format!("must be positive, not {}", self.density)));
        }
        let [low, high] = self.speed;
        if !(low.is_finite() && high.is_finite() && 0.0 < low && low <= high) {
            return Err(invalid(
                "traffic.speed",
                format!("must be [low, high] with 0 < low <= high, not [{low}, {high}]"),
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
        let gt = self.gt.map(|gt| GtTraffic { count: gt.count, game: gt.game, style: gt.style, role: gt.role });
        if let Some(gt) = gt.filter(|gt| gt.count > self.count) {
            return Err(invalid(
                "traffic.gt.count",
                format!("{} is more than the {} cars of traffic", gt.count, self.count),
            ));
        }
        Ok(TrafficSpec {
            gt,
            count: self.count,
            density: self.density,
            speed: self.speed,
            lanes: lanes.into_iter().map(|l| LaneId(l as u32)).collect(),
            style: self.style,
        })
    }
}
