//! The reward phase of a step (docs/rewards.md). An agent's reward for a step is the
//! paper's cost J (eq. 9, with its own style's Table III weights, averaged over the step's
//! control periods: the yardstick the built-in AV decides by) mapped into (0, 1] by
//! J_0 / (J_0 + J), as highway-env maps its rewards into [0, 1], times the share of its
//! aimed-for speed it drove (the paper's J charges nothing for standing still behind a
//! lane end or a slow car, and PPO learned to stop); the step it crashes or leaves the
//! road earns `RewardSpec::crash` (by default minus the episode length, so any episode
//! with a crash returns less than any without). The step's cost comes from the simulate
//! phase (`simulate::StepCost`).

use arena_sim::RewardSpec;

use super::simulate::StepCost;

/// The reward of one step: `spec.crash` (default: minus `max_cycles`) on the step the
/// agent crashes or leaves the road, else J_0 / (J_0 + J) times the step's mean speed
/// over `aim` (at most 1): in [0, 1].
pub fn reward(spec: &RewardSpec, max_cycles: u32, step: &StepCost, aim: f64, crashed_now: bool) -> f64 {
    if crashed_now {
        return spec.crash.unwrap_or(-f64::from(max_cycles));
    }
    if step.weighted.is_nan() {
        return 0.0;
    }
    let progress = if aim > 0.0 { (step.speed / aim).clamp(0.0, 1.0) } else { 1.0 };
    spec.cost_scale / (spec.cost_scale + step.weighted.max(0.0)) * progress
}
