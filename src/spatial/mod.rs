//! 6D spatial algebra (Featherstone 2008, ch. 2; Pinocchio's conventions).
//!
//! Every spatial vector stores its **linear part first**, as Pinocchio does:
//! a [`Motion`] is `[v; w]`, a [`Force`] is `[f; n]`. An [`SE3`] `aMb` maps coordinates
//! of frame `b` into frame `a`; `act` moves motions and forces from `b` to `a` and
//! `act_inv` the other way. A spatial [`Inertia`] is kept as (mass, centre of mass,
//! rotational inertia about the centre of mass), ten numbers, and only becomes a 6x6
//! matrix inside the articulated-body algorithm.

mod force;
mod inertia;
mod motion;
mod se3;
mod so3;

pub use force::Force;
pub use inertia::{Inertia, InertiaError, InertiaMoments};
pub use motion::Motion;
pub use se3::SE3;
pub use so3::{exp3, exp6, jexp3, jexp6, jlog3, log3, log6, skew};

/// A 6x6 matrix in the spatial layout (linear rows/columns first).
pub type Matrix6 = nalgebra::Matrix6<f64>;
/// A 6-vector in the spatial layout (linear first).
pub type Vector6 = nalgebra::Vector6<f64>;
pub use nalgebra::{Matrix3, Vector3};
