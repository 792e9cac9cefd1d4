use super::*;
use crate::scenario::builtin;

fn state_bits(world: &World) -> Vec<u64> {
    world.vehicles.iter().flat_map(|v| v.state.to_array()).map(f64::to_bits).collect()
}

#[test]
fn same_seed_same_bits_other_seed_differs() {
    let scenario = builtin("highway").unwrap().unwrap();
    let run = |seed| {
        let mut world = scenario.build(seed);
        for _ in 0..1000 {
            world.tick();
        }
        world
    };
    let (a, b, c) = (run(3), run(3), run(4));
    assert_eq!(state_bits(&a), state_bits(&b));
    assert_ne!(state_bits(&a), state_bits(&c));
}

#[test]
fn ten_minutes_of_dense_traffic_without_a_collision() {
    let overrides = [("vehicle.ego_0.driver".to_string(), toml::Value::Table(toml::toml! { kind = "idm" }))];
    let text = crate::scenario::BUILTIN[2].2;
    let scenario = crate::scenario::Scenario::parse("highway.toml", text, &overrides).unwrap();
    let mut world = scenario.build(11);
    let mut lane_changes = 0;
    let mut lanes: Vec<LaneId> = world.vehicles.iter().map(|v| v.target_lane).collect();
    let ticks = (600.0 / world.params.physics_dt).round() as usize;
    for _ in 0..ticks {
        world.tick();
        for (lane, vehicle) in lanes.iter_mut().zip(&world.vehicles) {
            lane_changes += usize::from(*lane != vehicle.target_lane);
            *lane = vehicle.target_lane;
        }
    }
    assert!(world.collisions.is_empty(), "collisions: {:?}", world.collisions);
    assert!(
        world.vehicles.iter().all(|v| matches!(v.status, Status::Driving | Status::Exited)),
        "someone left the road"
    );
    assert!(lane_changes > 20, "MOBIL should have changed lanes, saw {lane_changes}");
    assert!((world.time - 600.0).abs() < 1e-6);
}

#[test]
fn a_car_that_does_not_brake_hits_a_stopped_one() {
    let road = Road::straight(1000.0, 2, 4.0, 30.0);
    let mut world = World::new(road.clone(), WorldParams::default(), 0);
    let stopped = world.add(Vehicle::new(
        "stopped",
        &road,
        LaneId(0),
        100.0,
        0.0,
        Style::Normal,
        Driver::Agent(AgentCommand::Track),
    ));
    let direct = Driver::Agent(AgentCommand::Direct(Command { accel: 0.0, preview: 0.0 }));
    let blind = world.add(Vehicle::new("blind", &road, LaneId(0), 20.0, 20.0, Style::Normal, direct));
    let beside = world.add(Vehicle::new("beside", &road, LaneId(1), 20.0, 20.0, Style::Normal, Driver::Idm));
    world.vehicle_mut(stopped).target_speed = 0.0;
    world.advance(6.0);
    assert_eq!(world.collisions, vec![Collision { rear: blind, front: stopped }]);
    assert_eq!(world.vehicle(blind).status, Status::Crashed);
    assert_eq!(world.vehicle(beside).status, Status::Driving);
}

#[test]
fn idm_stops_before_a_lane_end_when_it_cannot_merge() {
    let road = Road::new(
        crate::road::Pose { x: 0.0, y: 0.0, heading: 0.0 },
        vec![crate::road::Section::Straight { length: 500.0 }],
        4.0,
        vec![30.0, 30.0],
        &[(LaneId(1), 150.0)],
    );
    let mut world = World::new(road.clone(), WorldParams::default(), 0);
    let merging = world.add(Vehicle::new("m", &road, LaneId(1), 10.0, 15.0, Style::Normal, Driver::Idm));
    // A wall of slow cars on the through lane leaves no gap to merge into.
    for k in 0..40 {
        world.add(Vehicle::new(
            &format!("w{k}"),
            &road,
            LaneId(0),
            k as f64 * 6.0,
            0.0,
            Style::Normal,
            Driver::Agent(AgentCommand::Track),
        ));
        let last = VehicleId(world.vehicles.len() as u32 - 1);
        world.vehicle_mut(last).target_speed = 0.0;
    }
    world.advance(30.0);
    let m = world.vehicle(merging);
    assert_eq!(m.status, Status::Driving);
    assert!(m.state.s < 150.0 && m.state.vx < 0.5, "s {} v {}", m.state.s, m.state.vx);
}

#[test]
fn oriented_boxes() {
    let half = (2.5, 1.0);
    assert!(oriented_boxes_overlap((0.0, 0.0, 0.0), (4.9, 0.0, 0.0), half));
    assert!(!oriented_boxes_overlap((0.0, 0.0, 0.0), (5.1, 0.0, 0.0), half));
    assert!(!oriented_boxes_overlap((0.0, 0.0, 0.0), (0.0, 2.1, 0.0), half));
    // Rotated 90 degrees, the long side now reaches across.
    assert!(oriented_boxes_overlap((0.0, 0.0, 0.0), (0.0, 3.4, std::f64::consts::FRAC_PI_2), half));
    assert!(
        !oriented_boxes_overlap((0.0, 0.0, 0.0), (3.6, 0.0, 0.3), half)
            || 3.6 < 2.5 + 2.5 * 0.3f64.cos() + 0.3f64.sin()
    );
}
