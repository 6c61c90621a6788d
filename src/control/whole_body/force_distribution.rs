//! Contact forces inside the friction cones that come closest to the base rows of eq. (11)
//! (Winkler 2015, sec. V-B), by priority:
//!
//! ```text
//! min_lambda  1/2 (A lambda - b_b)^T S (A lambda - b_b) + eps/2 sum_i lambda_i^T W_i lambda_i
//! subject to  |lambda_i,t| <= mu lambda_i,z  (each stance foot; swing feet carry nothing)
//! ```
//!
//! with `A = J_cb^T` (6 x 3k), `S = diag(s)` the priority of each base row and `W_i =
//! diag(w_t, w_t, 1)` as in [`contact_forces`](super::inverse_dynamics::contact_forces).
//!
//! Why: when the pseudo-inverse of eq. (11) asks a foot to pull or for more tangential force
//! than the ground gives, clipping that one foot leaves an arbitrary part of the base wrench
//! unmet, often a roll or pitch moment: the base then tilts and drags a foot off its
//! stone. With `S` weighting the vertical force and the roll and pitch moments above the
//! horizontal forces and the yaw moment, the other feet take over what they can, and what
//! cannot be met is a horizontal lag of the CoG, which the virtual model corrects.
//!
//! Solved by accelerated projected gradient (FISTA, Beck and Teboulle 2009) with the
//! gradient restart of O'Donoghue and Candes 2015: the projection onto a circular cone is
//! closed-form, the problem has at most `3 x feet` unknowns, and the start is the clipped
//! pseudo-inverse solution, which is optimal whenever nothing was clipped.

use super::legs::FootKinematics;
use nalgebra::{Matrix6, Vector3, Vector6};

/// Iteration limit and tolerance of [`FrictionConeDistribution`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistributionSettings {
    /// Row priorities `s` of the base wrench residual, `[f_x, f_y, f_z, m_x, m_y, m_z]` in
    /// the base frame (1/N^2 and 1/(N m)^2).
    pub wrench_priority: Vector6<f64>,
    /// `eps` relative to the largest eigenvalue of `A^T S A`: the tie-break towards small,
    /// vertical forces.
    pub regularization: f64,
    pub max_iterations: usize,
    /// Stop when a projected-gradient step moves every force by less than this (N).
    pub tolerance: f64,
}

/// What one solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DistributionInfo {
    pub iterations: usize,
    /// `|S^1/2 (A lambda - b_b)|` at the solution.
    pub weighted_residual: f64,
    pub converged: bool,
}

/// One instance of the problem: the base rows `b_b`, the feet (their base Jacobians), which
/// of them stand, the friction coefficient and the tangential weight `w_t` of `W_i`.
#[derive(Clone, Copy, Debug)]
pub struct DistributionProblem<'a> {
    pub base_rows: &'a Vector6<f64>,
    pub feet: &'a [FootKinematics],
    pub stance: &'a [bool],
    pub mu: f64,
    pub tangential_weight: f64,
}

/// Buffers of the solver, one force per foot, allocated once.
#[derive(Clone, Debug)]
pub struct FrictionConeDistribution {
    extrapolated: Vec<Vector3<f64>>,
    previous: Vec<Vector3<f64>>,
}

impl FrictionConeDistribution {
    pub fn new(feet: usize) -> Self {
        Self { extrapolated: vec![Vector3::zeros(); feet], previous: vec![Vector3::zeros(); feet] }
    }

    /// Improves `forces` (on entry: inside the cones, e.g. the clipped pseudo-inverse
    /// forces; zero for swing feet) to the solution of the problem above.
    pub fn solve(&mut self, settings: &DistributionSettings, problem: &DistributionProblem<'_>, forces: &mut [Vector3<f64>]) -> DistributionInfo {
        let DistributionProblem { base_rows, feet, stance, mu, tangential_weight } = *problem;
        let s = &settings.wrench_priority;
        // Lipschitz constant of the gradient: lambda_max(S^1/2 A A^T S^1/2) + eps max(w_t, 1).
        let mut gram = Matrix6::zeros();
        for (foot, _) in feet.iter().zip(stance).filter(|(_, &on)| on) {
            gram += foot.base_jacobian.transpose() * foot.base_jacobian;
        }
        let root = s.map(f64::sqrt);
        let scaled = Matrix6::from_diagonal(&root) * gram * Matrix6::from_diagonal(&root);
        let largest = scaled.symmetric_eigenvalues().amax();
        if largest <= 0.0 {
            return DistributionInfo::default();
        }
        let eps = settings.regularization * largest;
        let step = 1.0 / (largest + eps * tangential_weight.max(1.0));
        let weight = Vector3::new(tangential_weight, tangential_weight, 1.0);

        self.previous.copy_from_slice(forces);
        self.extrapolated.copy_from_slice(forces);
        let mut momentum = 1.0f64;
        let mut info = DistributionInfo::default();
        for iteration in 1..=settings.max_iterations {
            // Gradient at the extrapolated point: A_i^T S r + eps W_i lambda_i.
            let residual = base_row_residual(base_rows, feet, &self.extrapolated);
            let weighted = s.component_mul(&residual);
            let mut largest_move = 0.0f64;
            let mut restart = 0.0;
            for (i, foot) in feet.iter().enumerate() {
                if !stance[i] {
                    forces[i] = Vector3::zeros();
                    continue;
                }
                let y = self.extrapolated[i];
                let gradient = foot.base_jacobian * weighted + weight.component_mul(&y) * eps;
                let next = project_to_cone(&(y - gradient * step), mu);
                largest_move = largest_move.max((next - y).amax());
                restart += (y - next).dot(&(next - self.previous[i]));
                forces[i] = next;
            }
            info.iterations = iteration;
            if largest_move < settings.tolerance {
                info.converged = true;
                break;
            }
            // FISTA extrapolation, restarted when it points uphill.
            let next_momentum = if restart > 0.0 { 1.0 } else { 0.5 * (1.0 + (1.0 + 4.0 * momentum * momentum).sqrt()) };
            let beta = if restart > 0.0 { 0.0 } else { (momentum - 1.0) / next_momentum };
            momentum = next_momentum;
            for ((extrapolated, previous), force) in self.extrapolated.iter_mut().zip(self.previous.iter_mut()).zip(forces.iter()) {
                *extrapolated = force + (force - *previous) * beta;
                *previous = *force;
            }
        }
        let residual = base_row_residual(base_rows, feet, forces);
        info.weighted_residual = root.component_mul(&residual).norm();
        info
    }
}

/// `A lambda - b_b`: the base wrench the forces give, less the one asked.
fn base_row_residual(base_rows: &Vector6<f64>, feet: &[FootKinematics], forces: &[Vector3<f64>]) -> Vector6<f64> {
    feet.iter().zip(forces).fold(-base_rows, |r, (foot, f)| r + foot.base_jacobian.transpose() * f)
}

/// Euclidean projection onto the cone `|f_t| <= mu f_z` about the world vertical: a force
/// inside stays; one in the polar cone (`mu |f_t| <= -f_z`) goes to zero; any other goes to
/// the nearest generator, `f_z' = (mu |f_t| + f_z) / (1 + mu^2)`, `|f_t'| = mu f_z'`.
pub fn project_to_cone(f: &Vector3<f64>, mu: f64) -> Vector3<f64> {
    let tangential = f.xy().norm();
    if tangential <= mu * f.z {
        return *f;
    }
    if mu * tangential <= -f.z {
        return Vector3::zeros();
    }
    let normal = (mu * tangential + f.z) / (1.0 + mu * mu);
    let scale = mu * normal / tangential;
    Vector3::new(f.x * scale, f.y * scale, normal)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clarabel::algebra::CscMatrix;
    use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
    use nalgebra::{DMatrix, DVector, Matrix3x6};

    /// A foot at `r` from the base origin of a level base: `pdot = v_lin + w x r`.
    fn foot_at(r: Vector3<f64>) -> FootKinematics {
        let mut base_jacobian = Matrix3x6::zeros();
        base_jacobian.fixed_view_mut::<3, 3>(0, 0).copy_from(&nalgebra::Matrix3::identity());
        base_jacobian.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-r.cross_matrix()));
        FootKinematics { position: r, base_jacobian, ..Default::default() }
    }

    fn settings() -> DistributionSettings {
        DistributionSettings { wrench_priority: Vector6::new(1.0, 1.0, 10.0, 111.0, 111.0, 11.0), regularization: 1e-4, max_iterations: 5000, tolerance: 1e-7 }
    }

    /// The objective of the problem at `forces`.
    fn objective(s: &DistributionSettings, b: &Vector6<f64>, feet: &[FootKinematics], forces: &[Vector3<f64>], eps: f64, w_t: f64) -> f64 {
        let mut r = -b;
        for (foot, f) in feet.iter().zip(forces) {
            r += foot.base_jacobian.transpose() * f;
        }
        let w = Vector3::new(w_t, w_t, 1.0);
        0.5 * r.dot(&s.wrench_priority.component_mul(&r)) + 0.5 * eps * forces.iter().map(|f| f.dot(&w.component_mul(f))).sum::<f64>()
    }

    /// The same problem as a second-order cone program solved by Clarabel: its optimal
    /// forces (stance feet only, in order).
    fn clarabel_reference(s: &DistributionSettings, b: &Vector6<f64>, feet: &[FootKinematics], stance: &[bool], mu: f64, eps: f64, w_t: f64) -> Vec<Vector3<f64>> {
        let on: Vec<usize> = (0..feet.len()).filter(|&i| stance[i]).collect();
        let n = 3 * on.len();
        let mut a = DMatrix::zeros(6, n);
        for (k, &i) in on.iter().enumerate() {
            a.view_mut((0, 3 * k), (6, 3)).copy_from(&feet[i].base_jacobian.transpose());
        }
        let sm = DMatrix::from_diagonal(&DVector::from_iterator(6, s.wrench_priority.iter().copied()));
        let mut p = a.transpose() * &sm * &a;
        for k in 0..on.len() {
            p[(3 * k, 3 * k)] += eps * w_t;
            p[(3 * k + 1, 3 * k + 1)] += eps * w_t;
            p[(3 * k + 2, 3 * k + 2)] += eps;
        }
        let q = -(a.transpose() * &sm * DVector::from_iterator(6, b.iter().copied()));
        let rows_p: Vec<Vec<f64>> = (0..n).map(|r| (0..n).map(|c| if c >= r { p[(r, c)] } else { 0.0 }).collect()).collect();
        // s = 0 - A_c lambda in SOC(3) per foot: (mu lambda_z, lambda_x, lambda_y).
        let mut rows_a = vec![vec![0.0; n]; n];
        for k in 0..on.len() {
            rows_a[3 * k][3 * k + 2] = -mu;
            rows_a[3 * k + 1][3 * k] = -1.0;
            rows_a[3 * k + 2][3 * k + 1] = -1.0;
        }
        let cones: Vec<SupportedConeT<f64>> = on.iter().map(|_| SupportedConeT::SecondOrderConeT(3)).collect();
        let settings = DefaultSettingsBuilder::default().verbose(false).tol_gap_abs(1e-12).tol_gap_rel(1e-12).tol_feas(1e-12).build().unwrap();
        let mut solver = DefaultSolver::new(&CscMatrix::from(&rows_p), q.as_slice(), &CscMatrix::from(&rows_a), &vec![0.0; n], &cones, settings).unwrap();
        solver.solve();
        assert!(matches!(solver.solution.status, SolverStatus::Solved | SolverStatus::AlmostSolved), "{:?}", solver.solution.status);
        let x = &solver.solution.x;
        (0..on.len()).map(|k| Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2])).collect()
    }

    /// Base wrenches HyQ's feet cannot give without pulling or slipping (a roll moment with
    /// one foot lifted, a large push sideways, a pitch moment on two feet): the solution from
    /// the clipped pseudo-inverse start matches Clarabel's optimum, and meets the prioritized
    /// base rows better than the clipped forces did.
    #[test]
    fn redistribution_matches_a_cone_program_solver() {
        let feet: Vec<FootKinematics> = [(0.37, 0.33), (0.37, -0.33), (-0.37, 0.33), (-0.37, -0.33)].iter().map(|&(x, y)| foot_at(Vector3::new(x, y, -0.55))).collect();
        let weight = 830.0;
        let cases = [
            (Vector6::new(0.0, 0.0, weight, -250.0, -150.0, 0.0), [true, true, true, false]),
            (Vector6::new(0.0, 520.0, weight, 0.0, 0.0, 30.0), [true; 4]),
            (Vector6::new(600.0, 0.0, weight, -60.0, 250.0, 0.0), [true, false, false, true]),
            (Vector6::new(-80.0, 90.0, 0.6 * weight, 300.0, -200.0, -50.0), [false, true, true, true]),
        ];
        let (mu, w_t) = (0.6, 10.0);
        let s = settings();
        let mut solver = FrictionConeDistribution::new(4);
        for (case, (b, stance)) in cases.iter().enumerate() {
            let mut forces = vec![Vector3::zeros(); 4];
            super::super::contact_forces(b, &feet, stance, w_t, &mut forces);
            let clipped = super::super::clip_to_friction_cones(&mut forces, stance, mu);
            assert!(clipped > 0, "case {case}: the pseudo-inverse forces fit the cones; the case tests nothing");
            let before = forces.clone();
            let info = solver.solve(&s, &DistributionProblem { base_rows: b, feet: &feet, stance, mu, tangential_weight: w_t }, &mut forces);
            assert!(info.converged, "case {case}: {info:?}");
            for (i, f) in forces.iter().enumerate() {
                assert!(f.xy().norm() <= mu * f.z + 1e-9, "case {case}, foot {i}: {f} outside the cone");
                assert!(stance[i] || *f == Vector3::zeros(), "case {case}: swing foot {i} carries {f}");
            }
            // eps as the solver scales it: relative to lambda_max(S^1/2 A A^T S^1/2).
            let mut gram = Matrix6::zeros();
            for (foot, _) in feet.iter().zip(stance).filter(|(_, &on)| on) {
                gram += foot.base_jacobian.transpose() * foot.base_jacobian;
            }
            let root = s.wrench_priority.map(f64::sqrt);
            let eps = s.regularization * (Matrix6::from_diagonal(&root) * gram * Matrix6::from_diagonal(&root)).symmetric_eigenvalues().amax();
            let reference = clarabel_reference(&s, b, &feet, stance, mu, eps, w_t);
            let mut expected = vec![Vector3::zeros(); 4];
            for (k, i) in (0..4).filter(|&i| stance[i]).enumerate() {
                expected[i] = reference[k];
            }
            let (ours, theirs) = (objective(&s, b, &feet, &forces, eps, w_t), objective(&s, b, &feet, &expected, eps, w_t));
            // No worse than the interior-point optimum, and as good to its own accuracy.
            assert!(ours <= theirs * (1.0 + 1e-7) && theirs - ours <= 1e-4 * theirs, "case {case}: objective {ours} against Clarabel's {theirs}");
            assert!(objective(&s, b, &feet, &forces, eps, w_t) < objective(&s, b, &feet, &before, eps, w_t), "case {case}: no better than clipping");
        }
    }

    /// Forces already inside the cones at the unconstrained optimum stay where they are.
    #[test]
    fn feasible_optimum_is_kept() {
        let feet: Vec<FootKinematics> = [(0.37, 0.33), (0.37, -0.33), (-0.37, 0.33), (-0.37, -0.33)].iter().map(|&(x, y)| foot_at(Vector3::new(x, y, -0.55))).collect();
        let b = Vector6::new(20.0, -10.0, 830.0, 5.0, -8.0, 1.0);
        let stance = [true; 4];
        let s = DistributionSettings { regularization: 0.0, ..settings() };
        let mut forces = vec![Vector3::zeros(); 4];
        super::super::contact_forces(&b, &feet, &stance, 10.0, &mut forces);
        assert_eq!(super::super::clip_to_friction_cones(&mut forces, &stance, 0.6), 0);
        let start = forces.clone();
        let info = FrictionConeDistribution::new(4).solve(&s, &DistributionProblem { base_rows: &b, feet: &feet, stance: &stance, mu: 0.6, tangential_weight: 10.0 }, &mut forces);
        assert!(info.converged && info.iterations <= 2 && info.weighted_residual < 1e-6, "{info:?}");
        for (f, g) in forces.iter().zip(&start) {
            assert!((f - g).amax() < 1e-6);
        }
    }

    #[test]
    fn cone_projection_is_the_nearest_point() {
        let mu = 0.6;
        let cases = [Vector3::new(1.0, 2.0, 10.0), Vector3::new(3.0, -4.0, 1.0), Vector3::new(0.5, 0.2, -3.0), Vector3::new(-2.0, 1.0, -0.5), Vector3::new(0.0, 0.0, -1.0)];
        for f in cases {
            let p = project_to_cone(&f, mu);
            assert!(p.xy().norm() <= mu * p.z + 1e-12, "{p} outside the cone");
            // Nearest: no point of a dense sample of the cone is closer.
            let best = (0..=400).flat_map(|a| (0..=60).map(move |z| (a, z))).map(|(a, z)| {
                let angle = a as f64 / 400.0 * std::f64::consts::TAU;
                let fz = z as f64 * 0.25;
                let r = mu * fz;
                (Vector3::new(r * angle.cos(), r * angle.sin(), fz) - f).norm()
            });
            let sampled = best.fold(f64::INFINITY, f64::min);
            assert!((p - f).norm() <= sampled + 1e-9, "{f}: projection at {} but a cone point at {sampled}", (p - f).norm());
        }
    }
}
