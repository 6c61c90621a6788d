//! Nguyen 2022's contact-timing optimization (sec. II-B, eq. (2)) on the single rigid
//! body, formulated as `../shared/anchors/nguyen2022/contact_timing.py` formulates it (the
//! oracle legwork is checked against), and solved with [`crate::ipocp`].
//!
//! Choices the paper leaves open follow the script (see its README): Lee's rotation error,
//! `R_ref` rotating linearly over the knot index, the final rotation as
//! `skew(R_g^T R_N) = 0` with `tr(R_g^T R_N) >= 2.9`, `Omegadot_0 = 0` as zero net body
//! torque at the first knot, every otherwise free variable bounded by `+-1e3` and the
//! rotation entries by `+-1.5`, the targets of the jumps the paper does not give.

// Index loops over rows and columns read like the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::exp_map::{exp, ExpMap};
use super::params::SrbParams;
use super::stage::{rotation_error_map, PlatformBox, Shared, SrbStage, BIG, P, R, T, V, W};
use crate::ipocp::{BarrierUpdate, MuOracle, Problem, ProblemError, Settings, SolveError, SolveResult, Solver, Stage};
use nalgebra::{DVector, Matrix3, Vector3};
use std::sync::Arc;

/// Feet in contact per phase, order LF, RF, LH, RH.
pub type Contacts = [bool; 4];

const ALL: Contacts = [true; 4];
const NONE: Contacts = [false; 4];

/// A jump as the contact-timing formulation sees it (the jump files of [`crate::jump`]
/// describe the seven of the paper's Table I).
#[derive(Clone, Debug, PartialEq)]
pub struct JumpSpec {
    pub name: &'static str,
    /// CoM displacement goal (world).
    pub displacement: Vector3<f64>,
    /// Goal rotation as axis and angle.
    pub axis: Vector3<f64>,
    pub angle: f64,
    /// Height of the start box above the landing ground.
    pub box_height: f64,
    /// The start box the airborne legs must clear (top at `box_height`, this extent in x
    /// and y, world); `None`: no clearance rows, the reference script's problem.
    pub clear_of: Option<BoxExtent>,
    pub phases: Vec<Contacts>,
    /// `[T_min, T_max]` of (2j).
    pub total_time: (f64, f64),
    /// Bounds `[lo, hi]` of each phase's duration `T_i` (s), one per phase; `None`: every
    /// phase within the settings' `[t_lo, t_hi]` (the reference script's 0.1-1.0 s).
    pub phase_time: Option<Vec<(f64, f64)>>,
    /// How much higher (m, world z) than in the standing pose the CoM ends over the landing
    /// feet (0: the standing pose). The final pose is the touch-down pose and the full body
    /// lands in its legs' inverse kinematics: straighter legs leave a longer stroke to stop
    /// the touch-down speed in under the motors' torque limit (docs/experiments/jump-flip-4.md).
    pub landing_extension: f64,
}

/// The largest [`JumpSpec::landing_extension`] (m): the stance CoM height bound is the
/// standing height + 0.15 m, and the A1's legs (0.2 + 0.2 m) are straight about 0.13 m above
/// its standing pose.
pub const MAX_LANDING_EXTENSION: f64 = 0.12;

/// The seven jumps of the paper's Table I under the reference script's names (`lateral30`,
/// `spin90`, ...: its `JUMPS` keys and results), read from the embedded jump files
/// ([`crate::jump::EMBEDDED_JUMPS`]): the files' targets, which land clear of the box.
pub fn jumps() -> Vec<JumpSpec> {
    embedded_specs(|jump| jump.srb())
}

/// The reference script's own problems (its `JUMPS`, whose targets land barrel_roll and
/// double_backflip over the start box: [`crate::jump::Jump::reference_srb`]), for the
/// comparison with its optima.
pub fn reference_jumps() -> Vec<JumpSpec> {
    embedded_specs(|jump| jump.reference_srb())
}

fn embedded_specs(spec: impl Fn(&crate::jump::Jump) -> JumpSpec) -> Vec<JumpSpec> {
    crate::jump::EMBEDDED_JUMPS
        .iter()
        .map(|&(name, script_name, _)| {
            let jump = crate::jump::Jump::embedded(name).unwrap_or_else(|e| panic!("the embedded jump files are checked by tests/jumps.rs: {e}"));
            JumpSpec { name: script_name, ..spec(&jump) }
        })
        .collect()
}

/// The horizontal extent of a start box (world, m): `[x_min, x_max]`, `[y_min, y_max]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxExtent {
    pub x: [f64; 2],
    pub y: [f64; 2],
}

/// Settings of the formulation (defaults: the script's, in parentheses).
#[derive(Clone, Debug, PartialEq)]
pub struct ContactTimingSettings {
    /// Knots per phase `N_i` (30).
    pub knots_per_phase: usize,
    /// Friction coefficient (0.6), vertical force bounds per foot (0, 200 N), sphere radius
    /// of (2d) (0.14 m).
    pub mu: f64,
    pub f_min: f64,
    pub f_max: f64,
    pub radius: f64,
    /// Bound on each component of the CoM velocity `|pdot_i|` on the knots of the contact
    /// phases and the lift-off knot (1.5 m/s; infinite: none, as eq. (2) and the reference
    /// script). The SRB has no legs: without it the cost (a smaller `Omega` over a longer
    /// flight) sends the flight to the time bound, and spin_90 / barrel_roll asked for a
    /// 3.2 / 3.7 m/s take-off that an A1 leg delivers only at its 21 rad/s and 33.5 N m
    /// limits (a leg of two 0.2 m links lengthens at `0.2 sin(|q_knee| / 2) qdot_knee`:
    /// 1.9 m/s at the knee's take-off angle of 0.92 rad). 1.5 m/s is the take-off of the
    /// paper's own timings (Table I flights of 0.28-0.33 s on flat ground).
    pub max_stance_speed: f64,
    /// Bounds of each `T_i` (0.1, 1.0 s), where the jump gives none of its own
    /// (`JumpSpec::phase_time`).
    pub t_lo: f64,
    pub t_hi: f64,
    /// Cost weights `eps_Omega`, `eps_R`, `eps_f` (1, 10, 1e-4).
    pub eps_omega: f64,
    pub eps_r: f64,
    pub eps_f: f64,
    /// Weight each knot's cost by its interval `T_i / N_i` (the script's `--cost-dt`; true).
    /// False: the cost summed per knot, as eq. (2) is printed.
    pub cost_dt: bool,
    /// The SO(3) step's exponential (`Exact`; `Taylor4` is the paper's and the script's).
    pub exp_map: ExpMap,
    /// Clearance from the start box (`JumpSpec::clear_of`) of each airborne leg's tuck point
    /// (m; not in the script, whose problems have no box: 0.02). The tuck point is the top of
    /// the foot's sphere (2d), `R (pbar^s + r e_z)`: the shallowest foot the single rigid
    /// body's own leg model allows, straight under the nominal foot.
    pub box_clearance: f64,
}

impl Default for ContactTimingSettings {
    fn default() -> Self {
        Self {
            knots_per_phase: 30,
            mu: 0.6,
            f_min: 0.0,
            f_max: 200.0,
            radius: 0.14,
            max_stance_speed: 1.5,
            t_lo: 0.1,
            t_hi: 1.0,
            eps_omega: 1.0,
            eps_r: 10.0,
            eps_f: 1e-4,
            cost_dt: true,
            exp_map: ExpMap::Exact,
            box_clearance: 0.02,
        }
    }
}

/// What is wrong with a contact-timing problem's inputs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ContactTimingError {
    #[error("contact-timing setting `{field}` = {value}: expected {expected}")]
    Setting { field: &'static str, value: f64, expected: &'static str },
    #[error("jump '{jump}': {problem}")]
    Jump { jump: String, problem: &'static str },
    #[error("the body's inertia is not invertible: {0:?}")]
    SingularInertia(Matrix3<f64>),
    #[error(transparent)]
    Problem(#[from] ProblemError),
}

impl ContactTimingSettings {
    /// Checks the ranges the formulation needs.
    pub fn validate(&self) -> Result<(), ContactTimingError> {
        let check = |field, value: f64, ok: bool, expected| if ok { Ok(()) } else { Err(ContactTimingError::Setting { field, value, expected }) };
        // The paper's N_i is 30; a thousand per phase already takes minutes, more would not
        // fit in memory before the solve could refuse them.
        check("knots_per_phase", self.knots_per_phase as f64, (1..=MAX_KNOTS_PER_PHASE).contains(&self.knots_per_phase), "between 1 and 1000")?;
        check("mu", self.mu, self.mu > 0.0, "> 0")?;
        check("f_min", self.f_min, self.f_min.is_finite() && self.f_min <= self.f_max, "finite and <= f_max")?;
        check("f_max", self.f_max, self.f_max.is_finite(), "finite")?;
        check("radius", self.radius, self.radius > 0.0, "> 0")?;
        check("max_stance_speed", self.max_stance_speed, self.max_stance_speed > 0.0, "> 0 (infinite: no bound)")?;
        check("t_lo", self.t_lo, self.t_lo > 0.0 && self.t_lo <= self.t_hi, "> 0 and <= t_hi")?;
        check("t_hi", self.t_hi, self.t_hi.is_finite(), "finite")?;
        check("box_clearance", self.box_clearance, self.box_clearance.is_finite() && self.box_clearance >= 0.0, "finite and >= 0")?;
        for (field, v) in [("eps_omega", self.eps_omega), ("eps_r", self.eps_r), ("eps_f", self.eps_f)] {
            check(field, v, v >= 0.0 && v.is_finite(), ">= 0")?;
        }
        Ok(())
    }
}

/// The most knots per phase the contact timing accepts (the paper uses 30).
pub const MAX_KNOTS_PER_PHASE: usize = 1000;

/// `exp(hat(axis * angle))`.
fn rotation(axis: &Vector3<f64>, angle: f64) -> Matrix3<f64> {
    exp(ExpMap::Exact, &(axis * angle))
}

/// The contact-timing problem of one jump: stages, initial guess and the numbers to read
/// the solution with.
pub struct ContactTimingProblem {
    pub problem: Problem,
    pub guess: Vec<DVector<f64>>,
    pub phases: usize,
    pub knots: usize,
    /// Knots per phase `N_i` (the same for every phase).
    pub knots_per_phase: usize,
    /// Feet in contact per phase (the jump's contact sequence).
    pub phase_contacts: Vec<Contacts>,
    /// Feet at the start (where stance feet stay) and at the goal (world, order LF, RF, LH, RH).
    pub feet_start: [Vector3<f64>; 4],
    pub feet_goal: [Vector3<f64>; 4],
}

impl ContactTimingProblem {
    /// Builds the problem of `jump` for the body `params`.
    pub fn new(jump: &JumpSpec, params: &SrbParams, s: &ContactTimingSettings) -> Result<Self, ContactTimingError> {
        s.validate()?;
        let bad = |problem| ContactTimingError::Jump { jump: jump.name.to_string(), problem };
        if jump.phases.len() < 2 || jump.phases.last() != Some(&NONE) || jump.phases[0] != ALL {
            return Err(bad("phases must start with all four feet in contact and end with a flight phase"));
        }
        if jump.phases[..jump.phases.len() - 1].iter().any(|c| !c.iter().any(|&f| f)) {
            return Err(bad("only the last phase may be a flight phase"));
        }
        let (t_min, t_max) = jump.total_time;
        if t_min.is_nan() || t_max.is_nan() || t_min > t_max || jump.axis.norm().is_nan() || jump.axis.norm() == 0.0 {
            return Err(bad("total_time must be an interval (min <= max) and the axis nonzero"));
        }
        let phase_time: Vec<(f64, f64)> = match &jump.phase_time {
            None => vec![(s.t_lo, s.t_hi); jump.phases.len()],
            Some(b) if b.len() != jump.phases.len() => return Err(bad("phase_time needs one [lo, hi] per phase")),
            Some(b) if b.iter().any(|&(lo, hi)| !(lo > 0.0 && lo <= hi && hi.is_finite())) => return Err(bad("phase_time bounds must be 0 < lo <= hi, finite")),
            Some(b) => b.clone(),
        };
        let sum = |f: fn(&(f64, f64)) -> f64| phase_time.iter().map(f).sum::<f64>();
        if sum(|b| b.0) > t_max || sum(|b| b.1) < t_min {
            return Err(bad("the phase_time bounds cannot sum into total_time (2j)"));
        }
        if !(0.0..=MAX_LANDING_EXTENSION).contains(&jump.landing_extension) {
            return Err(bad("landing_extension must be within [0, MAX_LANDING_EXTENSION = 0.12] m"));
        }
        let inertia_inv = params.inertia.try_inverse().ok_or(ContactTimingError::SingularInertia(params.inertia))?;
        let np = jump.phases.len();
        let n = s.knots_per_phase;
        let nc = n * np;
        // Sphere centres: the standing feet, put exactly on the ground plane (mean height).
        let h0 = -params.foot_rel_com.iter().map(|f| f[2]).sum::<f64>() / 4.0;
        let pbar: [Vector3<f64>; 4] = std::array::from_fn(|f| Vector3::new(params.foot_rel_com[f][0], params.foot_rel_com[f][1], -h0));
        let p0 = Vector3::new(0.0, 0.0, jump.box_height + h0);
        // The landing feet stand where the standing pose at the displaced CoM puts them; the
        // CoM ends `landing_extension` above that pose (the legs straighter at touch-down).
        let pg_standing = p0 + jump.displacement;
        let pg = pg_standing + Vector3::new(0.0, 0.0, jump.landing_extension);
        let rg = rotation(&jump.axis, jump.angle);
        let feet_start = std::array::from_fn(|f| p0 + pbar[f]);
        let feet_goal = std::array::from_fn(|f| pg_standing + rg * pbar[f]);
        let shared = Arc::new(Shared {
            mass: params.mass,
            inertia: params.inertia,
            inertia_inv,
            pbar,
            radius: s.radius,
            mu: s.mu,
            eps_omega: s.eps_omega,
            eps_r: s.eps_r,
            eps_f: s.eps_f,
            cost_dt: s.cost_dt,
            exp_map: s.exp_map,
            knots_per_phase: vec![n; np],
            phases: np,
            t_sum: jump.total_time,
            height: (0.5 * h0, h0 + 0.15),
            ground: jump.box_height,
            p0,
            pg,
            rg,
            feet_start,
            feet_goal,
            platform: jump.clear_of.map(|b| PlatformBox { top: jump.box_height, x: b.x, y: b.y }),
            tuck: std::array::from_fn(|f| pbar[f] + Vector3::new(0.0, 0.0, s.radius)),
            box_clearance: s.box_clearance,
        });
        let phase_of = |k: usize| k.min(nc - 1) / n;
        let k_flight = n * (np - 1);
        let nx = T + np;
        // Initial guess of the script: an even split of the mid total time (each phase's
        // share clamped into its bounds), a straight CoM line, no rotation in stance and a
        // constant rate in flight, feet interpolated.
        let t_even = 0.5 * (jump.total_time.0 + jump.total_time.1) / np as f64;
        let t_phase: Vec<f64> = phase_time.iter().map(|&(lo, hi)| t_even.clamp(lo, hi)).collect();
        let t_total: f64 = t_phase.iter().sum();
        let t_flight = t_phase[np - 1];
        let flight_arc = Self::flight_arc(&shared, jump, k_flight, nc);
        let mut stages: Vec<Box<dyn Stage>> = Vec::with_capacity(nc + 1);
        let mut guess = Vec::with_capacity(nc + 1);
        for k in 0..=nc {
            let last = k == nc;
            let phase = phase_of(k);
            let contact = if last { NONE } else { jump.phases[phase] };
            let ang_ref = jump.angle * k as f64 / nc as f64;
            let rot_err = rotation_error_map(&rotation(&jump.axis, ang_ref));
            let mut bounds = Vec::new();
            // p, pdot, Omega; pdot within the stance speed up to the lift-off knot.
            let speed = if k <= k_flight { s.max_stance_speed.min(BIG) } else { BIG };
            for j in 0..9 {
                let b = if (V..V + 3).contains(&(P + j)) { speed } else { BIG };
                bounds.push((P + j, -b, b));
            }
            for j in 0..9 {
                bounds.push((R + j, -1.5, 1.5));
            }
            if k == 0 {
                for (i, &(lo, hi)) in phase_time.iter().enumerate() {
                    bounds.push((T + i, lo, hi));
                }
            }
            if !last {
                for f in 0..4 {
                    let u = nx + 3 * f;
                    if contact[f] {
                        bounds.push((u, -BIG, BIG));
                        bounds.push((u + 1, -BIG, BIG));
                        bounds.push((u + 2, s.f_min, s.f_max));
                    } else {
                        for j in 0..3 {
                            bounds.push((u + j, -BIG, BIG));
                        }
                    }
                }
            }
            let ncontact = contact.iter().filter(|&&c| c).count();
            // Clearance rows of the airborne legs over their interval (the last knot's feet
            // are the landing's, off the box by the file's checks).
            let n_box = if shared.platform.is_some() && !last && ncontact == 0 { 4 } else { 0 };
            let n_general = n_box + if last { 4 + 1 } else { 4 * ncontact + 4 + usize::from(ncontact > 0) + usize::from(k == 0) };
            stages.push(Box::new(SrbStage { shared: shared.clone(), knot: k, phase, last, contact, rot_err, bounds, n_general, n_box }));
            // Guess.
            let frac = k as f64 / nc as f64;
            let mut z = DVector::zeros(if last { nx } else { nx + 12 });
            let mut p = p0 * (1.0 - frac) + pg * frac;
            if k > k_flight && k < nc {
                p.z += flight_arc * (std::f64::consts::PI * (k - k_flight) as f64 / (nc - k_flight) as f64).sin();
            }
            let v = (pg - p0) / t_total;
            let w = if k >= k_flight && k < nc { jump.axis * (jump.angle / t_flight) } else { Vector3::zeros() };
            let ang = jump.angle * (k.saturating_sub(k_flight)) as f64 / (nc - k_flight) as f64;
            let rguess = rotation(&jump.axis, ang);
            for j in 0..3 {
                z[P + j] = p[j];
                z[V + j] = v[j];
                z[W + j] = w[j];
            }
            for a in 0..3 {
                for b in 0..3 {
                    z[R + a + 3 * b] = rguess[(a, b)];
                }
            }
            for i in 0..np {
                z[T + i] = t_phase[i];
            }
            if !last {
                for f in 0..4 {
                    let u = nx + 3 * f;
                    if contact[f] {
                        z[u + 2] = params.mass * 9.81 / ncontact as f64;
                    } else {
                        let pf = feet_start[f] * (1.0 - frac) + feet_goal[f] * frac;
                        for j in 0..3 {
                            z[u + j] = pf[j];
                        }
                    }
                }
            }
            guess.push(z);
        }
        Ok(Self {
            problem: Problem::new(stages)?,
            guess,
            phases: np,
            knots: nc,
            knots_per_phase: n,
            phase_contacts: jump.phases.clone(),
            feet_start,
            feet_goal,
        })
    }

    /// Height of the arc added to the guess's straight CoM line over the flight (`0` without
    /// a box): the largest lift any flight knot's tuck points need to be `box_clearance` above
    /// the box top where they are over it, so the solve starts with the airborne legs clear of
    /// the box (inside it the signed distance's nearest face switches between top and side).
    fn flight_arc(sh: &Shared, jump: &JumpSpec, k_flight: usize, nc: usize) -> f64 {
        let Some(b) = &sh.platform else { return 0.0 };
        let mut lift: f64 = 0.0;
        for k in k_flight + 1..nc {
            let frac = k as f64 / nc as f64;
            let p = sh.p0 * (1.0 - frac) + sh.pg * frac;
            let r = rotation(&jump.axis, jump.angle * (k - k_flight) as f64 / (nc - k_flight) as f64);
            for t in &sh.tuck {
                let a = p + r * t;
                let over = a.x > b.x[0] - sh.box_clearance && a.x < b.x[1] + sh.box_clearance && a.y > b.y[0] - sh.box_clearance && a.y < b.y[1] + sh.box_clearance;
                if over {
                    lift = lift.max(b.top + sh.box_clearance - a.z);
                }
            }
        }
        lift
    }

    /// The solver settings the pipeline solves the contact timing with: ipocp's defaults
    /// with the adaptive barrier update's quality-function oracle (Nocedal, Wächter & Waltz
    /// 2009), which reaches the same optima as the monotone rule in 40 % fewer iterations over
    /// the seven jumps (docs/experiments/jump-speed-3.md).
    pub fn solver_settings() -> Settings {
        Settings { barrier_update: BarrierUpdate::Adaptive(MuOracle::QualityFunction), ..Settings::default() }
    }

    /// A solver for this problem.
    pub fn solver(&self, settings: Settings) -> Result<Solver, SolveError> {
        Ok(Solver::new(&self.problem, settings)?)
    }

    /// Solves from the script's initial guess.
    pub fn solve(&self, solver: &mut Solver) -> Result<SolveResult, SolveError> {
        solver.solve(&self.problem, &self.guess)
    }

    /// The phase durations `T_i` of an iterate.
    pub fn durations(&self, primal: &[DVector<f64>]) -> Vec<f64> {
        (0..self.phases).map(|i| primal[0][T + i]).collect()
    }
}
