//! Floating-base inverse dynamics by partitioning, Winkler 2015, sec. V-B, eq. (11):
//!
//! ```text
//! M [qdd_b; qdd] + [h_b; h_q] = [0; tau] + [J_cb^T; J_cq^T] lambda        (11)
//!  \_____________  ____________/
//!                \/
//!        b = RNEA(q, v, vd^ref)
//! ```
//!
//! The six base rows hold no torque: they fix the stance contact forces,
//! `lambda = (J_cb^T)^+ b_b` (Moore-Penrose, the paper's choice: the least-squares and then
//! minimum-norm forces; legwork weights the tangential components, see [`contact_forces`]);
//! the joint rows then give `tau^id = b_q - J_cq^T lambda`.
//!
//! In the paper nothing keeps `lambda` inside the friction cones or pushing (not pulling) on
//! the ground: the minimum-norm forces of a standing or slowly moving robot are close to
//! vertical and positive, but an aggressive reference can ask for forces the ground cannot
//! give. legwork spreads the tangential forces by the normal ones
//! ([`friction_weighted_contact_forces`]) and clips what still leaves a cone
//! ([`clip_to_friction_cones`], which also zeroes pulling forces); the controller then
//! redistributes the clipped forces inside the cones
//! ([`FrictionConeDistribution`](super::FrictionConeDistribution)).

use super::legs::{FootKinematics, LegChain};
use nalgebra::{DVector, Matrix3, Matrix6, Vector3, Vector6};

/// Eigenvalues of `J_cb^T J_cb` below this fraction of the largest are treated as zero (a
/// direction of base wrench no stance foot can produce, e.g. the moment about the line
/// through two feet).
const RANK_TOLERANCE: f64 = 1e-10;

/// The stance contact forces from the base rows of eq. (11): the least-squares, then
/// least-`lambda^T W lambda` solution of `A lambda = b_b` with `A = J_cb^T` (6 x 3k over the `k`
/// stance feet), `lambda = W^-1 A^T (A W^-1 A^T)^+ b_b`, `A W^-1 A^T = sum_i J_cb,i^T W_i^-1
/// J_cb,i` (6 x 6, pseudo-inverted through its eigenvalues). `W_i = diag(w_t, w_t, 1)` in the
/// world frame: with `w_t = 1` it is the paper's Moore-Penrose solution; a larger `w_t` asks
/// the same base wrench with less tangential force, which the ground can only give up to
/// `mu F_n` (with `w_t = 10`, HyQ's feet stopped sliding off stepping stones).
/// Writes one force per foot into `forces` (world frame, the ground on the foot; zero for
/// swing feet) and returns the residual `|b_b - J_cb^T lambda|` of the base rows: zero when
/// the stance feet span every base wrench (three or more feet not on one line).
pub fn contact_forces(base_rows: &Vector6<f64>, feet: &[FootKinematics], stance: &[bool], tangential_weight: f64, forces: &mut [Vector3<f64>]) -> f64 {
    weighted_contact_forces(base_rows, feet, stance, |_| tangential_weight, forces)
}

/// [`contact_forces`], then once more with each stance foot's tangential weight scaled by
/// `(F_mean / F_n,i)^2` (its first-pass normal force `F_n,i` against the stance mean, floored
/// at a tenth of it): the ground gives a foot tangential force only up to `mu F_n`, so a foot
/// that bears little weight (the third foot of a triangle whose CoG sits near the opposite
/// edge) must be asked for little of it. The second pass spreads the tangential forces
/// roughly in proportion to the normal ones; the base rows are met as before. `weights` is
/// scratch space, one entry per foot. Returns the residual of the base rows.
pub fn friction_weighted_contact_forces(base_rows: &Vector6<f64>, feet: &[FootKinematics], stance: &[bool], tangential_weight: f64, weights: &mut [f64], forces: &mut [Vector3<f64>]) -> f64 {
    let residual = contact_forces(base_rows, feet, stance, tangential_weight, forces);
    let (sum, count) = forces.iter().zip(stance).filter(|(_, &s)| s).fold((0.0, 0usize), |(sum, count), (f, _)| (sum + f.z.max(0.0), count + 1));
    if count == 0 || sum <= 0.0 {
        return residual;
    }
    let mean = sum / count as f64;
    for (w, f) in weights.iter_mut().zip(forces.iter()) {
        *w = tangential_weight * (mean / f.z.max(0.1 * mean)).powi(2);
    }
    weighted_contact_forces(base_rows, feet, stance, |i| weights[i], forces)
}

/// The weighted least-squares, then least-norm forces with foot `i`'s tangential weight
/// `tangential_weight(i)`.
fn weighted_contact_forces(base_rows: &Vector6<f64>, feet: &[FootKinematics], stance: &[bool], tangential_weight: impl Fn(usize) -> f64, forces: &mut [Vector3<f64>]) -> f64 {
    let winv = |i: usize| {
        let w = tangential_weight(i);
        Matrix3::from_diagonal(&Vector3::new(1.0 / w, 1.0 / w, 1.0))
    };
    let mut gram = Matrix6::zeros();
    for (i, foot) in feet.iter().enumerate().filter(|&(i, _)| stance[i]) {
        gram += foot.base_jacobian.transpose() * winv(i) * foot.base_jacobian;
    }
    let eigen = gram.symmetric_eigen();
    let largest = eigen.eigenvalues.amax();
    let mut y = Vector6::zeros();
    for k in 0..6 {
        let sigma = eigen.eigenvalues[k];
        if sigma > RANK_TOLERANCE * largest {
            let u = eigen.eigenvectors.column(k);
            y += u * (u.dot(base_rows) / sigma);
        }
    }
    let mut produced = Vector6::zeros();
    for (i, (foot, force)) in feet.iter().zip(forces.iter_mut()).enumerate() {
        *force = if stance[i] { winv(i) * (foot.base_jacobian * y) } else { Vector3::zeros() };
        produced += foot.base_jacobian.transpose() * *force;
    }
    (base_rows - produced).norm()
}

/// Clips each stance force into its friction cone about the world vertical, `|f_t| <= mu
/// f_n` with `f_n >= 0`: a pulling force becomes zero, and a tangential part beyond the cone
/// is scaled down. Eq. (11) does not bound the forces, and a fast swing leg's reaction or a
/// correction of the virtual model can ask a lightly loaded foot to pull (its leg then
/// lifts it off the ground, measured: 14 cm, landing 8 cm away) or for more tangential force
/// than the ground gives (the foot slides; off a pallet's edge it takes the robot with it).
/// With the forces clipped the base rows are no longer met exactly: the base falls a little
/// behind its reference, which the virtual model then corrects. The cones are vertical
/// because the walk's terrains are level blocks. Returns the number of clipped feet.
pub fn clip_to_friction_cones(forces: &mut [Vector3<f64>], stance: &[bool], mu: f64) -> usize {
    let mut clipped = 0;
    for (force, _) in forces.iter_mut().zip(stance).filter(|(_, &s)| s) {
        if force.z < 0.0 {
            *force = Vector3::zeros();
            clipped += 1;
            continue;
        }
        let bound = mu * force.z;
        let tangential = force.xy().norm();
        if tangential > bound {
            let scale = bound / tangential;
            force.x *= scale;
            force.y *= scale;
            clipped += 1;
        }
    }
    clipped
}

/// The joint rows of eq. (11): `tau^id = b_q - J_cq^T lambda`, into `tau` (`nv` entries,
/// the six base entries set to zero: the base is not actuated).
pub fn joint_torques(b: &DVector<f64>, legs: &[LegChain], feet: &[FootKinematics], forces: &[Vector3<f64>], tau: &mut DVector<f64>) {
    tau.copy_from(b);
    tau.fixed_rows_mut::<6>(0).fill(0.0);
    for leg in legs {
        let t = feet[leg.foot].leg_jacobian.transpose() * forces[leg.foot];
        for k in 0..3 {
            tau[leg.v_index[k]] -= t[k];
        }
    }
}
