//! Many vehicles stepped together: their states, inputs and constants held in blocks of
//! `BLOCK` vehicles, one array of `BLOCK` numbers per quantity (structure of arrays), and
//! each block advanced at once by the same RK4 of eq. (1)-(8) that `VehicleStep` runs for
//! one vehicle. The block step is compiled for AVX-512, AVX2 and SSE4.1 and the widest
//! the machine has is picked at run time (`multiversion`), so one release binary runs on
//! any x86-64.
//!
//! Each vehicle's result is the same bits as `VehicleStep::step` gives it alone: the model is
//! written once over `Lanes`, whose operations are lane-wise IEEE-754 arithmetic with no
//! fused multiply-add, so neither the block width, nor the vector width, nor which
//! vehicles share a block changes a bit (tests below check every width on this machine).

use multiversion::multiversion;

use super::integrate::{VehicleStep, step_lanes};
use super::lanes::Lanes;
use super::model::{Inputs, Model};
use super::state::{Command, StateLanes, VehicleState};

/// Vehicles per block: 8 doubles fill one AVX-512 register (two AVX2, four SSE).
pub const BLOCK: usize = 8;

/// `BLOCK` vehicles. Lanes past the fleet's last vehicle hold a vehicle of an earlier
/// step or a copy of the block's first one, so they step like any car; they are never
/// read.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Block {
    x: StateLanes<BLOCK>,
    inputs: Inputs<BLOCK>,
    model: Model<BLOCK>,
}

/// The vehicles of one physics step. Kept from step to step: a slot's constants are
/// written again only when another vehicle takes it or its stepper changed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Fleet {
    blocks: Vec<Block>,
    /// Which stepper each slot's constants came from (`push`'s `key`).
    keys: Vec<u64>,
    len: usize,
    dt: f64,
}

impl Fleet {
    /// Empties the fleet, keeping its memory and its constants.
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Adds a vehicle to step with `stepper` (every vehicle of a fleet steps by the same
    /// dt) under `command` on a lane of `curvature`. `key` names the stepper: a slot
    /// whose last vehicle had the same key keeps its constants, so a caller gives each
    /// distinct stepper a distinct key and a changed stepper a new one.
    pub fn push(&mut self, key: u64, stepper: &VehicleStep, state: &VehicleState, command: Command, curvature: f64) {
        let (index, lane) = (self.len / BLOCK, self.len % BLOCK);
        if index == self.blocks.len() {
            // A new block: every lane a copy of this vehicle until others take them.
            self.blocks.push(Block { model: Model::splat(&stepper.model), ..Block::default() });
            self.keys.extend([key; BLOCK]);
        } else if self.keys[self.len] != key {
            self.blocks[index].model.set_lane(lane, &stepper.model);
            self.keys[self.len] = key;
        }
        let block = &mut self.blocks[index];
        for (lanes, value) in block.x.iter_mut().zip(state.to_array()) {
            lanes.0[lane] = value;
        }
        block.inputs.accel.0[lane] = command.accel;
        block.inputs.preview.0[lane] = command.preview;
        block.inputs.curvature.0[lane] = curvature;
        self.len += 1;
        self.dt = stepper.dt;
    }

    /// The state of vehicle `index` (in order of `push`).
    pub fn state(&self, index: usize) -> VehicleState {
        let block = &self.blocks[index / BLOCK];
        VehicleState::from_array(block.x.map(|lanes| lanes.0[index % BLOCK]))
    }

    /// Advances every vehicle by one physics step, a block at a time with the widest
    /// vectors the machine has.
    pub fn step(&mut self) {
        let used = self.len.div_ceil(BLOCK);
        step_dispatched(&mut self.blocks[..used], self.dt);
    }

    /// `step` N vehicles at a time, compiled without target features: for the tests.
    #[cfg(test)]
    fn step_unvectorised<const N: usize>(&mut self) {
        let used = self.len.div_ceil(BLOCK);
        step_blocks::<N>(&mut self.blocks[..used], self.dt);
    }

    /// `step` compiled for each instruction set the dispatch chooses from, whichever this
    /// machine has: for the tests, as the dispatch picks only the widest.
    #[cfg(all(test, target_arch = "x86_64"))]
    fn step_with_each_instruction_set(&self) -> Vec<(&'static str, Fleet)> {
        #[target_feature(enable = "avx512f,avx512vl,avx512dq")]
        unsafe fn avx512(blocks: &mut [Block], dt: f64) {
            step_blocks::<BLOCK>(blocks, dt)
        }
        #[target_feature(enable = "avx2,avx")]
        unsafe fn avx2(blocks: &mut [Block], dt: f64) {
            step_blocks::<BLOCK>(blocks, dt)
        }
        #[target_feature(enable = "sse4.1")]
        unsafe fn sse41(blocks: &mut [Block], dt: f64) {
            step_blocks::<BLOCK>(blocks, dt)
        }
        let used = self.len.div_ceil(BLOCK);
        let mut stepped = Vec::new();
        let mut run = |name, step: &dyn Fn(&mut [Block], f64)| {
            let mut fleet = self.clone();
            step(&mut fleet.blocks[..used], fleet.dt);
            stepped.push((name, fleet));
        };
        // SAFETY (each): the function runs only where the CPU reports its features.
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
            && std::arch::is_x86_feature_detected!("avx512dq")
        {
            run("avx512", &|blocks, dt| unsafe { avx512(blocks, dt) });
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            run("avx2", &|blocks, dt| unsafe { avx2(blocks, dt) });
        }
        if std::arch::is_x86_feature_detected!("sse4.1") {
            run("sse4.1", &|blocks, dt| unsafe { sse41(blocks, dt) });
        }
        stepped
    }
}

#[multiversion(targets("x86_64+avx512f+avx512vl+avx512dq", "x86_64+avx2+avx", "x86_64+sse4.1"))]
fn step_dispatched(blocks: &mut [Block], dt: f64) {
    step_blocks::<BLOCK>(blocks, dt);
}

/// Steps every block, N of its vehicles at a time (N divides `BLOCK`).
#[inline(always)]
fn step_blocks<const N: usize>(blocks: &mut [Block], dt: f64) {
    for block in blocks {
        for from in (0..BLOCK).step_by(N) {
            let x: StateLanes<N> = block.x.map(|lanes| Lanes::part(&lanes, from));
            let inputs = Inputs {
                accel: Lanes::part(&block.inputs.accel, from),
                preview: Lanes::part(&block.inputs.preview, from),
                curvature: Lanes::part(&block.inputs.curvature, from),
            };
            let next = step_lanes(&x, &inputs, &Model::part(&block.model, from), dt);
            for (lanes, wide) in next.into_iter().zip(&mut block.x) {
                lanes.write_into(wide, from);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::STATES;
    use crate::dynamics::{DriverParams, Style, VehicleParams};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// 203 vehicles (not a multiple of any block) of every style, from a standstill to
    /// 40 m/s, with headings and steering beyond the series' range and at the lock, on
    /// straight lanes and arcs.
    fn mixed_fleet() -> (Fleet, Vec<(VehicleStep, VehicleState, Command, f64)>) {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut fleet = Fleet::default();
        let mut alone = Vec::new();
        for i in 0..203 {
            let driver = DriverParams::for_style(Style::ALL[i % 3]);
            let stepper = VehicleStep::new(&VehicleParams::default(), &driver, 1.0 / 30.0);
            let state = VehicleState {
                vx: rng.random_range(-0.5..40.0),
                vy: rng.random_range(-2.0..2.0),
                yaw_rate: rng.random_range(-1.0..1.0),
                heading: rng.random_range(-0.6..0.6),
                s: rng.random_range(0.0..1000.0),
                d: rng.random_range(-12.0..2.0),
                steer: rng.random_range(-0.7..0.7),
                steer_rate: rng.random_range(-3.0..3.0),
            };
            let command = Command { accel: rng.random_range(-6.0..3.0), preview: rng.random_range(-12.0..2.0) };
            // Straight lanes in runs of blocks, and arcs, so both paths of eq. (6) run.
            let curvature = [0.0, 0.0, 0.002, -0.01][(i / 16) % 4];
            fleet.push(i as u64, &stepper, &state, command, curvature);
            alone.push((stepper, state, command, curvature));
        }
        (fleet, alone)
    }

    fn bits(fleet: &Fleet) -> Vec<[u64; STATES]> {
        (0..fleet.len).map(|i| fleet.state(i).to_array().map(f64::to_bits)).collect()
    }

    #[test]
    fn every_block_width_gives_each_vehicle_the_bits_it_gets_alone() {
        let (fleet, alone) = mixed_fleet();
        let expected: Vec<[u64; STATES]> = alone
            .iter()
            .map(|(stepper, state, command, curvature)| {
                stepper.step(state, *command, *curvature).to_array().map(f64::to_bits)
            })
            .collect();
        let mut dispatched = fleet.clone();
        dispatched.step();
        assert_eq!(bits(&dispatched), expected, "the widest vectors of this machine");
        for (width, step) in [
            (1, Fleet::step_unvectorised::<1> as fn(&mut Fleet)),
            (2, Fleet::step_unvectorised::<2>),
            (4, Fleet::step_unvectorised::<4>),
            (8, Fleet::step_unvectorised::<8>),
        ] {
            let mut unvectorised = fleet.clone();
            step(&mut unvectorised);
            assert_eq!(bits(&unvectorised), expected, "blocks of {width} without target features");
        }
        #[cfg(target_arch = "x86_64")]
        for (instructions, stepped) in fleet.step_with_each_instruction_set() {
            assert_eq!(bits(&stepped), expected, "blocks of {BLOCK} compiled for {instructions}");
        }
    }

    #[test]
    fn the_limits_hold_in_a_block() {
        let (mut fleet, alone) = mixed_fleet();
        fleet.step();
        let lock = VehicleParams::default().max_steer;
        for (i, (_, before, ..)) in alone.iter().enumerate() {
            let after = fleet.state(i);
            assert!(after.vx >= 0.0, "vehicle {i} reversed");
            assert!(after.steer.abs() <= lock, "vehicle {i} steered past the lock");
            assert!(after.s != before.s || before.vx <= 0.0, "vehicle {i} did not move");
        }
    }

    #[test]
    fn a_cleared_fleet_steps_only_what_is_pushed_again() {
        let (mut fleet, alone) = mixed_fleet();
        fleet.clear();
        let (stepper, state, command, curvature) = alone[5];
        fleet.push(5, &stepper, &state, command, curvature);
        fleet.step();
        assert_eq!(fleet.len, 1);
        assert_eq!(fleet.state(0), stepper.step(&state, command, curvature));
    }
}
