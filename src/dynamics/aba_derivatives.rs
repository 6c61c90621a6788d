//! placeholder
use super::Data;
use crate::model::Model;
use nalgebra::DVector;
/// placeholder
pub fn compute_aba_derivatives(_model: &Model, _data: &mut Data, _q: &DVector<f64>, _v: &DVector<f64>, _tau: &DVector<f64>) {}
/// placeholder
pub fn compute_minverse(_model: &Model, _data: &mut Data, _q: &DVector<f64>) {}
