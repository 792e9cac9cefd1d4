use std::sync::atomic::AtomicUsize;

use super::*;
use crate::scenario::{Scenario, builtin_scenario};

fn state_bits(world: &World) -> Vec<u64> {
    world.vehicles().iter().flat_map(|v| v.state.to_array()).map(f64::to_bits).collect()
}

#[test]
fn same_seed_same_bits_other_seed_differs() {
    let scenario = builtin_scenario("highway").unwrap().unwrap();
    let run = |seed| {
        let (mut world, mut stepper) = (scenario.build(seed), Stepper::new());
        for _ in 0..1000 {
            stepper.tick(&mut world);
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
    let text = crate::scenario::BUILTIN_SCENARIOS[2].2;
    let scenario = Scenario::parse("highway.toml", text, &overrides).unwrap();
    let (mut world, mut stepper) = (scenario.build(11), Stepper::new());
    let mut lane_changes = 0;
    let mut lanes: Vec<LaneId> = world.vehicles().iter().map(|v| v.target_lane).collect();
    let ticks = (600.0 / world.params().physics_dt).round() as usize;
    for _ in 0..ticks {
        stepper.tick(&mut world);
        for (lane, vehicle) in lanes.iter_mut().zip(world.vehicles()) {
            lane_changes += usize::from(*lane != vehicle.target_lane);
            *lane = vehicle.target_lane;
        }
    }
    assert!(world.collisions().is_empty(), "collisions: {:?}", world.collisions());
    assert!(
        world.vehicles().iter().all(|v| matches!(v.status, Status::Driving | Status::Exited)),
        "someone left the road"
    );
    assert!(lane_changes > 20, "MOBIL should have changed lanes, saw {lane_changes}");
    assert!((world.time() - 600.0).abs() < 1e-6);
}

#[test]
fn a_car_that_does_not_brake_hits_a_stopped_one() {
    let road = Road::straight(1000.0, 2, 4.0, 30.0);
    let mut world = World::new(road.clone(), WorldParams::default(), 0);
    let stopped = world.add(
        VehicleSetup::new("stopped", Style::Normal),
        Vehicle::new(&road, LaneId(0), 100.0, 0.0, Driver::Agent(AgentCommand::Track)),
    );
    let direct = Driver::Agent(AgentCommand::Direct(Command { accel: 0.0, preview: 0.0 }));
    let blind =
        world.add(VehicleSetup::new("blind", Style::Normal), Vehicle::new(&road, LaneId(0), 20.0, 20.0, direct));
    let beside =
        world.add(VehicleSetup::new("beside", Style::Normal), Vehicle::new(&road, LaneId(1), 20.0, 20.0, Driver::Idm));
    world.vehicle_mut(stopped).target_speed = 0.0;
    world.advance(6.0);
    assert_eq!(
        world.collisions(),
        vec![Collision { rear: blind, front: stopped, at_fault: AtFault::Rear, entry_rule: AtFault::Rear }]
    );
    assert_eq!(world.vehicle(blind).status, Status::Crashed);
    assert_eq!(world.vehicle(beside).status, Status::Driving);
}

#[test]
fn a_car_that_cuts_in_at_a_short_gap_is_at_fault() {
    let road = Road::straight(1000.0, 2, 4.0, 30.0);
    let mut world = World::new(road.clone(), WorldParams::default(), 0);
    let direct = Driver::Agent(AgentCommand::Direct(Command { accel: 0.0, preview: 0.0 }));
    let behind =
        world.add(VehicleSetup::new("behind", Style::Normal), Vehicle::new(&road, LaneId(0), 20.0, 20.0, direct));
    let track = Driver::Agent(AgentCommand::Track);
    let cutter =
        world.add(VehicleSetup::new("cutter", Style::Normal), Vehicle::new(&road, LaneId(1), 45.0, 12.0, track));
    world.change_lane(cutter, LaneId(0));
    world.advance(6.0);
    let collisions = world.collisions();
    assert_eq!(
        collisions,
        vec![Collision { rear: behind, front: cutter, at_fault: AtFault::Front, entry_rule: AtFault::Front }]
    );
    assert!(collisions[0].is_at_fault(cutter) && !collisions[0].is_at_fault(behind));
}

#[test]
fn a_car_behind_that_accelerates_into_the_gap_it_had_given_is_at_fault() {
    // A car changes into lane 0 17 m ahead of a car at its speed of 12 m/s (safe: 12 m);
    // once its body is in the lane, that car accelerates at 6 m/s^2 into it, and strikes
    // it less than 2 s after the changer's centre crossed the line (the old rule's window).
    let road = Road::straight(1000.0, 2, 4.0, 30.0);
    let mut world = World::new(road.clone(), WorldParams::default(), 0);
    let coasting = |accel| Driver::Agent(AgentCommand::Direct(Command { accel, preview: 0.0 }));
    let behind = world
        .add(VehicleSetup::new("behind", Style::Normal), Vehicle::new(&road, LaneId(0), 20.0, 12.0, coasting(0.0)));
    let track = Driver::Agent(AgentCommand::Track);
    let changer =
        world.add(VehicleSetup::new("changer", Style::Normal), Vehicle::new(&road, LaneId(1), 42.0, 12.0, track));
    world.change_lane(changer, LaneId(0));
    let mut stepper = Stepper::new();
    while !world.vehicle(changer).occupancy.iter().any(|o| o.lane == LaneId(0)) {
        stepper.advance(&mut world, 0.1);
        assert!(world.time() < 3.0, "the changer never reached into lane 0");
    }
    let entry = world.vehicle(changer).occupancy.iter().find(|o| o.lane == LaneId(0)).copied().unwrap();
    let gap = entry.behind.expect("a car behind it as it entered");
    assert_eq!(gap.rear, behind);
    assert!(gap.gap > 12.0 && gap.gap < 17.0 && gap.established == entry.since, "{entry:?}");
    world.command_agent(behind, AgentCommand::Direct(Command { accel: 6.0, preview: 0.0 }));
    stepper.advance(&mut world, 4.0);
    let collisions = world.collisions();
    assert_eq!(
        collisions,
        vec![Collision { rear: behind, front: changer, at_fault: AtFault::Rear, entry_rule: AtFault::Front }]
    );
}

#[test]
fn the_notes_of_lane_entries_do_not_change_the_dynamics() {
    // Attribution only reads the world: with every car's notes wiped at every control
    // instant, the cars move to the same bits.
    let scenario = builtin_scenario("highway").unwrap().unwrap();
    let (mut noted, mut wiped) = (scenario.build(5), scenario.build(5));
    let mut stepper = Stepper::new();
    for tick in 0..600 {
        stepper.tick(&mut noted);
        stepper.tick(&mut wiped);
        if tick % 10 == 9 {
            for vehicle in &mut wiped.state.vehicles {
                vehicle.occupancy.clear();
            }
        }
    }
    assert_eq!(state_bits(&noted), state_bits(&wiped));
    assert!(noted.vehicles().iter().any(|v| v.occupancy.iter().any(|o| o.since.is_some())), "no car changed lanes");
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
    let merging =
        world.add(VehicleSetup::new("m", Style::Normal), Vehicle::new(&road, LaneId(1), 10.0, 15.0, Driver::Idm));
    // A wall of slow cars on the through lane leaves no gap to merge into.
    for k in 0..40 {
        world.add(
            VehicleSetup::new(&format!("w{k}"), Style::Normal),
            Vehicle::new(&road, LaneId(0), k as f64 * 6.0, 0.0, Driver::Agent(AgentCommand::Track)),
        );
        let last = VehicleId(world.vehicles().len() as u32 - 1);
        world.vehicle_mut(last).target_speed = 0.0;
    }
    world.advance(30.0);
    let m = world.vehicle(merging);
    assert_eq!(m.status, Status::Driving);
    assert!(m.state.s < 150.0 && m.state.vx < 0.5, "s {} v {}", m.state.s, m.state.vx);
}

/// A straight 600 m road of `lanes` lanes whose last lane ends at `end`.
fn on_ramp(lanes: usize, end: f64) -> Road {
    let origin = crate::road::Pose { x: 0.0, y: 0.0, heading: 0.0 };
    let sections = vec![crate::road::Section::Straight { length: 600.0 }];
    Road::new(origin, sections, 4.0, vec![30.0; lanes], &[(LaneId(lanes as u32 - 1), end)])
}

/// Adds a car on `lane` at `s`, `speed`, aiming for `target_speed`, driven by `driver`.
fn add_car(world: &mut World, name: &str, (lane, s): (u32, f64), (speed, target_speed): (f64, f64), driver: Driver) {
    let mut vehicle = Vehicle::new(world.road(), LaneId(lane), s, speed, driver);
    vehicle.target_speed = target_speed;
    world.add(VehicleSetup::new(name, Style::Normal), vehicle);
}

#[test]
fn mobil_does_not_move_a_through_car_into_a_lane_that_ends() {
    // A through car at 25 m/s closes on a car at 12 m/s; the lane beside it, free, ends
    // 300 m ahead: 12 s of driving, far beyond the old two-second horizon, and still a
    // lane the car would have to leave again.
    let mut world = World::new(on_ramp(2, 400.0), WorldParams::default(), 0);
    let track = Driver::Agent(AgentCommand::Track);
    add_car(&mut world, "slow", (0, 140.0), (12.0, 12.0), track);
    add_car(&mut world, "through", (0, 100.0), (25.0, 25.0), Driver::Idm);
    let through = world.find("through").unwrap();
    let mut stepper = Stepper::new();
    for _ in 0..1000 {
        stepper.tick(&mut world);
        assert_eq!(world.vehicle(through).target_lane, LaneId(0), "t = {:.2}", world.time());
    }
    assert!(world.collisions().is_empty(), "{:?}", world.collisions());
    // The ramp's own car still leaves it for the through lane, which ends no earlier.
    let mut world = World::new(on_ramp(2, 400.0), WorldParams::default(), 0);
    add_car(&mut world, "merging", (1, 100.0), (20.0, 25.0), Driver::Idm);
    world.advance(10.0);
    let merging = world.vehicle(world.find("merging").unwrap());
    assert_eq!((merging.target_lane, merging.status), (LaneId(0), Status::Driving));
}

#[test]
fn the_road_edge_past_a_lane_end_holds_a_car_told_to_drive_onto_it() {
    // Past the end of lane 1, a car in lane 0 is told to change into it: an IDM car and a
    // learner's meta action alike steer for the ended lane's centre. The edge holds both;
    // only a learner's continuous action may leave the road.
    for driver in [Driver::Idm, Driver::Agent(AgentCommand::Track)] {
        let mut world = World::new(on_ramp(2, 200.0), WorldParams::default(), 0);
        add_car(&mut world, "car", (0, 250.0), (20.0, 20.0), driver.clone());
        let car = world.find("car").unwrap();
        world.change_lane(car, LaneId(1));
        let mut stepper = Stepper::new();
        for _ in 0..800 {
            stepper.tick(&mut world);
            let v = world.vehicle(car);
            assert_eq!(v.status, Status::Driving, "{driver:?} t = {:.2}: d = {}", world.time(), v.state.d);
            // The preview stops where the body would touch the edge, d = -1; the driver
            // overshoots it by no more than a lane change may.
            let overshoot = crate::dynamics::LANE_CHANGE_BOUNDS.max_overshoot;
            assert!(v.state.d > -1.0 - overshoot, "{driver:?} t = {:.2}: d = {}", world.time(), v.state.d);
        }
    }
    let direct = Driver::Agent(AgentCommand::Direct(Command { accel: 0.0, preview: -4.0 }));
    let mut world = World::new(on_ramp(2, 200.0), WorldParams::default(), 0);
    add_car(&mut world, "learner", (0, 250.0), (20.0, 20.0), direct);
    world.advance(8.0);
    assert_eq!(world.ending(world.find("learner").unwrap()), Some(Ending::LaneEnd));
}

#[test]
fn a_car_leaving_a_lane_end_from_a_standstill_does_not_turn_across_the_road() {
    // A game-theoretic car waits at the end of its lane, the lane beside it free. Below
    // its MPC's 2 m/s it aims at the target lane's centre outright, and the driver held the
    // wheels at their lock as it crept off (in traffic, across both lanes and off the far
    // edge). Now its preview lies no further sideways than its speed lets it reach.
    for style in Style::ALL {
        let mut world = World::new(on_ramp(2, 200.0), WorldParams::default(), 0);
        let mut vehicle = Vehicle::new(world.road(), LaneId(1), 190.0, 0.0, Driver::Idm);
        vehicle.target_speed = 20.0;
        let gt =
            crate::gt::GtSetup { game: crate::gt::Game::Stackelberg, role: Role::Leader, params: Default::default() };
        let car = world.add_gt(VehicleSetup::new("waiting", style), vehicle, gt);
        let mut stepper = Stepper::new();
        let mut turned: f64 = 0.0;
        for _ in 0..1500 {
            stepper.tick(&mut world);
            turned = turned.max(world.vehicle(car).state.heading.abs());
        }
        let v = world.vehicle(car);
        assert_eq!(world.ending(car), None, "{style:?}: {:?}", v.state);
        // 0.33 rad at most when measured; 0.54-0.61 with the preview unbounded.
        assert!(turned < 0.45, "{style:?}: turned {turned} rad");
        assert!(v.state.d > -2.0 && v.state.d < 1.0, "{style:?} merged and kept its lane: {:?}", v.state);
    }
}

#[test]
fn two_cars_changing_into_one_lane_from_both_sides_do_not_meet_there() {
    // Abreast in lanes 0 and 2, each behind a slow car, both find lane 1 free at the same
    // MOBIL instant. The one behind (abreast: the smaller id) gives way.
    for (left_s, right_s) in [(100.0, 100.0), (100.0, 104.0), (104.0, 100.0)] {
        let mut world = World::new(Road::straight(1000.0, 3, 4.0, 30.0), WorldParams::default(), 0);
        let track = Driver::Agent(AgentCommand::Track);
        add_car(&mut world, "a_slow", (0, left_s + 35.0), (12.0, 12.0), track.clone());
        add_car(&mut world, "b_slow", (2, right_s + 35.0), (12.0, 12.0), track);
        add_car(&mut world, "left", (0, left_s), (22.0, 25.0), Driver::Idm);
        add_car(&mut world, "right", (2, right_s), (22.0, 25.0), Driver::Idm);
        let ids = [world.find("left").unwrap(), world.find("right").unwrap()];
        let mut stepper = Stepper::new();
        let mut into_middle = [false; 2];
        for _ in 0..1500 {
            stepper.tick(&mut world);
            for (k, &id) in ids.iter().enumerate() {
                into_middle[k] |= world.vehicle(id).target_lane == LaneId(1);
            }
        }
        assert_eq!(into_middle, [true, true], "both set out for the middle lane ({left_s}, {right_s})");
        assert!(world.collisions().is_empty(), "({left_s}, {right_s}): {:?}", world.collisions());
    }
}

#[test]
fn oriented_boxes() {
    let half = (2.5, 1.0);
    assert!(oriented_boxes_overlap((0.0, 0.0, 0.0), (4.9, 0.0, 0.0), half));
    assert!(!oriented_boxes_overlap((0.0, 0.0, 0.0), (5.1, 0.0, 0.0), half));
    assert!(!oriented_boxes_overlap((0.0, 0.0, 0.0), (0.0, 2.1, 0.0), half));
    // Rotated 90 degrees, the long side now reaches across.
    assert!(oriented_boxes_overlap((0.0, 0.0, 0.0), (0.0, 3.4, std::f64::consts::FRAC_PI_2), half));

    // Turned 0.3 rad, straight ahead: the turned box's rear-left corner, (-2.5, 1.0) in its
    // own frame, lies (-2.5 cos 0.3 - sin 0.3, -2.5 sin 0.3 + cos 0.3) = (-2.684, 0.217) from
    // its centre. It is the box's rearmost point and within the first box's width, so the
    // two first touch when it meets the first box's front (x = 2.5): with the centres
    // 2.5 + 2.5 cos 0.3 + sin 0.3 = 5.184 m apart. (Leaving out the width's sin 0.3 puts
    // that at 4.888; testing the turned box's axes alone, at 5.426.)
    let turned = 0.3f64;
    let touch = 2.5 + 2.5 * turned.cos() + turned.sin();
    assert!((touch - 5.184).abs() < 1e-3, "{touch}");
    for x in [3.6, touch - 0.01] {
        assert!(oriented_boxes_overlap((0.0, 0.0, 0.0), (x, 0.0, turned), half), "turned box {x} m ahead");
    }
    for x in [touch + 0.01, 5.3] {
        assert!(!oriented_boxes_overlap((0.0, 0.0, 0.0), (x, 0.0, turned), half), "turned box {x} m ahead");
    }

    // Turned 45 degrees, up and to the left at (-c, c): its lower long side lies
    // sqrt(2) c - 1 from the first box's centre along n = (-1, 1) / sqrt(2), the first
    // box's top-left corner (-2.5, 1) at 3.5 / sqrt(2) = 2.475 along n (and 1.06 m from the
    // side's middle, well within its 2.5 m half length). At c = 2.5 the side is at 2.536,
    // 6 cm clear of the corner, though the boxes' shadows on both of the first box's axes
    // overlap: only the turned box's own axis n separates them. At c = 2.4 it is at 2.394,
    // 8 cm into the corner.
    let diagonal = std::f64::consts::FRAC_PI_4;
    assert!(!oriented_boxes_overlap((0.0, 0.0, 0.0), (-2.5, 2.5, diagonal), half));
    assert!(oriented_boxes_overlap((0.0, 0.0, 0.0), (-2.4, 2.4, diagonal), half));
    // Either box may come first.
    assert!(!oriented_boxes_overlap((-2.5, 2.5, diagonal), (0.0, 0.0, 0.0), half));
    assert!(oriented_boxes_overlap((-2.4, 2.4, diagonal), (0.0, 0.0, 0.0), half));
}

/// Every vehicle's state bits after each of `ticks` ticks of `stepper`, by name.
fn trajectories_with(
    mut world: World,
    stepper: &mut Stepper,
    ticks: usize,
) -> std::collections::BTreeMap<String, Vec<u64>> {
    let mut out: std::collections::BTreeMap<String, Vec<u64>> = std::collections::BTreeMap::new();
    for _ in 0..ticks {
        stepper.tick(&mut world);
        for (i, vehicle) in world.vehicles().iter().enumerate() {
            let bits = vehicle.state.to_array().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            out.entry(world.name(VehicleId(i as u32)).to_string()).or_default().extend(bits);
        }
    }
    out
}

/// `trajectories_with` a stepper of its own.
fn trajectories(world: World, ticks: usize) -> std::collections::BTreeMap<String, Vec<u64>> {
    trajectories_with(world, &mut Stepper::new(), ticks)
}

/// `text` with its `[[vehicle]]` blocks in the order `order` gives.
fn permuted(text: &str, order: &dyn Fn(usize) -> Vec<usize>) -> String {
    let mut table: toml::Table = text.parse().unwrap();
    let Some(toml::Value::Array(vehicles)) = table.remove("vehicle") else { panic!("no [[vehicle]] blocks") };
    let reordered: Vec<toml::Value> = order(vehicles.len()).into_iter().map(|i| vehicles[i].clone()).collect();
    // A file with one [[vehicle]] block (highway.toml: the rest is generated traffic)
    // has no other order.
    assert!(vehicles.len() < 2 || reordered != vehicles, "the permutation must change the order");
    table.insert("vehicle".into(), toml::Value::Array(reordered));
    toml::to_string(&table).unwrap()
}

fn gt_driver(role: &str) -> toml::Value {
    let mut driver = toml::Table::new();
    driver.insert("kind".into(), "gt".into());
    driver.insert("game".into(), "stackelberg".into());
    driver.insert("role".into(), role.into());
    toml::Value::Table(driver)
}

#[test]
fn the_order_of_vehicles_in_a_file_changes_no_trajectory() {
    let reversed = |n: usize| (0..n).rev().collect::<Vec<_>>();
    let rotated = |n: usize| (1..n).chain([0]).collect::<Vec<_>>();
    // Every shipped file as it is, and the paper's two scenarios with a Stackelberg
    // leader and its followers: the case where file order used to decide who saw whom.
    let paper_drivers = |names: &[&str]| {
        let mut overrides = vec![("vehicle.ec_0.driver".to_string(), gt_driver("leader"))];
        overrides.extend(names.iter().map(|name| (format!("vehicle.{name}.driver"), gt_driver("follower"))));
        overrides
    };
    type Overrides = Vec<(String, toml::Value)>;
    let mut cases: Vec<(&str, &str, Overrides)> =
        crate::scenario::BUILTIN_SCENARIOS.iter().map(|(_, file, text)| (*file, *text, vec![])).collect();
    cases.push(("merge.toml", crate::scenario::BUILTIN_SCENARIOS[0].2, paper_drivers(&["ac"])));
    cases.push(("overtake.toml", crate::scenario::BUILTIN_SCENARIOS[1].2, paper_drivers(&["ac1", "ac2"])));
    for (file, text, overrides) in &cases {
        let build = |text: &str| Scenario::parse(file, text, overrides).unwrap().build(5);
        let expected = trajectories(build(text), 1000);
        assert!(expected.len() >= 2, "{file}");
        for order in [&reversed as &dyn Fn(usize) -> Vec<usize>, &rotated] {
            let got = trajectories(build(&permuted(text, order)), 1000);
            assert!(got == expected, "{file} with overrides {overrides:?}: a trajectory depends on the file order");
        }
    }
}

#[test]
fn a_stackelberg_follower_answers_its_leaders_decision_of_this_period() {
    // The merge with a Stackelberg leader (EC) and follower (AC): in the first period the
    // follower reads what the leader decided in that same period, whichever comes first.
    let overrides = vec![
        ("vehicle.ec_0.driver".to_string(), gt_driver("leader")),
        ("vehicle.ac.driver".to_string(), gt_driver("follower")),
    ];
    let text = crate::scenario::BUILTIN_SCENARIOS[0].2;
    let mut world = Scenario::parse("merge.toml", text, &overrides).unwrap().build(0);
    Stepper::new().tick(&mut world);
    let (ec, ac) = (world.find("ec_0").unwrap(), world.find("ac").unwrap());
    // The scene the tick's drivers read, with what they announced in it.
    let scene = &world.scene;
    let Driver::Gt(leader) = &world.vehicle(ec).driver else { panic!("ec_0 is gt") };
    let announced = scene.car(ec).decided.expect("the leader announced its decision");
    assert_eq!(announced.0, leader.decision.accel);
    assert!(scene.car(ac).decided.is_none(), "followers announce nothing");
}

#[test]
fn game_theoretic_cars_deciding_on_several_threads_give_the_same_bits_as_in_turn() {
    let text = crate::scenario::BUILTIN_SCENARIOS.iter().find(|(name, ..)| *name == "highway-gt").unwrap().2;
    let scenario = Scenario::parse("highway-gt.toml", text, &[]).unwrap();
    let run = |threads| {
        let mut stepper = Stepper::new();
        stepper.set_decision_threads(threads);
        trajectories_with(scenario.build(9), &mut stepper, 400)
    };
    let alone = run(1);
    assert_eq!(alone, run(2));
    assert_eq!(alone, run(3));
}

/// highway-gt's world of seed 4 on `threads` decision threads run for 60 control
/// periods, its learner tracking its targets (asked again every period, as meta actions
/// do), moving to another lane in periods 3, 13, ... and to another target speed in
/// periods 7, 17, ...: every vehicle's state at the end of each period. Before each
/// period the scene is taken, as an env's cost sampling takes it; `before_tick` runs
/// next, given the period, ahead of the learner's command.
fn learner_periods(threads: usize, before_tick: &dyn Fn(&mut World, &mut Stepper, usize)) -> Vec<Vec<u64>> {
    let text = crate::scenario::BUILTIN_SCENARIOS.iter().find(|(name, ..)| *name == "highway-gt").unwrap().2;
    let mut world = Scenario::parse("highway-gt.toml", text, &[]).unwrap().build(4);
    let mut stepper = Stepper::new();
    stepper.set_decision_threads(threads);
    let ego = world.find("ego_0").expect("highway-gt's learner");
    let mut periods = Vec::new();
    for period in 0..60 {
        world.scene();
        before_tick(&mut world, &mut stepper, period);
        world.command_agent(ego, AgentCommand::Track);
        match period % 10 {
            3 => {
                let lane = if world.current_lane(ego).0 == 0 { 1 } else { 0 };
                world.change_lane(ego, LaneId(lane));
            }
            7 => {
                let speed = world.vehicle(ego).target_speed;
                world.set_target_speed(ego, if speed > 25.0 { 20.0 } else { 30.0 });
            }
            _ => {}
        }
        for _ in 0..world.params().substeps_per_control() {
            stepper.tick(&mut world);
        }
        periods.push(state_bits(&world));
    }
    periods
}

#[test]
fn a_stepper_dropped_and_built_again_mid_episode_changes_no_bit() {
    // Every shipped scenario; a new stepper at every control period, with another thread
    // count, after decisions made ahead (which go with the old one), and with the
    // decision clock and explanations on in the old one.
    for (name, file, text) in crate::scenario::BUILTIN_SCENARIOS {
        let scenario = Scenario::parse(file, text, &[]).unwrap();
        let reference = trajectories(scenario.build(3), 600);
        let mut world = scenario.build(3);
        let mut stepper = Stepper::new();
        let mut out: std::collections::BTreeMap<String, Vec<u64>> = std::collections::BTreeMap::new();
        for tick in 0..600 {
            if tick % 10 == 0 {
                world.scene();
                stepper.decide_ahead(&world, &|| false);
                stepper.clock_decisions(true);
                stepper.set_explain(true);
                stepper = Stepper::new();
                stepper.set_decision_threads(1 + tick / 10 % 3);
            }
            stepper.tick(&mut world);
            for (i, vehicle) in world.vehicles().iter().enumerate() {
                let bits = vehicle.state.to_array().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                out.entry(world.name(VehicleId(i as u32)).to_string()).or_default().extend(bits);
            }
        }
        assert!(out == reference, "{name}: a new stepper changed the world");
    }
}

/// Puts a made-up acceleration in place of every decision made ahead.
fn spoil_decisions_made_ahead(stepper: &mut Stepper) {
    let ahead = stepper.ahead.as_mut().expect("decisions were made ahead");
    for (decision, _) in ahead.decided.iter_mut().flatten() {
        *decision = Decision::Accel(-3.0);
    }
}

#[test]
fn decisions_made_ahead_are_the_ones_their_tick_makes_and_dropped_when_a_vehicle_changes() {
    let reference = learner_periods(1, &|_, _, _| {});
    // Made ahead on one thread fewer than the tick's: in turn with 2, in parallel with 3;
    // all of them, or the first few when told to stop (the tick decides the rest).
    for threads in [2, 3] {
        let ahead = learner_periods(threads, &|world, stepper, _| stepper.decide_ahead(world, &|| false));
        assert_eq!(ahead, reference, "deciding ahead on {threads} threads changed the world");
        let partly = learner_periods(threads, &|world, stepper, _| {
            let asked = AtomicUsize::new(0);
            stepper.decide_ahead(world, &|| asked.fetch_add(1, Ordering::Relaxed) >= 3);
            let ahead = stepper.ahead.as_ref().expect("some were made");
            assert!(ahead.decided.iter().flatten().count() < 10, "it stops when told to");
        });
        assert_eq!(partly, reference, "deciding part ahead on {threads} threads changed the world");
    }
    // They are what the tick uses: made-up ones in their place change the world...
    let kept = learner_periods(2, &|world, stepper, period| {
        stepper.decide_ahead(world, &|| false);
        if period == 20 {
            spoil_decisions_made_ahead(stepper);
        }
    });
    assert_eq!(kept[..20], reference[..20]);
    assert_ne!(kept[20], reference[20], "the tick did not use the decisions made ahead");
    // ... unless the learner's vehicle changed in between, a state was restored, or the
    // world is another one (a copy that went its own way since).
    let dropped = learner_periods(3, &|world, stepper, period| {
        stepper.decide_ahead(world, &|| false);
        if period % 10 == 3 || period % 10 == 7 {
            spoil_decisions_made_ahead(stepper);
        }
        if period == 20 {
            spoil_decisions_made_ahead(stepper);
            world.restore(world.state().clone()).expect("its own state");
        }
        if period == 30 {
            let mut other = world.clone();
            other.set_target_speed(VehicleId(0), 5.0);
            other.scene();
            stepper.decide_ahead(&other, &|| false);
            spoil_decisions_made_ahead(stepper);
        }
    });
    assert_eq!(dropped, reference, "decisions made ahead outlived a change they depend on");
}

/// A `gt` car alone in the middle of three lanes, at 25 m/s, and the world it drives in.
fn lone_gt_car() -> (World, VehicleId) {
    let road = Road::straight(3000.0, 3, 4.0, 30.0);
    let mut world = World::new(road.clone(), WorldParams::default(), 0);
    let vehicle = Vehicle::new(&road, LaneId(1), 50.0, 25.0, Driver::Idm);
    let setup = GtSetup { game: Game::Nash, role: Role::Leader, params: GtParams::default() };
    let id = world.add_gt(VehicleSetup::new("gt", Style::Normal), vehicle, setup);
    (world, id)
}

#[test]
fn a_gt_car_forced_to_return_to_a_lane_goes_there_and_stays_until_released() {
    let (mut world, id) = lone_gt_car();
    let mut stepper = Stepper::new();
    stepper.advance(&mut world, 2.0);
    assert_eq!((world.current_lane(id), world.forced(id)), (LaneId(1), None));
    // Alone on the road it keeps its lane; forced, it goes to lane 0 at its own speed.
    world.force(id, Forced::ReturnToLane(LaneId(0)));
    let speed = world.vehicle(id).state.vx;
    stepper.advance(&mut world, 6.0);
    let vehicle = world.vehicle(id);
    assert_eq!((world.current_lane(id), vehicle.target_lane), (LaneId(0), LaneId(0)));
    assert!(vehicle.state.d.abs() < 0.2, "settled at the centre of lane 0: d = {}", vehicle.state.d);
    assert!((vehicle.state.vx - speed).abs() < 2.0, "its speed is its own: {} then {}", speed, vehicle.state.vx);
    assert_eq!(world.vehicle(id).status, Status::Driving);
    // Not part of the state: a restored state keeps the world's hook, and a copy has it.
    world.restore(world.state().clone()).unwrap();
    assert_eq!(world.clone().forced(id), Some(Forced::ReturnToLane(LaneId(0))));
    world.release(id);
    assert_eq!(world.forced(id), None);
    stepper.advance(&mut world, 1.0);
    assert_eq!(world.vehicle(id).status, Status::Driving);
}

#[test]
fn a_gt_car_forced_to_brake_brakes_at_that_rate_to_a_stop_and_no_further() {
    let (mut world, id) = lone_gt_car();
    let mut stepper = Stepper::new();
    stepper.advance(&mut world, 1.0);
    world.force(id, Forced::Brake(-6.0));
    let before = world.vehicle(id).state.vx;
    stepper.advance(&mut world, 2.0);
    let after = world.vehicle(id).state.vx;
    // -6 m/s^2 for 2 s, applied through the driver model's longitudinal response.
    assert!((before - after - 12.0).abs() < 1.5, "{before} -> {after} m/s in 2 s");
    assert_eq!(world.vehicle(id).command.accel, -6.0);
    stepper.advance(&mut world, 6.0);
    let stopped = world.vehicle(id).state.vx;
    assert!((-0.05..0.5).contains(&stopped), "stopped, not reversing: {stopped} m/s");
    assert_eq!(world.current_lane(id), LaneId(1), "its steering is its own");
    // Released, it drives off again.
    world.release(id);
    stepper.advance(&mut world, 3.0);
    assert!(world.vehicle(id).state.vx > stopped + 3.0, "{}", world.vehicle(id).state.vx);
}

#[test]
#[should_panic(expected = "force a gt car")]
fn only_a_gt_car_can_be_forced() {
    let (mut world, _) = lone_gt_car();
    let road = world.road().clone();
    let idm =
        world.add(VehicleSetup::new("idm", Style::Normal), Vehicle::new(&road, LaneId(0), 10.0, 20.0, Driver::Idm));
    world.force(idm, Forced::Brake(-6.0));
}

#[test]
fn the_av_enters_no_gap_the_responsibility_rule_would_call_too_close() {
    // The AV's gap rule (gt::SafetyParams) counts on the car behind as the responsibility
    // rule does: its response time, and both cars braking at the same hardest braking.
    let safety = crate::gt::GtParams::default().safety;
    assert_eq!(safety.follower_response, crate::world::BLAME_RESPONSE_TIME);
    assert_eq!(safety.lead_brake, crate::world::BLAME_BRAKE);
}

#[test]
fn a_replaced_driver_drives_the_car_from_then_on_with_its_style_and_setup() {
    let (mut world, id) = lone_gt_car();
    let mut stepper = Stepper::new();
    stepper.advance(&mut world, 1.0);
    world.force(id, Forced::Brake(-6.0));
    world.replace_driver(id, Driver::Idm, None, Style::Aggressive);
    assert_eq!((world.gt_setup(id), world.forced(id)), (None, None));
    assert_eq!(world.style(id), Style::Aggressive);
    assert_eq!(*world.driver_params(id), DriverParams::for_style(Style::Aggressive));
    let setup = GtSetup { game: Game::Stackelberg, role: Role::Leader, params: GtParams::default() };
    world.replace_driver(id, Driver::Gt(Box::default()), Some(setup), Style::Conservative);
    assert_eq!(world.gt_setup(id).map(|s| s.game), Some(Game::Stackelberg));
    assert_eq!(world.style(id), Style::Conservative);
    // The same car, the same state: it drives on under its new driver.
    let before = world.vehicle(id).state;
    stepper.advance(&mut world, 1.0);
    assert!(world.vehicle(id).state.s > before.s + 20.0);
    assert_eq!(world.vehicle(id).status, Status::Driving);
}

#[test]
#[should_panic(expected = "needs its setup")]
fn a_gt_driver_without_a_setup_is_refused() {
    let (mut world, id) = lone_gt_car();
    world.replace_driver(id, Driver::Gt(Box::default()), None, Style::Normal);
}
