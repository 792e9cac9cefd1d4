//! The recording phase: while recording is on, the world as a client records it
//! (`arena_protocol::WorldStart`, `WorldFrame`), assembled from what the world exposes
//! read-only: the road's own geometry sampled into world-coordinate polylines, each
//! vehicle's description, and a frame of every vehicle at the end of each control period
//! (taken by `simulate` as it ticks), with the collisions since the last frame and the
//! physics step each happened in. Nothing here writes a file or opens a connection: the
//! frames travel in the replies and the client records them (docs/viewing.md).

use arena_protocol::{
    CollisionEvent, DriverInfo, ErrorCode, ErrorReply, Fault, GtRole, LaneGeometry, RoadGeometry, VehicleFrame,
    VehicleInfo, WorldFrame, WorldStart,
};

use arena_sim::{AtFault, Driver, LaneId, Road, Role, Section, VehicleId, World};

use super::{episode, error, style_of};

/// Heading change (rad) between two points of an arc's polyline: 0.02, chosen here (the
/// chord then strays R * 0.02^2 / 8 from the arc, 1.5 cm on overtake's 300 m radius).
const ARC_STEP: f64 = 0.02;
/// Most points of all lane lines together (16 bytes each, so 4 MiB of a reply): a road
/// of many lanes and long arcs is sampled more coarsely rather than making a reply of
/// tens of megabytes. Section starts are always kept (at most `MAX_ROAD_SECTIONS` a line,
/// which this budget holds for every lane count a road may have).
const MAX_ROAD_POINTS: usize = 1 << 18;
/// The bytes a recording may add to one reply (the rest of the message limit carries the
/// agents' rows): a `VehicleFrame` encodes to at most 67 bytes, a collision to 36.
const MAX_RECORDING_BYTES: usize = arena_protocol::MAX_MESSAGE_BYTES / 2;
const FRAME_BYTES_PER_VEHICLE: usize = 72 + 40;

/// What recording keeps between frames: how many of the world's collisions the last
/// frame reported, and those seen since, with when and where.
#[derive(Debug, Clone, Default)]
pub struct Recorder {
    reported: usize,
    events: Vec<CollisionEvent>,
    /// The frames of the step under way.
    pub frames: Vec<WorldFrame>,
}

impl Recorder {
    /// Starts over for a fresh world.
    pub fn restart(&mut self, world: &World) {
        self.reported = world.collisions().len();
        self.events.clear();
        self.frames.clear();
    }

    /// Notes the collisions of the physics step just taken, with its time and place.
    pub fn after_tick(&mut self, world: &World) {
        let collisions = world.collisions();
        for collision in &collisions[self.reported.min(collisions.len())..] {
            let (rear, front) = (world.vehicle(collision.rear), world.vehicle(collision.front));
            let road = world.road();
            let a = road.to_global(rear.state.s, rear.state.d, 0.0);
            let b = road.to_global(front.state.s, front.state.d, 0.0);
            self.events.push(CollisionEvent {
                time: world.time(),
                rear: collision.rear.0,
                front: collision.front.0,
                at_fault: match collision.at_fault {
                    AtFault::Rear => Fault::Rear,
                    AtFault::Front => Fault::Front,
                    AtFault::Both => Fault::Both,
                },
                x: (a.x + b.x) / 2.0,
                y: (a.y + b.y) / 2.0,
            });
        }
        self.reported = collisions.len();
    }

    /// Takes a frame of the world now, with the collisions noted since the last one.
    pub fn take_frame(&mut self, world: &World) {
        let frame = frame(world, std::mem::take(&mut self.events));
        self.frames.push(frame);
    }
}

/// Refuses recording a world whose frames would not fit a reply: `vehicles` vehicles,
/// `frames` frames a step.
pub fn check_fits(vehicles: usize, frames: usize) -> Result<(), ErrorReply> {
    let bytes = vehicles.saturating_mul(frames).saturating_mul(FRAME_BYTES_PER_VEHICLE);
    if bytes > MAX_RECORDING_BYTES {
        return Err(error(
            ErrorCode::InvalidScenario,
            format!(
                "record: {vehicles} vehicles x {frames} frames a step make about {bytes} bytes a reply, more than \
                 the {MAX_RECORDING_BYTES} a recording may add; use fewer vehicles or a shorter sim.step_dt"
            ),
        ));
    }
    Ok(())
}

/// The road, the vehicles and a frame of the world now; `learners` are the env's agents'
/// vehicle names.
pub fn start(world: &World, learners: &[&str]) -> WorldStart {
    let body = world.vehicle_params();
    let vehicles = world
        .vehicles()
        .iter()
        .zip(world.setups())
        .enumerate()
        .map(|(i, (vehicle, setup))| VehicleInfo {
            name: setup.name.clone(),
            learner: learners.contains(&setup.name.as_str()),
            driver: match (world.gt_setup(VehicleId(i as u32)), &vehicle.driver) {
                (None, Driver::Agent(_)) => DriverInfo::Learner,
                (None, _) => DriverInfo::Idm,
                (Some(gt), _) => DriverInfo::Gt {
                    game: match gt.game {
                        arena_sim::Game::Nash => arena_protocol::Game::Nash,
                        arena_sim::Game::Stackelberg => arena_protocol::Game::Stackelberg,
                    },
                    role: match gt.role {
                        Role::Leader => GtRole::Leader,
                        Role::Follower => GtRole::Follower,
                    },
                },
            },
            style: style_of(setup.style),
            length: body.length,
            width: body.width,
        })
        .collect();
    WorldStart { road: road(world.road()), vehicles, frame: frame(world, Vec::new()) }
}

/// Every vehicle now.
fn frame(world: &World, collisions: Vec<CollisionEvent>) -> WorldFrame {
    let road = world.road();
    let vehicles = world
        .vehicles()
        .iter()
        .enumerate()
        .map(|(i, vehicle)| {
            let state = &vehicle.state;
            let pose = road.to_global(state.s, state.d, state.heading);
            let id = arena_sim::VehicleId(i as u32);
            VehicleFrame {
                x: pose.x,
                y: pose.y,
                heading: pose.heading,
                s: state.s,
                d: state.d,
                speed: state.vx,
                accel: vehicle.command.accel,
                lane: road.nearest_lane(state.d).0,
                target_lane: vehicle.target_lane.0,
                end: episode::ended(world, id).unwrap_or(arena_protocol::EndReason::Running),
            }
        })
        .collect();
    WorldFrame { time: world.time(), vehicles, collisions }
}

/// The road's lanes as polylines in world coordinates.
pub fn road(road: &Road) -> RoadGeometry {
    let stations = stations(road, MAX_ROAD_POINTS / (3 * road.lane_count()));
    let half = road.lane_width() / 2.0;
    let lanes = (0..road.lane_count())
        .map(|lane| {
            let lane = LaneId(lane as u32);
            let end = road.lane_end(lane);
            let mut along: Vec<f64> = stations.iter().copied().filter(|&s| s < end).collect();
            along.push(end);
            let centre_d = road.lane_center(lane);
            let line = |d: f64| {
                along
                    .iter()
                    .map(|&s| {
                        let pose = road.to_global(s, d, 0.0);
                        [pose.x, pose.y]
                    })
                    .collect::<Vec<_>>()
            };
            LaneGeometry {
                centre: line(centre_d),
                left: line(centre_d + half),
                right: line(centre_d - half),
                end,
                ends_early: end < road.length(),
                speed_limit: road.speed_limit(lane),
            }
        })
        .collect();
    RoadGeometry { length: road.length(), lane_width: road.lane_width(), lanes }
}

/// Where along the reference line lane lines are sampled: each section's start, and on
/// arcs every `ARC_STEP` of heading (fewer if a line would pass `line_points`); the
/// road's end is added by each lane.
fn stations(road: &Road, line_points: usize) -> Vec<f64> {
    let sections = road_sections(road);
    let wanted: usize = sections.iter().map(|&(_, section)| arc_points(section)).sum();
    let thin = wanted.div_ceil(line_points.max(1)).max(1);
    let mut stations = Vec::new();
    for (start, section) in sections {
        let points = (arc_points(section) / thin).max(1);
        stations.extend((0..points).map(|k| start + section.length() * k as f64 / points as f64));
    }
    stations
}

/// Points an arc's line wants (one for a straight: its start).
fn arc_points(section: Section) -> usize {
    let turn = (section.curvature() * section.length()).abs();
    ((turn / ARC_STEP).ceil() as usize).clamp(1, MAX_ROAD_POINTS)
}

/// Each section with where it starts along the reference line.
fn road_sections(road: &Road) -> Vec<(f64, Section)> {
    let mut start = 0.0;
    road.sections()
        .iter()
        .map(|&section| {
            let at = start;
            start += section.length();
            (at, section)
        })
        .collect()
}
