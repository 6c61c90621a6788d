//! A synthetic but physically plausible trajectory for the viz tests (no simulator needed):
//! the embedded HyQ stands, bobs, trots in place (diagonal pairs lifted 8 cm) and stands
//! again. Feet are placed by inverse kinematics with legwork's own Jacobians, so stance
//! feet stay on the ground; the stance feet share the weight plus the base's vertical
//! acceleration; torques are the static ones, `g(q) - J^T f`.

#![allow(dead_code)]

use legwork::dynamics::{compute_joint_jacobians, difference, frame_jacobian, generalized_gravity, update_frame_placements, Data, ReferenceFrame};
use legwork::io::{Knot, Trajectory};
use legwork::model::{embedded, Model, STANDARD_GRAVITY};
use legwork::terrain::TerrainSpec;
use nalgebra::{DVector, Matrix3, Matrix6xX, Vector3};
use std::f64::consts::PI;

/// Time step of the synthetic trajectory (s).
pub const DT: f64 = 0.002;

/// HyQ and a trot in place of `duration` seconds on flat ground.
pub fn hyq_trot(duration: f64) -> (Model, Trajectory) {
    let model = embedded::load("hyq").expect("embedded HyQ");
    let traj = trot(&model, duration, TerrainSpec::flat());
    (model, traj)
}

/// The velocity indices of the joints between the base and each foot.
fn leg_dofs(model: &Model) -> Vec<Vec<usize>> {
    model
        .feet
        .iter()
        .map(|foot| {
            let mut dofs = Vec::new();
            let mut j = model.frames[foot.frame].parent_joint;
            while j > 1 {
                dofs.push(model.joints[j].idx_v);
                j = model.joints[j].parent;
            }
            dofs.reverse();
            dofs
        })
        .collect()
}

/// Swing height of foot `f` at time `t` (0 in stance): standing until 0.6 s, then a trot
/// of 0.5 s cycles (LF+RH, then RF+LH, each swing 0.2 s) until 0.4 s before the end.
fn swing_height(f: usize, t: f64, duration: f64) -> f64 {
    let (start, end, half, swing) = (0.6, duration - 0.4, 0.25, 0.2);
    if t < start || t >= end {
        return 0.0;
    }
    let s = (t - start) % (2.0 * half);
    let diagonal = usize::from(s >= half); // 0: LF+RH swing, 1: RF+LH
    let phase = s - half * diagonal as f64;
    let swinging = matches!((diagonal, f), (0, 0) | (0, 3) | (1, 1) | (1, 2));
    if swinging && phase < swing {
        0.08 * (PI * phase / swing).sin()
    } else {
        0.0
    }
}

/// Base height offset and its second derivative: a slow bob while standing, a faster one
/// while trotting.
fn bob(t: f64) -> (f64, f64) {
    let (a, w) = (0.02, 2.0 * PI * 0.8);
    (a * (w * t).sin(), -a * w * w * (w * t).sin())
}

/// The trajectory of `model` (a quadruped with a `standing` pose) trotting in place.
pub fn trot(model: &Model, duration: f64, terrain: TerrainSpec) -> Trajectory {
    let mut data = Data::new(model);
    let mut q = model.reference_configuration("standing").expect("standing pose").clone();
    let legs = leg_dofs(model);
    let nfeet = model.feet.len();
    // Lift the base so the foot spheres rest on the ground (z = 0).
    legwork::dynamics::forward_kinematics(model, &mut data, &q);
    update_frame_placements(model, &mut data);
    let lowest = model.feet.iter().map(|f| data.o_m_f[f.frame].translation.z - f.radius).fold(f64::INFINITY, f64::min);
    q[2] -= lowest;
    legwork::dynamics::forward_kinematics(model, &mut data, &q);
    update_frame_placements(model, &mut data);
    let footholds: Vec<Vector3<f64>> = model.feet.iter().map(|f| data.o_m_f[f.frame].translation).collect();
    let (z0, pitch_amp) = (q[2], 0.03);

    let mut jac = Matrix6xX::zeros(model.nv);
    let n = (duration / DT).round() as usize + 1;
    let mut qs: Vec<DVector<f64>> = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 * DT;
        let (dz, _) = bob(t);
        q[2] = z0 + dz;
        let pitch = pitch_amp * (2.0 * PI * 0.4 * t).sin();
        let (s, c) = (0.5 * pitch).sin_cos();
        q[3] = 0.0;
        q[4] = s;
        q[5] = 0.0;
        q[6] = c;
        // Newton steps on each leg's three joints towards its foothold (lifted in swing).
        for _ in 0..30 {
            compute_joint_jacobians(model, &mut data, &q);
            update_frame_placements(model, &mut data);
            let mut worst = 0.0f64;
            for (f, foot) in model.feet.iter().enumerate() {
                let target = footholds[f] + Vector3::new(0.0, 0.0, swing_height(f, t, duration));
                let e = target - data.o_m_f[foot.frame].translation;
                worst = worst.max(e.norm());
                frame_jacobian(model, &data, foot.frame, ReferenceFrame::LocalWorldAligned, &mut jac);
                let j3 = Matrix3::from_fn(|r, c| jac[(r, legs[f][c])]);
                if let Some(dq) = j3.lu().solve(&e) {
                    for (c, &dof) in legs[f].iter().enumerate() {
                        q[dof + 1] += dq[c]; // joint coordinates: idx_q = idx_v + 1 after the free flyer
                    }
                }
            }
            if worst < 1e-9 {
                break;
            }
        }
        qs.push(q.clone());
    }

    let mut traj = Trajectory::new(model, "synthetic trot in place (test)", DT, terrain);
    let weight = model.total_mass();
    let mut v = DVector::zeros(model.nv);
    for (k, qk) in qs.iter().enumerate() {
        let t = k as f64 * DT;
        let next = &qs[(k + 1).min(n - 1)];
        let prev = &qs[k.saturating_sub(1)];
        difference(model, prev, next, &mut v);
        v /= DT * ((k + 1).min(n - 1) - k.saturating_sub(1)).max(1) as f64;
        let in_contact: Vec<bool> = (0..nfeet).map(|f| swing_height(f, t, duration) == 0.0).collect();
        let stance = in_contact.iter().filter(|&&c| c).count().max(1) as f64;
        let fz = weight * (STANDARD_GRAVITY + bob(t).1) / stance;
        let contact_force: Vec<[f64; 3]> = in_contact.iter().map(|&c| if c { [0.0, 0.0, fz] } else { [0.0; 3] }).collect();
        // Static torques: g(q) - sum J_f^T f_f on the actuated joints.
        let mut tau = generalized_gravity(model, &mut data, qk).clone();
        compute_joint_jacobians(model, &mut data, qk);
        for (f, foot) in model.feet.iter().enumerate() {
            frame_jacobian(model, &data, foot.frame, ReferenceFrame::LocalWorldAligned, &mut jac);
            let force = Vector3::from(contact_force[f]);
            tau -= jac.rows(0, 3).transpose() * force;
        }
        traj.knots.push(Knot {
            t,
            q: qk.as_slice().to_vec(),
            v: v.as_slice().to_vec(),
            tau: tau.as_slice()[6..].to_vec(),
            contact_force,
            in_contact,
            feedback_gain: None,
        });
    }
    traj.summary.insert("note".into(), "synthetic, for tests".into());
    traj
}

/// The RGB pixels of a PNG.
pub fn decode_png(path: &std::path::Path) -> (u32, u32, Vec<[u8; 3]>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    assert_eq!(info.bit_depth, png::BitDepth::Eight, "unexpected PNG bit depth");
    let pixels = buf[..info.buffer_size()]
        .chunks(channels)
        .map(|c| if channels >= 3 { [c[0], c[1], c[2]] } else { [c[0]; 3] })
        .collect();
    (info.width, info.height, pixels)
}
