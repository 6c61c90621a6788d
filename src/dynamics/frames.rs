//! Frame placements in the world.

use super::Data;
use crate::model::Model;
use crate::spatial::SE3;
use nalgebra::Vector3;

/// `oMf = oMi[parent] * placement` for every frame. Needs [`super::forward_kinematics`] first.
pub fn update_frame_placements(model: &Model, data: &mut Data) {
    for (k, fr) in model.frames.iter().enumerate() {
        data.o_m_f[k] = data.o_m_i[fr.parent_joint] * fr.placement;
    }
}

/// World position of a frame's origin (after forward kinematics): `oMi[parent] p`, without
/// the rotation product of [`frame_placement`] (feet in contact models, costs, reports).
#[inline]
pub fn frame_position(model: &Model, data: &Data, frame: usize) -> Vector3<f64> {
    let fr = &model.frames[frame];
    data.o_m_i[fr.parent_joint].act_point(&fr.placement.translation)
}

/// World placement of one frame (after forward kinematics); also stored in `data.o_m_f`.
pub fn frame_placement(model: &Model, data: &mut Data, frame: usize) -> SE3 {
    let fr = &model.frames[frame];
    let m = data.o_m_i[fr.parent_joint] * fr.placement;
    data.o_m_f[frame] = m;
    m
}
