use super::*;
use crate::dynamics::Style;
use crate::gt::field::{FieldParams, Obstacle, road_lines};
use crate::road::Road;

fn straight_field(road: &Road) -> Field {
    let params = FieldParams::default();
    Field::new(params, 2.0, vec![], road_lines(road, &params, true))
}

/// A problem on a straight road at 10 Hz, coasting, with the preview point free across the road.
fn problem<'a>(
    state: VehicleState,
    previous_preview: f64,
    target: f64,
    models: (&'a VehicleParams, &'a DriverParams),
    field: &'a Field,
    nominal: &'a [f64],
) -> MpcProblem<'a> {
    let (vehicle, driver) = models;
    MpcProblem {
        state,
        accel: AccelRamp::step(0.0),
        previous_preview,
        target,
        curvature: 0.0,
        vehicle,
        driver,
        dt: 0.1,
        field,
        nominal,
        preview_bounds: (-10.0, 2.0),
    }
}

/// Closed loop: the MPC plans every 0.1 s, the model integrates at 100 Hz.
fn lane_change(style: Style, speed: f64, from: f64, to: f64, seconds: f64) -> (Vec<f64>, u32, f64) {
    let road = Road::straight(2000.0, 3, 4.0, 30.0);
    let field = straight_field(&road);
    let (vehicle, driver) = (VehicleParams::default(), DriverParams::for_style(style));
    let params = MpcParams::default();
    let mut mpc = Mpc::new();
    let mut state = VehicleState::cruising(0.0, from, speed);
    let (mut preview, mut plan, mut offsets, mut iterations) = (from, Vec::new(), Vec::new(), 0);
    let mut peak = 0.0f64;
    for _ in 0..(seconds * 10.0) as usize {
        let now = problem(state, preview, to, (&vehicle, &driver), &field, &plan);
        let solution = mpc.solve(&now, &params).expect("the lane-change QP solves");
        iterations = iterations.max(solution.iterations);
        (preview, plan) = (solution.preview, solution.plan);
        for _ in 0..10 {
            state = dynamics::step(&state, Command { accel: 0.0, preview }, 0.0, 0.01, &vehicle, &driver);
            peak = peak.max(state.lateral_accel(&vehicle).abs());
        }
        offsets.push(state.d);
    }
    (offsets, iterations, peak)
}

#[test]
fn a_lane_change_settles_without_overshoot_for_every_style_and_speed() {
    for style in Style::ALL {
        for speed in [15.0, 20.0, 30.0] {
            let (offsets, iterations, peak) = lane_change(style, speed, -4.0, 0.0, 10.0);
            // The move bound binds at the start: clarabel solved those periods.
            assert!(iterations > 0 && iterations < 50, "{style:?} at {speed} m/s: {iterations} iterations");
            let overshoot = offsets.iter().fold(f64::NEG_INFINITY, |m, &d| m.max(d));
            let settled = offsets.iter().rposition(|d| d.abs() > 0.2).map_or(0.0, |k| (k + 1) as f64 * 0.1);
            assert!(overshoot < 0.2, "{style:?} at {speed} m/s overshoots by {overshoot:.3} m");
            assert!(settled < 5.0, "{style:?} at {speed} m/s settles only at {settled:.1} s");
            // A lane change, not a swerve: the preview point moves at most max_step per period.
            assert!(peak < 2.5, "{style:?} at {speed} m/s: peak lateral acceleration {peak:.2} m/s^2");
            assert!(offsets[19] < -1.5, "{style:?} at {speed} m/s is already at {:.2} m after 2 s", offsets[19]);
        }
    }
}

#[test]
fn lane_keeping_stays_on_the_centre_between_the_lines() {
    let (offsets, iterations, _) = lane_change(Style::Normal, 25.0, -4.0, -4.0, 5.0);
    assert!(offsets.iter().all(|d| (d + 4.0).abs() < 0.05), "{offsets:?}");
    assert_eq!(iterations, 0, "no bound is active: every QP solved directly");
}

#[test]
fn the_direct_solution_is_the_one_clarabel_converges_to_and_declines_an_active_bound() {
    let road = Road::straight(2000.0, 3, 4.0, 30.0);
    let mut field = straight_field(&road);
    field.add_obstacle(Obstacle { s: 25.0, d: -1.0, heading: 0.0, speed: 20.0 });
    let (vehicle, driver) = (VehicleParams::default(), DriverParams::default());
    let params = MpcParams::default();
    let state = VehicleState { heading: 0.004, ..VehicleState::cruising(0.0, -4.2, 20.0) };
    let keeping = build_qp(&problem(state, -4.2, -4.0, (&vehicle, &driver), &field, &[]), &params);
    let direct = unconstrained(&keeping).expect("lane keeping activates no bound");
    let interior = Mpc::new().solve_qp(&keeping).unwrap();
    let moves = direct.iter().fold(0.0f64, |m, z| m.max(z.abs()));
    assert!(moves > 1e-3, "the obstacle and the offset move the plan: {direct:?}");
    for (z, x) in direct.iter().zip(&interior) {
        assert!((z - x).abs() < 1e-5, "direct {direct:?}\nclarabel {interior:?}");
    }
    // A lane change wants more than max_step at once: the direct solution breaks the bound.
    let changing = build_qp(&problem(state, -4.2, 4.0, (&vehicle, &driver), &field, &[]), &params);
    assert_eq!(unconstrained(&changing), None);
    let plan = Mpc::new().solve_qp(&changing).unwrap();
    assert!((plan[0] - params.max_step).abs() < 1e-4, "the first move rides the bound: {plan:?}");
}

#[test]
fn the_constrained_sides_are_the_constraint_matrix_times_the_moves() {
    let z = [0.1, -0.25, 0.05, 0.3];
    let a = constraint_matrix(z.len());
    let mut product = vec![0.0; 4 * z.len()];
    for (j, zj) in z.iter().enumerate() {
        for k in a.colptr[j]..a.colptr[j + 1] {
            product[a.rowval[k]] += a.nzval[k] * zj;
        }
    }
    let sides = constrained_sides(&z);
    assert!(sides.iter().zip(&product).all(|(x, y)| (x - y).abs() < 1e-15), "{sides:?} against {product:?}");
    assert_eq!(sides[3], 0.1 - 0.25 + 0.05 + 0.3);
}

#[test]
fn the_field_pushes_the_plan_away_from_an_obstacle_beside_the_path() {
    let road = Road::straight(2000.0, 3, 4.0, 30.0);
    let (vehicle, driver) = (VehicleParams::default(), DriverParams::default());
    let mut field = straight_field(&road);
    let state = VehicleState::cruising(0.0, -4.0, 20.0);
    let preview = |field: &Field| {
        let p = problem(state, -4.0, -4.0, (&vehicle, &driver), field, &[]);
        Mpc::new().solve(&p, &MpcParams::default()).unwrap().preview
    };
    let free = preview(&field);
    // A car creeping just to the left, level with us: we move right.
    field.add_obstacle(Obstacle { s: 5.0, d: -2.6, heading: 0.0, speed: 20.0 });
    let pushed = preview(&field);
    assert!(pushed < free - 0.05, "free {free}, pushed {pushed}");
}

#[test]
fn a_reused_solver_returns_the_same_bits_as_a_fresh_one() {
    let road = Road::straight(2000.0, 3, 4.0, 30.0);
    let field = straight_field(&road);
    let (vehicle, driver) = (VehicleParams::default(), DriverParams::default());
    let params = MpcParams::default();
    let make = |d: f64, target: f64| {
        let state = VehicleState { heading: 0.01, ..VehicleState::cruising(10.0, d, 22.0) };
        MpcProblem { accel: AccelRamp::step(1.0), ..problem(state, d, target, (&vehicle, &driver), &field, &[]) }
    };
    let (x, y) = (make(-4.0, 0.0), make(-1.0, -8.0));
    let fresh = Mpc::new().solve(&x, &params).unwrap();
    let mut reused = Mpc::new();
    reused.solve(&y, &params).unwrap();
    reused.solve(&x, &params).unwrap();
    let again = reused.solve(&x, &params).unwrap();
    let bits = |s: &MpcSolution| s.plan.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&fresh), bits(&again));
    assert_eq!(fresh.preview.to_bits(), again.preview.to_bits());
}

#[test]
fn an_infeasible_qp_is_an_error_not_a_panic() {
    let n = MpcParams::default().control_horizon;
    let qp = Qp { p: DMatrix::identity(n, n), q: DVector::zeros(n), b: vec![-1.0; 4 * n] };
    let error = Mpc::new().solve_qp(&qp).unwrap_err();
    assert!(matches!(error, MpcError::Solver(_)), "{error:?}");
    let road = Road::straight(2000.0, 3, 4.0, 30.0);
    let field = straight_field(&road);
    let (vehicle, driver) = (VehicleParams::default(), DriverParams::default());
    let state = VehicleState { yaw_rate: f64::NAN, ..VehicleState::cruising(0.0, 0.0, 20.0) };
    let broken = problem(state, 0.0, 0.0, (&vehicle, &driver), &field, &[]);
    assert_eq!(Mpc::new().solve(&broken, &MpcParams::default()), Err(MpcError::NonFinite));
}
