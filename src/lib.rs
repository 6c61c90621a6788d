//! # legwork
//!
//! Whole-body motion generation for four-legged robots. This crate is the library behind
//! the `legwork` command: robot models (URDF import and embedded HyQ and Unitree A1),
//! rigid-body dynamics with analytic derivatives, and (in later modules) contact,
//! simulation and trajectory optimization.
//!
//! The dynamics follow Pinocchio's design and conventions: an immutable
//! [`model::Model`] and a mutable [`dynamics::Data`] workspace, algorithms as free
//! functions that allocate nothing.
//!
//! ```
//! use legwork::{model::embedded, dynamics::{Data, aba, rnea}};
//! let model = embedded::load("hyq").unwrap();
//! let mut data = Data::new(&model);
//! let q = model.reference_configuration("standing").unwrap().clone();
//! let v = nalgebra::DVector::zeros(model.nv);
//! let tau = nalgebra::DVector::zeros(model.nv);
//! let qdd = aba(&model, &mut data, &q, &v, &tau).clone();
//! // Free fall: the base accelerates down at g (expressed in the base frame).
//! let tau_back = rnea(&model, &mut data, &q, &v, &qdd);
//! assert!(tau_back.norm() < 1e-9);
//! ```

pub mod contact;
pub mod control;
pub mod dynamics;
pub mod export;
pub mod fullbody;
pub mod io;
pub mod ipocp;
pub mod job;
pub mod jump;
pub mod linalg;
pub mod model;
pub mod mpc;
pub mod ocp;
pub mod plan;
pub mod report;
pub mod sim;
pub mod slq;
pub mod spatial;
pub mod srb;
pub mod terrain;
pub mod viz;
pub mod walk;
pub mod zmp;
