//! Rigid-body dynamics algorithms, one per file, Pinocchio's Model/Data split.
//!
//! Every algorithm is a free function `f(&model, &mut data, q, ...)` that writes its
//! results into `data` (and returns a reference to the main one). Nothing allocates after
//! [`Data::new`]. Inputs are assumed valid (length, finiteness): check user input once with
//! [`crate::model::Model::check_configuration`] and `check_tangent`.
//!
//! | algorithm | file | reference |
//! |---|---|---|
//! | forward kinematics | `kinematics.rs` | Featherstone 2008, §4.? |
//! | frame placements and Jacobians | `frames.rs`, `jacobian.rs` | Pinocchio `frames.hpp`, `jacobian.hpp` |
//! | centre of mass and its Jacobian | `com.rs` | Pinocchio `center-of-mass.hpp` |
//! | RNEA, non-linear effects, gravity | `rnea.rs` | Featherstone 2008, Table 5.1 |
//! | ABA (with external forces) | `aba.rs` | Featherstone 2008, Table 7.1 |
//! | CRBA | `crba.rs` | Featherstone 2008, Table 6.2 |
//! | centroidal momentum and its matrix | `centroidal.rs` | Orin, Goswami & Lee 2013 |
//! | integrate / difference on the configuration manifold | `configuration.rs` | Sola et al. 2018 |
//! | RNEA derivatives | `rnea_derivatives.rs` | Carpentier & Mansard 2018, Alg. 1 |
//! | ABA derivatives, `M^-1` | `aba_derivatives.rs` | Carpentier & Mansard 2018, §IV; Featherstone 2008, Table 6.3 |
//! | `M^-1` of a trunk with equal serial limbs (the same bits, faster) | `minverse_limbs.rs` | Featherstone 2008, Table 6.3 |

mod aba;
mod aba_derivatives;
mod centroidal;
mod com;
mod configuration;
mod crba;
mod data;
mod frames;
mod jacobian;
mod kinematics;
mod minverse_limbs;
mod rnea;
mod rnea_derivatives;

pub use aba::{aba, aba_with_external_forces, aba_with_external_forces_after_kinematics};
pub use aba_derivatives::{compute_aba_derivatives, compute_minverse, mass_matrix_factor, mass_matrix_factored_solve, mass_matrix_solve};
pub use centroidal::{centroidal_map, centroidal_momentum};
pub use com::{center_of_mass, com_jacobian};
pub use configuration::{
    base_orientation, difference, difference_into, integrate, integrate_jacobians, integrate_velocity_jacobian, random_configuration,
    tangent_jacobian_tr_mul,
};
pub use crba::crba;
pub use data::Data;
pub use frames::{frame_placement, frame_position, update_frame_placements};
pub use jacobian::{compute_joint_jacobians, frame_jacobian, ReferenceFrame};
pub use kinematics::{forward_kinematics, forward_kinematics_velocity, joint_transform};
pub use rnea::{generalized_gravity, nonlinear_effects, rnea};
pub use rnea_derivatives::{compute_rnea_derivatives, rnea_derivatives_forward, rnea_derivatives_tr_mul};

/// Uniform numbers in [0, 1) from a 64-bit LCG: the reproducible random states of the
/// dynamics' tests.
#[cfg(test)]
pub(crate) fn uniform_from(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}
