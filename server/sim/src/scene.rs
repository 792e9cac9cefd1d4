//! What every driver decides from: the road and each car on it as they were at the start
//! of the control period, with the lane-sorted index that answers neighbour queries (the
//! car ahead in a lane, the car behind, the nearest one, the cars near a point). Drivers
//! read a `Scene` and return decisions; the world applies them afterwards, so no decision
//! sees another of the same period unless the tick order says so (followers read their
//! leader's `decided`). One index serves IDM/MOBIL, the game-theoretic AV, its potential
//! field and the env's observations.

use serde::{Deserialize, Serialize};

use crate::dynamics::{DriverParams, Style, VehicleParams, VehicleState};
use crate::road::{LaneChange, LaneId, Road};

/// Index of a vehicle in its world.
#[repr(transparent)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct VehicleId(pub u32);

/// Whether a vehicle is still driving.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Status {
    /// On the road and driving.
    Driving,
    /// Hit another vehicle; it brakes to a stop and stays as an obstacle.
    Crashed,
    /// Left the paved road (past a lane end or over an edge).
    OffRoad,
    /// Reached the end of the road and left the world.
    Exited,
}

/// What a game-theoretic (`gt`) car does in its game.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Decides its acceleration and lane (the paper's EC).
    #[default]
    Leader,
    /// Keeps its lane and only chooses its acceleration, answering the nearest leader
    /// (or learner) in an adjacent lane: its part of the Nash equilibrium, or its best
    /// response to the leader's decision of this period under Stackelberg (the paper's AC).
    Follower,
}

/// Who drives a car, as other drivers may know it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum DriverKind {
    /// A learner outside the process.
    Agent,
    /// IDM + MOBIL background traffic.
    Idm,
    /// The game-theoretic AV in this role.
    Gt(Role),
}

/// One car as drivers see it at the start of the control period.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Car {
    /// Its id in the world.
    pub id: VehicleId,
    /// The 8 states of eq. (8).
    pub state: VehicleState,
    /// Its driving style.
    pub style: Style,
    /// Table I's parameters for its style.
    pub driver_params: DriverParams,
    /// The lane it is in by position (its target lane when off the lanes).
    pub lane: LaneId,
    /// The lane it is in or changing to.
    pub target_lane: LaneId,
    /// The speed its driver aims for (m/s).
    pub target_speed: f64,
    /// The acceleration commanded in the last period (m/s^2).
    pub accel: f64,
    /// The preview point commanded in the last period (m).
    pub preview: f64,
    /// Driving, crashed, off road or gone.
    pub status: Status,
    /// Who drives it.
    pub driver: DriverKind,
    /// What it decided this period (acceleration, lane change), once it has: leaders and
    /// learners decide before followers, who answer this.
    pub decided: Option<(f64, LaneChange)>,
}

impl Car {
    /// Speed along the lane (m/s).
    pub fn speed(&self) -> f64 {
        self.state.lane_speed()
    }

    /// Whether it takes part in traffic (driving, or crashed and in the way).
    pub fn on_road(&self) -> bool {
        matches!(self.status, Status::Driving | Status::Crashed)
    }

    /// The lane change it is making: its target lane against the lane it is in.
    pub fn lane_change(&self) -> LaneChange {
        LaneChange::between(self.lane, self.target_lane)
    }
}

/// Something ahead in a lane: a car, or the lane's end as a stopped car just past it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lead {
    /// Position along the road (m).
    pub s: f64,
    /// Offset (m).
    pub d: f64,
    /// Speed along the lane (m/s).
    pub speed: f64,
    /// The car, or `None` for a lane end.
    pub car: Option<VehicleId>,
}

impl Lead {
    fn of(car: &Car) -> Lead {
        Lead { s: car.state.s, d: car.state.d, speed: car.speed(), car: Some(car.id) }
    }
}

/// The road and its cars as of the last control instant, with the neighbour index.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The road everyone drives on.
    pub road: Road,
    /// Body and tyres, shared by every vehicle (Table II).
    pub vehicle: VehicleParams,
    /// Simulated time of the snapshot (s).
    pub time: f64,
    /// Length of a control period (s).
    pub control_dt: f64,
    cars: Vec<Car>,
    /// Every car on the road, by s (ties by id).
    order: Vec<u32>,
    /// Per lane, the cars in it, changing into it or with part of their body over its
    /// line, by (s, id).
    lanes: Vec<Vec<(f64, u32)>>,
}

impl Scene {
    /// An empty scene on `road`.
    pub fn new(road: Road, vehicle: VehicleParams, control_dt: f64) -> Scene {
        let lanes = vec![Vec::new(); road.lane_count()];
        Scene { road, vehicle, time: 0.0, control_dt, cars: Vec::new(), order: Vec::new(), lanes }
    }

    /// Takes `cars` (indexed by id; each one's `lane` is found here from its position)
    /// at `time` and rebuilds the index, reusing its memory.
    pub(crate) fn refresh(&mut self, time: f64, cars: impl Iterator<Item = Car>) {
        self.time = time;
        self.cars.clear();
        let road = &self.road;
        self.cars.extend(
            cars.map(|car| Car { lane: road.lane_at(car.state.s, car.state.d).unwrap_or(car.target_lane), ..car }),
        );
        self.order.clear();
        self.order.extend((0..self.cars.len() as u32).filter(|&i| self.cars[i as usize].on_road()));
        let cars = &self.cars;
        // Unstable (no scratch allocation) yet deterministic: ties are broken by index.
        self.order
            .sort_unstable_by(|&a, &b| cars[a as usize].state.s.total_cmp(&cars[b as usize].state.s).then(a.cmp(&b)));
        for lane in &mut self.lanes {
            lane.clear();
        }
        let (road, body) = (&self.road, &self.vehicle);
        for &index in &self.order {
            let car = &self.cars[index as usize];
            let (s, d) = (car.state.s, car.state.d);
            self.lanes[car.lane.0 as usize].push((s, index));
            if car.target_lane != car.lane {
                self.lanes[car.target_lane.0 as usize].push((s, index));
            }
            // A body across a lane line is in the lane beyond it too, whatever the lane
            // change: a car stopped halfway out of a lane that ends, or drifting, is the
            // leader of the cars behind it on both sides of the line.
            // Half its width, and half its length times |sin heading| <= |heading|, as
            // the world's collision sweep bounds a body's sideways reach.
            let reach = 0.5 * (body.width + body.length * car.state.heading.abs());
            let listed = [car.lane, car.target_lane];
            let left = road.lane_at(s, d + reach).filter(|lane| !listed.contains(lane));
            let right = road.lane_at(s, d - reach).filter(|lane| !listed.contains(lane) && Some(*lane) != left);
            for lane in [left, right].into_iter().flatten() {
                self.lanes[lane.0 as usize].push((s, index));
            }
        }
    }

    /// Records what car `id` decided this period, for the followers that answer it.
    pub(crate) fn record_decision(&mut self, id: VehicleId, accel: f64, change: LaneChange) {
        self.cars[id.0 as usize].decided = Some((accel, change));
    }

    /// `f` of this scene with car `id` changing to `lane`, the scene as it was afterwards.
    /// The lanes' car lists stay as they are: for `id`'s own plan only, which never reads
    /// `id` from them.
    pub(crate) fn with_target_lane<R>(&mut self, id: VehicleId, lane: LaneId, f: impl FnOnce(&Scene) -> R) -> R {
        let own = std::mem::replace(&mut self.cars[id.0 as usize].target_lane, lane);
        let result = f(self);
        self.cars[id.0 as usize].target_lane = own;
        result
    }

    /// The car with this id.
    pub fn car(&self, id: VehicleId) -> &Car {
        &self.cars[id.0 as usize]
    }

    /// Every car, by id (gone ones included).
    pub fn cars(&self) -> &[Car] {
        &self.cars
    }

    fn in_lane(&self, lane: LaneId) -> &[(f64, u32)] {
        self.lanes.get(lane.0 as usize).map_or(&[], Vec::as_slice)
    }

    /// The nearest car in `lane` at or ahead of `s`, other than those in `exclude`.
    pub fn ahead(&self, lane: LaneId, s: f64, exclude: &[VehicleId]) -> Option<&Car> {
        let list = self.in_lane(lane);
        let split = list.partition_point(|&(other, _)| other < s);
        list[split..].iter().map(|&(_, i)| &self.cars[i as usize]).find(|car| !exclude.contains(&car.id))
    }

    /// The nearest car in `lane` behind `s`, other than those in `exclude`.
    pub fn behind(&self, lane: LaneId, s: f64, exclude: &[VehicleId]) -> Option<&Car> {
        let list = self.in_lane(lane);
        let split = list.partition_point(|&(other, _)| other < s);
        list[..split].iter().rev().map(|&(_, i)| &self.cars[i as usize]).find(|car| !exclude.contains(&car.id))
    }

    /// The car in `lane` nearest to `s` along the road within `range` (the one ahead on
    /// a tie), other than those in `exclude`.
    pub fn nearest(&self, lane: LaneId, s: f64, range: f64, exclude: &[VehicleId]) -> Option<&Car> {
        let ahead = self.ahead(lane, s, exclude).filter(|car| car.state.s - s <= range);
        let behind = self.behind(lane, s, exclude).filter(|car| s - car.state.s <= range);
        match (ahead, behind) {
            (Some(a), Some(b)) => Some(if s - b.state.s < a.state.s - s { b } else { a }),
            (a, b) => a.or(b),
        }
    }

    /// The cars on the road within `range` of `s` along it, in any lane, by s.
    pub fn around(&self, s: f64, range: f64) -> impl Iterator<Item = &Car> {
        let cars = &self.cars;
        let first = self.order.partition_point(|&i| cars[i as usize].state.s < s - range);
        self.order[first..].iter().map(move |&i| &cars[i as usize]).take_while(move |car| car.state.s <= s + range)
    }

    /// The end of `lane` as a stopped car just past it, if the lane ends before the road.
    pub fn lane_end(&self, lane: LaneId) -> Option<Lead> {
        let end = self.road.lane_end(lane);
        (end < self.road.length()).then(|| Lead {
            s: end + self.vehicle.length / 2.0,
            d: self.road.lane_center(lane),
            speed: 0.0,
            car: None,
        })
    }

    /// What a car at `s` in `lane` must not run into: the nearer of the car ahead (other
    /// than `exclude`) and the lane's end.
    pub fn leader(&self, lane: LaneId, s: f64, exclude: &[VehicleId]) -> Option<Lead> {
        let car = self.ahead(lane, s, exclude).map(Lead::of);
        match (car, self.lane_end(lane).filter(|end| end.s > s)) {
            (Some(car), Some(end)) => Some(if car.s <= end.s { car } else { end }),
            (car, end) => car.or(end),
        }
    }

    /// The car ahead in `lane` as a `Lead` (lane ends left out).
    pub fn lead_car(&self, lane: LaneId, s: f64, exclude: &[VehicleId]) -> Option<Lead> {
        self.ahead(lane, s, exclude).map(Lead::of)
    }

    /// The lane `change` leads to from `lane`, if the road has it.
    pub fn lane_beside(&self, lane: LaneId, change: LaneChange) -> Option<LaneId> {
        let next = i64::from(lane.0) + i64::from(change.sigma());
        self.road.has_lane(next).then_some(LaneId(next as u32))
    }
}
