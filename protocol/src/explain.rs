//! The game-theoretic AV explained (version 8): with `CreateOptions::explain`, every step
//! reply carries one [`DecisionExplained`] per decision a game-theoretic car took during
//! the step: the game it played, both players' cost tables as the search computed them
//! (cells it proved irrelevant and skipped are NaN, rows it pruned whole are marked), the
//! equilibrium chosen, what the car then commanded, and the predicted paths. The per-agent
//! infos are untouched (their schema is fixed).

use serde::{Deserialize, Serialize};

use crate::messages::Game;
use crate::world::GtRole;

/// One game-theoretic car's decision of one control period.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DecisionExplained {
    /// Simulated time of the decision (s): the start of the control period it commands.
    pub time: f64,
    /// The car that decided (index into `WorldStart::vehicles`, the scenario's order).
    pub vehicle: u32,
    /// Nash (eq. 15-16) or Stackelberg (eq. 17-18).
    pub game: Game,
    /// Leader: the car is the game's EC. Follower: the car is its AC and `tables` holds the
    /// game of the leader it answers (a Stackelberg follower's one row is the leader's
    /// announced action; its column, AC's best reply of eq. 17b); a follower with no
    /// leader in play is the EC of its own lane's game (`ec` is itself).
    pub role: GtRole,
    /// The game's EC (a vehicle index).
    pub ec: u32,
    /// The side games played, left (`side` -1) before right (+1).
    pub tables: Vec<GameTable>,
    /// The table whose equilibrium was played (index into `tables`), the one that costs
    /// EC least (eq. 16a / 18a); `None` when EC had no action at all.
    pub chosen: Option<u32>,
    /// The acceleration the games chose for this car (m/s^2): EC's row or AC's column.
    pub games_accel: f64,
    /// The acceleration the car then commanded (m/s^2), reached at the jerk bound: the
    /// games' unless the safety layer lowered it (`safety`) or the MPC failed (`fallback`).
    pub accel: f64,
    /// The lane change the car decided: -1 left, 0 keep, +1 right.
    pub sigma: i8,
    /// Whether the safety layer lowered the games' acceleration.
    pub safety: bool,
    /// Whether the MPC failed and the car fell back to the safe command.
    pub fallback: bool,
    /// EC's predicted path at the chosen equilibrium (one point per prediction sample).
    pub planned: Vec<PathPoint>,
    /// AC's predicted path at the chosen equilibrium (empty with no AC).
    pub predicted: Vec<PathPoint>,
}

/// One side's bimatrix game: EC's actions (rows) x AC's (columns), costs row-major.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GameTable {
    /// -1: the left lane's game, +1: the right's (each includes EC's lane-keeping rows).
    pub side: i8,
    /// The AC of this side (a vehicle index), if there is one (else one column).
    pub adjacent: Option<u32>,
    /// EC's actions: (acceleration m/s^2, sigma -1/0/+1).
    pub ec_actions: Vec<(f64, i8)>,
    /// AC's accelerations (m/s^2).
    pub ac_actions: Vec<f64>,
    /// J^EC of eq. (9) per (row, col), rows x cols; NaN where the search skipped the cell.
    pub ec_costs: Vec<f64>,
    /// J^AC per (row, col); NaN where the search skipped the cell.
    pub ac_costs: Vec<f64>,
    /// Rows the search pruned whole (none of their cells computed): provably neither EC's
    /// choice nor any column's least cost for EC.
    pub pruned: Vec<bool>,
    /// The equilibrium's row.
    pub row: u32,
    /// The equilibrium's column (AC's action EC predicts).
    pub col: u32,
    /// False for a Nash game without a pure equilibrium (EC then kept its current lane
    /// decision, its best row against AC's best replies).
    pub exact: bool,
    /// J^EC at the equilibrium.
    pub cost: f64,
}

/// A point of a predicted path, in world coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PathPoint {
    /// Seconds after the decision.
    pub t: f64,
    /// Global X (m).
    pub x: f64,
    /// Global Y (m).
    pub y: f64,
    /// Speed (m/s).
    pub speed: f64,
}
