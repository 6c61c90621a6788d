//! The feasibility layer of the whole-body problem: inequality constraints `g(x_k) <= 0` on
//! every knot's state that every task gets (issue 16, item 2), handled as an augmented
//! Lagrangian running cost (Powell-Hestenes-Rockafellar, as ALTRO does around iLQR):
//!
//! ```text
//! psi(c; lambda, rho) = 1 / (2 rho) (max(0, lambda + rho c)^2 - lambda^2)
//! dpsi/dc = max(0, lambda + rho c),   d2psi/dc2 = rho [lambda + rho c > 0]
//! ```
//!
//! added as `dt psi` per constraint and knot, with Gauss-Newton derivatives (`l_x += dt
//! psi' J^T`, `l_xx += dt psi'' J^T J`, `J = dc/dx`). With zero multipliers it is the
//! quadratic exterior penalty `rho / 2 max(0, c)^2`; [`FeasibilityConstraints::update_multipliers`]
//! is the outer update `lambda <- max(0, lambda + rho c)`.
//!
//! The constraints, each normalized so that `c = 1` is a violation of the size of its bound:
//!
//! ```text
//! friction      (|T| - eta mu F_n) / (m g)       per foot in contact, T the tangential force
//!                                                 the spring and damper ask for (eq. 10,
//!                                                 before the cone of eq. 11 cuts it)
//! penetration   (p_n - p_max) / p_max             per foot
//! joint limits  (q - q_max), (q_min - q)          rad, per limited joint
//! joint speed   (|v| - v_max) / v_max             per joint with a velocity limit
//! ```
//!
//! Why the demanded tangential force and not the contact force: at the cone's edge the
//! contact force is `mu F_n` whatever the spring's stretch, so its derivative cannot say
//! "stretch the spring less", only "press less". The demanded force `T = -s (k_t P (c - a)
//! + d_t P pdot)` inside `eta mu F_n` means the cone never cuts it: the foot sticks to its
//! anchor and moves at most `|T| / (k_t s)` from it (issue 16: loaded feet that stick).

use crate::contact::ContactParams;
use crate::model::Model;
use crate::sim::joint_limits::{limited_coordinates, LimitedCoordinate};
use crate::sim::{FootState, StepDerivatives, ANCHOR_DIM};
use nalgebra::{DMatrix, DVector, Matrix3, RowVector3, Vector3};

/// The constraints' bounds and penalty parameters (defaults in parentheses).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeasibilitySettings {
    /// `eta`: a loaded foot's tangential force within `eta mu F_n` (0.75, issue 16).
    pub friction_margin: f64,
    /// `p_max`: the deepest a foot sphere may sink into the ground (0.01 m).
    pub max_penetration: f64,
    /// `rho` of the friction, penetration, joint-limit and joint-speed constraints (per
    /// second, on the normalized residuals: 1e4, 1e3, 1e4, 1e3).
    pub friction_penalty: f64,
    pub penetration_penalty: f64,
    pub joint_limit_penalty: f64,
    pub joint_speed_penalty: f64,
    /// Augmented-Lagrangian rounds on a task's full horizon (1): its iterations are split
    /// among them, and the multipliers updated after each round (and after each
    /// continuation stage), `lambda <- max(0, lambda + rho c)`, `rho` held. One round is
    /// the quadratic penalty (plus the stages' multipliers): three rounds of 13 iterations
    /// each left squat_jump at apex 0.789 m and rearing 38 deg past a knee limit, the
    /// inner solves too short to converge (docs/experiments/feasible-slq.md).
    pub outer_rounds: usize,
    /// The penalties are multiplied by this after each round's multiplier update (1: held).
    pub penalty_growth: f64,
    /// Grow only the penalties of the constraints violated at the update (per knot and
    /// constraint), not all of them.
    pub local_penalty_growth: bool,
    /// The friction residual's unit ([`FrictionForm::Demand`]).
    pub friction_form: FrictionForm,
    /// The joint-limit constraints hold this far inside each limit (0 rad).
    pub joint_limit_margin: f64,
    /// The polish: after the task's own iterations, when the plan still violates a
    /// constraint, one more augmented-Lagrangian round from the plan, its multipliers
    /// updated first, of at most this share of the iterations spent so far (0.5; 0: none),
    /// so a solve costs at most `1 + polish_share` times the iterations it did without
    /// (docs/experiments/feasible-slq-3.md).
    pub polish_share: f64,
    /// The polish's iterations split into this many rounds, the multipliers updated before
    /// each (2): the method of multipliers needs more than one update, and the polish starts
    /// at a converged plan, so its short rounds do not cost the task's solve what splitting
    /// the task's own budget did.
    pub polish_rounds: usize,
    /// The bounds the polish holds the plan to, inside the targets (`eta` 0.70 against 0.75,
    /// 9 mm against 10, joints 0.02 rad inside their range): a multiplier round ends near
    /// its bounds, some knots a little over, so it aims inside the targets to meet them.
    /// The task's own solve keeps the targets' bounds ([`Self::friction_margin`],
    /// [`Self::max_penetration`], [`Self::joint_limit_margin`]).
    pub polish_friction_margin: f64,
    pub polish_max_penetration: f64,
    pub polish_joint_limit_margin: f64,
    /// The last state `x_N` carries the constraints too, as a knot (`dt psi`; false: on in
    /// the task's solve it cost sidestep 0.297 -> 0.273 m and trot 0.96 -> 0.83 m, and the
    /// last knots stay at the cone's edge, docs/experiments/feasible-slq-4.md).
    pub terminal_knot: bool,
    /// `mu` (per second) of the relaxed logarithmic barriers beside the augmented-Lagrangian
    /// terms (0: none, the augmented Lagrangian alone): per knot `dt mu sum w B(h)`
    /// ([`relaxed_barrier`]) on the slack `h = -c` of each friction row (in the ratio form,
    /// weighted by the load `w = min(F_n / F_load, 1)` so a row that appears at touch-down
    /// starts at zero), each penetration row and each joint-limit side, as OCS2's SLQ keeps
    /// state-input inequalities (Farshidian et al.): the gradients and Gauss-Newton
    /// Hessians go into the backward pass's LQ model, and the plan is pushed off each bound
    /// before it reaches it. The joint-speed rows keep the augmented Lagrangian only.
    pub barrier_weight: f64,
    /// `delta` of the barrier's quadratic extension (slack below it).
    pub barrier_delta: f64,
    /// `mu` is multiplied by this at each outer update (after a continuation stage, before a
    /// polish round), down to [`Self::barrier_min_weight`].
    pub barrier_decrease: f64,
    pub barrier_min_weight: f64,
    /// The barriers start with the polish (their weight zero in the task's own solve and its
    /// continuation stages), so the task's solve is the augmented Lagrangian's alone.
    pub barrier_from_polish: bool,
    /// The friction rows carry a barrier too (false: penetration and joint limits only).
    /// A friction row appears at touch-down with no slack (`|T|` and `F_n` both start at
    /// zero), so its barrier charges every light contact; on pallet_push it lifted the
    /// tripod's lightly loaded foot (docs/experiments/feasible-slq-6.md).
    pub barrier_friction: bool,
    /// The feet's speeds near and on the ground, rows that act *before* a contact
    /// (docs/experiments/feasible-slq-7.md): most friction-margin misses are touch-downs,
    /// where a swing foot arrives with tangential speed and the damper of eq. (10) asks for
    /// `d_t v_t s(p_n)` while `F_n` is still building up; no row at the touch-down knot can
    /// remove that, the swing must arrive slower. Per foot, with `h` its clearance (`-p_n`)
    /// and `w(h)` a smoothstep from 1 at the ground (and below) to 0 at
    /// [`Self::landing_clearance`] (C1 at both ends):
    ///
    /// ```text
    /// landing   (w(h) |v_t| - v_land) / v_land          tangential speed near the ground
    /// impact    (w(h) v_down - v_impact) / v_impact     speed into the ground, v_down = -n . v
    /// slide     ((F_n / F_ref) |v_t| - v_slide) / v_slide   a loaded foot, F_ref its standing load
    /// ```
    ///
    /// (`v_t = P v` the foot's velocity in the tangent plane.) Functions of the state only,
    /// as every row of this layer: no contact schedule. Each row is an augmented-Lagrangian
    /// term as the others, with its own penalty (0: off).
    /// `h_0`: the clearance below which the landing and impact rows act (0.03 m).
    pub landing_clearance: f64,
    /// `d`: the penetration over which the landing and impact rows fade out again, leaving a
    /// settled stance to the slide and friction rows (infinite: they stay on while touching).
    pub landing_depth: f64,
    /// `v_land`: a foot's tangential speed at the ground (0.1 m/s, the metrics' slide speed).
    pub landing_speed: f64,
    /// `v_impact`: a foot's speed into the ground at the ground (0.5 m/s).
    pub impact_speed: f64,
    /// `v_slide`: a foot's tangential speed under its standing load (0.05 m/s).
    pub slide_speed: f64,
    /// `rho` of the landing, impact and slide rows (per second; 0, 0, 0: off).
    pub landing_penalty: f64,
    pub impact_penalty: f64,
    pub slide_penalty: f64,
    /// The landing, impact and slide rows start with the polish (their penalties zero in the
    /// task's own solve and its continuation stages; true): in the task's solve they cost
    /// sidestep, pallet_push and rearing their targets (docs/experiments/feasible-slq-7.md).
    pub foot_speed_from_polish: bool,
}

/// How the friction residual is normalized.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrictionForm {
    /// `(|T| - eta mu F_n) / (m g)`: a force, in the robot's weight.
    Demand,
    /// `(|T| - eta mu F_n) / (eta mu max(F_n, F_load))`, `F_load` a tenth of a foot's share
    /// of the weight (the metrics' "loaded"): above `F_load` the ratio `|T| / (eta mu F_n) - 1`,
    /// so a lightly loaded foot at the cone's edge costs what a heavily loaded one does (the
    /// target counts knots, not newtons).
    Ratio,
}

impl Default for FeasibilitySettings {
    fn default() -> Self {
        Self { friction_margin: 0.75, max_penetration: 0.01, friction_penalty: 1e4, penetration_penalty: 1e3, joint_limit_penalty: 1e4, joint_speed_penalty: 1e3, outer_rounds: 1, penalty_growth: 1.0, local_penalty_growth: false, friction_form: FrictionForm::Demand, joint_limit_margin: 0.0, polish_share: 0.5, polish_rounds: 2, polish_friction_margin: 0.70, polish_max_penetration: 0.009, polish_joint_limit_margin: 0.02, terminal_knot: false, barrier_weight: 0.0, barrier_delta: 0.1, barrier_decrease: 1.0, barrier_min_weight: 0.0, barrier_from_polish: false, barrier_friction: true, landing_clearance: 0.03, landing_depth: f64::INFINITY, landing_speed: 0.1, impact_speed: 0.5, slide_speed: 0.05, landing_penalty: 0.0, impact_penalty: 0.0, slide_penalty: 0.0, foot_speed_from_polish: true }
    }
}

/// A feasibility setting out of its range; names the field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("feasibility setting `{field}`: expected {expected}, got {value}")]
pub struct FeasibilitySettingsError {
    pub field: &'static str,
    pub expected: &'static str,
    pub value: f64,
}

impl FeasibilitySettings {
    /// The margin in (0, 1], the penetration bound positive, the penalties finite and >= 0
    /// (0 switches a kind off), at least one round.
    pub fn validate(&self) -> Result<(), FeasibilitySettingsError> {
        let bad = |field, expected, value| Err(FeasibilitySettingsError { field, expected, value });
        for (field, value) in [("friction_margin", self.friction_margin), ("polish_friction_margin", self.polish_friction_margin)] {
            if !(value > 0.0 && value <= 1.0) {
                return bad(field, "a fraction in (0, 1]", value);
            }
        }
        for (field, value) in [("max_penetration", self.max_penetration), ("polish_max_penetration", self.polish_max_penetration)] {
            if !(value.is_finite() && value > 0.0) {
                return bad(field, "a finite depth > 0 (m)", value);
            }
        }
        for (field, value) in [("friction_penalty", self.friction_penalty), ("penetration_penalty", self.penetration_penalty), ("joint_limit_penalty", self.joint_limit_penalty), ("joint_speed_penalty", self.joint_speed_penalty)] {
            if !(value.is_finite() && value >= 0.0) {
                return bad(field, "a finite number >= 0", value);
            }
        }
        for (field, value) in [("landing_penalty", self.landing_penalty), ("impact_penalty", self.impact_penalty), ("slide_penalty", self.slide_penalty)] {
            if !(value.is_finite() && value >= 0.0) {
                return bad(field, "a finite number >= 0", value);
            }
        }
        if self.landing_depth.is_nan() || self.landing_depth <= 0.0 {
            return bad("landing_depth", "a depth > 0 (m; infinite: no fade)", self.landing_depth);
        }
        for (field, value) in [("landing_clearance", self.landing_clearance), ("landing_speed", self.landing_speed), ("impact_speed", self.impact_speed), ("slide_speed", self.slide_speed)] {
            if !(value.is_finite() && value > 0.0) {
                return bad(field, "a finite number > 0 (m, m/s)", value);
            }
        }
        for (field, value) in [("barrier_weight", self.barrier_weight), ("barrier_min_weight", self.barrier_min_weight)] {
            if !(value.is_finite() && value >= 0.0) {
                return bad(field, "a finite weight >= 0 (per second)", value);
            }
        }
        if !(self.barrier_delta.is_finite() && self.barrier_delta > 0.0 && self.barrier_delta < 1.0) {
            return bad("barrier_delta", "a slack in (0, 1)", self.barrier_delta);
        }
        if !(self.barrier_decrease > 0.0 && self.barrier_decrease <= 1.0) {
            return bad("barrier_decrease", "a factor in (0, 1]", self.barrier_decrease);
        }
        if self.outer_rounds == 0 {
            return bad("outer_rounds", "at least 1", 0.0);
        }
        if self.polish_rounds == 0 {
            return bad("polish_rounds", "at least 1", 0.0);
        }
        if !(self.penalty_growth.is_finite() && self.penalty_growth >= 1.0) {
            return bad("penalty_growth", "a finite factor >= 1", self.penalty_growth);
        }
        if !(self.polish_share.is_finite() && self.polish_share >= 0.0) {
            return bad("polish_share", "a finite share >= 0 of the iterations", self.polish_share);
        }
        for (field, value) in [("joint_limit_margin", self.joint_limit_margin), ("polish_joint_limit_margin", self.polish_joint_limit_margin)] {
            if !(value.is_finite() && value >= 0.0) {
                return bad(field, "a finite angle >= 0 (rad)", value);
            }
        }
        Ok(())
    }

    /// These settings with the polish's bounds in place of the targets'.
    pub fn with_polish_bounds(&self) -> Self {
        Self { friction_margin: self.polish_friction_margin, max_penetration: self.polish_max_penetration, joint_limit_margin: self.polish_joint_limit_margin, ..*self }
    }
}

/// Multipliers per foot and knot: friction, penetration, landing, impact, slide.
const FOOT_ROWS: usize = 5;

/// A foot's speed along the ground and into it.
struct FootSpeeds {
    /// `v_t = P v`, the velocity in the tangent plane (`P = I - n n^T`).
    tangent_velocity: Vector3<f64>,
    /// `|v_t|`.
    tangential: f64,
    /// `v_down = -n . v`, positive towards the ground.
    down: f64,
}

impl FootSpeeds {
    fn of(foot: &FootState) -> Self {
        let n = foot.normal;
        let tangent_velocity = foot.velocity - n * n.dot(&foot.velocity);
        Self { tangential: tangent_velocity.norm(), down: -n.dot(&foot.velocity), tangent_velocity }
    }
}

/// `(w, dw/dh)` of the landing rows' window at clearance `h` ([`FeasibilitySettings::landing_clearance`]
/// `h_0`, [`FeasibilitySettings::landing_depth`] `d`): `1 - S(h / h_0)` above the ground
/// (`S(t) = 3 t^2 - 2 t^3`), 0 from `h_0` up; below the ground 1 (`d` infinite) or
/// `1 - S(-h / d)`, 0 from a penetration `d` on. C1 everywhere, so a foot's row fades in as it
/// comes down (and, with a finite `d`, out as it settles into a stance).
#[inline]
fn landing_window(h: f64, h_0: f64, d: f64) -> (f64, f64) {
    let fade = |t: f64| (1.0 - t * t * (3.0 - 2.0 * t), -6.0 * t * (1.0 - t));
    if h >= h_0 {
        (0.0, 0.0)
    } else if h > 0.0 {
        let (w, dw) = fade(h / h_0);
        (w, dw / h_0)
    } else if -h >= d {
        (0.0, 0.0)
    } else if d.is_finite() {
        let (w, dw) = fade(-h / d);
        (w, -dw / d)
    } else {
        (1.0, 0.0)
    }
}

/// A speed limit of one velocity coordinate.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SpeedLimit {
    idx_v: usize,
    limit: f64,
}

/// The constraints of one problem, with their multipliers (one per constraint and knot).
#[derive(Clone, Debug, PartialEq)]
pub struct FeasibilityConstraints {
    pub settings: FeasibilitySettings,
    /// `m g` (N), the friction residuals' unit.
    weight: f64,
    feet: usize,
    coordinates: Vec<LimitedCoordinate>,
    speeds: Vec<SpeedLimit>,
    /// `lambda`, knot-major: per knot the feet's friction and penetration, then each limited
    /// coordinate's upper and lower side, then the speeds.
    multipliers: Vec<f64>,
    /// `rho` of each constraint (same order): the kind's penalty of `settings`, grown by
    /// the outer rounds (all of them, or with `local_penalty_growth` those still violated).
    penalties: Vec<f64>,
    /// `mu` of the relaxed barriers now ([`FeasibilitySettings::barrier_weight`], lowered by
    /// [`Self::decrease_barrier`]).
    barrier_weight: f64,
}

/// The largest violation of each kind over a trajectory (in the constraints' units:
/// friction in `m g`, penetration in `p_max`, joints in rad, speeds in `v_max`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Violation {
    pub friction: f64,
    pub penetration: f64,
    pub joint_limit: f64,
    pub joint_speed: f64,
    /// The feet's landing, impact and slide rows (in their speeds' units).
    pub foot_speed: f64,
}

impl Violation {
    /// The largest of the targets' kinds (the foot speeds are means to them, not targets).
    pub fn max(&self) -> f64 {
        self.friction.max(self.penetration).max(self.joint_limit).max(self.joint_speed)
    }
}

impl FeasibilityConstraints {
    /// The constraints of `model` over `knots` knots, multipliers zero; `settings` checked.
    pub fn new(model: &Model, knots: usize, settings: FeasibilitySettings) -> Result<Self, FeasibilitySettingsError> {
        settings.validate()?;
        let coordinates: Vec<LimitedCoordinate> = limited_coordinates(model).collect();
        let speeds: Vec<SpeedLimit> = model.actuated_joints().filter(|j| j.limits.velocity[0].is_finite() && j.limits.velocity[0] > 0.0).map(|j| SpeedLimit { idx_v: j.idx_v, limit: j.limits.velocity[0] }).collect();
        let feet = model.feet.len();
        let per_knot = FOOT_ROWS * feet + 2 * coordinates.len() + speeds.len();
        let mut penalty_of_knot = Vec::with_capacity(per_knot);
        let foot_speed = if settings.foot_speed_from_polish { 0.0 } else { 1.0 };
        for _ in 0..feet {
            penalty_of_knot.extend([settings.friction_penalty, settings.penetration_penalty, foot_speed * settings.landing_penalty, foot_speed * settings.impact_penalty, foot_speed * settings.slide_penalty]);
        }
        penalty_of_knot.extend(std::iter::repeat_n(settings.joint_limit_penalty, 2 * coordinates.len()));
        penalty_of_knot.extend(std::iter::repeat_n(settings.joint_speed_penalty, speeds.len()));
        let penalties = penalty_of_knot.iter().copied().cycle().take(per_knot * (knots + 1)).collect();
        Ok(Self { settings, weight: model.total_mass() * 9.81, feet, coordinates, speeds, multipliers: vec![0.0; per_knot * (knots + 1)], penalties, barrier_weight: if settings.barrier_from_polish { 0.0 } else { settings.barrier_weight } })
    }

    fn per_knot(&self) -> usize {
        FOOT_ROWS * self.feet + 2 * self.coordinates.len() + self.speeds.len()
    }

    /// Where residual `which` sits among its knot's multipliers.
    fn index(&self, which: Residual) -> usize {
        let (feet, coordinates) = (FOOT_ROWS * self.feet, self.coordinates.len());
        match which {
            Residual::Friction(i) => FOOT_ROWS * i,
            Residual::Penetration(i) => FOOT_ROWS * i + 1,
            Residual::Landing(i) => FOOT_ROWS * i + 2,
            Residual::Impact(i) => FOOT_ROWS * i + 3,
            Residual::Slide(i) => FOOT_ROWS * i + 4,
            Residual::Upper(j) => feet + 2 * j,
            Residual::Lower(j) => feet + 2 * j + 1,
            Residual::Speed(j) => feet + 2 * coordinates + j,
        }
    }

    /// A foot's friction residual `c` and the demanded tangential force `T` it is made of
    /// ([`tangential_demand`]), `None` for a foot without normal force.
    fn friction_residual(&self, form: FrictionForm, params: &ContactParams, foot: &FootState, anchor: Option<&Vector3<f64>>) -> Option<(f64, Vector3<f64>)> {
        let c = &foot.contact;
        if c.normal_force <= 0.0 {
            return None;
        }
        let demand = tangential_demand(params, foot, anchor);
        let norm = demand.norm();
        let residual = (norm - self.settings.friction_margin * params.friction * c.normal_force) / self.friction_unit(form, params, c.normal_force);
        Some((residual, demand))
    }

    /// The friction residual's denominator `D` at normal force `F_n` ([`FrictionForm`]).
    fn friction_unit(&self, form: FrictionForm, params: &ContactParams, normal_force: f64) -> f64 {
        match form {
            FrictionForm::Demand => self.weight,
            FrictionForm::Ratio => self.settings.friction_margin * params.friction * normal_force.max(self.loaded_force()),
        }
    }

    /// A tenth of a foot's share of the weight: a foot under this is not "loaded" (the
    /// metrics' threshold).
    fn loaded_force(&self) -> f64 {
        0.1 * self.weight / self.feet.max(1) as f64
    }

    /// The residuals of knot `k`'s state, each with its multiplier and penalty, to `f(index,
    /// c, lambda, rho)` (constraint order of [`Self::multipliers`]).
    fn for_each_residual(&self, k: usize, at: KnotContacts<'_>, mut f: impl FnMut(Residual, f64, f64, f64)) {
        let KnotContacts { q, v, anchors, params, feet } = at;
        let s = &self.settings;
        let base = k * self.per_knot();
        let mut call = |which: Residual, c: f64| {
            let i = base + self.index(which);
            f(which, c, self.multipliers.get(i).copied().unwrap_or(0.0), self.penalties.get(i).copied().unwrap_or(0.0));
        };
        for (i, foot) in feet.iter().enumerate() {
            if let Some((c, _)) = self.friction_residual(s.friction_form, params, foot, anchors[i].as_ref()) {
                call(Residual::Friction(i), c);
            }
            if foot.contact.penetration > 0.0 {
                call(Residual::Penetration(i), (foot.contact.penetration - s.max_penetration) / s.max_penetration);
            }
            let speeds = FootSpeeds::of(foot);
            let (w, _) = landing_window(-foot.contact.penetration, s.landing_clearance, s.landing_depth);
            if w > 0.0 {
                call(Residual::Landing(i), (w * speeds.tangential - s.landing_speed) / s.landing_speed);
                call(Residual::Impact(i), (w * speeds.down - s.impact_speed) / s.impact_speed);
            }
            if foot.contact.normal_force > 0.0 {
                call(Residual::Slide(i), (foot.contact.normal_force / self.standing_force() * speeds.tangential - s.slide_speed) / s.slide_speed);
            }
        }
        for (j, b) in self.coordinates.iter().enumerate() {
            let x = q[b.idx_q];
            call(Residual::Upper(j), x - (b.upper - s.joint_limit_margin));
            call(Residual::Lower(j), (b.lower + s.joint_limit_margin) - x);
        }
        for (j, sp) in self.speeds.iter().enumerate() {
            call(Residual::Speed(j), (v[sp.idx_v].abs() - sp.limit) / sp.limit);
        }
    }

    /// A foot's share of the weight standing, `F_ref = m g / feet` (N).
    fn standing_force(&self) -> f64 {
        self.weight / self.feet.max(1) as f64
    }

    /// `scale sum psi(c)` at knot `k`.
    pub fn cost(&self, k: usize, scale: f64, at: KnotContacts<'_>) -> f64 {
        let mut cost = 0.0;
        self.for_each_residual(k, at, |_, c, lambda, rho| cost += psi(c, lambda, rho).0);
        scale * cost + self.barrier_cost(scale, at)
    }

    /// Adds `scale psi` and its Gauss-Newton derivatives to `(l_x, l_xx)`; `step` holds the
    /// foot Jacobians of the knot's first integration step (from its state), and
    /// `anchor_states` says whether the tangent has anchor coordinates (`2 nv + 3 f`).
    /// Returns `scale sum psi`.
    #[allow(clippy::too_many_arguments)] // a knot's inputs and outputs, as the solver's rollouts
    pub fn add_derivatives(
        &self,
        k: usize,
        scale: f64,
        at: KnotContacts<'_>,
        step: &StepDerivatives,
        anchor_states: bool,
        scratch: &mut DVector<f64>,
        (l_x, l_xx): (&mut DVector<f64>, &mut DMatrix<f64>),
    ) -> f64 {
        let KnotContacts { v, .. } = at;
        let nv = v.len();
        let mut cost = 0.0;
        self.for_each_residual(k, at, |which, c, lambda, rho| {
            let (value, slope, curvature) = psi(c, lambda, rho);
            if slope == 0.0 && curvature == 0.0 {
                return;
            }
            cost += value;
            // J = dc/dx: one entry for a joint (l_x[i] += s psi' J_i, l_xx[i, i] += s psi''
            // J_i^2), a dense row through the foot Jacobians for a foot (into `scratch`).
            let single = match which {
                Residual::Upper(j) => Some((self.coordinates[j].idx_v, 1.0)),
                Residual::Lower(j) => Some((self.coordinates[j].idx_v, -1.0)),
                Residual::Speed(j) => {
                    let sp = self.speeds[j];
                    Some((nv + sp.idx_v, v[sp.idx_v].signum() / sp.limit))
                }
                Residual::Friction(i) => {
                    if !self.friction_row(self.settings.friction_form, i, c, at, step, anchor_states, scratch) {
                        return;
                    }
                    None
                }
                Residual::Penetration(i) => {
                    self.penetration_row(i, at, step, scratch);
                    None
                }
                Residual::Landing(i) | Residual::Impact(i) | Residual::Slide(i) => {
                    self.foot_speed_row(which, i, at, step, scratch);
                    None
                }
            };
            if let Some((i, jac)) = single {
                l_x[i] += scale * slope * jac;
                l_xx[(i, i)] += scale * curvature * jac * jac;
                return;
            }
            l_x.axpy(scale * slope, scratch, 1.0);
            if curvature > 0.0 {
                l_xx.ger(scale * curvature, scratch, scratch, 1.0);
            }
        });
        scale * cost + self.add_barrier_derivatives(scale, at, step, anchor_states, scratch, (l_x, l_xx))
    }

    /// The relaxed barriers' rows at a knot's state, each as `(row, h, w)`: the slack `h =
    /// -c >= 0` and the row's weight `w` (see [`FeasibilitySettings::barrier_weight`]).
    fn for_each_barrier_row(&self, at: KnotContacts<'_>, mut f: impl FnMut(BarrierRow, f64, f64)) {
        let KnotContacts { q, anchors, params, feet, .. } = at;
        let s = &self.settings;
        let loaded = self.loaded_force();
        for (i, foot) in feet.iter().enumerate() {
            let friction = if s.barrier_friction { self.friction_residual(FrictionForm::Ratio, params, foot, anchors[i].as_ref()) } else { None };
            if let Some((c, _)) = friction {
                f(BarrierRow::Friction(i, c), -c, (foot.contact.normal_force / loaded).min(1.0));
            }
            if foot.contact.penetration > 0.0 {
                f(BarrierRow::Penetration(i), (s.max_penetration - foot.contact.penetration) / s.max_penetration, 1.0);
            }
        }
        for (j, b) in self.coordinates.iter().enumerate() {
            let x = q[b.idx_q];
            f(BarrierRow::Upper(j), (b.upper - s.joint_limit_margin) - x, 1.0);
            f(BarrierRow::Lower(j), x - (b.lower + s.joint_limit_margin), 1.0);
        }
    }

    /// `scale mu sum w B(h)` over the barrier rows of a knot's state.
    fn barrier_cost(&self, scale: f64, at: KnotContacts<'_>) -> f64 {
        let mu = self.barrier_weight;
        if mu <= 0.0 {
            return 0.0;
        }
        let delta = self.settings.barrier_delta;
        let mut sum = 0.0;
        self.for_each_barrier_row(at, |_, h, w| sum += w * relaxed_barrier(h, delta).0);
        scale * mu * sum
    }

    /// Adds `scale mu sum w B(h)` and its derivatives to `(l_x, l_xx)`: `d(w B) = B dw - w
    /// B'(h) dc` and the Gauss-Newton `w B''(h) dc dc^T` (`h = -c`; `dw = dF_n / F_load` on a
    /// foot under `F_load`, zero above). Returns the term.
    #[allow(clippy::too_many_arguments)]
    fn add_barrier_derivatives(&self, scale: f64, at: KnotContacts<'_>, step: &StepDerivatives, anchor_states: bool, scratch: &mut DVector<f64>, (l_x, l_xx): (&mut DVector<f64>, &mut DMatrix<f64>)) -> f64 {
        let mu = self.barrier_weight;
        if mu <= 0.0 {
            return 0.0;
        }
        let delta = self.settings.barrier_delta;
        let loaded = self.loaded_force();
        let s = scale * mu;
        let mut sum = 0.0;
        self.for_each_barrier_row(at, |row, h, w| {
            let (b, db, d2b) = relaxed_barrier(h, delta);
            sum += w * b;
            // dc/dx of the row: one entry for a joint, a dense row for a foot.
            let single = match row {
                BarrierRow::Upper(j) => Some((self.coordinates[j].idx_v, 1.0)),
                BarrierRow::Lower(j) => Some((self.coordinates[j].idx_v, -1.0)),
                BarrierRow::Friction(i, c) => {
                    if self.friction_row(FrictionForm::Ratio, i, c, at, step, anchor_states, scratch) {
                        l_x.axpy(-s * w * db, scratch, 1.0);
                        l_xx.ger(s * w * d2b, scratch, scratch, 1.0);
                    }
                    if at.feet[i].contact.normal_force < loaded {
                        self.normal_force_row(i, at, step, scratch);
                        l_x.axpy(s * b / loaded, scratch, 1.0);
                    }
                    return;
                }
                BarrierRow::Penetration(i) => {
                    self.penetration_row(i, at, step, scratch);
                    None
                }
            };
            match single {
                Some((i, jac)) => {
                    l_x[i] -= s * w * db * jac;
                    l_xx[(i, i)] += s * w * d2b * jac * jac;
                }
                None => {
                    l_x.axpy(-s * w * db, scratch, 1.0);
                    l_xx.ger(s * w * d2b, scratch, scratch, 1.0);
                }
            }
        });
        s * sum
    }

    /// The barrier's weight after an outer update: `mu <- max(mu_min, decrease mu)`
    /// ([`FeasibilitySettings::barrier_decrease`]), the central path of an interior point
    /// method followed one multiplier update at a time.
    pub fn decrease_barrier(&mut self) {
        self.barrier_weight = (self.barrier_weight * self.settings.barrier_decrease).max(self.settings.barrier_min_weight.min(self.barrier_weight));
    }

    /// Switches the landing, impact and slide rows on at their penalties, at every knot (the
    /// polish's start with [`FeasibilitySettings::foot_speed_from_polish`]).
    pub fn start_foot_speed_rows(&mut self) {
        let (per_knot, s) = (self.per_knot(), self.settings);
        for knot in self.penalties.chunks_mut(per_knot) {
            for foot in knot[..FOOT_ROWS * self.feet].chunks_mut(FOOT_ROWS) {
                foot[2..5].copy_from_slice(&[s.landing_penalty, s.impact_penalty, s.slide_penalty]);
            }
        }
    }

    /// Switches the barriers on at their initial weight (the polish's start with
    /// [`FeasibilitySettings::barrier_from_polish`]).
    pub fn start_barrier(&mut self) {
        self.barrier_weight = self.settings.barrier_weight;
    }

    /// The barrier's current weight `mu` (per second).
    pub fn barrier_weight(&self) -> f64 {
        self.barrier_weight
    }

    /// `dc/dx` of foot `i`'s friction residual `c` in `form` into `row` (tangent of the
    /// state, anchors included with `anchor_states`); false where `|T| = 0` (no direction).
    #[allow(clippy::too_many_arguments)]
    fn friction_row(&self, form: FrictionForm, i: usize, c: f64, at: KnotContacts<'_>, step: &StepDerivatives, anchor_states: bool, row: &mut DVector<f64>) -> bool {
        let KnotContacts { v, anchors, params, feet, .. } = at;
        let nv = v.len();
        let foot = &feet[i];
        let Some((_, demand)) = self.friction_residual(form, params, foot, anchors[i].as_ref()) else { return false };
        let norm = demand.norm();
        if norm == 0.0 {
            return false;
        }
        row.as_mut_slice().fill(0.0);
        // c = (|T| - eta mu F_n) / D: dc = (d|T| - eta mu dF_n) / D, and where D is eta mu
        // F_n (the ratio form above F_load) also - c dD / D = - c eta mu dF_n / D: together
        // - eta mu (1 + c) dF_n / D.
        let unit = self.friction_unit(form, params, foot.contact.normal_force);
        let normal_factor = match form {
            FrictionForm::Ratio if foot.contact.normal_force > self.loaded_force() => 1.0 + c,
            _ => 1.0,
        };
        let (jp, jd) = step.foot_jacobians(i);
        let d = tangential_demand_derivatives(params, foot, anchors[i].as_ref(), &demand);
        let dir = (demand / norm).transpose();
        let n_t = foot.normal.transpose();
        let eta_mu = self.settings.friction_margin * params.friction;
        // dc/dp, dc/dpdot (rows), then through the foot Jacobians.
        let a_p: RowVector3<f64> = (dir * d.position - n_t * foot.contact.d_position * (eta_mu * normal_factor)) / unit;
        let a_v: RowVector3<f64> = (dir * d.velocity - n_t * foot.contact.d_velocity * (eta_mu * normal_factor)) / unit;
        for j in 0..nv {
            row[j] = a_p.dot(&jp.column(j).transpose()) + a_v.dot(&jd.column(j).transpose());
            row[nv + j] = a_v.dot(&jp.column(j).transpose());
        }
        if anchor_states && anchors[i].is_some() {
            let a_a = dir * d.anchor / unit;
            for r in 0..ANCHOR_DIM {
                row[2 * nv + ANCHOR_DIM * i + r] = a_a[r];
            }
        }
        true
    }

    /// `dc/dx` of foot `i`'s landing, impact or slide residual into `row` (surface held; `p`,
    /// `pdot` the foot's position and velocity, `h = n . (p - s) - r` its clearance):
    ///
    /// ```text
    /// landing  dc = (|v_t| w'(h) n^T dp + w e^T dpdot) / v_land,        e = v_t / |v_t|
    /// impact   dc = (v_down w'(h) n^T dp - w n^T dpdot) / v_impact
    /// slide    dc = (|v_t| dF_n / F_ref + F_n / F_ref e^T dpdot) / v_slide
    /// ```
    ///
    /// with `dp = J_p dq`, `dpdot = J_d dq + J_p dv` through the foot Jacobians.
    fn foot_speed_row(&self, which: Residual, i: usize, at: KnotContacts<'_>, step: &StepDerivatives, row: &mut DVector<f64>) {
        let nv = at.v.len();
        let foot = &at.feet[i];
        let s = &self.settings;
        let speeds = FootSpeeds::of(foot);
        let e = if speeds.tangential > 0.0 { speeds.tangent_velocity / speeds.tangential } else { Vector3::zeros() };
        let n = foot.normal;
        let (w, dw) = landing_window(-foot.contact.penetration, s.landing_clearance, s.landing_depth);
        // dc = a_p . dp + a_v . dpdot (rows); the slide's dF_n part first, into `row`.
        let (a_p, a_v): (Vector3<f64>, Vector3<f64>) = match which {
            Residual::Landing(_) => {
                row.as_mut_slice().fill(0.0);
                (n * (speeds.tangential * dw / s.landing_speed), e * (w / s.landing_speed))
            }
            Residual::Impact(_) => {
                row.as_mut_slice().fill(0.0);
                (n * (speeds.down * dw / s.impact_speed), -n * (w / s.impact_speed))
            }
            _ => {
                let reference = self.standing_force();
                self.normal_force_row(i, at, step, row);
                *row *= speeds.tangential / (reference * s.slide_speed);
                (Vector3::zeros(), e * (foot.contact.normal_force / (reference * s.slide_speed)))
            }
        };
        let (jp, jd) = step.foot_jacobians(i);
        for j in 0..nv {
            row[j] += a_p.dot(&jp.column(j)) + a_v.dot(&jd.column(j));
            row[nv + j] += a_v.dot(&jp.column(j));
        }
    }

    /// `dF_n/dx` of foot `i` into `row` (surface held: `F_n = n . F`).
    fn normal_force_row(&self, i: usize, at: KnotContacts<'_>, step: &StepDerivatives, row: &mut DVector<f64>) {
        let nv = at.v.len();
        let foot = &at.feet[i];
        row.as_mut_slice().fill(0.0);
        let (jp, jd) = step.foot_jacobians(i);
        let n_t = foot.normal.transpose();
        let a_p: RowVector3<f64> = n_t * foot.contact.d_position;
        let a_v: RowVector3<f64> = n_t * foot.contact.d_velocity;
        for j in 0..nv {
            row[j] = a_p.dot(&jp.column(j).transpose()) + a_v.dot(&jd.column(j).transpose());
            row[nv + j] = a_v.dot(&jp.column(j).transpose());
        }
    }

    /// `dc/dx` of foot `i`'s penetration residual `(p_n - p_max) / p_max` into `row`.
    fn penetration_row(&self, i: usize, at: KnotContacts<'_>, step: &StepDerivatives, row: &mut DVector<f64>) {
        // p_n = r - n . (p - s): dp_n/ddq = -n^T dp/ddq.
        let nv = at.v.len();
        row.as_mut_slice().fill(0.0);
        let (jp, _) = step.foot_jacobians(i);
        let n = at.feet[i].normal;
        for j in 0..nv {
            row[j] = -n.dot(&jp.column(j)) / self.settings.max_penetration;
        }
    }

    /// The outer update of the augmented Lagrangian, `lambda <- max(0, lambda + rho c)`, at
    /// knot `k`.
    pub fn update_multipliers(&mut self, k: usize, at: KnotContacts<'_>) {
        let base = k * self.per_knot();
        let mut updates = Vec::new();
        self.for_each_residual(k, at, |which, c, lambda, rho| updates.push((which, (lambda + rho * c).max(0.0), c > 0.0)));
        // A constraint not evaluated at this state (a foot off the ground, or above the
        // landing rows' clearance) releases its multiplier.
        self.multipliers[base..base + FOOT_ROWS * self.feet].fill(0.0);
        let grow_here = self.settings.local_penalty_growth;
        for (which, lambda, violated) in updates {
            let i = base + self.index(which);
            self.multipliers[i] = lambda;
            if grow_here && violated {
                self.penalties[i] *= self.settings.penalty_growth;
            }
        }
    }

    /// Adds knot `k`'s largest violations to `worst`.
    pub fn violation(&self, k: usize, at: KnotContacts<'_>, worst: &mut Violation) {
        self.for_each_residual(k, at, |which, c, _, _| {
            let slot = match which {
                Residual::Friction(_) => &mut worst.friction,
                Residual::Penetration(_) => &mut worst.penetration,
                Residual::Upper(_) | Residual::Lower(_) => &mut worst.joint_limit,
                Residual::Speed(_) => &mut worst.joint_speed,
                Residual::Landing(_) | Residual::Impact(_) | Residual::Slide(_) => &mut worst.foot_speed,
            };
            *slot = slot.max(c);
        });
    }

    /// The penalties after an outer round: each multiplied by
    /// [`FeasibilitySettings::penalty_growth`] (ALTRO's schedule).
    pub fn grow_penalties(&mut self) {
        if self.settings.local_penalty_growth {
            return; // grown constraint by constraint in `update_multipliers`
        }
        let g = self.settings.penalty_growth;
        self.penalties.iter_mut().for_each(|rho| *rho *= g);
    }

    /// Multipliers of knots `0 .. knots` from a solution of another horizon with the same
    /// robot (a continuation stage): knot for knot, zero past its end.
    pub fn carry_multipliers_from(&mut self, other: &Self) {
        let n = self.multipliers.len().min(other.multipliers.len());
        self.multipliers[..n].copy_from_slice(&other.multipliers[..n]);
        self.penalties[..n].copy_from_slice(&other.penalties[..n]);
        self.barrier_weight = other.barrier_weight;
    }
}

/// A knot's state with the contacts evaluated there: what the constraints are functions of.
#[derive(Clone, Copy)]
pub struct KnotContacts<'s> {
    pub q: &'s DVector<f64>,
    pub v: &'s DVector<f64>,
    pub anchors: &'s [Option<Vector3<f64>>],
    pub params: &'s ContactParams,
    /// The feet's contacts at `(q, v, anchors)`.
    pub feet: &'s [FootState],
}

/// Which constraint a residual is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Residual {
    Friction(usize),
    Penetration(usize),
    Landing(usize),
    Impact(usize),
    Slide(usize),
    Upper(usize),
    Lower(usize),
    Speed(usize),
}

/// A row of the relaxed barriers: a foot's friction (with its residual `c` in the ratio
/// form), a foot's penetration, a limited coordinate's upper or lower side.
#[derive(Clone, Copy, Debug, PartialEq)]
enum BarrierRow {
    Friction(usize, f64),
    Penetration(usize),
    Upper(usize),
    Lower(usize),
}

/// `(B, dB/dh, d2B/dh2)` of the relaxed logarithmic barrier on a slack `h` (Feller and
/// Ebenbauer 2017, "Relaxed logarithmic barrier function based model predictive control of
/// linear systems"; OCS2's `RelaxedBarrierPenalty`):
///
/// ```text
/// B(h) = -ln h                                       h > delta
/// B(h) = 1/2 ((h - 2 delta) / delta)^2 - 1/2 - ln delta   h <= delta
/// ```
///
/// C2 at `h = delta` (value `-ln delta`, slope `-1 / delta`, curvature `1 / delta^2`), and
/// defined for every `h`, so an iterate outside the constraint still has a finite cost
/// and a gradient pointing inside.
#[inline]
pub fn relaxed_barrier(h: f64, delta: f64) -> (f64, f64, f64) {
    if h > delta {
        (-h.ln(), -1.0 / h, 1.0 / (h * h))
    } else {
        let r = (h - 2.0 * delta) / delta;
        (0.5 * r * r - 0.5 - delta.ln(), r / delta, 1.0 / (delta * delta))
    }
}

/// `(psi, dpsi/dc, d2psi/dc2)` of the augmented Lagrangian term.
#[inline]
fn psi(c: f64, lambda: f64, rho: f64) -> (f64, f64, f64) {
    if rho <= 0.0 {
        return (0.0, 0.0, 0.0); // a constraint without penalty is off
    }
    let shifted = lambda + rho * c;
    if shifted > 0.0 {
        ((shifted * shifted - lambda * lambda) / (2.0 * rho), shifted, rho)
    } else {
        (-lambda * lambda / (2.0 * rho), 0.0, 0.0)
    }
}

/// The tangential force the spring and damper of eq. (10) ask for at a foot,
/// `T = -s(p_n) (k_t P (c - a) + d_t P pdot)` (zero spring without an anchor), before the
/// friction cone of eq. (11).
pub fn tangential_demand(params: &ContactParams, foot: &FootState, anchor: Option<&Vector3<f64>>) -> Vector3<f64> {
    let (s, _) = params.profile(foot.contact.penetration);
    let tangent = Matrix3::identity() - foot.normal * foot.normal.transpose();
    let spring = if anchor.is_some() { foot.contact.tangential_offset * params.tangential_stiffness } else { Vector3::zeros() };
    -(spring + tangent * foot.velocity * params.tangential_damping) * s
}

/// `dT/dp`, `dT/dpdot`, `dT/da` of [`tangential_demand`] (3 x 3, surface held).
struct DemandDerivatives {
    position: Matrix3<f64>,
    velocity: Matrix3<f64>,
    anchor: Matrix3<f64>,
}

/// With `T = s u`, `u = -(k_t P (c - a) + d_t P pdot)` and `dp_n/dp = -n^T`:
///
/// ```text
/// dT/dp = -k_t s P - s'(p_n) u n^T,   dT/dpdot = -d_t s P,   dT/da = k_t s P
/// ```
fn tangential_demand_derivatives(params: &ContactParams, foot: &FootState, anchor: Option<&Vector3<f64>>, demand: &Vector3<f64>) -> DemandDerivatives {
    let (s, ds) = params.profile(foot.contact.penetration);
    let n = foot.normal;
    let tangent = Matrix3::identity() - n * n.transpose();
    let k_t = if anchor.is_some() { params.tangential_stiffness } else { 0.0 };
    // T = u s: dT/dp = s du/dp + u ds/dp_n dp_n/dp = s du/dp - u ds n^T.
    let u = if s > 0.0 { demand / s } else { Vector3::zeros() };
    DemandDerivatives { position: -tangent * (k_t * s) - u * n.transpose() * ds, velocity: -tangent * (params.tangential_damping * s), anchor: tangent * (k_t * s) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::{contact_force, Surface};

    #[test]
    fn bad_settings_are_named() {
        let model = crate::model::embedded::load("hyq").unwrap();
        assert!(FeasibilityConstraints::new(&model, 10, FeasibilitySettings::default()).is_ok());
        let err = FeasibilityConstraints::new(&model, 10, FeasibilitySettings { friction_margin: 1.5, ..Default::default() }).unwrap_err();
        assert_eq!(err.field, "friction_margin");
        let err = FeasibilitySettings { friction_penalty: f64::NAN, ..Default::default() }.validate().unwrap_err();
        assert!(err.to_string().contains("friction_penalty"), "{err}");
        assert_eq!(FeasibilitySettings { outer_rounds: 0, ..Default::default() }.validate().unwrap_err().field, "outer_rounds");
        assert_eq!(FeasibilitySettings { polish_rounds: 0, ..Default::default() }.validate().unwrap_err().field, "polish_rounds");
        assert_eq!(FeasibilitySettings { polish_friction_margin: 0.0, ..Default::default() }.validate().unwrap_err().field, "polish_friction_margin");
        assert_eq!(FeasibilitySettings { polish_max_penetration: -1e-3, ..Default::default() }.validate().unwrap_err().field, "polish_max_penetration");
        assert_eq!(FeasibilitySettings { barrier_weight: -1.0, ..Default::default() }.validate().unwrap_err().field, "barrier_weight");
        assert_eq!(FeasibilitySettings { barrier_delta: 0.0, ..Default::default() }.validate().unwrap_err().field, "barrier_delta");
        assert_eq!(FeasibilitySettings { barrier_decrease: 1.5, ..Default::default() }.validate().unwrap_err().field, "barrier_decrease");
        assert_eq!(FeasibilitySettings { landing_penalty: -1.0, ..Default::default() }.validate().unwrap_err().field, "landing_penalty");
        assert_eq!(FeasibilitySettings { landing_clearance: 0.0, ..Default::default() }.validate().unwrap_err().field, "landing_clearance");
        assert_eq!(FeasibilitySettings { landing_depth: 0.0, ..Default::default() }.validate().unwrap_err().field, "landing_depth");
        assert_eq!(FeasibilitySettings { slide_speed: f64::NAN, ..Default::default() }.validate().unwrap_err().field, "slide_speed");
        // Off by default: the augmented Lagrangian alone.
        assert_eq!(FeasibilityConstraints::new(&model, 10, FeasibilitySettings::default()).unwrap().barrier_weight(), 0.0);
        let s = FeasibilitySettings::default();
        assert_eq!((s.landing_penalty, s.impact_penalty, s.slide_penalty), (0.0, 0.0, 0.0));
        // Switched on, the foot-speed rows wait for the polish, then carry their penalties
        // at every knot and foot.
        let on = FeasibilitySettings { landing_penalty: 3.0, impact_penalty: 5.0, slide_penalty: 7.0, ..Default::default() };
        let mut c = FeasibilityConstraints::new(&model, 10, on).unwrap();
        let rows = |c: &FeasibilityConstraints| c.penalties.chunks(c.per_knot()).flat_map(|k| k[..FOOT_ROWS * c.feet].chunks(FOOT_ROWS).map(|f| [f[2], f[3], f[4]]).collect::<Vec<_>>()).collect::<Vec<_>>();
        assert!(rows(&c).iter().all(|r| *r == [0.0; 3]));
        c.start_foot_speed_rows();
        assert_eq!(rows(&c).len(), 11 * model.feet.len());
        assert!(rows(&c).iter().all(|r| *r == [3.0, 5.0, 7.0]));
        assert!(c.penalties.chunks(c.per_knot()).all(|k| k[0] == on.friction_penalty && k[1] == on.penetration_penalty));
        // The polish's bounds replace the targets' and nothing else.
        let s = FeasibilitySettings::default();
        let polish = s.with_polish_bounds();
        assert_eq!((polish.friction_margin, polish.max_penetration, polish.joint_limit_margin), (s.polish_friction_margin, s.polish_max_penetration, s.polish_joint_limit_margin));
        assert_eq!(FeasibilitySettings { friction_margin: s.friction_margin, max_penetration: s.max_penetration, joint_limit_margin: s.joint_limit_margin, ..polish }, s);
    }

    /// `psi` is C1 across the activation and its derivatives match differences.
    #[test]
    fn the_augmented_lagrangian_term_and_its_derivatives() {
        for (lambda, rho) in [(0.0, 10.0), (2.0, 10.0), (0.5, 1e3)] {
            for c in [-1.0, -0.1, 0.05, 0.3] {
                let (v, d1, d2) = psi(c, lambda, rho);
                let h = 1e-6;
                let fd = (psi(c + h, lambda, rho).0 - psi(c - h, lambda, rho).0) / (2.0 * h);
                assert!((fd - d1).abs() < 1e-5 * (1.0 + d1.abs()), "lambda {lambda}, c {c}: {fd} vs {d1}");
                let fd2 = (psi(c + h, lambda, rho).1 - psi(c - h, lambda, rho).1) / (2.0 * h);
                assert!((fd2 - d2).abs() < 1e-4 * (1.0 + d2), "{fd2} vs {d2}");
                assert!(v.is_finite());
            }
        }
        // Zero penalty: off.
        assert_eq!(psi(0.2, 1.0, 0.0), (0.0, 0.0, 0.0));
        // Zero multiplier: the quadratic penalty.
        assert_eq!(psi(0.2, 0.0, 10.0).0, 0.5 * 10.0 * 0.04);
        assert_eq!(psi(-0.2, 0.0, 10.0), (0.0, 0.0, 0.0));
    }

    /// The demanded tangential force's derivatives against central differences, sticking
    /// and beyond the cone (where the contact force saturates but the demand does not).
    #[test]
    fn demand_derivatives_match_finite_differences() {
        let params = ContactParams::default();
        let r = 0.02;
        let surface = Surface { point: Vector3::new(0.1, -0.2, 0.05), normal: Vector3::new(0.2, -0.1, 1.0).normalize() };
        let n = surface.normal;
        let tangent = Matrix3::identity() - n * n.transpose();
        let foot_at = |p: Vector3<f64>, v: Vector3<f64>, a: Option<&Vector3<f64>>| {
            let contact = contact_force(&params, r, &p, &v, &surface, a);
            FootState { position: p, velocity: v, normal: n, contact }
        };
        for (depth, anchor_offset, velocity) in [(0.004, 0.0005, Vector3::new(0.02, 0.01, -0.1)), (0.015, 0.06, Vector3::new(0.3, -0.1, 0.05)), (0.012, 0.0, Vector3::new(0.1, 0.2, 0.0))] {
            let base = surface.point + tangent * Vector3::new(0.01, 0.02, 0.0);
            let p = base + n * (r - depth);
            let a = base - tangent * Vector3::new(anchor_offset, -0.5 * anchor_offset, 0.0);
            let foot = foot_at(p, velocity, Some(&a));
            let demand = tangential_demand(&params, &foot, Some(&a));
            let d = tangential_demand_derivatives(&params, &foot, Some(&a), &demand);
            let h = 1e-7;
            for i in 0..3 {
                let e = Vector3::ith(i, h);
                let at = |p: Vector3<f64>, v: Vector3<f64>, a: Vector3<f64>| tangential_demand(&params, &foot_at(p, v, Some(&a)), Some(&a));
                let fd_p = (at(p + e, velocity, a) - at(p - e, velocity, a)) / (2.0 * h);
                let fd_v = (at(p, velocity + e, a) - at(p, velocity - e, a)) / (2.0 * h);
                let fd_a = (at(p, velocity, a + e) - at(p, velocity, a - e)) / (2.0 * h);
                let scale = 1.0 + d.position.norm();
                assert!((d.position.column(i) - fd_p).norm() / scale < 1e-6, "dT/dp {i}: {} vs {fd_p}", d.position.column(i));
                assert!((d.velocity.column(i) - fd_v).norm() / (1.0 + d.velocity.norm()) < 1e-6);
                assert!((d.anchor.column(i) - fd_a).norm() / scale < 1e-6);
            }
            if anchor_offset == 0.06 {
                assert!(foot.contact.slipping, "the far anchor is beyond the cone");
                assert!(demand.norm() > params.friction * foot.contact.normal_force);
            }
        }
    }
}
