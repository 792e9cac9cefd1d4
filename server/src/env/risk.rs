//! How near a crash an agent drives: its closest approach to the cars that matter (the
//! gap and time to collision the episode's figures report) and the risk in [0, 1] that the
//! reward charges for it (docs/rewards.md, "Risk"). The paper's cost J rises steeply near
//! another car, but the reward's J_0 / (J_0 + J) saturates at 0, so a step at a near miss
//! cost at most that step's own reward: PPO learned to pass cars side by side, faster.

use arena_sim::{VehicleId, World};

/// Time to collision (s) below which a closing gap is a risk, rising to 1 at contact:
/// 1.5 s, the critical TTC of the traffic-conflict literature (Hayward's 1972 measure;
/// Vogel 2003 uses 1.5 s for a dangerous encounter).
pub const RISKY_TTC: f64 = 1.5;
/// Time headway (s) to the car ahead below which following is a risk: 0.5 s, half of the
/// 1 s IDM's `time_headway` keeps (highway-env's constant).
pub const RISKY_HEADWAY: f64 = 0.5;
/// Clearance (m) between two cars' outlines below which it is a risk, in any direction:
/// 1 m, half of what two cars level with each other keep at the centres of 4 m lanes.
pub const RISKY_CLEARANCE: f64 = 1.0;

/// The smallest bumper-to-bumper gap (m) and time to collision (s) to the cars that
/// matter now: the car ahead in the lane the vehicle is in and in the lane it changes
/// to, and the car behind in that target lane. Infinite when there is none (or, for the
/// time, when no gap ahead or behind closes).
pub fn closest_approach(world: &mut World, id: VehicleId) -> (f64, f64) {
    let scene = world.scene();
    let car = scene.car(id);
    let length = scene.vehicle.length;
    let (s, speed) = (car.state.s, car.speed());
    // (gap, closing speed) to the car ahead in each lane, and behind in the target lane.
    let ahead = [car.lane, car.target_lane]
        .map(|lane| scene.ahead(lane, s, &[id]).map(|ahead| (ahead.state.s - s - length, speed - ahead.speed())));
    let behind = (car.target_lane != car.lane)
        .then(|| scene.behind(car.target_lane, s, &[id]))
        .flatten()
        .map(|behind| (s - behind.state.s - length, behind.speed() - speed));
    ahead.into_iter().chain([behind]).flatten().fold((f64::INFINITY, f64::INFINITY), |(gap, ttc), (g, closing)| {
        // Beside a car (g <= 0) there is no time to close a gap along the road.
        let time = if g > 0.0 && closing > 0.0 { g / closing } else { f64::INFINITY };
        (gap.min(g), ttc.min(time))
    })
}

/// The risk of vehicle `id` now, in [0, 1]: the largest of how far its time to collision
/// is below `RISKY_TTC`, its headway (to the cars of `closest_approach`; 0 beside a car of
/// the lane it changes into) below `RISKY_HEADWAY` and its clearance to any car
/// below `RISKY_CLEARANCE` (outlines as rectangles along the lanes: a car cutting in
/// diagonally close counts as one beside), each as a share (0 at the threshold, 1 at
/// contact).
pub fn risk(world: &mut World, id: VehicleId) -> f64 {
    let (gap, ttc) = closest_approach(world, id);
    let scene = world.scene();
    let car = scene.car(id);
    let (length, width) = (scene.vehicle.length, scene.vehicle.width);
    let below = |value: f64, threshold: f64| (1.0 - value / threshold).clamp(0.0, 1.0);
    // A gap of 0 or less is a car beside in the lane being entered: full risk.
    let headway = below(gap.max(0.0) / car.speed().max(1.0), RISKY_HEADWAY);
    let (s, d) = (car.state.s, car.state.d);
    let close = scene
        .around(s, length + RISKY_CLEARANCE)
        .filter(|other| other.id != id)
        .map(|other| {
            let along = ((other.state.s - s).abs() - length).max(0.0);
            let across = ((other.state.d - d).abs() - width).max(0.0);
            below(along.hypot(across), RISKY_CLEARANCE)
        })
        .fold(0.0, f64::max);
    below(ttc, RISKY_TTC).max(headway).max(close)
}
