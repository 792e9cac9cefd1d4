//! The model the MPC plans with: eq. (22)-(23), the analytic Jacobians of f about a
//! point (with the affine term that keeps it exact there), and eq. (24), their exact
//! zero-order-hold discretisation over one planning step.

use nalgebra::{SMatrix, SVector};

use super::model::{Model, derivative, lateral_forces};
use super::params::{DriverParams, VehicleParams};
use super::state::{Command, INPUTS, STATES, VehicleState, lanes_of};

/// The continuous-time linearisation of eq. (22)–(23) around (x_t, u_t), plus the
/// affine term `f(x_t, u_t) - A x_t - B u_t` so the model stays exact at the point.
#[derive(Debug, Clone, PartialEq)]
pub struct Linearisation {
    /// A_t = df/dx.
    pub a: SMatrix<f64, STATES, STATES>,
    /// B_t = df/du, columns [a_x, Y_p].
    pub b: SMatrix<f64, STATES, INPUTS>,
    /// f(x_t, u_t) - A_t x_t - B_t u_t.
    pub offset: SVector<f64, STATES>,
}

/// eq. (23): the analytic Jacobians of `derivative` (above the low-speed guard).
pub fn linearise(
    state: &VehicleState,
    command: Command,
    curvature: f64,
    vehicle: &VehicleParams,
    driver: &DriverParams,
) -> Linearisation {
    let x = state.to_array();
    let [vx, vy, r, heading, _, d, steer, _] = x;
    let VehicleParams {
        mass, yaw_inertia, front_axle: lf, rear_axle: lr, front_stiffness: kf, rear_stiffness: kr, ..
    } = *vehicle;
    let mut a = SMatrix::<f64, STATES, STATES>::zeros();
    let mut b = SMatrix::<f64, STATES, INPUTS>::zeros();
    let (front, ..) = lateral_forces(&lanes_of(&x), &Model::new(vehicle, driver));
    let front = front.0[0];
    let (sin_steer, cos_steer) = steer.sin_cos();

    // Tyre forces' partials over [vx, vy, r, steer].
    let front_d = [kf * (vy + lf * r) / (vx * vx), -kf / vx, -kf * lf / vx, kf];
    let rear_d = [kr * (vy - lr * r) / (vx * vx), -kr / vx, kr * lr / vx, 0.0];
    let columns = [0, 1, 2, 6];

    a[(0, 1)] = r;
    a[(0, 2)] = vy;
    b[(0, 0)] = 1.0;
    for (k, &col) in columns.iter().enumerate() {
        a[(1, col)] = (front_d[k] * cos_steer + rear_d[k]) / mass;
        a[(2, col)] = (lf * front_d[k] * cos_steer - lr * rear_d[k]) / yaw_inertia;
    }
    a[(1, 0)] -= r;
    a[(1, 2)] -= vx;
    a[(1, 6)] -= front * sin_steer / mass;
    a[(2, 6)] -= lf * front * sin_steer / yaw_inertia;

    let (sin, cos) = heading.sin_cos();
    let stretch = 1.0 - curvature * d;
    let s_dot = (vx * cos - vy * sin) / stretch;
    let s_dot_d = [cos / stretch, -sin / stretch, (-vx * sin - vy * cos) / stretch, s_dot * curvature / stretch];
    for (k, &col) in [0, 1, 3, 5].iter().enumerate() {
        a[(4, col)] = s_dot_d[k];
        a[(3, col)] = -curvature * s_dot_d[k];
    }
    a[(3, 2)] = 1.0;
    a[(5, 0)] = sin;
    a[(5, 1)] = cos;
    a[(5, 3)] = vx * cos - vy * sin;
    a[(6, 7)] = 1.0;

    let DriverParams { delay, preview_time, steering_gain, damping, .. } = *driver;
    let gain = steering_gain / (damping * delay * delay);
    let ratio = driver.steering_ratio_at(vx);
    let ratio_dvx = driver.steering_ratio_slope_at(vx);
    let error = command.preview - (d + preview_time * vx * heading);
    a[(7, 7)] = -1.0 / (damping * delay);
    a[(7, 6)] = -1.0 / (damping * delay * delay);
    a[(7, 5)] = -ratio * gain;
    a[(7, 3)] = -ratio * gain * preview_time * vx;
    a[(7, 0)] = gain * (ratio_dvx * error - ratio * preview_time * heading);
    b[(7, 1)] = ratio * gain;

    let f = SVector::from(derivative(&x, command, curvature, vehicle, driver));
    let offset = f - a * SVector::from(x) - b * SVector::from([command.accel, command.preview]);
    Linearisation { a, b, offset }
}

/// The largest 1-norm of [[A, B, c], [0, 0, 0]] dT `discretise` takes: a vehicle's is
/// tens at most (gains over time constants of tenths of a second, times dT; the gt
/// bench's worlds keep their digest under this bound); past 1e12 the state it came from
/// has blown up, or came so from outside.
pub const MAX_MODEL_NORM: f64 = 1e12;

/// The discrete model of eq. (24): x(k+1) = A_k x(k) + B_k u(k) + c_k.
#[derive(Debug, Clone, PartialEq)]
pub struct Discretisation {
    /// A_k = e^(A_t dT).
    pub a: SMatrix<f64, STATES, STATES>,
    /// B_k = integral_0^dT e^(A_t tau) B_t dtau.
    pub b: SMatrix<f64, STATES, INPUTS>,
    /// The same integral applied to the affine term.
    pub offset: SVector<f64, STATES>,
}

impl Linearisation {
    /// eq. (24), exactly: the exponential of the augmented matrix [[A, B, c], [0, 0, 0]] dT
    /// holds A_k, B_k and c_k in its top rows (zero-order hold on u).
    pub fn discretise(&self, dt: f64) -> Discretisation {
        const N: usize = STATES + INPUTS + 1;
        let mut augmented = SMatrix::<f64, N, N>::zeros();
        augmented.fixed_view_mut::<STATES, STATES>(0, 0).copy_from(&(self.a * dt));
        augmented.fixed_view_mut::<STATES, INPUTS>(0, STATES).copy_from(&(self.b * dt));
        augmented.fixed_view_mut::<STATES, 1>(0, STATES + INPUTS).copy_from(&(self.offset * dt));
        // nalgebra squares the exponential about log2 of the matrix's norm times: an
        // infinite entry would make that 2^64 times (a server held forever by one bad
        // state). A model past `MAX_MODEL_NORM` is not a vehicle's: it is all NaN, which
        // the MPC refuses (`MpcError::NonFinite`) and falls back from.
        let norm =
            augmented.column_iter().map(|column| column.iter().map(|x| x.abs()).sum::<f64>()).fold(0.0, f64::max);
        if !augmented.iter().all(|x| x.is_finite()) || norm > MAX_MODEL_NORM {
            let nan = SMatrix::<f64, N, N>::from_element(f64::NAN);
            return Discretisation {
                a: nan.fixed_view::<STATES, STATES>(0, 0).into_owned(),
                b: nan.fixed_view::<STATES, INPUTS>(0, STATES).into_owned(),
                offset: nan.fixed_view::<STATES, 1>(0, STATES + INPUTS).into_owned(),
            };
        }
        let exp = augmented.exp();
        Discretisation {
            a: exp.fixed_view::<STATES, STATES>(0, 0).into_owned(),
            b: exp.fixed_view::<STATES, INPUTS>(0, STATES).into_owned(),
            offset: exp.fixed_view::<STATES, 1>(0, STATES + INPUTS).into_owned(),
        }
    }
}
