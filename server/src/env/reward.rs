//! The reward phase of a step (docs/rewards.md). An agent's reward for a step is the
//! paper's cost J (eq. 9, with its own style's Table III weights, averaged over the step's
//! control periods: the yardstick the built-in AV decides by) mapped into (0, 1] by
//! J_0 / (J_0 + J), as highway-env maps its rewards into [0, 1], times the share of its
//! aimed-for speed it drove (the paper's J charges nothing for standing still behind a
//! lane end or a slow car, and PPO learned to stop), less `RewardSpec::risk_weight` times
//! the step's risk (`risk::risk`: how near a crash it drove; J_0 / (J_0 + J) alone cannot
//! charge a near miss more than one step's reward, and PPO learned to pass cars side by
//! side), plus `RewardSpec::goal_bonus` on the step it reaches the scenario's goal (less
//! it on a step that leaves it: potential-based shaping, so an episode's payments sum to
//! the bonus times whether it ends there and did not start there); the step it crashes or
//! leaves the road earns `RewardSpec::crash_reward` (by default below any episode without
//! a crash). The step's cost and risk come from the simulate phase (`simulate::StepCost`).

use arena_sim::RewardSpec;

use super::simulate::StepCost;

/// Whether the agent is at the scenario's goal before and after a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GoalChange {
    pub before: bool,
    pub after: bool,
}

impl GoalChange {
    /// +1 on reaching the goal, -1 on leaving it, else 0.
    fn sign(self) -> f64 {
        f64::from(u8::from(self.after)) - f64::from(u8::from(self.before))
    }
}

/// The reward of one step: `spec.crash_reward` on the step the agent crashes or leaves
/// the road, else J_0 / (J_0 + J) times the step's mean speed over `aim` (at most 1),
/// less `risk_weight` times its mean risk, plus `goal_bonus` if the step reached the goal
/// (minus it if it left it): in [-risk_weight - goal_bonus, 1 + goal_bonus].
pub fn reward(
    spec: &RewardSpec,
    max_cycles: u32,
    step: &StepCost,
    aim: f64,
    crashed_now: bool,
    goal: GoalChange,
) -> f64 {
    if crashed_now {
        return spec.crash_reward(max_cycles);
    }
    let shaping = spec.goal_bonus * goal.sign();
    if step.weighted.is_nan() {
        return shaping;
    }
    let progress = if aim > 0.0 { (step.speed / aim).clamp(0.0, 1.0) } else { 1.0 };
    spec.cost_scale / (spec.cost_scale + step.weighted.max(0.0)) * progress - spec.risk_weight * step.risk + shaping
}
