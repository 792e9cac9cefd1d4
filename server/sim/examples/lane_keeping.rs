//! Whether a car holds its lane at highway speed (issue 23's weave, docs/baselines.md,
//! "The driver model at speed"): one car per style and speed alone on a straight road,
//! started 5 cm off its lane's centre, driven for 120 s in a `World` at the 10 ms step,
//! once by IDM (traffic) and once as a learner holding its lane (a continuous action of
//! zero offset). Prints the largest offset from the centre over the last 20 s.
//! `cargo run --release -p arena-sim --example lane_keeping [-- --csv FILE]`: `--csv` also
//! writes every cell (`driver,style,speed,max_offset`), from which the doc's table is
//! rendered (scripts/docs-tables).

use arena_sim::{AgentCommand, Command, Driver, LaneId, Road, Style, Vehicle, VehicleSetup, World, WorldParams};

const SPEEDS: [f64; 5] = [27.0, 30.0, 33.0, 36.0, 40.0];
const SECONDS: f64 = 120.0;
const TAIL: f64 = 20.0;

/// The largest |offset| (m) over the last `TAIL` s of a lone car at `speed`.
fn sway(style: Style, speed: f64, driver: Driver) -> f64 {
    let road = Road::straight(SECONDS * 45.0 + 100.0, 1, 4.0, 45.0);
    let mut world = World::new(road.clone(), WorldParams::default(), 0);
    let mut car = Vehicle::new(&road, LaneId(0), 10.0, speed, driver);
    car.state.d = 0.05;
    let id = world.add(VehicleSetup::new("car", style), car);
    world.advance(SECONDS - TAIL);
    let (mut largest, mut stepper) = (0.0f64, arena_sim::Stepper::new());
    for _ in 0..(TAIL / world.params().physics_dt).round() as usize {
        stepper.tick(&mut world);
        largest = largest.max(world.vehicle(id).state.d.abs());
    }
    largest
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let csv_path = args.iter().position(|a| a == "--csv").map(|k| args.get(k + 1).expect("--csv FILE").clone());
    let mut csv = String::from("driver,style,speed,max_offset\n");
    println!("| driver | style | {} |", SPEEDS.map(|v| format!("{v:.0} m/s")).join(" | "));
    println!("|---|---|{}", "---:|".repeat(SPEEDS.len()));
    let learner = Driver::Agent(AgentCommand::Direct(Command { accel: 0.0, preview: 0.0 }));
    for (name, driver) in [("IDM", Driver::Idm), ("learner", learner)] {
        for style in Style::ALL {
            let offsets = SPEEDS.map(|v| sway(style, v, driver.clone()));
            for (speed, offset) in SPEEDS.iter().zip(offsets) {
                csv += &format!("{name},{},{speed},{offset}\n", style.name());
            }
            let cells = offsets.map(|d| format!("{d:.4} m"));
            println!("| {name} | {} | {} |", style.name(), cells.join(" | "));
        }
    }
    if let Some(path) = csv_path {
        std::fs::write(&path, csv).unwrap_or_else(|e| panic!("writing {path}: {e}"));
    }
}
