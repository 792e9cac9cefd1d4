//! The world as a recording sees it (version 7): while recording is on for an env
//! (`CreateOptions::record`, or `RequestBody::Record`), reset replies carry a
//! [`WorldStart`] (the road's own geometry in world coordinates, every vehicle's
//! description and the first frame) and step replies a [`WorldFrame`] per control period
//! (every vehicle's pose, speed, lane and status, and the collisions since the last
//! frame). The server writes no file and connects nowhere for this: the client records
//! what the replies carry (docs/viewing.md).

use serde::{Deserialize, Serialize};

use crate::info::EndReason;
use crate::messages::{Game, Style};
use crate::names::named;

/// What a recording needs to begin: the road, who is on it, and the world now.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorldStart {
    /// The road, in world coordinates.
    pub road: RoadGeometry,
    /// Every vehicle of the world, by index (the index `WorldFrame::vehicles`,
    /// `CollisionEvent` and the `collision_with` info use).
    pub vehicles: Vec<VehicleInfo>,
    /// The world now (at a reset: time 0).
    pub frame: WorldFrame,
}

/// A road's lanes as polylines in world coordinates (m), sampled from its own straight and
/// arc sections (straights at their ends, arcs at least every 0.02 rad of heading).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RoadGeometry {
    /// Length of the reference line (m).
    pub length: f64,
    /// Width of every lane (m).
    pub lane_width: f64,
    /// Per lane, 0 the leftmost.
    pub lanes: Vec<LaneGeometry>,
}

/// One lane: its centre line and edges from the road's start to where the lane ends.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LaneGeometry {
    /// Centre line, (x, y) points (m).
    pub centre: Vec<[f64; 2]>,
    /// Left edge (the side of lane 0), the same number of points.
    pub left: Vec<[f64; 2]>,
    /// Right edge.
    pub right: Vec<[f64; 2]>,
    /// Where the lane ends, along the reference line (m).
    pub end: f64,
    /// The lane ends before the road does (merge's ending lane): its last points are a
    /// lane end to mark.
    pub ends_early: bool,
    /// Speed limit (m/s).
    pub speed_limit: f64,
}

/// One vehicle as it was when the recording began; fixed for the episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehicleInfo {
    /// Its name (a learner's is its agent's name).
    pub name: String,
    /// It is an agent of the env (it has observations and rewards), whoever drives it.
    pub learner: bool,
    /// Who drives it.
    pub driver: DriverInfo,
    /// Its driving style.
    pub style: Style,
    /// Body length and width (m).
    pub length: f64,
    /// Body width (m).
    pub width: f64,
}

/// Who drives a vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum DriverInfo {
    /// A learner, through the env's actions.
    Learner,
    /// IDM + MOBIL.
    Idm,
    /// The paper's game-theoretic AV.
    Gt {
        /// The game it plays.
        game: Game,
        /// Its role in it.
        role: GtRole,
    },
}

/// A game-theoretic car's role in its game.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum GtRole {
    /// Decides acceleration and lane (the paper's EC).
    Leader,
    /// Keeps its lane, answering a leader (the paper's AC).
    Follower,
}

named!(GtRole, "role", { Leader => "leader", Follower => "follower" });

/// The world at one instant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorldFrame {
    /// Simulated time since the episode began (s).
    pub time: f64,
    /// Every vehicle, in the order of `WorldStart::vehicles`.
    pub vehicles: Vec<VehicleFrame>,
    /// Collisions since the last frame, in the order they happened.
    pub collisions: Vec<CollisionEvent>,
}

/// One vehicle at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VehicleFrame {
    /// Global position of its centre (m).
    pub x: f64,
    /// Global Y (m).
    pub y: f64,
    /// Global heading (rad, counter-clockwise from the X axis).
    pub heading: f64,
    /// Distance along the road (m).
    pub s: f64,
    /// Offset from the reference line, positive left (m).
    pub d: f64,
    /// Speed along its heading (m/s).
    pub speed: f64,
    /// The acceleration its driver commands this control period (m/s^2).
    pub accel: f64,
    /// The lane nearest its centre (as the `lane` info).
    pub lane: u32,
    /// The lane it is in or changing to.
    pub target_lane: u32,
    /// `Running` while it drives; otherwise why it stopped (`Collision`, `OffRoad`,
    /// `LaneEnd`, `RoadEnd`).
    pub end: EndReason,
}

/// A collision: when and where, the two vehicles, who is at fault.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CollisionEvent {
    /// Simulated time of the physics step it happened in (s).
    pub time: f64,
    /// The vehicle behind (index into `WorldStart::vehicles`).
    pub rear: u32,
    /// The vehicle ahead.
    pub front: u32,
    /// Who is at fault (docs/design.md, "Collision attribution").
    pub at_fault: Fault,
    /// The midpoint of the two cars then (m).
    pub x: f64,
    /// Its Y (m).
    pub y: f64,
}

/// Who is at fault for a collision.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Fault {
    /// The car behind: it struck a car in its lane, or changed lanes into it.
    Rear,
    /// The car ahead: it changed lanes into the rear car's space.
    Front,
    /// Both changed lanes into each other's space at once.
    Both,
}

named!(Fault, "fault", { Rear => "rear", Front => "front", Both => "both" });
