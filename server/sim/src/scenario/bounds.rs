//! What one scenario may ask of the server: a scenario can come from a client (an inline
//! file of up to 1 MiB, plus overrides), and the worst one of each kind should cost about
//! 1 CPU-second and 64 MiB to create, reset or step, whatever it says. Each bound is one
//! constant here, checked by `validate` on the file as written and on every override and
//! `[vary]` draw, and refused with the key, the value, the bound and what to do
//! (docs/parameters.md, "Scenario bounds").

use super::file::{DriverFile, ScenarioFile, SimFile};
use super::{DriverSpec, Scenario, ScenarioErrorKind};

/// Most sections a road may have: a vehicle's conversion to global coordinates searches
/// them and `to_frenet` walks them all. The shipped roads have 1 or 2, a
/// researcher's tens; 1024 leaves room for a road drawn as many short pieces.
pub const MAX_ROAD_SECTIONS: usize = 1024;

/// Farthest the road reaches (m): how far its origin may lie from (0, 0), how long it may
/// be, and how wide (lanes x lane width). 1000 km is 50 times the shipped highways; within
/// it a coordinate resolves to well under a micrometre, which the start's overlap check
/// relies on.
pub const MAX_ROAD_EXTENT: f64 = 1.0e6;

/// Fastest a scenario may set a car or a lane (m/s): speeds, target speeds, speed limits
/// and traffic's speed range. 100 m/s is 360 km/h, over twice the shipped highways'; a
/// speed of 1e180 turned the dynamics to NaN within one step.
pub const MAX_SPEED: f64 = 100.0;

/// Most vehicles a scenario may have, its `[[vehicle]]`s and its `[traffic] count`
/// together (each alone, and their sum). Every physics tick moves every vehicle, and every
/// driver looks at its neighbours: 2048 keeps a world's step near a millisecond per tick
/// while admitting 40 times highway-env's 50 cars and inline files of hundreds.
pub const MAX_VEHICLES: usize = 2048;

/// Most learners (`driver = { kind = "agent" }`) a scenario may have: one action each per
/// step, and a step carries at most `arena_protocol::bounds::MAX_ACTIONS` (1024) of them;
/// the server asserts the two are equal.
pub const MAX_LEARNERS: usize = 1024;

/// Most game-theoretic cars a scenario may have (vehicles driven by `gt` plus
/// `[traffic] gt.count`). Each decision of one costs 0.1-5 ms (games and an MPC); 64 is
/// four times the 16 of a crowded research highway, and `MAX_GT_DECISIONS_PER_STEP`
/// bounds how often they decide.
pub const MAX_GT_CARS: usize = 64;

/// Most physics ticks in one env step (`sim.step_dt / sim.physics_dt`): a step runs them
/// all before it answers. The shipped files take 10-50; 1000 is 10 s of simulated time at
/// the 10 ms step.
pub const MAX_PHYSICS_TICKS_PER_STEP: usize = 1000;

/// Most control periods in one env step (`sim.step_dt / sim.control_dt`, rounded up):
/// every driver decides once a period. The shipped files take 1 (0.1 s steps) or 10
/// (highway's 1 s steps); 100 is a 10 s step at the paper's 10 Hz.
pub const MAX_CONTROL_PERIODS_PER_STEP: usize = 100;

/// Most game-theoretic decisions in one env step: game-theoretic cars times control
/// periods per step (`Scenario::gt_decisions_per_step`). At up to 5 ms a decision, 320
/// keeps a step within about 1.6 CPU-s in the worst case and far below in the usual 0.1-1
/// ms; it admits 32 cars at highway's 1 s steps (highway-gt has 8, so 80) and 64 at 0.1 s
/// steps. The server adds its own experts' decisions for learners before checking it.
pub const MAX_GT_DECISIONS_PER_STEP: usize = 320;

/// Most keys a `[vary]` table may draw: each is applied as an override on every draw, and
/// finding a vehicle by name searches them all. merge-random draws 6; 256 lets a file draw
/// the place and speed of a hundred cars.
pub const MAX_VARY_KEYS: usize = 256;

/// How many times an episode's `[vary]` draws are made again when they place two cars on
/// each other or off the road, before the reset is refused; fewer for a large file, so
/// that every reset reads at most `VARY_DRAW_BUDGET_BYTES` of it.
pub const EPISODE_DRAWS: usize = 20;

/// How much scenario text (and overrides) the draws of one reset may validate in all:
/// each draw validates the whole file again, at about 10 ms per 100 KiB. 4 MiB gives
/// every file under 200 KiB its 20 draws and the largest inline file (1 MiB) 4.
pub const VARY_DRAW_BUDGET_BYTES: usize = 4 << 20;

/// How many draws a reset of `text_bytes` of scenario may make.
pub(super) fn episode_draws(text_bytes: usize) -> usize {
    (VARY_DRAW_BUDGET_BYTES / text_bytes.max(1)).clamp(1, EPISODE_DRAWS)
}

impl Scenario {
    /// Physics ticks in one env step.
    pub fn physics_ticks_per_step(&self) -> usize {
        ratio(self.step_dt, self.world.physics_dt)
    }

    /// Control periods that begin in one env step (at least 1): how many times each
    /// driver decides in it.
    pub fn control_periods_per_step(&self) -> usize {
        periods(self.step_dt, self.world.control_dt)
    }

    /// Game-theoretic cars: vehicles driven by `gt` and `[traffic] gt.count`.
    pub fn gt_cars(&self) -> usize {
        let named = self.vehicles.iter().filter(|v| matches!(v.driver, DriverSpec::Gt { .. })).count();
        named + self.traffic.as_ref().and_then(|t| t.gt.as_ref()).map_or(0, |gt| gt.count as usize)
    }

    /// Game-theoretic decisions in one env step: `gt_cars` x `control_periods_per_step`,
    /// held to `MAX_GT_DECISIONS_PER_STEP` (the env adds its learners' expert decisions).
    pub fn gt_decisions_per_step(&self) -> usize {
        self.gt_cars().saturating_mul(self.control_periods_per_step())
    }
}

/// `long / short` rounded, saturating (`validate` has made both positive and finite).
fn ratio(long: f64, short: f64) -> usize {
    (long / short).round() as usize
}

/// Periods of `period` that begin within `step`: the ratio rounded up, but not for the
/// last bits of rounding (1.0 / 0.1 is 10.000000000000002), and at least 1.
fn periods(step: f64, period: f64) -> usize {
    let ratio = step / period;
    ((ratio * (1.0 - 1e-9)).ceil() as usize).max(1)
}

fn too_many(key: &str, message: String) -> ScenarioErrorKind {
    ScenarioErrorKind::Invalid { key: key.to_string(), message }
}

impl ScenarioFile {
    /// The counts and rates of `bounds`, checked before any vehicle is placed, so that a
    /// file past them costs no more than reading it. `sim`'s periods must be positive.
    pub(super) fn check_bounds(&self) -> Result<(), ScenarioErrorKind> {
        check_timing(&self.sim)?;
        let sections = self.road.sections.len();
        if sections > MAX_ROAD_SECTIONS {
            return Err(too_many(
                "road.sections",
                format!(
                    "has {sections} sections, more than the {MAX_ROAD_SECTIONS} a road may have \
                     (MAX_ROAD_SECTIONS); join consecutive straight sections, or arcs of one radius, into one"
                ),
            ));
        }
        self.check_vehicle_counts()?;
        self.check_gt(periods(self.sim.step_dt, self.sim.control_dt))
    }

    fn check_vehicle_counts(&self) -> Result<(), ScenarioErrorKind> {
        let named = self.vehicles.len();
        if named > MAX_VEHICLES {
            return Err(too_many(
                "vehicle",
                format!(
                    "lists {named} vehicles, more than the {MAX_VEHICLES} a scenario may have (MAX_VEHICLES); \
                     give fewer [[vehicle]]s, or let [traffic] place the others"
                ),
            ));
        }
        let traffic = self.traffic.as_ref().map_or(0, |t| t.count as usize);
        if traffic > MAX_VEHICLES || named + traffic > MAX_VEHICLES {
            return Err(too_many(
                "traffic.count",
                format!(
                    "{traffic} with the {named} [[vehicle]]s makes {} vehicles, more than the {MAX_VEHICLES} \
                     a scenario may have (MAX_VEHICLES); lower traffic.count",
                    named + traffic
                ),
            ));
        }
        let learners = self.vehicles.iter().filter(|v| matches!(v.driver, DriverFile::Agent { .. })).count();
        if learners > MAX_LEARNERS {
            return Err(too_many(
                "vehicle",
                format!(
                    "lists {learners} vehicles driven by `agent`, more than the {MAX_LEARNERS} learners a \
                     scenario may have (MAX_LEARNERS, the actions one step carries); drive the others by `idm`"
                ),
            ));
        }
        Ok(())
    }

    fn check_gt(&self, periods: usize) -> Result<(), ScenarioErrorKind> {
        let named = self.vehicles.iter().filter(|v| matches!(v.driver, DriverFile::Gt { .. })).count();
        let traffic = self.traffic.as_ref().and_then(|t| t.gt.as_ref()).map_or(0, |gt| gt.count as usize);
        let key = if traffic > 0 { "traffic.gt.count" } else { "vehicle" };
        let cars = named + traffic;
        if cars > MAX_GT_CARS {
            return Err(too_many(
                key,
                format!(
                    "{named} vehicles driven by `gt` and {traffic} of [traffic] gt make {cars} game-theoretic \
                     cars, more than the {MAX_GT_CARS} a scenario may have (MAX_GT_CARS); drive the others by `idm`"
                ),
            ));
        }
        let decisions = cars * periods;
        if decisions > MAX_GT_DECISIONS_PER_STEP {
            return Err(too_many(
                "sim.step_dt",
                format!(
                    "{} s makes each of the {cars} game-theoretic cars decide {periods} times per env step, \
                     {decisions} decisions, more than the {MAX_GT_DECISIONS_PER_STEP} a step may take \
                     (MAX_GT_DECISIONS_PER_STEP); shorten sim.step_dt or drive fewer cars by `gt`",
                    self.sim.step_dt
                ),
            ));
        }
        Ok(())
    }
}

/// Ticks and control periods per env step; the periods are positive and finite.
fn check_timing(sim: &SimFile) -> Result<(), ScenarioErrorKind> {
    let ticks = ratio(sim.step_dt, sim.physics_dt);
    if ticks > MAX_PHYSICS_TICKS_PER_STEP {
        return Err(too_many(
            "sim.physics_dt",
            format!(
                "{} s makes {ticks} physics ticks per env step of sim.step_dt = {} s, more than the \
                 {MAX_PHYSICS_TICKS_PER_STEP} a step may take (MAX_PHYSICS_TICKS_PER_STEP); \
                 lengthen sim.physics_dt or shorten sim.step_dt",
                sim.physics_dt, sim.step_dt
            ),
        ));
    }
    let periods = periods(sim.step_dt, sim.control_dt);
    if periods > MAX_CONTROL_PERIODS_PER_STEP {
        return Err(too_many(
            "sim.step_dt",
            format!(
                "{} s holds {periods} control periods of sim.control_dt = {} s, more than the \
                 {MAX_CONTROL_PERIODS_PER_STEP} an env step may take (MAX_CONTROL_PERIODS_PER_STEP); \
                 shorten sim.step_dt or lengthen sim.control_dt",
                sim.step_dt, sim.control_dt
            ),
        ));
    }
    Ok(())
}
