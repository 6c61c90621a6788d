//! Solver settings with IPOPT's defaults (Wächter & Biegler 2006, "On the implementation of
//! an interior-point filter line-search algorithm for large-scale nonlinear programming",
//! Math. Programming 106; the names of IPOPT's options in brackets).

/// Settings of [`super::Solver`] (defaults in parentheses).
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// Tolerance of the scaled optimality error `E_0` (1e-8) \[`tol`\].
    pub tolerance: f64,
    /// Unscaled tolerances that must also hold at convergence: dual infeasibility (1),
    /// constraint violation (1e-4), complementarity (1e-4) [`dual_inf_tol`, `constr_viol_tol`,
    /// `compl_inf_tol`].
    pub dual_infeasibility_tolerance: f64,
    pub constraint_violation_tolerance: f64,
    pub complementarity_tolerance: f64,
    /// Maximum iterations (3000) \[`max_iter`\].
    pub max_iterations: usize,
    /// Initial barrier parameter (0.1) \[`mu_init`\]; smaller for a warm start close to the optimum.
    pub mu_init: f64,
    /// Monotone barrier update `mu <- max(tol/10, min(kappa_mu mu, mu^theta_mu))` when
    /// `E_mu <= kappa_epsilon mu` (0.2, 1.5, 10) [`mu_linear_decrease_factor`,
    /// `mu_superlinear_decrease_power`, `barrier_tol_factor`].
    pub kappa_mu: f64,
    pub theta_mu: f64,
    pub kappa_epsilon: f64,
    /// How the barrier parameter is chosen (the monotone rule above) \[`mu_strategy`\].
    pub barrier_update: BarrierUpdate,
    /// The adaptive update's bounds on `mu`: at least `adaptive_mu_min` (1e-11) \[`mu_min`\], at
    /// most `adaptive_mu_max_factor` (1e3) times the first iterate's average complementarity
    /// \[`mu_max_fact`\]; `mu = sigma avg(s z)` with the centering `sigma` in
    /// `[sigma_min, sigma_max]` (1e-6, 100) [`sigma_min`, `sigma_max`].
    pub adaptive_mu_min: f64,
    pub adaptive_mu_max_factor: f64,
    pub sigma_min: f64,
    pub sigma_max: f64,
    /// The adaptive update's globalization (Nocedal, Wächter & Waltz 2009, sec. 5, the KKT-error
    /// test): free choice of `mu` while the optimality error is at most
    /// `adaptive_mu_error_reduction` (0.9999) times one of the last
    /// `adaptive_mu_error_references` (4) accepted errors [`adaptive_mu_kkterror_red_fact`,
    /// `adaptive_mu_kkterror_red_iters`]; otherwise the monotone rule from
    /// `mu = adaptive_mu_monotone_init_factor avg(s z)` (0.8) \[`adaptive_mu_monotone_init_factor`\]
    /// until the error is that much below the references again.
    pub adaptive_mu_error_reduction: f64,
    pub adaptive_mu_error_references: usize,
    pub adaptive_mu_monotone_init_factor: f64,
    /// Fraction-to-the-boundary `tau = max(tau_min, 1 - mu)` (0.99) \[`tau_min`\].
    pub tau_min: f64,
    /// Initial slacks pushed into the interior by `min(bound_push max(1, |bound|), bound_frac
    /// (upper - lower))` (1e-2, 1e-2) [`bound_push`, `bound_frac`].
    pub bound_push: f64,
    pub bound_frac: f64,
    /// Initial bound multipliers (1) \[`bound_mult_init_val`\].
    pub bound_multiplier_init: f64,
    /// Least-squares estimate of the equality multipliers at the start, discarded if its
    /// largest entry exceeds `multiplier_init_max` (true, 1e3) \[`constr_mult_init_max`\].
    pub least_squares_multipliers: bool,
    pub multiplier_init_max: f64,
    /// Bound multipliers are kept within `[mu / (kappa_sigma d), kappa_sigma mu / d]` (1e10)
    /// \[`kappa_sigma`\].
    pub kappa_sigma: f64,
    /// Scaling threshold `s_max` of the optimality error (100).
    pub s_max: f64,
    /// Inertia correction: first regularization, smallest, largest, decrease and increase
    /// factors (1e-4, 1e-20, 1e40, 1/3, 8, 100 for the first increase) [`first_hessian_perturbation`,
    /// `min_hessian_perturbation`, `max_hessian_perturbation`, `perturb_dec_fact`,
    /// `perturb_inc_fact`, `perturb_inc_fact_first`].
    pub regularization_first: f64,
    pub regularization_min: f64,
    pub regularization_max: f64,
    pub regularization_decrease: f64,
    pub regularization_increase: f64,
    pub regularization_increase_first: f64,
    /// Pivots of the constraint elimination below this, relative to the largest entry of
    /// the stage's constraint block, count as zero (1e-10).
    pub pivot_tolerance: f64,
    /// Filter line search: `gamma_theta`, `gamma_phi`, `delta`, `s_theta`, `s_phi`,
    /// `eta_phi`, `gamma_alpha` (1e-5, 1e-8, 1, 1.1, 2.3, 1e-4, 0.05) and the backtracking
    /// factor (0.5).
    pub gamma_theta: f64,
    pub gamma_phi: f64,
    pub switching_delta: f64,
    pub s_theta: f64,
    pub s_phi: f64,
    pub eta_phi: f64,
    pub gamma_alpha: f64,
    pub backtracking_factor: f64,
    /// Second-order corrections tried when the full step is rejected and increases the
    /// infeasibility (4; 0 turns them off) \[`max_soc`\], and their required decrease (0.99)
    /// \[`kappa_soc`\].
    pub max_second_order_corrections: usize,
    pub kappa_soc: f64,
    /// Iterative refinement of every KKT solve (sec. 3.1 of the paper's implementation; IPOPT
    /// refines on the full system): while the residual of the step, relative to the step
    /// and the right-hand side, is above `refinement_residual_ratio` (1e-10)
    /// \[`residual_ratio_max`\], solve again for the residual, at most `max_refinement_steps`
    /// times (10) \[`max_refinement_steps`\], stopping when a correction does not shrink the
    /// ratio. Without it the end game stalls where the Riccati solve's round-off (about 1e-8
    /// of the gradient on the full-body stages) exceeds the dual infeasibility left to remove.
    pub refinement_residual_ratio: f64,
    pub max_refinement_steps: usize,
    /// Feasibility restoration (sec. 3.3; the `restoration` module) where the filter line
    /// search fails from an infeasible point (true): minimize the l1 violation plus a
    /// proximity term, return once the filter accepts. Its penalty `rho` (1000)
    /// \[`resto_penalty_parameter`\], the reduction of the violation it must reach before it
    /// returns (0.9) \[`required_infeasibility_reduction`\], its iteration limit per call (500)
    /// and the number of calls per solve (10).
    pub restoration: bool,
    pub restoration_penalty: f64,
    pub restoration_reduction: f64,
    pub restoration_max_iterations: usize,
    pub max_restorations: usize,
    /// Evaluate the stages (values, Jacobians, Hessians) on rayon's threads (false: worth it
    /// when a stage's evaluation costs more than a thread hand-off, as full-body dynamics do).
    pub parallel: bool,
    /// Print one line per iteration to stderr (false).
    pub verbose: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            tolerance: 1e-8,
            dual_infeasibility_tolerance: 1.0,
            constraint_violation_tolerance: 1e-4,
            complementarity_tolerance: 1e-4,
            max_iterations: 3000,
            mu_init: 0.1,
            kappa_mu: 0.2,
            theta_mu: 1.5,
            kappa_epsilon: 10.0,
            barrier_update: BarrierUpdate::Monotone,
            adaptive_mu_min: 1e-11,
            adaptive_mu_max_factor: 1e3,
            sigma_min: 1e-6,
            sigma_max: 100.0,
            adaptive_mu_error_reduction: 0.9999,
            adaptive_mu_error_references: 4,
            adaptive_mu_monotone_init_factor: 0.8,
            tau_min: 0.99,
            bound_push: 1e-2,
            bound_frac: 1e-2,
            bound_multiplier_init: 1.0,
            least_squares_multipliers: true,
            multiplier_init_max: 1e3,
            kappa_sigma: 1e10,
            s_max: 100.0,
            regularization_first: 1e-4,
            regularization_min: 1e-20,
            regularization_max: 1e40,
            regularization_decrease: 1.0 / 3.0,
            regularization_increase: 8.0,
            regularization_increase_first: 100.0,
            pivot_tolerance: 1e-10,
            gamma_theta: 1e-5,
            gamma_phi: 1e-8,
            switching_delta: 1.0,
            s_theta: 1.1,
            s_phi: 2.3,
            eta_phi: 1e-4,
            gamma_alpha: 0.05,
            backtracking_factor: 0.5,
            max_second_order_corrections: 4,
            kappa_soc: 0.99,
            refinement_residual_ratio: 1e-10,
            max_refinement_steps: 10,
            restoration: true,
            restoration_penalty: 1e3,
            restoration_reduction: 0.9,
            restoration_max_iterations: 500,
            max_restorations: 10,
            parallel: false,
            verbose: false,
        }
    }
}

/// The barrier parameter's update.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BarrierUpdate {
    /// Fiacco-McCormick: `mu` fixed until the barrier problem is solved to
    /// `kappa_epsilon mu`, then decreased (Wächter & Biegler 2006, eq. 7) \[`monotone`\].
    Monotone,
    /// `mu` chosen at every iteration by the oracle (Nocedal, Wächter & Waltz 2009), with the
    /// monotone rule as the fallback when the optimality error stops decreasing \[`adaptive`\].
    Adaptive(MuOracle),
}

/// How the adaptive update picks `mu = sigma avg(s z)` (Nocedal, Wächter & Waltz 2009)
/// \[`mu_oracle`\].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MuOracle {
    /// Mehrotra's probing (sec. 3): the affine-scaling step (`mu = 0`) to the boundary,
    /// `sigma = (avg(s z) after it / avg(s z))^3` \[`probing`\].
    Probing,
    /// The quality function (sec. 4): `sigma` minimizes the linearized KKT error after the
    /// step `d_aff + sigma d_cen`, by golden section on `log sigma` \[`quality-function`\].
    QualityFunction,
    /// LOQO's rule (eq. 3.6): `sigma = 0.1 min(0.05 (1 - xi) / xi, 2)^3`, `xi = min(s z) /
    /// avg(s z)` \[`loqo`\].
    Loqo,
}

impl std::str::FromStr for BarrierUpdate {
    type Err = String;

    /// `monotone`, or the adaptive update's oracle: `probing`, `quality-function`, `loqo`.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        match name {
            "monotone" => Ok(Self::Monotone),
            "probing" => Ok(Self::Adaptive(MuOracle::Probing)),
            "quality-function" => Ok(Self::Adaptive(MuOracle::QualityFunction)),
            "loqo" => Ok(Self::Adaptive(MuOracle::Loqo)),
            other => Err(format!("barrier update `{other}`: expected monotone, probing, quality-function or loqo")),
        }
    }
}

/// A setting out of its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("ipocp setting `{field}` = {value}: expected {expected}")]
pub struct SettingsError {
    pub field: &'static str,
    pub value: f64,
    pub expected: &'static str,
}

impl Settings {
    /// Checks the ranges the algorithm relies on.
    pub fn validate(&self) -> Result<(), SettingsError> {
        let check = |field, value: f64, ok: bool, expected| if ok { Ok(()) } else { Err(SettingsError { field, value, expected }) };
        check("tolerance", self.tolerance, self.tolerance > 0.0, "> 0")?;
        check("mu_init", self.mu_init, self.mu_init > 0.0, "> 0")?;
        check("kappa_mu", self.kappa_mu, self.kappa_mu > 0.0 && self.kappa_mu < 1.0, "in (0, 1)")?;
        check("theta_mu", self.theta_mu, self.theta_mu > 1.0 && self.theta_mu < 2.0, "in (1, 2)")?;
        check("tau_min", self.tau_min, self.tau_min > 0.0 && self.tau_min < 1.0, "in (0, 1)")?;
        check("bound_push", self.bound_push, self.bound_push > 0.0, "> 0")?;
        check("bound_frac", self.bound_frac, self.bound_frac > 0.0 && self.bound_frac <= 0.5, "in (0, 0.5]")?;
        check("bound_multiplier_init", self.bound_multiplier_init, self.bound_multiplier_init > 0.0, "> 0")?;
        check("backtracking_factor", self.backtracking_factor, self.backtracking_factor > 0.0 && self.backtracking_factor < 1.0, "in (0, 1)")?;
        check("kappa_sigma", self.kappa_sigma, self.kappa_sigma >= 1.0, ">= 1")?;
        check("pivot_tolerance", self.pivot_tolerance, self.pivot_tolerance > 0.0 && self.pivot_tolerance < 1.0, "in (0, 1)")?;
        check("regularization_first", self.regularization_first, self.regularization_first > 0.0, "> 0")?;
        check("restoration_penalty", self.restoration_penalty, self.restoration_penalty > 0.0, "> 0")?;
        check("restoration_reduction", self.restoration_reduction, self.restoration_reduction > 0.0 && self.restoration_reduction < 1.0, "in (0, 1)")?;
        check("adaptive_mu_min", self.adaptive_mu_min, self.adaptive_mu_min > 0.0, "> 0")?;
        check("adaptive_mu_max_factor", self.adaptive_mu_max_factor, self.adaptive_mu_max_factor > 0.0, "> 0")?;
        check("sigma_min", self.sigma_min, self.sigma_min > 0.0 && self.sigma_min < 1.0, "in (0, 1)")?;
        check("sigma_max", self.sigma_max, self.sigma_max >= 1.0, ">= 1")?;
        check("adaptive_mu_error_reduction", self.adaptive_mu_error_reduction, self.adaptive_mu_error_reduction > 0.0 && self.adaptive_mu_error_reduction < 1.0, "in (0, 1)")?;
        check("adaptive_mu_error_references", self.adaptive_mu_error_references as f64, self.adaptive_mu_error_references >= 1, ">= 1")?;
        check("adaptive_mu_monotone_init_factor", self.adaptive_mu_monotone_init_factor, self.adaptive_mu_monotone_init_factor > 0.0, "> 0")?;
        check("regularization_increase", self.regularization_increase, self.regularization_increase > 1.0, "> 1")?;
        Ok(())
    }
}
