//! Settings of the full-body optimization and the box a jump starts from.

use super::FullBodyError;
use crate::ipocp::{BarrierUpdate, Settings};
use nalgebra::Vector3;

/// An axis-aligned box in the world (the platform of `barrel_roll`, `double_barrel_roll`,
/// `double_backflip`): its top face at `top`, `x` and `y` its extent; it reaches down to
/// the ground (no lower face is checked).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxObstacle {
    /// Height of the top face (m).
    pub top: f64,
    /// `[x_min, x_max]` and `[y_min, y_max]` (m).
    pub x: [f64; 2],
    pub y: [f64; 2],
}

impl BoxObstacle {
    /// Signed distance of `p` from the box (negative inside) and its gradient: outside, the
    /// Euclidean distance to the box (differentiable everywhere outside); inside, minus the
    /// distance to the nearest face (top, or a side), whose gradient still points out, so a
    /// point the guess put inside the box is pushed out.
    pub fn signed_distance(&self, p: &Vector3<f64>) -> (f64, Vector3<f64>) {
        let cx = 0.5 * (self.x[0] + self.x[1]);
        let cy = 0.5 * (self.y[0] + self.y[1]);
        let e = Vector3::new((p.x - cx).abs() - 0.5 * (self.x[1] - self.x[0]), (p.y - cy).abs() - 0.5 * (self.y[1] - self.y[0]), p.z - self.top);
        let sign = Vector3::new(if p.x >= cx { 1.0 } else { -1.0 }, if p.y >= cy { 1.0 } else { -1.0 }, 1.0);
        let out = e.map(|v| v.max(0.0));
        let d = out.norm();
        if d > 0.0 {
            return (d, out.component_mul(&sign) / d);
        }
        let axis = e.imax();
        let mut g = Vector3::zeros();
        g[axis] = sign[axis];
        (e[axis], g)
    }

    fn validate(&self) -> Result<(), FullBodyError> {
        let ok = self.top.is_finite() && self.x[0] < self.x[1] && self.y[0] < self.y[1] && self.x.iter().chain(&self.y).all(|v| v.is_finite());
        if ok {
            Ok(())
        } else {
            Err(FullBodyError::Setting { field: "box", value: self.top, expected: "a finite top and x_min < x_max, y_min < y_max" })
        }
    }
}

/// Settings of the full-body problem (defaults in parentheses). Joint angle, velocity and
/// torque limits are the robot model's (A1: 33.5 N m, 21 rad/s).
#[derive(Clone, Debug, PartialEq)]
pub struct FullBodySettings {
    /// Time step (0.01 s, the paper's).
    pub dt: f64,
    /// Pre-landing knots `a`: the joints hold the pre-landing angles with zero velocity over
    /// the last `a` knots and the last (10).
    pub pre_landing_knots: usize,
    /// Friction coefficient of the pyramid `|f_x|, |f_y| <= mu f_z` (0.6, the SRB's) and the
    /// minimum normal force on a stance foot (2 N).
    pub mu: f64,
    pub min_normal_force: f64,
    /// Upper bound on a foot's normal force over its last pushing interval (N; infinite, the
    /// default: no bound). Why: the plan's contact is rigid, so its optimal push peaks at
    /// lift-off and drops to zero in no time; a compliant ground (legwork's simulator,
    /// MuJoCo's soft constraints) has to release the compression that force caused, and
    /// the feet stay loaded past the plan's lift-off (lateral_down in legwork's simulator:
    /// 9 ms, the right feet longer than the left, roll momentum -0.08 N m s against the
    /// plan's +0.09; docs/experiments/jump-box-2.md). Bounded, the push ends on lightly
    /// loaded feet, which unload as fast as the legs retract.
    pub lift_off_normal_force: f64,
    /// Half extents of the trunk's box in the base frame (A1: 0.1335, 0.097, 0.057 m) and the
    /// clearance kept from it and from the jump's box (0.01 m; a swing foot keeps its radius).
    pub trunk_half_extents: Vector3<f64>,
    pub clearance: f64,
    /// Extra clearance of an airborne foot from the jump's box beyond its radius (0: the
    /// radius alone, as before; the pipeline uses `clearance`: a plan that grazes the box
    /// edge is clipped by any tracking error, docs/experiments/jump-box.md).
    pub airborne_foot_margin: f64,
    /// Smallest distance (base frame) between the left and right feet and knees in y
    /// (0.05 m), and between the front and hind feet and knees of a side in x (0.1 m).
    pub legs_apart_y: f64,
    pub legs_apart_x: f64,
    /// Cost weights (eq. 4, written out): CoM tracking (100 / m^2), base position and
    /// orientation deviation from the SRB pose (10, 10), joint deviation from the guess (0.1),
    /// velocities (1e-3), torques `eps_tau` (1e-3), forces against the SRB's (1e-4).
    pub w_com: f64,
    pub w_base_position: f64,
    pub w_base_orientation: f64,
    pub w_joint: f64,
    pub w_velocity: f64,
    pub w_torque: f64,
    pub w_force: f64,
    /// Weight of the joint accelerations `|qdd_j|^2` of every interval (`qdd` the step's ABA
    /// output, s^4 / rad^2; 0 = off). Why: the semi-implicit step carries angular momentum
    /// over a flight interval with an error `O(dt^2 |v| |qdd|)`; with the legs free to
    /// reverse at the joint-speed limit within one 10 ms step (2000-4000 rad/s^2 without
    /// it) the optimizer gains rotation in the air that the continuous dynamics (the
    /// simulator, MuJoCo) do not have (docs/experiments/jump-spin.md).
    pub w_acceleration: f64,
    /// Bound on every joint acceleration `|qdd_j|` of every interval (rad/s^2; infinite =
    /// no rows): the same error bounded as a constraint.
    pub max_joint_acceleration: f64,
    /// Ballistic flight: over every flight interval with free joints (no foot pushing, before
    /// the pre-landing window), the centroidal momentum as equalities
    /// `h_G(x_{k+1}) = h_G(x_k) + dt [m g; 0]` (Nguyen 2022, sec. II-C: only gravity acts in
    /// flight), its angular rows or all six. Why: the semi-implicit step does not conserve
    /// `h_G` (double_barrel_roll's plan gained 8-30 % roll momentum in the air,
    /// docs/experiments/jump-flip.md, jump-flip-2.md), so the plan's rotation is not what the
    /// joints' motion gives under physics. The pre-landing window has no rows: its joints are
    /// held, the step has no freedom left to meet them. Default off.
    pub ballistic_flight: BallisticFlight,
    /// Weight of `|h_G(x_{k+1}) - h_G(x_k) - dt [m g; 0]|^2` over the same intervals (a
    /// penalty instead of equalities; 0 = off, the default).
    pub w_flight_momentum: f64,
    /// The same balance over every stance interval, with the stance feet's impulse
    /// `dt [sum lambda; sum (p_f(q_k) - c(q_k)) x lambda]` (the step applies the forces at
    /// `q_k`): the last push before lift-off decides the flight's momentum, and the
    /// semi-implicit step's defect there is as large as in flight (double_barrel_roll: the
    /// run leaves 10 % short of the plan with its push tracked to 0.5 % up to the last
    /// interval). Only with `ballistic_flight` on (its rows). Default off.
    pub momentum_balance_in_stance: bool,
    /// `Some(n)`: after `n` Gauss-Newton iterations without convergence, at the first
    /// iterate whose constraint violation is at most 1, continue from that
    /// iterate (primal and duals, warm) with the dynamics' and constraints' curvature
    /// (weighted by their multipliers) added to the Hessian, by forward differences of the
    /// multiplier-weighted constraint gradient (`nx + 2` gradient passes per knot, ~4
    /// Gauss-Newton iterations' worth per Hessian; docs/experiments/fb-speed.md). From the
    /// start the exact curvature with the first multipliers' estimates makes the steps worse
    /// (measured on lateral_down). `None`: Gauss-Newton throughout (the default).
    pub constraint_curvature_after: Option<usize>,
    /// The largest constraint violation at which the Gauss-Newton phase hands over to the
    /// curvature phase (1.0; infinite: after `constraint_curvature_after` iterations whatever
    /// the violation).
    pub curvature_max_violation: f64,
    /// `Some(w)`: hand over to the curvature phase before `constraint_curvature_after`
    /// iterations too, once the violation is at most `curvature_max_violation` and has not
    /// reached a new low for `w` Gauss-Newton iterations (a stalled Gauss-Newton phase;
    /// docs/experiments/fb-speed-3.md). `None`: the iteration count only (the default).
    pub curvature_on_stall: Option<usize>,
    /// Start the joint torques from inverse dynamics of the guess's motion with the SRB's
    /// forces (false: the guess's massless-leg torques `-J^T f`, the default).
    pub start_torques_by_inverse_dynamics: bool,
    /// The curvature's gradient passes take `w^T d RNEA / d(q, v)` by a weighted backward
    /// sweep (`dynamics::rnea_derivatives_tr_mul`, `O(nv)`) instead of forming the two RNEA
    /// derivative matrices and multiplying (`O(nv d)`); same values up to rounding, which the
    /// forward differences amplify (docs/experiments/fb-speed-3.md: -12.5 % instructions per
    /// curvature iteration on lateral_down, the seven jumps' status and landings unchanged).
    /// Default on; off: the matrices (the iterates of before, to the bit).
    pub curvature_rnea_tr_mul: bool,
    /// The curvature phase forms the constraints' curvature at every `curvature_refresh`-th
    /// iteration of each knot and reuses the last one formed in between (a lagged Hessian:
    /// the iterations in between cost a Gauss-Newton one; knots with the flight's momentum
    /// rows, whose curvature is taken from the Jacobians, form it every iteration). 1: formed
    /// every iteration (the default; the jump pipeline uses 2, docs/experiments/fb-curvature-lag.md).
    pub curvature_refresh: usize,
    /// The barrier update of the curvature phase (`None`: the solver's, the default).
    pub curvature_barrier_update: Option<BarrierUpdate>,
    /// The interior-point solver's settings (`ipocp` defaults, 300 iterations at most,
    /// optimality tolerance 1e-6, constraint violation 1e-6; `parallel` on: the stages'
    /// evaluations on rayon's pool, the same iterates, lateral_down 2.19 -> 1.66 s on two
    /// idle cores, BENCHMARKS.md).
    pub solver: Settings,
}

/// Which rows of the flight's centroidal momentum balance are equalities
/// ([`FullBodySettings::ballistic_flight`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BallisticFlight {
    Off,
    /// The angular momentum about the CoM (3 rows).
    Angular,
    /// Linear and angular (6 rows).
    Full,
}

impl BallisticFlight {
    pub fn rows(self) -> usize {
        match self {
            Self::Off => 0,
            Self::Angular => 3,
            Self::Full => 6,
        }
    }
}

impl std::str::FromStr for BallisticFlight {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "off" => Ok(Self::Off),
            "angular" => Ok(Self::Angular),
            "full" => Ok(Self::Full),
            _ => Err(format!("ballistic flight: expected off, angular or full, got `{s}`")),
        }
    }
}

impl Default for FullBodySettings {
    fn default() -> Self {
        Self {
            dt: 0.01,
            pre_landing_knots: 10,
            mu: 0.6,
            min_normal_force: 2.0,
            lift_off_normal_force: f64::INFINITY,
            trunk_half_extents: Vector3::new(0.1335, 0.097, 0.057),
            clearance: 0.01,
            airborne_foot_margin: 0.0,
            legs_apart_y: 0.05,
            legs_apart_x: 0.1,
            w_com: 100.0,
            w_base_position: 10.0,
            w_base_orientation: 10.0,
            w_joint: 0.1,
            w_velocity: 1e-3,
            w_torque: 1e-3,
            w_force: 1e-4,
            w_acceleration: 0.0,
            max_joint_acceleration: f64::INFINITY,
            ballistic_flight: BallisticFlight::Off,
            w_flight_momentum: 0.0,
            momentum_balance_in_stance: false,
            constraint_curvature_after: None,
            curvature_max_violation: 1.0,
            curvature_on_stall: None,
            start_torques_by_inverse_dynamics: false,
            curvature_rnea_tr_mul: true,
            curvature_barrier_update: None,
            curvature_refresh: 1,
            solver: Settings { max_iterations: 300, tolerance: 1e-6, constraint_violation_tolerance: 1e-6, parallel: true, ..Settings::default() },
        }
    }
}

impl FullBodySettings {
    /// Checks the ranges the formulation needs (and the box, if any).
    pub fn validate(&self, obstacle: Option<&BoxObstacle>) -> Result<(), FullBodyError> {
        let check = |field, value: f64, ok: bool, expected| if ok { Ok(()) } else { Err(FullBodyError::Setting { field, value, expected }) };
        check("dt", self.dt, self.dt > 0.0 && self.dt.is_finite(), "a finite positive step")?;
        check("pre_landing_knots", self.pre_landing_knots as f64, self.pre_landing_knots >= 1, ">= 1")?;
        check("curvature_refresh", self.curvature_refresh as f64, self.curvature_refresh >= 1, ">= 1")?;
        check("mu", self.mu, self.mu > 0.0 && self.mu.is_finite(), "> 0")?;
        check("min_normal_force", self.min_normal_force, self.min_normal_force >= 0.0 && self.min_normal_force.is_finite(), ">= 0")?;
        check(
            "lift_off_normal_force",
            self.lift_off_normal_force,
            self.lift_off_normal_force >= self.min_normal_force && !self.lift_off_normal_force.is_nan(),
            ">= min_normal_force (infinite: no bound)",
        )?;
        for (field, v) in [
            ("trunk_half_extents.x", self.trunk_half_extents.x),
            ("trunk_half_extents.y", self.trunk_half_extents.y),
            ("trunk_half_extents.z", self.trunk_half_extents.z),
        ] {
            check(field, v, v > 0.0 && v.is_finite(), "> 0")?;
        }
        for (field, v) in [
            ("clearance", self.clearance),
            ("airborne_foot_margin", self.airborne_foot_margin),
            ("legs_apart_y", self.legs_apart_y),
            ("legs_apart_x", self.legs_apart_x),
            ("w_com", self.w_com),
            ("w_base_position", self.w_base_position),
            ("w_base_orientation", self.w_base_orientation),
            ("w_joint", self.w_joint),
            ("w_acceleration", self.w_acceleration),
            ("w_flight_momentum", self.w_flight_momentum),
        ] {
            check(field, v, v >= 0.0 && v.is_finite(), ">= 0")?;
        }
        check("curvature_max_violation", self.curvature_max_violation, self.curvature_max_violation > 0.0 && !self.curvature_max_violation.is_nan(), "> 0 (infinite: no bound)")?;
        check("max_joint_acceleration", self.max_joint_acceleration, self.max_joint_acceleration > 0.0 && !self.max_joint_acceleration.is_nan(), "> 0 (infinite: no bound)")?;
        // Positive weights on every control and velocity keep the Gauss-Newton Hessian definite.
        for (field, v) in [("w_velocity", self.w_velocity), ("w_torque", self.w_torque), ("w_force", self.w_force)] {
            check(field, v, v > 0.0 && v.is_finite(), "> 0")?;
        }
        self.solver.validate().map_err(|e| FullBodyError::Setting { field: e.field, value: e.value, expected: e.expected })?;
        if let Some(b) = obstacle {
            b.validate()?;
        }
        Ok(())
    }
}
