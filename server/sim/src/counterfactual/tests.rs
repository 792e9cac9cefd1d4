use super::*;
use crate::dynamics::Command;
use crate::road::Road;
use crate::world::{AtFault, Vehicle, VehicleSetup, WorldParams};

/// A learner's command: accelerate at `accel`, steer to lateral offset `preview`.
fn direct(accel: f64, preview: f64) -> Driver {
    Driver::Agent(AgentCommand::Direct(Command { accel, preview }))
}

fn learner(world: &mut World, name: &str, lane: u32, s: f64, speed: f64) -> VehicleId {
    let road = world.road().clone();
    let preview = road.lane_center(LaneId(lane));
    let vehicle = Vehicle::new(&road, LaneId(lane), s, speed, direct(0.0, preview));
    world.add(VehicleSetup::new(name, Style::Normal), vehicle)
}

fn gt_car(world: &mut World, name: &str, lane: u32, s: f64, speed: f64, params: GtParams) -> VehicleId {
    let road = world.road().clone();
    let vehicle = Vehicle::new(&road, LaneId(lane), s, speed, Driver::Idm);
    let setup = GtSetup { game: Game::Nash, role: Role::Leader, params };
    world.add_gt(VehicleSetup::new(name, Style::Normal), vehicle, setup)
}

/// Runs `world` a control period at a time, `script` setting its learners' commands at the
/// start of each, until the first collision `wanted` picks (or `seconds`): the recorder
/// then, and that collision.
fn run_to_crash(
    mut world: World,
    seconds: f64,
    mut script: impl FnMut(&mut World),
    wanted: impl Fn(&Collision) -> bool,
) -> (Recorder, Option<Crash>) {
    let mut recorder = Recorder::new(world.params().control_dt);
    let mut stepper = Stepper::new();
    while world.time() < seconds - 1e-9 {
        script(&mut world);
        if let Some(crash) = recorder.period(&mut world, &mut stepper).into_iter().find(|c| wanted(&c.collision)) {
            return (recorder, Some(crash));
        }
    }
    (recorder, None)
}

/// A car at 20 m/s whose driver never brakes, 90 m behind a car stopped in the only lane.
fn rear_end_world() -> (World, VehicleId, VehicleId) {
    let road = Road::straight(1000.0, 1, 4.0, 30.0);
    let mut world = World::new(road, WorldParams::default(), 0);
    let stopped = learner(&mut world, "stopped", 0, 200.0, 0.0);
    let blind = learner(&mut world, "blind", 0, 105.0, 20.0);
    (world, stopped, blind)
}

#[test]
fn a_rear_end_the_rear_car_could_have_avoided_by_braking_from_2_s() {
    let (world, stopped, blind) = rear_end_world();
    let (recorder, crash) = run_to_crash(world, 10.0, |_| {}, |_| true);
    let crash = crash.expect("the blind car strikes the stopped one");
    assert_eq!((crash.collision.rear, crash.collision.front), (blind, stopped));
    assert_eq!(crash.collision.at_fault, AtFault::Rear);
    let verdict = verdict(&recorder, &crash);
    assert_eq!(verdict.avoidability(), Avoidability::Rear, "{verdict:#?}");
    // 1 s before, 20 m short at 20 m/s: braking at 8 needs 25 m; 2 s before, 40 m, it stops.
    let rear = &verdict.rear;
    assert!(rear.avoided.iter().all(|a| a.lead > 1.5), "{}", rear.describe());
    assert!(rear.avoided.iter().any(|a| a.reference == Reference::Brake && a.lead == 2.0), "{}", rear.describe());
    assert!(rear.avoided_by(Reference::Idm), "{}", rear.describe());
    assert_eq!(rear.earliest(), Some(3.0));
    // The stopped car has one lane and a car at 20 m/s behind it that never brakes.
    assert!(verdict.front.avoided.is_empty(), "{}", verdict.front.describe());
    assert_eq!(verdict.replays(), 2 * 3 * 8);
}

#[test]
fn a_verdict_is_the_same_bits_twice_and_with_the_cars_added_in_the_other_order() {
    let (world, stopped, blind) = rear_end_world();
    let (recorder, crash) = run_to_crash(world, 10.0, |_| {}, |_| true);
    let crash = crash.unwrap();
    let (a, b) = (verdict(&recorder, &crash), verdict(&recorder, &crash));
    assert_eq!(a, b);
    assert_eq!(a.time.to_bits(), b.time.to_bits());
    // The same cars added the other way round: other ids, the same verdict.
    let road = Road::straight(1000.0, 1, 4.0, 30.0);
    let mut world = World::new(road, WorldParams::default(), 0);
    let blind_2 = learner(&mut world, "blind", 0, 105.0, 20.0);
    let stopped_2 = learner(&mut world, "stopped", 0, 200.0, 0.0);
    assert_ne!(blind_2, blind);
    let (recorder, crash_2) = run_to_crash(world, 10.0, |_| {}, |_| true);
    let c = verdict(&recorder, &crash_2.unwrap());
    assert_eq!((c.rear.id, c.front.id), (blind_2, stopped_2));
    assert_eq!(c.time.to_bits(), a.time.to_bits());
    assert_eq!((&c.rear.avoided, c.rear.replays), (&a.rear.avoided, a.rear.replays));
    assert_eq!((&c.front.avoided, c.front.replays), (&a.front.avoided, a.front.replays));
    assert_eq!(c.rear.simulated.to_bits(), a.rear.simulated.to_bits());
    let _ = stopped;
}

#[test]
fn the_reference_braking_is_the_avs_emergency_braking() {
    assert_eq!(REFERENCE_BRAKE, -GtParams::default().safety.emergency_brake);
    assert_eq!(Reference::ALL.len(), 8);
}

/// The car cut off: a gt car at 25 m/s in lane 0 (the road's edge beside it), a learner 8 m
/// behind it holding 25 m/s, a learner level with it in lane 1 and, just clear of it, a
/// learner ahead in lane 1 that cuts in at `CUT_IN_AT` and brakes at a learner's limit.
fn cut_in_world() -> (World, [VehicleId; 4]) {
    let road = Road::straight(2000.0, 2, 4.0, 25.0);
    let mut world = World::new(road, WorldParams::default(), 0);
    let av = gt_car(&mut world, "av", 0, 100.0, 25.0, GtParams::default());
    let tail = learner(&mut world, "tail", 0, 100.0 - 5.0 - 8.0, 25.0);
    let beside = learner(&mut world, "beside", 1, 99.0, 25.0);
    let cutter = learner(&mut world, "cutter", 1, 100.0 + 5.0 + 0.1, 25.0);
    (world, [av, tail, beside, cutter])
}

const CUT_IN_AT: f64 = 0.5;

/// The cut-in of `cut_in_world`, run to the av's first collision.
fn cut_in() -> (Recorder, Crash, [VehicleId; 4]) {
    let (world, cars) = cut_in_world();
    let [av, _, _, cutter] = cars;
    let script = |world: &mut World| {
        if world.time() >= CUT_IN_AT - 1e-9 {
            world.command_agent(cutter, AgentCommand::Direct(Command { accel: -6.0, preview: 0.0 }));
            world.set_target_lane(cutter, LaneId(0));
        }
    };
    let (recorder, crash) = run_to_crash(world, 12.0, script, |c| c.other(av).is_some());
    (recorder, crash.expect("a collision of the av"), cars)
}

#[test]
fn a_cut_in_at_the_smallest_gap_braking_at_a_learners_limit_is_unavoidable_for_the_car_cut_off() {
    let (recorder, crash, [av, tail, beside, cutter]) = cut_in();
    assert_eq!((crash.collision.rear, crash.collision.front), (av, cutter));
    assert_eq!(crash.collision.at_fault, AtFault::Front);
    let verdict = verdict(&recorder, &crash);
    assert!(verdict.rear.avoided.is_empty(), "{}", verdict.rear.describe());
    // Leads 2 and 3 both start from the episode's first copy: 16 replays.
    assert_eq!(verdict.rear.replays, 16);
    // The cutter could have: any driver that keeps its lane does.
    assert_eq!(verdict.avoidability(), Avoidability::Front);
    assert!(verdict.front.avoided_by(Reference::Idm), "{}", verdict.front.describe());
    // Why no driver of the av can: from the episode's first copy (the cut-in begins 0.5 s
    // into it, so every lead starts there or 0.4 s before the cut-in), no plan of constant
    // acceleration (+3 to -8 m/s^2) and steering (its lane, lane 1, off the edge) avoids it.
    // Holding the lane it closes the 0.1 m to the cutter, which brakes at 6, unless it
    // brakes hard itself; then the car 8 m behind, holding 25 m/s, closes that gap in
    // sqrt(16 / |a|) s (2 s at -4, 1.4 s at -8), well within the horizon. Steering into lane
    // 1 meets the car level with it there (or the cutter, still in it); lane 0's other side
    // is the road's edge. Every reference driver is one of these plans or changes it within
    // the same bounds (the AV brakes at 8 at most, IDM at 6).
    let ring = &recorder.ring;
    let start = ring.iter().rposition(|e| e.world.time() <= crash.time - 3.0 + 1e-9).unwrap_or(0);
    let until = crash.time + HORIZON;
    let run = |accel: f64, preview: f64| {
        let mut world = ring[start].world.clone();
        world.replace_driver(av, direct(accel, preview), None, Style::Normal);
        let (avoided, _, world) = run_from(ring, start, world, av, false, until, |_| {});
        let hit = world.collisions().iter().find_map(|c| c.other(av));
        (avoided, hit, world.vehicle(av).status)
    };
    let mut plans = Vec::new();
    for preview in [0.0, -4.0, 4.0] {
        for accel in [3.0, 2.0, 0.0, -2.0, -4.0, -5.0, -6.0, -7.0, -8.0] {
            plans.push((accel, preview, run(accel, preview)));
        }
    }
    let table = format!("{plans:?}");
    for (accel, preview, (avoided, hit, status)) in plans {
        assert!(!avoided, "{table}");
        match preview {
            // Holding its lane: braking at 2 or less it strikes the cutter, at 4 or more
            // the car behind strikes it first.
            0.0 if accel >= -2.0 => assert_eq!(hit, Some(cutter), "{table}"),
            0.0 => assert_eq!(hit, Some(tail), "{table}"),
            // Into lane 1: the car level with it there (or, braking, the one behind).
            p if p < 0.0 => assert!(hit.is_some_and(|car| [beside, tail, cutter].contains(&car)), "{table}"),
            _ => assert!(hit.is_some() || status == Status::OffRoad, "{table}"),
        }
    }
    let _ = (tail, beside);
}

/// An AV without its safety layer (the games alone) at 25 m/s in lane 0 of three, behind a
/// car at 15 m/s, changes into lane 1; 0.5 s after it begins, a learner coming up in lane 2
/// at 30 m/s, 15 m behind it, cuts into lane 1 without braking.
fn abort_world() -> (World, VehicleId, VehicleId) {
    let road = Road::straight(2000.0, 3, 4.0, 25.0);
    let mut world = World::new(road.clone(), WorldParams::default(), 0);
    let mut games_alone = GtParams::default();
    games_alone.safety.enabled = false;
    let av = gt_car(&mut world, "av", 0, 100.0, 25.0, games_alone);
    let mut slow = Vehicle::new(&road, LaneId(0), 150.0, 15.0, Driver::Idm);
    slow.target_speed = 15.0;
    world.add(VehicleSetup::new("slow", Style::Normal), slow);
    let cutter = learner(&mut world, "cutter", 2, 85.0, 30.0);
    (world, av, cutter)
}

fn abort_run() -> (Recorder, Crash, VehicleId, VehicleId) {
    let (world, av, cutter) = abort_world();
    let mut began = None;
    let script = |world: &mut World| {
        let time = world.time();
        if began.is_none() && world.vehicle(av).target_lane == LaneId(1) {
            began = Some(time);
        }
        if began.is_some_and(|at| time >= at + 0.5 - 1e-9) {
            world.command_agent(cutter, AgentCommand::Direct(Command { accel: 0.0, preview: -4.0 }));
            world.set_target_lane(cutter, LaneId(1));
        }
    };
    let (recorder, crash) = run_to_crash(world, 15.0, script, |c| c.other(av).is_some());
    (recorder, crash.expect("a collision of the av"), av, cutter)
}

#[test]
fn a_learner_cut_in_the_av_could_have_avoided_by_aborting_its_lane_change() {
    let (recorder, crash, av, cutter) = abort_run();
    assert_eq!(crash.collision.other(av), Some(cutter));
    // The responsibility rule puts the AV at fault: its body reached lane 1 first, too
    // close ahead of the cutter.
    assert!(crash.collision.is_at_fault(av));
    // As it drove, the AV never gave its change up.
    let ring = &recorder.ring;
    let changing = ring.iter().position(|e| e.world.vehicle(av).target_lane == LaneId(1)).expect("it changes");
    assert!(ring.iter().skip(changing).all(|e| e.world.vehicle(av).target_lane == LaneId(1)));
    let verdict = verdict(&recorder, &crash);
    let mine = verdict.of(av).unwrap();
    assert!(mine.avoidable(), "{}", mine.describe());
    // A reference AV in its place that avoided it gave the change up: from a copy taken
    // after the change began, its target lane went back to lane 0.
    let aborted = mine.avoided.iter().filter(|a| matches!(a.reference, Reference::Gt(..))).any(|a| {
        let start = ring.iter().position(|e| e.world.time() == a.start).unwrap();
        if start < changing {
            return false;
        }
        let mut world = ring[start].world.clone();
        put(&mut world, av, a.reference);
        let mut lanes = Vec::new();
        let (avoided, _, _) = run_from(ring, start, world, av, false, crash.time + HORIZON, |world| {
            lanes.push(world.vehicle(av).target_lane);
        });
        avoided && lanes.contains(&LaneId(0))
    });
    assert!(aborted, "{mine:?}");
}
