//! The merge benchmark of issue 23: each of the six game-theoretic policies (style x
//! game) driving the merging car of scenarios/merge-random.toml over seeds 0..99 (or
//! SEEDS from FIRST), as
//! `arena eval --policy gt:<style>:<game>` drives it, tabled as success / lane end /
//! collision / off road per policy (docs/design.md, "Merging that completes"), with the
//! AV's commanded jerk and its model's jerk per physics step (issue 24, docs/design.md,
//! "Jerk"); `--no-jerk` runs every `gt` car (ec_0 and AC) without its jerk bound:
//!
//! `cargo run --release -p arena-sim --example merge_random [-- SEEDS [FIRST] | -- --trace SEED STYLE GAME] [--no-jerk]`
//!
//! An episode is the env's: the seed seeds the seeds (`Env::reset(Some(seed))`), whose
//! first draw seeds both the `[vary]` draws and the world; the learner (ec_0) becomes a
//! `gt` leader of the policy's style and game with the default constants; the world
//! advances in 0.1 s steps for at most `max_cycles` of them, ending when ec_0 stops
//! driving. Success is server/src/env/episode.rs's: ended on the road (time limit or
//! road end) in a `[goal]` lane, ahead of every `[goal] ahead_of` car.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use arena_sim::Game;
use arena_sim::GtParams;
use arena_sim::Role;
use arena_sim::Style;
use arena_sim::analysis::{JerkSummary, commanded_jerk, longitudinal_jerk};
use arena_sim::{Driver, Ending, Status};
use arena_sim::{DriverSpec, Scenario, builtin_scenario};

struct Episode {
    /// How ec_0 stopped driving; `None`: it drove until the time limit.
    end: Option<Ending>,
    success: bool,
    /// When ec_0's first lane change began (s), if one did.
    change_at: Option<f64>,
    /// The shortest full-width duration of a lane change it decided (s), if one was
    /// shortened (docs/design.md, "Merging that completes").
    shortest: Option<f64>,
    /// Whether it gave up a lane change under way.
    aborted: bool,
    /// Whether it came to a stop (under 0.5 m/s) in the ending lane.
    stopped: bool,
    /// Its largest lateral acceleration while driving (m/s^2).
    peak_lateral: f64,
    /// Its commanded jerk between control periods while driving (m/s^3).
    commanded_jerk: Vec<f64>,
    /// Its model's longitudinal jerk per physics step while driving (m/s^3).
    step_jerk: Vec<f64>,
    /// Its commands that left the jerk bound because a lane change was aborted.
    abort_jumps: u32,
}

fn episode(scenario: &Scenario, seed: u64, style: Style, game: Game, params: GtParams, trace: bool) -> Episode {
    let world_seed = ChaCha8Rng::seed_from_u64(seed).next_u64();
    let mut draws = ChaCha8Rng::seed_from_u64(world_seed);
    let mut drawn = scenario.episode(&mut draws, &[]).expect("merge-random draws valid episodes");
    for vehicle in drawn.vehicles.iter_mut().filter(|v| matches!(v.driver, DriverSpec::Agent(_))) {
        vehicle.style = style;
        vehicle.driver = DriverSpec::Gt { game, role: Role::Leader, params };
    }
    // AC (a gt follower) drives with the same jerk bound as ec_0, on or off.
    for vehicle in drawn.vehicles.iter_mut() {
        if let DriverSpec::Gt { params: theirs, .. } = &mut vehicle.driver {
            theirs.decision.jerk = params.decision.jerk;
        }
    }
    let mut world = drawn.build(world_seed);
    let mut stepper = arena_sim::Stepper::new();
    stepper.set_decision_threads(1);
    let ec = world.find("ec_0").expect("merge-random has ec_0");
    let ticks = (drawn.step_dt / world.params().physics_dt).round() as u64;
    let start_lane = world.vehicle(ec).target_lane;
    let mut e = Episode {
        end: None,
        success: false,
        change_at: None,
        shortest: None,
        aborted: false,
        stopped: false,
        peak_lateral: 0.0,
        commanded_jerk: Vec::new(),
        step_jerk: Vec::new(),
        abort_jumps: 0,
    };
    let substeps = world.params().substeps_per_control();
    let (control_dt, physics_dt) = (world.params().control_dt, world.params().physics_dt);
    let (mut count, mut last_command, mut last_accel) = (0u64, world.vehicle(ec).command.accel, None);
    for _ in 0..drawn.max_cycles {
        for _ in 0..ticks {
            let driving = world.vehicle(ec).status == Status::Driving;
            stepper.tick(&mut world);
            let v = world.vehicle(ec);
            if driving {
                if count.is_multiple_of(substeps) {
                    e.commanded_jerk.push(commanded_jerk(last_command, v.command.accel, control_dt));
                    last_command = v.command.accel;
                }
                if let Some(last) = last_accel {
                    e.step_jerk.push(longitudinal_jerk(last, v.longitudinal_accel, physics_dt));
                }
                last_accel = Some(v.longitudinal_accel);
            }
            count += 1;
            if v.status == Status::Driving {
                e.peak_lateral = e.peak_lateral.max(v.state.lateral_accel(world.vehicle_params()).abs());
            }
            if let Driver::Gt(gt) = &v.driver {
                if let Some(t) = gt.decision.duration {
                    e.shortest = Some(e.shortest.map_or(t, |s| s.min(t)));
                }
                e.aborted |= gt.decision.aborted;
                e.abort_jumps = gt.diagnostics.abort_jumps;
            }
            e.stopped |= world.current_lane(ec) == start_lane && v.state.vx < 0.5;
        }
        let v = world.vehicle(ec);
        if e.change_at.is_none() && v.target_lane != start_lane {
            e.change_at = Some(world.time());
        }
        if trace {
            let decision = match &v.driver {
                Driver::Gt(gt) => format!(
                    "{:?} a={:+.2} (command {:+.2}) T={:?} aborted={}",
                    gt.decision.lane_change,
                    gt.decision.accel,
                    v.command.accel,
                    gt.decision.duration,
                    gt.decision.aborted
                ),
                _ => String::new(),
            };
            let ac = world.find("ac").map(|ac| world.vehicle(ac));
            println!(
                "t={:5.1} s={:6.1} left={:6.1} d={:+.2} v={:5.2} target={} {decision} | ac s={:6.1} v={:5.2}",
                world.time(),
                v.state.s,
                world.road().lane_end(start_lane) - v.state.s,
                v.state.d,
                v.state.lane_speed(),
                v.target_lane.0,
                ac.map_or(f64::NAN, |ac| ac.state.s),
                ac.map_or(f64::NAN, |ac| ac.state.lane_speed()),
            );
        }
        if let Some(ending) = world.ending(ec) {
            e.end = Some(ending);
            break;
        }
    }
    // As the env's `episode_success`: ended on the road where the goal asks.
    e.success = matches!(e.end, None | Some(Ending::RoadEnd)) && drawn.goal.reached(&world, ec);
    e
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut params = GtParams::default();
    if let Some(at) = args.iter().position(|a| a == "--no-jerk") {
        args.remove(at);
        params.decision.jerk.enabled = false;
    }
    let scenario = builtin_scenario("merge-random").expect("merge-random is built in").expect("it validates");
    if let Some(at) = args.iter().position(|a| a == "--trace") {
        let arg = |k: usize| args.get(at + k).map(String::as_str).expect("--trace SEED STYLE GAME");
        let seed: u64 = arg(1).parse().expect("--trace SEED STYLE GAME");
        let style = Style::ALL.into_iter().find(|s| s.name() == arg(2)).expect("a style");
        let game = Game::ALL.into_iter().find(|g| g.name() == arg(3)).expect("a game");
        let e = episode(&scenario, seed, style, game, params, true);
        println!(
            "end {:?}, success {}, lane change from {:?} s, shortest duration {:?} s, aborted {}, stopped {}, \
             peak lateral acceleration {:.2} m/s^2",
            e.end, e.success, e.change_at, e.shortest, e.aborted, e.stopped, e.peak_lateral
        );
        return;
    }
    let seeds: u64 = args.first().map_or(100, |n| n.parse().expect("SEEDS: a count"));
    let first: u64 = args.get(1).map_or(0, |n| n.parse().expect("FIRST: the first seed"));
    let last = (first + seeds).saturating_sub(1);
    let bound = if params.decision.jerk.enabled { "on" } else { "off" };
    println!("merge-random, seeds {first}..{last}, ec_0 driven by gt:<style>:<game>, jerk bound {bound}\n");
    println!(
        "| policy | success | lane_end | collision | off_road | other failure | shortened (shortest T, s) | \
         aborted | stopped | peak a_y (m/s^2, seed) | jerk p95 / max (m/s^3) | per step p95 / max | abort jumps | \
         failing seeds |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for style in Style::ALL {
        for game in Game::ALL {
            let (mut success, mut lane_end, mut collision, mut off_road, mut other) = (0, 0, 0, 0, 0);
            let (mut shortened, mut shortest, mut aborted, mut stopped, mut peak) = (0, f64::INFINITY, 0, 0, 0.0f64);
            let mut failing = Vec::new();
            let (mut commanded, mut per_step, mut abort_jumps, mut peak_seed) = (Vec::new(), Vec::new(), 0, first);
            for seed in first..first + seeds {
                let e = episode(&scenario, seed, style, game, params, false);
                match (e.success, e.end) {
                    (true, _) => success += 1,
                    (false, Some(Ending::LaneEnd)) => lane_end += 1,
                    (false, Some(Ending::Collision)) => collision += 1,
                    (false, Some(Ending::OffRoad)) => off_road += 1,
                    (false, _) => other += 1,
                }
                if !e.success {
                    failing.push(format!("{seed}:{}", e.end.map_or("TimeLimit".to_string(), |end| format!("{end:?}"))));
                }
                if let Some(t) = e.shortest {
                    shortened += 1;
                    shortest = shortest.min(t);
                }
                aborted += usize::from(e.aborted);
                stopped += usize::from(e.stopped);
                if e.peak_lateral > peak {
                    (peak, peak_seed) = (e.peak_lateral, seed);
                }
                commanded.extend(e.commanded_jerk);
                per_step.extend(e.step_jerk);
                abort_jumps += e.abort_jumps;
            }
            let (c, t) = (JerkSummary::of(commanded), JerkSummary::of(per_step));
            let shortest = if shortened > 0 { format!(" ({shortest:.2})") } else { String::new() };
            println!(
                "| gt:{}:{} | {success} | {lane_end} | {collision} | {off_road} | {other} | {shortened}{shortest} | \
                 {aborted} | {stopped} | {peak:.2} ({peak_seed}) | {:.2} / {:.2} | {:.2} / {:.2} | {abort_jumps} | {} |",
                style.name(),
                game.name(),
                c.p95,
                c.max,
                t.p95,
                t.max,
                failing.join(" ")
            );
        }
    }
}
