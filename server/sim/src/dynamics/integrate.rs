//! Fixed-step integration of eq. (7)-(8): the classical RK4 step for any right-hand side,
//! the closed loop's step with the limits the model leaves out (no reversing, the
//! steering lock), and `VehicleStep`, that step with its constants prepared once. `Fleet`
//! runs the same `step_lanes` on blocks of vehicles.

use std::ops::{Add, Mul};

use super::lanes::{self, Lanes};
use super::model::{Inputs, Model, derivative_at};
use super::params::{DriverParams, VehicleParams};
use super::state::{Command, STATES, StateLanes, VehicleState, array_of, lanes_of};

/// A right-hand side x' = f(x) for `rk4`: any closure, or `Closed` (a trait, not a
/// closure, so that the world step's f is inlined into its vectorised caller).
pub trait Derivative<T> {
    /// f(x).
    fn at(&self, x: &[T; STATES]) -> [T; STATES];
}

impl<T, F: Fn(&[T; STATES]) -> [T; STATES]> Derivative<T> for F {
    #[inline(always)]
    fn at(&self, x: &[T; STATES]) -> [T; STATES] {
        self(x)
    }
}

/// f of eq. (7)-(8) for N vehicles under fixed inputs: the closed loop RK4 integrates.
struct Closed<'a, const N: usize> {
    inputs: &'a Inputs<N>,
    model: &'a Model<N>,
}

impl<const N: usize> Derivative<Lanes<N>> for Closed<'_, N> {
    #[inline(always)]
    fn at(&self, x: &StateLanes<N>) -> StateLanes<N> {
        derivative_at(x, self.inputs, self.model)
    }
}

/// One classical Runge–Kutta step of `dt` for any right-hand side, on one vehicle's
/// states (`f64`) or N vehicles' (`Lanes<N>`).
#[inline(always)]
pub fn rk4<T>(x: &[T; STATES], dt: f64, f: impl Derivative<T>) -> [T; STATES]
where
    T: Copy + From<f64> + Add<Output = T> + Mul<Output = T>,
{
    #[inline(always)]
    fn offset<T: Copy + From<f64> + Add<Output = T> + Mul<Output = T>>(
        x: &[T; STATES],
        k: &[T; STATES],
        h: f64,
    ) -> [T; STATES] {
        let mut y = *x;
        for (y, k) in y.iter_mut().zip(k) {
            *y = *y + T::from(h) * *k;
        }
        y
    }
    // k1 + 2 k2 + 2 k3 + k4 summed as each k comes (the same order, so the same bits),
    // which keeps fewer of them alive at once.
    let (half, sixth, two) = (dt * 0.5, dt * (1.0 / 6.0), T::from(2.0));
    let k = f.at(x);
    let mut sum = k;
    let k = f.at(&offset(x, &k, half));
    sum.iter_mut().zip(&k).for_each(|(sum, k)| *sum = *sum + two * *k);
    let k = f.at(&offset(x, &k, half));
    sum.iter_mut().zip(&k).for_each(|(sum, k)| *sum = *sum + two * *k);
    let k = f.at(&offset(x, &k, dt));
    sum.iter_mut().zip(&k).for_each(|(sum, k)| *sum = *sum + *k);
    offset(x, &sum, sixth)
}

/// One RK4 step of eq. (7)-(8) for N vehicles, then the limits the model does not
/// enforce itself: a car does not reverse, and the steering stops at its lock.
#[inline(always)]
pub(super) fn step_lanes<const N: usize>(
    x: &StateLanes<N>,
    inputs: &Inputs<N>,
    model: &Model<N>,
    dt: f64,
) -> StateLanes<N> {
    let mut next = rk4(x, dt, Closed { inputs, model });
    let zero = Lanes::splat(0.0);
    next[0] = Lanes::select(next[0].lt(zero), zero, next[0]);
    let locked = lanes::mask(|i| next[6].0[i].abs() > model.max_steer.0[i]);
    next[6] = Lanes::select(locked, next[6].clamp(-model.max_steer, model.max_steer), next[6]);
    next[7] = Lanes::select(locked, zero, next[7]);
    next
}

/// Advances a vehicle by one physics step with the driver model closing the loop:
/// `Fleet` does this for the world; tests step one vehicle.
#[cfg(test)]
pub fn step(
    state: &VehicleState,
    command: Command,
    curvature: f64,
    dt: f64,
    vehicle: &VehicleParams,
    driver: &DriverParams,
) -> VehicleState {
    VehicleStep::new(vehicle, driver, dt).step(state, command, curvature)
}

/// `step` with the constants of f prepared once, for a world that steps many vehicles
/// of the same kind every tick (`Fleet` steps them in blocks).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleStep {
    pub(super) model: Model<1>,
    pub(super) dt: f64,
}

impl VehicleStep {
    /// Prepares the step of a `vehicle` with `driver` over `dt`.
    pub fn new(vehicle: &VehicleParams, driver: &DriverParams, dt: f64) -> VehicleStep {
        VehicleStep { model: Model::new(vehicle, driver), dt }
    }

    /// One RK4 step of eq. (7)-(8).
    #[inline]
    pub fn step(&self, state: &VehicleState, command: Command, curvature: f64) -> VehicleState {
        let inputs = Inputs::one(command, curvature);
        VehicleState::from_array(array_of(&step_lanes(&lanes_of(&state.to_array()), &inputs, &self.model, self.dt)))
    }
}
