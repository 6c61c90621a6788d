//! placeholder
use super::Data;
use crate::model::Model;
use nalgebra::DVector;
/// placeholder
pub fn compute_rnea_derivatives(_model: &Model, _data: &mut Data, _q: &DVector<f64>, _v: &DVector<f64>, _a: &DVector<f64>) {}
