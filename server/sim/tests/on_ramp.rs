//! IDM + MOBIL traffic on an on-ramp (issue 43, "Traffic that does not create the
//! problem"): three lanes, the rightmost (the ramp, lane 2) ending at 600 m, through
//! traffic placed in lanes 0-1 as `[traffic]` places it, three IDM cars entering on the
//! ramp, 40 s. Over a family of seeds and two densities nothing in it may go wrong: no
//! through car moves into the ramp lane, no car drives past a lane's end or off the road,
//! no two cars collide. A ramp car that finds no gap stops before the end and waits.

use arena_sim::{
    Driver, Ending, Game, GtParams, GtSetup, LaneId, Role, Scenario, Status, Stepper, Style, Vehicle, VehicleId,
    VehicleSetup, World,
};

/// The road and its through traffic; `{density}` is filled in.
const ON_RAMP: &str = r#"
name = "on-ramp"
[sim]
physics_dt = 0.03333333333333333
control_dt = 0.1
[road]
lanes = 3
lane_width = 4.0
speed_limits = [30.0, 30.0, 30.0]
sections = [{ length = 3000.0 }]
lane_ends = [{ lane = 2, s = 600.0 }]
[traffic]
count = 24
density = {density}
speed = [18.0, 24.0]
lanes = [0, 1]
"#;

/// Where the ramp lane ends (m).
const RAMP_END: f64 = 600.0;
const RAMP: LaneId = LaneId(2);

/// The world of `seed`: through traffic at `density` (highway-env's, 1 in highway.toml)
/// and three IDM cars on the ramp among it, at 18 m/s and aiming for 24.
fn world(density: f64, seed: u64) -> World {
    let text = ON_RAMP.replace("{density}", &format!("{density:?}"));
    let scenario = Scenario::parse("on-ramp.toml", &text, &[]).expect("the on-ramp scenario validates");
    let mut world = scenario.build(seed);
    let road = world.road().clone();
    for (k, s) in [120.0, 260.0, 400.0].into_iter().enumerate() {
        let mut vehicle = Vehicle::new(&road, RAMP, s, 18.0, Driver::Idm);
        vehicle.target_speed = 24.0;
        world.add(VehicleSetup::new(&format!("ramp{k}"), Style::Normal), vehicle);
    }
    world
}

/// What went wrong in one episode, and how many ramp cars merged.
#[derive(Debug, Default)]
struct Tally {
    /// Through cars that set out for the ramp lane.
    into_ramp: Vec<String>,
    /// Cars ended past a lane's end or over the road's edge.
    off: Vec<String>,
    /// Collisions, as "rear-front".
    collisions: Vec<String>,
    /// Ramp cars in a through lane at the end.
    merged: usize,
}

fn run(density: f64, seed: u64) -> Tally {
    let mut world = world(density, seed);
    let through: Vec<bool> = world.vehicles().iter().map(|v| v.target_lane != RAMP).collect();
    let mut into_ramp = vec![false; through.len()];
    let mut stepper = Stepper::new();
    stepper.set_decision_threads(1);
    for _ in 0..(40.0 / world.params().physics_dt).round() as usize {
        stepper.tick(&mut world);
        for (k, vehicle) in world.vehicles().iter().enumerate() {
            into_ramp[k] |= through[k] && vehicle.target_lane == RAMP;
        }
    }
    let name = |k: usize| world.name(VehicleId(k as u32)).to_string();
    let ended_off = |k: usize| matches!(world.ending(VehicleId(k as u32)), Some(Ending::LaneEnd | Ending::OffRoad));
    let merged = world.vehicles().iter().enumerate().filter(|&(k, v)| {
        !through[k] && v.status == Status::Driving && world.road().lane_at(v.state.s, v.state.d) != Some(RAMP)
    });
    Tally {
        into_ramp: (0..through.len()).filter(|&k| into_ramp[k]).map(name).collect(),
        off: (0..through.len()).filter(|&k| ended_off(k)).map(name).collect(),
        collisions: world
            .collisions()
            .iter()
            .map(|c| format!("{}-{}", world.name(c.rear), world.name(c.front)))
            .collect(),
        merged: merged.count(),
    }
}

/// Every seed of 0..100 at `density`: the episodes where anything went wrong, and the ramp
/// cars that merged in all.
fn family(density: f64) -> (Vec<(u64, Tally)>, usize) {
    let mut failed = Vec::new();
    let mut merged = 0;
    for seed in 0..100 {
        let tally = run(density, seed);
        merged += tally.merged;
        if !(tally.into_ramp.is_empty() && tally.off.is_empty() && tally.collisions.is_empty()) {
            failed.push((seed, tally));
        }
    }
    (failed, merged)
}

#[test]
fn light_on_ramp_traffic_keeps_its_lanes_its_road_and_its_distance() {
    // Measured before MOBIL kept through cars off the ramp and the edge, the index and the
    // paths were fixed: 79 through cars into the ramp in 62 episodes, 20 cars ended off the
    // road or past the lane's end, 2 collisions.
    let (failed, merged) = family(0.5);
    assert!(failed.is_empty(), "{} episodes: {failed:?}", failed.len());
    // The ramp's own cars still merge where there are gaps (212 of 300 when measured, 228
    // before).
    assert!(merged >= 150, "{merged} of 300 ramp cars merged");
}

#[test]
fn on_ramp_traffic_at_highway_density_keeps_its_lanes_its_road_and_its_distance() {
    // Measured before: 486 through cars into the ramp, in every episode, stalling at its
    // end; 43 cars ended off the road or past the lane's end; 10 collisions. Dense through
    // lanes leave the ramp's cars few gaps MOBIL accepts: most wait at its end (22 of 300
    // merged when measured, 45 before).
    let (failed, _) = family(1.0);
    assert!(failed.is_empty(), "{} episodes: {failed:?}", failed.len());
}

/// IDM brakes for a lane's end as for a stopped car just past it, and so did before: this
/// keeps it so (a front bumper short of the end, whatever the car's lane change).
#[test]
fn a_ramp_car_that_finds_no_gap_stops_before_the_lane_end() {
    for seed in 0..20 {
        let mut world = world(1.0, seed);
        let mut stepper = Stepper::new();
        stepper.set_decision_threads(1);
        for _ in 0..(40.0 / world.params().physics_dt).round() as usize {
            stepper.tick(&mut world);
            for vehicle in world.vehicles().iter().filter(|v| v.status == Status::Driving) {
                let lane = world.road().lane_at(vehicle.state.s, vehicle.state.d);
                assert!(lane != Some(RAMP) || vehicle.state.s < RAMP_END - 2.5, "seed {seed}: {:?}", vehicle.state);
            }
        }
    }
}

/// The road's edges hold game-theoretic cars too: 6 of 16 through cars aggressive Nash
/// players, an aggressive Stackelberg leader merging from the ramp, 30 s. Measured before
/// the preview was held on the road and within reach: 2 cars over the left edge in these
/// 100 episodes (seeds 104 and 134), 1 with the road's band alone (159). Where such a car
/// runs past the ramp's end (its merge, or the ramp lane its own lane-end rule let it
/// enter) is the game-theoretic driver's, not asserted here: 4 cars in seeds 0..200.
#[test]
fn game_theoretic_traffic_on_an_on_ramp_stays_within_the_roads_edges() {
    let text = ON_RAMP.replace("{density}", "1.0").replace("count = 24", "count = 16")
        + "gt = { count = 6, game = \"nash\", style = \"aggressive\" }\n";
    let scenario = Scenario::parse("on-ramp-gt.toml", &text, &[]).expect("the on-ramp scenario validates");
    let mut over_the_edge = Vec::new();
    for seed in 100..200 {
        let mut world = scenario.build(seed);
        let mut vehicle = Vehicle::new(world.road(), RAMP, 250.0, 18.0, Driver::Idm);
        vehicle.target_speed = 24.0;
        let setup = GtSetup { game: Game::Stackelberg, role: Role::Leader, params: GtParams::default() };
        world.add_gt(VehicleSetup::new("merging", Style::Aggressive), vehicle, setup);
        let mut stepper = Stepper::new();
        stepper.set_decision_threads(1);
        stepper.advance(&mut world, 30.0);
        for k in 0..world.vehicles().len() {
            let id = VehicleId(k as u32);
            if world.ending(id) == Some(Ending::OffRoad) {
                over_the_edge.push((seed, world.name(id).to_string(), world.vehicle(id).state.d));
            }
        }
    }
    assert!(over_the_edge.is_empty(), "{over_the_edge:?}");
}
