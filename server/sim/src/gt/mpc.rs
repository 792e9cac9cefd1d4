//! Motion planning of §V-B: the Delta-u MPC of eq. (25)–(29) on the world core's
//! linearised, discretised driver + bicycle model (eq. 22–24, `dynamics`), with the
//! potential field (eq. 19–21) as its first output, linearised along the predicted path,
//! the lateral error to the target lane's centre and the heading error as the other two.
//! The input is the preview point Y_p; a_x is the game's decision, reached from the last
//! command at the jerk bound and then held over the horizon (`jerk::AccelRamp`).
//!
//! Condensed, the problem is a QP in the N_c input increments. Where the minimiser of
//! its objective keeps every bound (lane keeping, most of a lane change), that is its
//! exact solution, found with one Cholesky solve; otherwise clarabel solves it. The
//! solver is built once per problem size and then only has P, q and b overwritten
//! (clarabel's data updates); equilibration is off, so a solve depends on the problem
//! data alone and a reused solver returns the same bits as a fresh one (tested).

use std::cell::RefCell;

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus};
use nalgebra::{DMatrix, DVector, SVector};
use serde::{Deserialize, Serialize};

use super::field::Field;
use super::jerk::AccelRamp;
use crate::dynamics::{self, Command, DriverParams, STATES, VehicleParams, VehicleState};

/// The MPC's constants; the paper leaves all of them open.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MpcParams {
    /// N_p of eq. (25), prediction horizon (steps of the control period). 25, chosen
    /// here: 2.5 s at 10 Hz, past the driver's preview time and most of a lane change.
    pub prediction_horizon: usize,
    /// N_c of eq. (25), control horizon (steps). 10, chosen here: 1 s of input moves.
    pub control_horizon: usize,
    /// Q's weight on y_1, the potential field (1/unit^2). 20, chosen here.
    pub field_weight: f64,
    /// Q's weight on y_2, the lateral error to the target lane's centre (1/m^2). 1.
    pub lateral_weight: f64,
    /// Q's weight on y_3, the heading error to the lane (1/rad^2). 30, chosen here.
    pub heading_weight: f64,
    /// R of eq. (26), on each Delta Y_p (1/m^2). 10, chosen here: with `max_step` a 4 m
    /// lane change takes about 4 s and peaks at 1.5–2.1 m/s^2 sideways (tested).
    pub rate_weight: f64,
    /// Delta u_max of eq. (27) (m per step): the preview point moves at most this per
    /// control period. 0.15, chosen here (1.5 m/s sideways), matching the 4 s quintic the
    /// games predict with.
    pub max_step: f64,
    /// u_min, u_max of eq. (27): Y_p stays within the road's outer lane centres widened
    /// by this (m). 2, chosen here (to the road's edges).
    pub preview_margin: f64,
    /// Below this speed (m/s) the linearisation (which divides by v_x) is not used: Y_p
    /// is the target lane's centre. 2, chosen here.
    pub min_speed: f64,
    /// While the car keeps its lane, Y_p stays within this of the lane's centre (m), or
    /// within where it already is, if that is farther: an offset the field asks for (a car
    /// closing from behind, one drifting beside) is bounded, and a larger one only shrinks.
    /// 0.3, chosen here: the driver model's overshoot of a steady Y_p stays under 0.2 m,
    /// so the car keeps within 0.5 m of its lane's centre.
    #[serde(default = "default_lane_keeping_bound")]
    pub lane_keeping_bound: f64,
    /// Delta u_max (m per step) while the preview point comes back to the lane it keeps
    /// from beyond `lane_keeping_bound` (a lane change given up). 0.3, chosen here: twice
    /// `max_step`, since at a lane change's pace the change's sideways momentum carried
    /// the car past the line it had turned back from (a trace of dense on-ramp traffic).
    #[serde(default = "default_return_step")]
    pub return_step: f64,
}

fn default_lane_keeping_bound() -> f64 {
    MpcParams::default().lane_keeping_bound
}

fn default_return_step() -> f64 {
    MpcParams::default().return_step
}

impl Default for MpcParams {
    fn default() -> Self {
        MpcParams {
            prediction_horizon: 25,
            control_horizon: 10,
            field_weight: 20.0,
            lateral_weight: 1.0,
            heading_weight: 30.0,
            rate_weight: 10.0,
            max_step: 0.15,
            preview_margin: 2.0,
            min_speed: 2.0,
            lane_keeping_bound: 0.3,
            return_step: 0.3,
        }
    }
}

/// One planning problem.
#[derive(Debug, Clone, Copy)]
pub struct MpcProblem<'a> {
    /// The car now.
    pub state: VehicleState,
    /// a_x over the horizon: the decision's, along its ramp from the last command.
    pub accel: AccelRamp,
    /// u(k-1): the preview point applied last period (m).
    pub previous_preview: f64,
    /// The target lane's centre (m): y_2 is measured from it.
    pub target: f64,
    /// Road curvature at the car (1/m).
    pub curvature: f64,
    /// Table II.
    pub vehicle: &'a VehicleParams,
    /// Table I.
    pub driver: &'a DriverParams,
    /// Delta T of eq. (24) (s): the control period.
    pub dt: f64,
    /// The potential field around the car.
    pub field: &'a Field,
    /// Last period's Delta u plan, used (shifted) as the path the field is linearised on.
    pub nominal: &'a [f64],
    /// [u_min, u_max] (m).
    pub preview_bounds: (f64, f64),
}

/// A solved plan.
#[derive(Debug, Clone, PartialEq)]
pub struct MpcSolution {
    /// u(k|k) of eq. (29): the preview point to apply now (m).
    pub preview: f64,
    /// Delta u* of eq. (28).
    pub plan: Vec<f64>,
    /// Interior-point iterations (0 when the low-speed rule applied).
    pub iterations: u32,
}

/// Occurs when the MPC cannot produce a plan; the driver then falls back.
#[derive(Debug, Clone, PartialEq)]
pub enum MpcError {
    /// Occurs when the problem data are not finite (a state blew up).
    NonFinite,
    /// Occurs when clarabel refuses the problem at setup.
    Setup(String),
    /// Occurs when clarabel stops without a solution.
    Solver(String),
}

impl std::fmt::Display for MpcError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MpcError::NonFinite => write!(f, "MPC problem data not finite"),
            MpcError::Setup(message) => write!(f, "MPC QP refused at setup: {message}"),
            MpcError::Solver(status) => write!(f, "MPC QP not solved: {status}"),
        }
    }
}

/// The QP of eq. (26)–(27) in condensed form: min 1/2 z'Pz + q'z s.t. A z <= b, z = Delta u.
#[derive(Debug, Clone, PartialEq)]
pub struct Qp {
    /// The Hessian (dense, symmetric).
    pub p: DMatrix<f64>,
    /// The linear term.
    pub q: DVector<f64>,
    /// Right-hand sides of the stacked bounds [u <= max; -u <= -min; du <= max; -du <= max].
    pub b: Vec<f64>,
}

/// Builds the condensed QP: predicts the outputs of eq. (25b) as affine functions of the
/// increments and sums eq. (26).
pub(crate) fn build_qp(problem: &MpcProblem, params: &MpcParams) -> Qp {
    let n = params.control_horizon.max(1);
    let u_prev = problem.previous_preview.clamp(problem.preview_bounds.0, problem.preview_bounds.1);
    let command = Command { accel: problem.accel.to, preview: u_prev };
    let lin = dynamics::linearise(&problem.state, command, problem.curvature, problem.vehicle, problem.driver); // eq. (22)–(23)
    let disc = lin.discretise(problem.dt); // eq. (24)
    let b_y: SVector<f64, STATES> = disc.b.column(1).into_owned();
    let b_a: SVector<f64, STATES> = disc.b.column(0).into_owned();
    // a_x over step k: the ramp's mean over it (its value mid-step, as the world ramps a
    // command over the period), the decision's once it is reached.
    let drift = |k: usize| b_a * problem.accel.at((k as f64 + 0.5) * problem.dt) + disc.offset;
    let mut nominal: Vec<f64> = problem.nominal.iter().skip(1).copied().collect();
    nominal.resize(n, 0.0);

    let mut x = SVector::<f64, STATES>::from(problem.state.to_array());
    // d x(k) / d Delta u(j) is the response to one increment j steps late: the same
    // sequence shifted, `impulse[k - j]` for j <= k and zero before the increment, so
    // only the increments that have moved x(k) (the first `moved`) enter its terms.
    let mut impulse = Vec::with_capacity(params.prediction_horizon);
    let mut response = SVector::<f64, STATES>::zeros();
    let (mut p, mut q) = (DMatrix::<f64>::zeros(n, n), DVector::<f64>::zeros(n));
    let mut gain = vec![0.0; n];
    // eq. (26), ||y||_Q^2: P += w g g', q += c w g, as nalgebra's `ger` and `axpy` sum them.
    // Over P's columns as slices (column-major), so the compiler can use vectors: each
    // entry's sum is the same, (w g_j) g_i added once.
    let mut add = |gain: &[f64], constant: f64, weight: f64| {
        for (column, &gain_j) in p.as_mut_slice().chunks_exact_mut(n).zip(gain) {
            let scale = weight * gain_j;
            column.iter_mut().zip(gain).for_each(|(entry, &gain_i)| *entry += scale * gain_i);
        }
        let scale = constant * weight;
        q.as_mut_slice().iter_mut().zip(gain).for_each(|(entry, &gain_i)| *entry += scale * gain_i);
    };
    for k in 0..params.prediction_horizon {
        x = disc.a * x + b_y * u_prev + drift(k); // eq. (24) with u(k) = u(k-1) + sum of Delta u
        response = disc.a * response + b_y;
        impulse.push(response);
        let moved = n.min(k + 1);
        let sens = |j: usize| &impulse[k - j];
        let t = (k + 1) as f64 * problem.dt;
        let along = |i: usize| (0..moved).map(|j| sens(j)[i] * nominal[j]).sum::<f64>();
        let (nominal_s, nominal_d) = (x[4] + along(4), x[5] + along(5));
        let (value, grad_s, grad_d) = problem.field.gradient(nominal_s, nominal_d, t);
        // y_1 linearised at the nominal path; y_2, y_3 exact in the linear model.
        let gain = &mut gain[..moved];
        gain.iter_mut().enumerate().for_each(|(j, g)| *g = grad_s * sens(j)[4] + grad_d * sens(j)[5]);
        let field = value + grad_s * (x[4] - nominal_s) + grad_d * (x[5] - nominal_d);
        add(gain, field, params.field_weight);
        gain.iter_mut().enumerate().for_each(|(j, g)| *g = sens(j)[5]);
        add(gain, x[5] - problem.target, params.lateral_weight);
        gain.iter_mut().enumerate().for_each(|(j, g)| *g = sens(j)[3]);
        add(gain, x[3], params.heading_weight);
    }
    for i in 0..n {
        p[(i, i)] += params.rate_weight; // eq. (26), ||Delta u||_R^2
    }
    let (low, high) = problem.preview_bounds;
    let mut b = Vec::with_capacity(4 * n);
    b.extend(std::iter::repeat_n(high - u_prev, n)); // eq. (27): u <= u_max
    b.extend(std::iter::repeat_n(u_prev - low, n)); // u >= u_min
    b.extend(std::iter::repeat_n(params.max_step, 2 * n)); // |Delta u| <= Delta u_max
    Qp { p, q, b }
}

/// The solver workspace: one clarabel solver per problem size, updated in place.
pub struct Mpc {
    cache: Option<(usize, DefaultSolver<f64>)>,
}

impl Default for Mpc {
    fn default() -> Self {
        Mpc::new()
    }
}

impl std::fmt::Debug for Mpc {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mpc").field("size", &self.cache.as_ref().map(|(n, _)| *n)).finish()
    }
}

/// clarabel's settings. The gap and feasibility tolerances are 1e-6 rather than the
/// default 1e-8: the preview point needs millimetres, not nanometres, and the looser
/// stop saves interior-point iterations (docs/performance.md).
fn settings() -> DefaultSettings<f64> {
    DefaultSettings {
        verbose: false,
        equilibrate_enable: false,
        presolve_enable: false,
        input_sparse_dropzeros: false,
        tol_gap_abs: MPC_TOLERANCE,
        tol_gap_rel: MPC_TOLERANCE,
        tol_feas: MPC_TOLERANCE,
        ..DefaultSettings::default()
    }
}

/// The QP's gap and feasibility tolerance.
const MPC_TOLERANCE: f64 = 1e-6;

/// The upper triangle of a dense n x n matrix in CSC order.
fn upper_triangle(p: &DMatrix<f64>) -> Vec<f64> {
    let n = p.nrows();
    (0..n).flat_map(|j| (0..=j).map(move |i| (i, j))).map(|(i, j)| p[(i, j)]).collect()
}

/// The QP's solution when no bound of eq. (27) is active: the minimiser of 1/2 z'Pz + q'z
/// (P z = -q, by Cholesky: P is positive definite, R > 0 on its diagonal), if it keeps
/// every bound; the QP is convex, so it is then the QP's exact solution. `None` when it
/// breaks a bound (clarabel then solves the QP) or P is not positive definite.
fn unconstrained(qp: &Qp) -> Option<Vec<f64>> {
    let z = -qp.p.clone().cholesky()?.solve(&qp.q);
    let z: Vec<f64> = z.iter().copied().collect();
    let keeps = constrained_sides(&z).iter().zip(&qp.b).all(|(side, bound)| side <= bound);
    keeps.then_some(z)
}

/// A z for the constraint matrix of `constraint_matrix`: the preview point's moves summed
/// (u(k) - u(k-1)), negated, then the moves themselves, negated.
fn constrained_sides(z: &[f64]) -> Vec<f64> {
    let sums: Vec<f64> = z
        .iter()
        .scan(0.0, |sum, dz| {
            *sum += dz;
            Some(*sum)
        })
        .collect();
    let negated = |v: &[f64]| v.iter().map(|x| -x).collect::<Vec<_>>();
    [sums.clone(), negated(&sums), z.to_vec(), negated(z)].concat()
}

/// The constraint matrix [T; -T; I; -I] (T lower-triangular ones: u(k) - u(k-1) summed).
fn constraint_matrix(n: usize) -> CscMatrix<f64> {
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for j in 0..n {
        for i in j..n {
            rowval.push(i);
            nzval.push(1.0);
        }
        for i in j..n {
            rowval.push(n + i);
            nzval.push(-1.0);
        }
        rowval.extend([2 * n + j, 3 * n + j]);
        nzval.extend([1.0, -1.0]);
        colptr.push(rowval.len());
    }
    CscMatrix::new(4 * n, n, colptr, rowval, nzval)
}

fn hessian(n: usize, values: Vec<f64>) -> CscMatrix<f64> {
    let mut colptr = vec![0];
    let mut rowval = Vec::with_capacity(n * (n + 1) / 2);
    for j in 0..n {
        rowval.extend(0..=j);
        colptr.push(rowval.len());
    }
    CscMatrix::new(n, n, colptr, rowval, values)
}

impl Mpc {
    /// An empty workspace.
    pub fn new() -> Mpc {
        Mpc { cache: None }
    }

    /// Solves eq. (27) and returns eq. (28)–(29), or why it could not.
    pub fn solve(&mut self, problem: &MpcProblem, params: &MpcParams) -> Result<MpcSolution, MpcError> {
        let (low, high) = problem.preview_bounds;
        if low.partial_cmp(&high).is_none_or(|order| order.is_gt()) {
            return Err(MpcError::Setup(format!("empty preview bounds [{low}, {high}]")));
        }
        let target = problem.target.clamp(low, high);
        if problem.state.vx < params.min_speed {
            return Ok(MpcSolution { preview: target, plan: vec![0.0; params.control_horizon], iterations: 0 });
        }
        let qp = build_qp(problem, params);
        let finite = qp.p.iter().chain(qp.q.iter()).chain(qp.b.iter()).all(|v| v.is_finite());
        if !finite {
            return Err(MpcError::NonFinite);
        }
        let (plan, iterations) = match unconstrained(&qp) {
            Some(plan) => (plan, 0),
            None => (self.solve_qp(&qp)?, self.iterations()),
        };
        let u_prev = problem.previous_preview.clamp(problem.preview_bounds.0, problem.preview_bounds.1);
        let preview = u_prev + plan.first().copied().unwrap_or(0.0); // eq. (29)
        Ok(MpcSolution { preview, plan, iterations })
    }

    fn iterations(&self) -> u32 {
        self.cache.as_ref().map_or(0, |(_, solver)| solver.solution.iterations)
    }

    /// Solves a condensed QP, reusing the solver of its size.
    pub fn solve_qp(&mut self, qp: &Qp) -> Result<Vec<f64>, MpcError> {
        let n = qp.q.len();
        let values = upper_triangle(&qp.p);
        let q: Vec<f64> = qp.q.iter().copied().collect();
        match &mut self.cache {
            Some((size, solver)) if *size == n => {
                let updated =
                    solver.update_P(&values).and_then(|_| solver.update_q(&q)).and_then(|_| solver.update_b(&qp.b));
                updated.map_err(|e| MpcError::Setup(e.to_string()))?;
            }
            _ => {
                let cones = [NonnegativeConeT(4 * n)];
                let solver =
                    DefaultSolver::new(&hessian(n, values), &q, &constraint_matrix(n), &qp.b, &cones, settings())
                        .map_err(|e| MpcError::Setup(e.to_string()))?;
                self.cache = Some((n, solver));
            }
        }
        let Some((_, solver)) = &mut self.cache else { return Err(MpcError::Setup("no solver".into())) };
        solver.solve();
        match solver.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => Ok(solver.solution.x.clone()),
            status => Err(MpcError::Solver(format!("{status:?}"))),
        }
    }
}

thread_local! {
    /// Scratch for the world's AV drivers on this thread. Results do not depend on what
    /// it solved before (see the module doc), so sharing it keeps determinism.
    static WORKSPACE: RefCell<Mpc> = RefCell::new(Mpc::new());
}

/// Solves with this thread's workspace.
pub fn solve(problem: &MpcProblem, params: &MpcParams) -> Result<MpcSolution, MpcError> {
    WORKSPACE.with(|mpc| mpc.borrow_mut().solve(problem, params))
}

#[cfg(test)]
mod tests;
