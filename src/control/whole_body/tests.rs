//! Tests of the execution controller: the inverse-dynamics identity against ABA and against
//! rigid-contact forward dynamics, the pieces (pseudo-inverse, `Jd v`, inverse kinematics)
//! against reference computations, and HyQ in the simulator (sway, standing, push, a step).

use super::*;
use crate::dynamics::{aba_with_external_forces, compute_joint_jacobians, crba, forward_kinematics, frame_position, integrate, nonlinear_effects};
use crate::model::embedded;
use crate::sim::{standing_on_ground, Push, SimConfig, Simulator};
use crate::spatial::Force;
use crate::terrain::Plane;
use nalgebra::{DMatrix, UnitQuaternion};

fn hyq() -> Model {
    embedded::load("hyq").expect("embedded HyQ")
}

/// Deterministic numbers in [-1, 1] (a linear congruential generator).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
    fn vector3(&mut self, scale: f64) -> Vector3<f64> {
        Vector3::new(self.next(), self.next(), self.next()) * scale
    }
}

/// HyQ near its standing pose, tilted and moving: a generic state for the identities.
fn moving_state(model: &Model, seed: u64) -> (DVector<f64>, DVector<f64>) {
    let mut rng = Lcg(seed);
    let mut q = model.reference_configuration("standing").unwrap().clone();
    q[0] += 0.02 * rng.next();
    q[1] += 0.02 * rng.next();
    let tilt = UnitQuaternion::from_scaled_axis(rng.vector3(0.1));
    q.fixed_rows_mut::<4>(3).copy_from(&nalgebra::Vector4::new(tilt.i, tilt.j, tilt.k, tilt.w));
    for i in 7..model.nq {
        q[i] += 0.1 * rng.next();
    }
    let v = DVector::from_fn(model.nv, |_, _| 0.5 * rng.next());
    (q, v)
}

/// A reference away from the state, with feed-forward accelerations, and the given legs in
/// swing (foot targets a few centimetres from where the feet are).
fn moving_reference(model: &Model, q: &DVector<f64>, swing: &[usize], seed: u64) -> WholeBodyReference {
    let mut rng = Lcg(seed);
    let mut r = WholeBodyReference::holding(model, q);
    r.body.cog_position += rng.vector3(0.02);
    r.body.cog_velocity = rng.vector3(0.1);
    r.body.cog_acceleration = rng.vector3(0.5);
    r.body.orientation = UnitQuaternion::from_scaled_axis(rng.vector3(0.05)) * r.body.orientation;
    r.body.angular_velocity = rng.vector3(0.2);
    r.body.angular_acceleration = rng.vector3(1.0);
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, q);
    for &leg in swing {
        let p = frame_position(model, &data, model.feet[leg].frame);
        r.legs[leg] = LegMotion::Swing(FootMotion { position: p + rng.vector3(0.03), velocity: rng.vector3(0.2), acceleration: rng.vector3(2.0) });
    }
    r
}

fn controller(model: &Model) -> WholeBodyController<fn(f64, &mut WholeBodyReference)> {
    fn nothing(_: f64, _: &mut WholeBodyReference) {}
    WholeBodyController::with_default_gains(model, nothing as fn(f64, &mut WholeBodyReference), 0.001).unwrap()
}

/// The controller with eq. (11)'s forces left unclipped, for the identities that hold only
/// then (the random moving states ask for forces outside the friction cones).
fn unclipped_controller(model: &Model) -> WholeBodyController<fn(f64, &mut WholeBodyReference)> {
    let mut c = controller(model);
    c.gains.friction_coefficient = None;
    c
}

/// The contact forces as external forces on the feet's bodies (joint frames), as the
/// simulator applies them.
fn contact_wrenches(model: &Model, data: &Data, legs: &[LegChain], forces: &[Vector3<f64>]) -> Vec<Force> {
    let mut f_ext = vec![Force::zero(); model.njoints()];
    for leg in legs {
        let local = data.o_m_i[leg.joint].rotation.transpose() * forces[leg.foot];
        f_ext[leg.joint].f += local;
        f_ext[leg.joint].n += leg.point.cross(&local);
    }
    f_ext
}

/// Moving states (seed) with no swing leg and with each leg swinging in turn.
const MOVING_CASES: &[(u64, &[usize])] = &[(1, &[]), (2, &[0]), (3, &[3]), (4, &[1]), (5, &[2])];

/// Winkler 2015 eq. (11) as an identity: the torques and contact forces of a tick, given to
/// ABA, give back the reference acceleration, and under it the stance feet do not
/// accelerate while the swing feet follow their PD (ABA's own world accelerations).
#[test]
fn torques_and_contact_forces_reproduce_the_reference_acceleration() {
    let model = hyq();
    for &(seed, swing) in MOVING_CASES {
        let (q, v) = moving_state(&model, seed);
        let reference = moving_reference(&model, &q, swing, seed + 100);
        let mut c = unclipped_controller(&model);
        let mut tau = DVector::zeros(model.nv);
        c.execute(&model, &q, &v, &reference, &mut tau).unwrap();
        let tick = c.last_tick().clone();
        assert!(tick.base_row_residual < 1e-9, "three or more stance feet meet the base rows: {}", tick.base_row_residual);

        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q);
        let f_ext = contact_wrenches(&model, &data, c.legs(), &tick.contact_forces);
        let qdd = aba_with_external_forces(&model, &mut data, &q, &v, &tick.inverse_dynamics_torque, &f_ext).clone();
        let error = (&qdd - &tick.reference_acceleration).amax();
        assert!(error < 1e-8, "seed {seed}: ABA(tau^id, lambda) differs from vd^ref by {error:e}");

        // Feet accelerations from ABA's world spatial accelerations (gravity as a_0 = -g).
        let (kp, kd) = &c.gains().swing_foot;
        for leg in c.legs() {
            let o = &data.o_m_i[leg.joint];
            let p = o.act_point(&leg.point);
            let a = data.oa[leg.joint] - (-model.gravity);
            let vel = data.ov[leg.joint];
            let foot_velocity = vel.v + vel.w.cross(&p);
            let foot_acc = a.v + a.w.cross(&p) + vel.w.cross(&foot_velocity);
            let expected = match reference.legs[leg.foot] {
                LegMotion::Stance => Vector3::zeros(),
                LegMotion::Swing(m) => m.acceleration + kp.component_mul(&(m.position - p)) + kd.component_mul(&(m.velocity - foot_velocity)),
            };
            let e = (foot_acc - expected).amax();
            assert!(e < 1e-8, "seed {seed}, foot {}: acceleration {foot_acc:?}, expected {expected:?}", leg.foot);
        }
    }
}

/// The same identity from the other side: HyQ with its stance feet fixed (rigid contacts,
/// the model of the inverse dynamics), driven by `tau^id` alone, moves with `vd^ref` and
/// pushes on the ground with `lambda` (the KKT system of constrained forward dynamics;
/// `Jd v` by central differences, hence the looser tolerance).
#[test]
fn rigid_contact_forward_dynamics_of_the_torques_gives_the_reference() {
    let model = hyq();
    for (seed, swing) in [(11u64, vec![]), (12, vec![2])] {
        let (q, v) = moving_state(&model, seed);
        let reference = moving_reference(&model, &q, &swing, seed + 100);
        let mut c = unclipped_controller(&model);
        let mut tau = DVector::zeros(model.nv);
        c.execute(&model, &q, &v, &reference, &mut tau).unwrap();
        let tick = c.last_tick().clone();
        let stance: Vec<&LegChain> = c.legs().iter().filter(|l| matches!(reference.legs[l.foot], LegMotion::Stance)).collect();
        let (nv, nc) = (model.nv, 3 * stance.len());
        let mut data = Data::new(&model);
        // J_c(q) as a dense matrix and J_c(q) v.
        let jacobian_at = |data: &mut Data, q: &DVector<f64>| {
            compute_joint_jacobians(&model, data, q);
            let mut j = DMatrix::zeros(nc, nv);
            for (k, leg) in stance.iter().enumerate() {
                let p = foot_position(data, leg);
                j.view_mut((3 * k, 0), (3, 6)).copy_from(&base_jacobian(data, &p));
                let jq = leg_jacobian(data, leg, &p);
                for i in 0..3 {
                    j.view_mut((3 * k, leg.v_index[i]), (3, 1)).copy_from(&jq.column(i));
                }
            }
            j
        };
        let h = 1e-5;
        let mut qp = q.clone();
        let mut qm = q.clone();
        integrate(&model, &q, &(&v * h), &mut qp);
        integrate(&model, &q, &(&v * -h), &mut qm);
        let jdot_v = (jacobian_at(&mut data, &qp) * &v - jacobian_at(&mut data, &qm) * &v) / (2.0 * h);
        let jc = jacobian_at(&mut data, &q);
        let m = crba(&model, &mut data, &q).clone();
        let nle = nonlinear_effects(&model, &mut data, &q, &v).clone();
        // [M  -J^T] [vd    ]   [tau - h ]
        // [J   0  ] [lambda] = [-Jd v   ]
        let mut kkt = DMatrix::zeros(nv + nc, nv + nc);
        kkt.view_mut((0, 0), (nv, nv)).copy_from(&m);
        kkt.view_mut((0, nv), (nv, nc)).copy_from(&(-jc.transpose()));
        kkt.view_mut((nv, 0), (nc, nv)).copy_from(&jc);
        let mut rhs = DVector::zeros(nv + nc);
        rhs.rows_mut(0, nv).copy_from(&(&tick.inverse_dynamics_torque - &nle));
        rhs.rows_mut(nv, nc).copy_from(&(-jdot_v));
        let x = kkt.lu().solve(&rhs).expect("KKT system of four or three feet is regular");
        let acc_error = (x.rows(0, nv) - &tick.reference_acceleration).amax();
        assert!(acc_error < 1e-6, "seed {seed}: rigid-contact vd differs from vd^ref by {acc_error:e}");
        for (k, leg) in stance.iter().enumerate() {
            let e = (x.fixed_rows::<3>(nv + 3 * k) - tick.contact_forces[leg.foot]).amax();
            assert!(e < 1e-5, "seed {seed}, foot {}: rigid-contact force differs from lambda by {e:e} N", leg.foot);
        }
    }
}

/// The feet's kinematics (base and leg Jacobians) at a moving state of HyQ, after one tick.
fn moving_feet() -> Vec<FootKinematics> {
    let model = hyq();
    let (q, v) = moving_state(&model, 21);
    let mut c = controller(&model);
    let reference = moving_reference(&model, &q, &[], 7);
    let mut tau = DVector::zeros(model.nv);
    c.execute(&model, &q, &v, &reference, &mut tau).unwrap();
    c.ws.feet.clone()
}

/// `lambda = (J_cb^T)^+ b_b` against nalgebra's SVD pseudo-inverse of the 6 x 3k matrix:
/// four and three feet (exact base rows) and two diagonal feet (rank 5: least squares).
#[test]
fn contact_forces_are_the_moore_penrose_solution() {
    let feet = moving_feet();
    let b = Vector6::new(30.0, -20.0, 850.0, 15.0, -40.0, 5.0);
    for stance in [[true, true, true, true], [false, true, true, true], [true, false, false, true]] {
        let mut forces = vec![Vector3::zeros(); 4];
        let residual = contact_forces(&b, &feet, &stance, 1.0, &mut forces);
        let idx: Vec<usize> = (0..4).filter(|&i| stance[i]).collect();
        let mut a = DMatrix::zeros(6, 3 * idx.len());
        for (k, &i) in idx.iter().enumerate() {
            a.view_mut((0, 3 * k), (6, 3)).copy_from(&feet[i].base_jacobian.transpose());
        }
        let lambda = a.clone().pseudo_inverse(1e-12).unwrap() * DVector::from_column_slice(b.as_slice());
        for (k, &i) in idx.iter().enumerate() {
            let e = (forces[i] - lambda.fixed_rows::<3>(3 * k)).amax();
            assert!(e < 1e-8, "stance {stance:?}, foot {i}: {e:e} N from the SVD pseudo-inverse");
        }
        let expected_residual = (DVector::from_column_slice(b.as_slice()) - &a * &lambda).norm();
        assert!((residual - expected_residual).abs() < 1e-8);
        if idx.len() >= 3 {
            assert!(residual < 1e-9);
        } else {
            assert!(residual > 1.0, "two feet cannot produce every base wrench: residual {residual}");
        }
        for i in (0..4).filter(|&i| !stance[i]) {
            assert_eq!(forces[i], Vector3::zeros());
        }
    }
}

/// With a tangential weight `w_t`, the forces are the least-`lambda^T W lambda` solution:
/// `W^-1/2 (A W^-1/2)^+ b`, against nalgebra's SVD; the base rows are met as before, and
/// the tangential forces shrink.
#[test]
fn weighted_contact_forces_trade_tangential_for_normal_force() {
    let feet = moving_feet();
    let b = Vector6::new(120.0, -80.0, 850.0, 15.0, -40.0, 5.0);
    let w = 10.0;
    for stance in [[true, true, true, true], [false, true, true, true]] {
        let (mut plain, mut weighted) = (vec![Vector3::zeros(); 4], vec![Vector3::zeros(); 4]);
        contact_forces(&b, &feet, &stance, 1.0, &mut plain);
        let residual = contact_forces(&b, &feet, &stance, w, &mut weighted);
        assert!(residual < 1e-9);
        let idx: Vec<usize> = (0..4).filter(|&i| stance[i]).collect();
        let scale = nalgebra::Matrix3::from_diagonal(&Vector3::new(1.0 / w.sqrt(), 1.0 / w.sqrt(), 1.0));
        let mut a = DMatrix::zeros(6, 3 * idx.len());
        for (k, &i) in idx.iter().enumerate() {
            a.view_mut((0, 3 * k), (6, 3)).copy_from(&(feet[i].base_jacobian.transpose() * scale));
        }
        let mu = a.pseudo_inverse(1e-12).unwrap() * DVector::from_column_slice(b.as_slice());
        for (k, &i) in idx.iter().enumerate() {
            let expected = scale * mu.fixed_rows::<3>(3 * k);
            assert!((weighted[i] - expected).amax() < 1e-8, "stance {stance:?}, foot {i}");
        }
        let tangential = |f: &[Vector3<f64>]| f.iter().map(|f| f.xy().norm_squared()).sum::<f64>();
        assert!(tangential(&weighted) < tangential(&plain), "{} vs {}", tangential(&weighted), tangential(&plain));
    }
}

/// The friction-weighted second pass meets the base rows as the first does, and the foot
/// bearing the least weight is asked for a smaller share of tangential force: its
/// `|f_t| / f_n` drops (the ratio the ground must allow before the foot slides).
#[test]
fn friction_weighted_forces_unload_the_light_foot_tangentially() {
    let feet = moving_feet();
    let mut weights = vec![0.0; 4];
    let mut light_cases = 0;
    for stance in [[true, true, true, true], [false, true, true, true], [true, false, true, true], [true, true, false, true]] {
        for (mx, my) in [(0.0, 0.0), (60.0, 0.0), (-60.0, 40.0), (0.0, -90.0), (90.0, 90.0)] {
            let b = Vector6::new(120.0, -80.0, 850.0, mx, my, 15.0);
            let (mut single, mut weighted) = (vec![Vector3::zeros(); 4], vec![Vector3::zeros(); 4]);
            contact_forces(&b, &feet, &stance, 10.0, &mut single);
            let residual = friction_weighted_contact_forces(&b, &feet, &stance, 10.0, &mut weights, &mut weighted);
            assert!(residual < 1e-9, "stance {stance:?}, b {b:?}: residual {residual:e}");
            let stance_feet: Vec<usize> = (0..4).filter(|&i| stance[i]).collect();
            let mean = stance_feet.iter().map(|&i| single[i].z).sum::<f64>() / stance_feet.len() as f64;
            let light = *stance_feet.iter().min_by(|&&a, &&b| single[a].z.total_cmp(&single[b].z)).unwrap();
            if single[light].z > 0.0 && single[light].z < 0.5 * mean && weighted[light].z > 0.0 {
                light_cases += 1;
                let ratio = |f: &Vector3<f64>| f.xy().norm() / f.z;
                assert!(ratio(&weighted[light]) < ratio(&single[light]), "stance {stance:?}, b {b:?}, light foot {light}: {} -> {}", ratio(&single[light]), ratio(&weighted[light]));
            }
        }
    }
    assert!(light_cases >= 3, "only {light_cases} cases with a lightly loaded foot");
}

/// With the default gains every stance force ends inside its friction cone (mu = 0.6), and
/// on these random moving states some had to be clipped; clipping scales only the tangential
/// part, and a pulling foot gets no force at all.
#[test]
fn stance_forces_end_inside_the_friction_cones() {
    let model = hyq();
    let mut clipped = 0;
    for &(seed, swing) in MOVING_CASES {
        let (q, v) = moving_state(&model, seed);
        let reference = moving_reference(&model, &q, swing, seed + 100);
        let mut c = controller(&model);
        let mut tau = DVector::zeros(model.nv);
        c.execute(&model, &q, &v, &reference, &mut tau).unwrap();
        let mu = c.gains().friction_coefficient.unwrap();
        for (foot, f) in c.last_tick().contact_forces.iter().enumerate() {
            assert!(f.z >= 0.0 && f.xy().norm() <= mu * f.z + 1e-9, "seed {seed}, foot {foot}: {f:?}");
        }
        clipped += c.last_tick().cone_clipped_feet;
    }
    assert!(clipped > 0, "no force needed clipping: the test does not exercise it");
    let mut forces = [Vector3::new(30.0, 40.0, 100.0), Vector3::new(30.0, 40.0, -10.0), Vector3::new(3.0, 4.0, 100.0), Vector3::new(90.0, 0.0, 50.0)];
    let n = clip_to_friction_cones(&mut forces, &[true, true, true, false], 0.25);
    assert_eq!(n, 2);
    assert!((forces[0] - Vector3::new(15.0, 20.0, 100.0)).norm() < 1e-12);
    assert_eq!(forces[1], Vector3::zeros());
    assert_eq!(forces[2], Vector3::new(3.0, 4.0, 100.0));
    assert_eq!(forces[3], Vector3::new(90.0, 0.0, 50.0), "swing feet are left alone");
}

/// `Jd v` of each foot against central differences of `J(q) v` along `q(t) = q (+) t v`.
#[test]
fn foot_bias_acceleration_matches_finite_differences() {
    let model = hyq();
    let legs = leg_chains(&model).unwrap();
    let (q, v) = moving_state(&model, 31);
    let mut data = Data::new(&model);
    let mut velocity = vec![Motion::zero(); model.njoints()];
    let mut bias = vec![Motion::zero(); model.njoints()];
    compute_joint_jacobians(&model, &mut data, &q);
    velocities_and_bias(&model, &data, &v, &mut velocity, &mut bias);
    let mut feet = vec![FootKinematics::default(); 4];
    for leg in &legs {
        foot_kinematics(&data, leg, &velocity, &bias, &mut feet[leg.foot]);
        // The velocity from the recursion equals J v.
        assert!((feet[leg.foot].velocity - feet[leg.foot].jacobian_times(leg, &v)).amax() < 1e-12);
    }
    let h = 1e-5;
    let mut foot_velocity = |t: f64, leg: &LegChain| {
        let mut qt = q.clone();
        integrate(&model, &q, &(&v * t), &mut qt);
        compute_joint_jacobians(&model, &mut data, &qt);
        let p = foot_position(&data, leg);
        let mut f = FootKinematics { base_jacobian: base_jacobian(&data, &p), leg_jacobian: leg_jacobian(&data, leg, &p), ..Default::default() };
        f.position = p;
        f.jacobian_times(leg, &v)
    };
    for leg in &legs {
        let fd = (foot_velocity(h, leg) - foot_velocity(-h, leg)) / (2.0 * h);
        let e = (fd - feet[leg.foot].bias_acceleration).amax();
        assert!(e < 1e-6, "foot {}: Jd v {:?} vs finite differences {fd:?}", leg.foot, feet[leg.foot].bias_acceleration);
    }
}

/// Newton inverse kinematics reaches foot positions of random reachable leg postures
/// (the base tilted and moved) from the standing posture, to 1e-9 m.
#[test]
fn inverse_kinematics_reaches_reachable_feet() {
    let model = hyq();
    let legs = leg_chains(&model).unwrap();
    let mut data = Data::new(&model);
    for seed in 0..20u64 {
        let mut rng = Lcg(seed + 40);
        let (mut target_q, _) = moving_state(&model, seed + 40);
        for leg in &legs {
            for k in 0..3 {
                let (lo, hi) = (leg.lower[k], leg.upper[k]);
                // Well inside the limits and away from a stretched knee.
                target_q[leg.q_index[k]] = 0.5 * (lo + hi) + 0.3 * (hi - lo) * rng.next();
            }
        }
        forward_kinematics(&model, &mut data, &target_q);
        let targets: Vec<Vector3<f64>> = legs.iter().map(|l| foot_position(&data, l)).collect();
        let mut q = model.reference_configuration("standing").unwrap().clone();
        q.fixed_rows_mut::<7>(0).copy_from(&target_q.fixed_rows::<7>(0));
        let residual = legs_inverse_kinematics(&model, &mut data, &legs, &targets, &mut q, 1e-10, 30);
        assert!(residual < 1e-9, "seed {seed}: residual {residual} m");
        forward_kinematics(&model, &mut data, &q);
        for l in &legs {
            assert!((foot_position(&data, l) - targets[l.foot]).norm() < 1e-9);
        }
    }
}

#[test]
fn hyq_legs_are_found_by_name_and_bad_structures_refused() {
    let model = hyq();
    let legs = leg_chains(&model).unwrap();
    for (leg, name) in legs.iter().zip(["lf", "rf", "lh", "rh"]) {
        let names: Vec<&str> = leg.v_index.iter().map(|&i| model.joints[model.joint_of_dof[i]].name.as_str()).collect();
        assert_eq!(names, [format!("{name}_haa_joint"), format!("{name}_hfe_joint"), format!("{name}_kfe_joint")]);
    }
    let mut bad = model.clone();
    let lf_foot_frame = bad.feet[0].frame;
    bad.frames[lf_foot_frame].parent_joint = model.joint_id("lf_hfe_joint").unwrap();
    let e = leg_chains(&bad).unwrap_err().to_string();
    assert!(e.contains("hangs on 2 joints (lf_haa_joint, lf_hfe_joint)") && e.contains("'hyq'"), "{e}");
    let mut no_feet = model.clone();
    no_feet.feet.clear();
    assert!(leg_chains(&no_feet).unwrap_err().to_string().contains("no feet"));
}

#[test]
fn bad_references_and_gains_are_refused_by_name() {
    let model = hyq();
    let q = model.reference_configuration("standing").unwrap().clone();
    let v = DVector::zeros(model.nv);
    let mut c = controller(&model);
    let mut tau = DVector::zeros(model.nv);
    let mut r = WholeBodyReference::holding(&model, &q);
    r.body.cog_acceleration.y = f64::NAN;
    let e = c.execute(&model, &q, &v, &r, &mut tau).unwrap_err().to_string();
    assert!(e.contains("body.cog_acceleration") && e.contains("not finite"), "{e}");
    let mut r = WholeBodyReference::holding(&model, &q);
    r.legs = vec![LegMotion::Swing(FootMotion::at_rest(Vector3::zeros())); 4];
    assert!(c.execute(&model, &q, &v, &r, &mut tau).unwrap_err().to_string().contains("no stance leg"));
    let mut r = WholeBodyReference::holding(&model, &q);
    r.legs.pop();
    assert!(c.execute(&model, &q, &v, &r, &mut tau).unwrap_err().to_string().contains("one entry per foot (4), got 3"));
    let mut gains = WholeBodyGains::from_model(&model, &q, 0.001);
    gains.swing_foot.0.x = -1.0;
    let e = WholeBodyController::new(&model, |_: f64, _: &mut WholeBodyReference| {}, gains).err().unwrap().to_string();
    assert!(e.contains("`swing_foot`"), "{e}");
}

/// Standing still at the reference pose: no feedback, the minimum-norm forces carry the
/// weight (vertical forces sum to m g), and the torques hold the robot up: the KFE torques
/// are those of a static leg, `J_q^T lambda` (checked in the identity tests), positive
/// force on every foot.
#[test]
fn standing_reference_carries_the_weight_on_every_foot() {
    let model = hyq();
    let q = model.reference_configuration("standing").unwrap().clone();
    let v = DVector::zeros(model.nv);
    let mut c = controller(&model);
    let mut tau = DVector::zeros(model.nv);
    c.execute(&model, &q, &v, &WholeBodyReference::holding(&model, &q), &mut tau).unwrap();
    let tick = c.last_tick();
    let weight = model.total_mass() * 9.81;
    let total: Vector3<f64> = tick.contact_forces.iter().sum();
    assert!((total - Vector3::new(0.0, 0.0, weight)).amax() < 1e-6, "{total:?}");
    assert!(tick.contact_forces.iter().all(|f| f.z > 0.15 * weight), "{:?}", tick.contact_forces);
    assert!(tick.feedback_torque.amax() < 1e-6, "at the reference the joint PD is silent");
    assert!(tick.virtual_force.norm() < 1e-9 && tick.virtual_torque.norm() < 1e-9);
    assert!(tick.ik_residual < 1e-8);
}

// ---------------------------------------------------------------------------------------
// In the simulator (smooth contact model, 2 kHz physics, 1 kHz control).
// ---------------------------------------------------------------------------------------

/// `s(x)` = 10 x^3 - 15 x^4 + 6 x^5 on [0, 1] and its first two derivatives (zero velocity
/// and acceleration at both ends), clamped outside.
fn smoothstep(x: f64) -> (f64, f64, f64) {
    if x <= 0.0 {
        return (0.0, 0.0, 0.0);
    }
    if x >= 1.0 {
        return (1.0, 0.0, 0.0);
    }
    (x * x * x * (10.0 - 15.0 * x + 6.0 * x * x), 30.0 * x * x * (1.0 - x) * (1.0 - x), 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x))
}

/// What a simulated run records at every control tick.
#[derive(Default)]
struct Trace {
    t: Vec<f64>,
    /// Planned CoG, measured CoG (m).
    cog_plan: Vec<Vector3<f64>>,
    cog: Vec<Vector3<f64>>,
    /// Planned (feed-forward) and reference (eq. 10) CoG accelerations, and the realized one:
    /// the sum of the contact forces and the push over the mass, plus gravity, averaged over
    /// the control period.
    cog_acc_plan: Vec<Vector3<f64>>,
    cog_acc_reference: Vec<Vector3<f64>>,
    cog_acc: Vec<Vector3<f64>>,
    /// Realized `vd` over the control period against `vd^ref` (max over entries).
    acc_error: Vec<f64>,
    orientation_error: Vec<f64>,
    base: Vec<Vector3<f64>>,
    feet: Vec<Vec<Vector3<f64>>>,
}

/// Runs HyQ on flat ground under the controller, from the standing pose resting on the
/// ground, for `duration` s with optional pushes.
fn simulate<S: MotionSource>(
    model: &Model,
    controller: &mut WholeBodyController<S>,
    start: (DVector<f64>, DVector<f64>),
    duration: f64,
    pushes: &[Push],
) -> Trace {
    let ground = Plane::flat(0.0);
    let config = SimConfig::default();
    let (dt, per_control) = (config.physics_dt, (config.control_dt / config.physics_dt).round() as usize);
    let mut sim = Simulator::new(model, &ground, config, start.0, Some(start.1)).unwrap();
    for p in pushes {
        sim.add_push(*p);
    }
    let mass = model.total_mass();
    let gravity = model.gravity.v;
    let mut trace = Trace::default();
    let ticks = (duration / (dt * per_control as f64)).round() as usize;
    for _ in 0..ticks {
        let t = sim.state().t;
        let v_before = sim.state().v.clone();
        let mut cog_acc = Vector3::zeros();
        for _ in 0..per_control {
            let t_step = sim.state().t;
            sim.step(controller).unwrap();
            let push: Vector3<f64> = pushes.iter().filter(|p| t_step >= p.start && t_step < p.start + p.duration).map(|p| p.force).sum();
            let contact: Vector3<f64> = sim.feet().iter().map(|f| f.contact.force).sum();
            cog_acc += ((contact + push) / mass + gravity) / per_control as f64;
        }
        let tick = controller.last_tick();
        let realized = (&sim.state().v - &v_before) / (dt * per_control as f64);
        let reference = controller.reference();
        trace.t.push(t);
        trace.cog_plan.push(reference.body.cog_position);
        trace.cog.push(tick.cog);
        trace.cog_acc_plan.push(reference.body.cog_acceleration);
        trace.cog_acc_reference.push(tick.cog_reference_acceleration);
        trace.cog_acc.push(cog_acc);
        trace.acc_error.push((realized - &tick.reference_acceleration).amax());
        trace.orientation_error.push(tick.orientation_error.norm());
        let q = &sim.state().q;
        trace.base.push(Vector3::new(q[0], q[1], q[2]));
        trace.feet.push(sim.feet().iter().map(|f| f.position).collect());
    }
    trace
}

fn rms(x: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = x.fold((0.0, 0usize), |(s, n), e| (s + e * e, n + 1));
    (s / n.max(1) as f64).sqrt()
}

fn max(x: impl Iterator<Item = f64>) -> f64 {
    x.fold(0.0, f64::max)
}

/// HyQ in its standing pose with the feet just touching the ground.
fn resting_start(model: &Model) -> (DVector<f64>, DVector<f64>) {
    (standing_on_ground(model, &Plane::flat(0.0), 0.0).unwrap(), DVector::zeros(model.nv))
}

/// HyQ settled on the ground: one second under the controller holding the resting pose
/// (the feet sink about 7 mm into the compliant ground). The state at the end.
fn settled_start(model: &Model) -> (DVector<f64>, DVector<f64>) {
    let ground = Plane::flat(0.0);
    let (q0, v0) = resting_start(model);
    let hold = WholeBodyReference::holding(model, &q0);
    let mut c = WholeBodyController::with_default_gains(model, move |_: f64, r: &mut WholeBodyReference| r.clone_from(&hold), 0.001).unwrap();
    let mut sim = Simulator::new(model, &ground, SimConfig::default(), q0, Some(v0)).unwrap();
    for _ in 0..2000 {
        sim.step(&mut c).unwrap();
    }
    (sim.state().q.clone(), sim.state().v.clone())
}

/// A lateral sway of the CoG, 3 cm amplitude at 0.5 Hz (peak acceleration 0.30 m/s^2),
/// faded in over the first second, is tracked: the realized CoG acceleration (from the
/// simulated contact forces) follows the reference and the CoG the plan.
#[test]
fn simulated_hyq_tracks_a_lateral_sway() {
    let model = hyq();
    let start = settled_start(&model);
    let hold = WholeBodyReference::holding(&model, &start.0);
    let (amplitude, omega) = (0.03, std::f64::consts::PI);
    let source = move |t: f64, r: &mut WholeBodyReference| {
        r.clone_from(&hold);
        // y = A e(t) sin(w t), e the fade-in over [0, 1] s.
        let (e, de, dde) = smoothstep(t);
        let (s, c) = (omega * t).sin_cos();
        r.body.cog_position.y += amplitude * e * s;
        r.body.cog_velocity.y = amplitude * (de * s + e * omega * c);
        r.body.cog_acceleration.y = amplitude * (dde * s + 2.0 * de * omega * c - e * omega * omega * s);
    };
    let mut c = WholeBodyController::with_default_gains(&model, source, 0.001).unwrap();
    let trace = simulate(&model, &mut c, start, 5.0, &[]);
    let steady = || (0..trace.t.len()).filter(|&k| trace.t[k] >= 1.0);
    let pos_rms = rms(steady().map(|k| (trace.cog_plan[k] - trace.cog[k]).norm()));
    let pos_max = max(steady().map(|k| (trace.cog_plan[k] - trace.cog[k]).norm()));
    let acc_rms_ref = rms(steady().map(|k| (trace.cog_acc_reference[k] - trace.cog_acc[k]).norm()));
    let acc_rms_plan = rms(steady().map(|k| (trace.cog_acc_plan[k] - trace.cog_acc[k]).norm()));
    let acc_y_rms = rms(steady().map(|k| trace.cog_acc[k].y));
    let gen_acc_rms = rms(steady().map(|k| trace.acc_error[k]));
    let peak_sway = max(steady().map(|k| (trace.cog[k].y - trace.cog[0].y).abs()));
    let stats = c.stats();
    eprintln!(
        "sway 3 cm @ 0.5 Hz: CoG error rms {:.2} mm max {:.2} mm; realized sway {:.1} mm; CoG acceleration: rms {:.3} m/s^2 (y), \
         error to reference {:.4} m/s^2 rms, to plan {:.4} m/s^2 rms; generalized vd - vd^ref max-entry rms {:.3}; \
         orientation error max {:.3} deg; clipped ticks {} of {}",
        pos_rms * 1e3,
        pos_max * 1e3,
        peak_sway * 1e3,
        acc_y_rms,
        acc_rms_ref,
        acc_rms_plan,
        gen_acc_rms,
        max(steady().map(|k| trace.orientation_error[k])).to_degrees(),
        stats.clipped_ticks,
        stats.ticks
    );
    assert!(peak_sway > 0.028, "the robot must actually sway ({peak_sway} m)");
    assert!(pos_max < 0.0005, "CoG within 0.5 mm of the plan, got {pos_max} m");
    assert!(acc_rms_ref < 0.05, "realized CoG acceleration within 0.05 m/s^2 rms of eq. (10), got {acc_rms_ref}");
    assert!(acc_rms_plan < 0.01, "realized CoG acceleration within 0.01 m/s^2 rms of the plan, got {acc_rms_plan}");
    assert_eq!(stats.clipped_ticks, 0);
}

/// Standing for 3 s from the pose with the feet just touching the ground: the CoG stays on
/// its reference to within 3 mm while the feet sink 7 mm into the ground, and ends within
/// 0.5 mm (the standing joint PD sags 22 mm under the weight, README).
#[test]
fn simulated_hyq_stands_still_on_its_reference() {
    let model = hyq();
    let start = resting_start(&model);
    let q0 = start.0.clone();
    let hold = WholeBodyReference::holding(&model, &q0);
    let mut c = WholeBodyController::with_default_gains(&model, move |_: f64, r: &mut WholeBodyReference| r.clone_from(&hold), 0.001).unwrap();
    let trace = simulate(&model, &mut c, start, 3.0, &[]);
    let n = trace.t.len();
    let final_error = (trace.cog_plan[n - 1] - trace.cog[n - 1]).norm();
    let max_error = max((0..n).map(|k| (trace.cog_plan[k] - trace.cog[k]).norm()));
    let base_drift = (trace.base[n - 1] - Vector3::new(q0[0], q0[1], q0[2])).norm();
    eprintln!(
        "standing 3 s: CoG error final {:.3} mm, max {:.3} mm; base moved {:.3} mm; orientation error max {:.4} deg; clipped ticks {}",
        final_error * 1e3,
        max_error * 1e3,
        base_drift * 1e3,
        max(trace.orientation_error.iter().copied()).to_degrees(),
        c.stats().clipped_ticks
    );
    assert!(final_error < 0.0005 && max_error < 0.003, "CoG error final {final_error} m, max {max_error} m");
    assert!(base_drift < 0.002, "base moved {base_drift} m");
}

/// A 50 N lateral push on the base for 0.2 s (as the standing PD's test) is rejected.
#[test]
fn simulated_hyq_rejects_a_lateral_push() {
    let model = hyq();
    let start = settled_start(&model);
    let hold = WholeBodyReference::holding(&model, &start.0);
    let mut c = WholeBodyController::with_default_gains(&model, move |_: f64, r: &mut WholeBodyReference| r.clone_from(&hold), 0.001).unwrap();
    let push = Push::parse("0,50,0@1.0:0.2").unwrap();
    let trace = simulate(&model, &mut c, start, 3.2, &[push]);
    let error = |k: usize| (trace.cog_plan[k] - trace.cog[k]).norm();
    let peak = max((0..trace.t.len()).filter(|&k| trace.t[k] >= 1.0).map(error));
    let after = error(trace.t.len() - 1);
    let slide = max((0..4).map(|f| (trace.feet[trace.t.len() - 1][f] - trace.feet[0][f]).norm()));
    eprintln!("push 50 N x 0.2 s: peak CoG deviation {:.2} mm, 2 s after {:.3} mm, feet slid at most {:.2} mm", peak * 1e3, after * 1e3, slide * 1e3);
    assert!(peak > 0.0005, "the push must move the robot ({peak} m)");
    assert!(peak < 0.005 && after < 0.0001, "peak {peak} m, after {after} m");
    assert!(slide < 0.001, "feet slid {slide} m");
}

/// A step with one leg while three stand: the CoG first moves 6 cm inside the support
/// triangle of the other three feet (1.5 s), LF then lifts 8 cm, moves 10 cm forward and is
/// put down (0.8 s), and the robot holds for 1 s. The CoG stays within 2 mm of its plan,
/// the trunk within 0.5 deg, the stance feet move less than 4 mm (the tangential contact
/// spring), LF lands within 5 mm of its target; no torque is clipped.
#[test]
fn simulated_hyq_steps_with_one_leg_on_three() {
    let model = hyq();
    let start = settled_start(&model);
    let q0 = start.0.clone();
    let hold = WholeBodyReference::holding(&model, &q0);
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &q0);
    let feet0: Vec<Vector3<f64>> = model.feet.iter().map(|f| frame_position(&model, &data, f.frame)).collect();
    // Support triangle of RF, LH, RH; the CoG moves to 6 cm inside the edge RF-LH.
    let (rf, lh) = (feet0[1], feet0[2]);
    let edge = (lh - rf).xy().normalize();
    let inward = {
        let n = Vector3::new(edge.y, -edge.x, 0.0);
        if n.xy().dot(&(feet0[3] - rf).xy()) > 0.0 {
            n
        } else {
            -n
        }
    };
    let cog0 = hold.body.cog_position;
    let along = (cog0 - rf).xy().dot(&edge);
    let on_edge = rf + Vector3::new(edge.x, edge.y, 0.0) * along;
    let cog_target = Vector3::new(on_edge.x, on_edge.y, cog0.z) + inward * 0.06;
    let lf_start = feet0[0];
    let lf_target = lf_start + Vector3::new(0.10, 0.0, 0.0);
    let (shift_end, swing_end) = (1.5, 2.3);
    let lift = 0.08;
    let plan = move |t: f64, r: &mut WholeBodyReference| {
        r.clone_from(&hold);
        let (s, ds, dds) = smoothstep(t / shift_end);
        let d = cog_target - cog0;
        r.body.cog_position = cog0 + d * s;
        r.body.cog_velocity = d * (ds / shift_end);
        r.body.cog_acceleration = d * (dds / (shift_end * shift_end));
        if t >= shift_end && t < swing_end {
            let tau = swing_end - shift_end;
            let x = (t - shift_end) / tau;
            let (s, ds, dds) = smoothstep(x);
            let step = lf_target - lf_start;
            // Height 64 h x^3 (1 - x)^3: peak h at mid-swing, zero velocity and
            // acceleration at lift-off and touchdown.
            let z = 64.0 * lift * x.powi(3) * (1.0 - x).powi(3);
            let dz = 64.0 * lift * 3.0 * x * x * (1.0 - x) * (1.0 - x) * (1.0 - 2.0 * x);
            let ddz = 64.0 * lift * 6.0 * x * (1.0 - x) * (1.0 - 5.0 * x + 5.0 * x * x);
            r.legs[0] = LegMotion::Swing(FootMotion {
                position: lf_start + step * s + Vector3::new(0.0, 0.0, z),
                velocity: (step * ds + Vector3::new(0.0, 0.0, dz)) / tau,
                acceleration: (step * dds + Vector3::new(0.0, 0.0, ddz)) / (tau * tau),
            });
        }
    };
    let mut c = WholeBodyController::with_default_gains(&model, plan, 0.001).unwrap();
    let trace = simulate(&model, &mut c, start, 3.3, &[]);
    let n = trace.t.len();
    let cog_max = max((0..n).map(|k| (trace.cog_plan[k] - trace.cog[k]).norm()));
    let tilt_max = max(trace.orientation_error.iter().copied());
    let swing_peak = max((0..n).map(|k| trace.feet[k][0].z - lf_start.z));
    let landing = (trace.feet[n - 1][0] - lf_target).norm();
    let slide = max((1..4).map(|f| max((0..n).map(|k| (trace.feet[k][f] - feet0[f]).xy().norm()))));
    let lift_off_time = trace.t[(0..n).find(|&k| trace.feet[k][0].z > lf_start.z + 0.005).unwrap_or(n - 1)];
    let stats = c.stats();
    eprintln!(
        "step LF on three legs: CoG shift {:.1} mm, CoG error max {:.2} mm, trunk tilt error max {:.3} deg; LF peak lift {:.1} mm (plan 80), \
         lift-off at {:.3} s, landed {:.2} mm from target; stance feet slid at most {:.2} mm; clipped ticks {} of {}, max torque {:.1} N m",
        (cog_target - cog0).norm() * 1e3,
        cog_max * 1e3,
        tilt_max.to_degrees(),
        swing_peak * 1e3,
        lift_off_time,
        landing * 1e3,
        slide * 1e3,
        stats.clipped_ticks,
        stats.ticks,
        stats.max_torque
    );
    assert!(cog_max < 0.002, "CoG error {cog_max} m");
    assert!(tilt_max < 0.5f64.to_radians(), "trunk orientation error {} deg", tilt_max.to_degrees());
    assert!((swing_peak - lift).abs() < 0.005, "LF peak lift {swing_peak} m, plan {lift} m");
    assert!(landing < 0.005, "LF landed {landing} m from its target");
    assert!(slide < 0.004, "stance feet moved {slide} m in the ground plane");
    assert_eq!(stats.clipped_ticks, 0);
}

/// A reference the actuators cannot follow (the CoG accelerating up at 40 m/s^2): every
/// torque above its effort limit is clipped to it, and counted.
#[test]
fn torques_beyond_the_effort_limits_are_clipped_and_counted() {
    let model = hyq();
    let q = model.reference_configuration("standing").unwrap().clone();
    let v = DVector::zeros(model.nv);
    let mut c = controller(&model);
    let mut r = WholeBodyReference::holding(&model, &q);
    r.body.cog_acceleration.z = 40.0;
    let mut tau = DVector::zeros(model.nv);
    c.execute(&model, &q, &v, &r, &mut tau).unwrap();
    let tick = c.last_tick();
    let mut expected = 0;
    for j in model.actuated_joints() {
        let i = j.idx_v;
        let raw = tick.inverse_dynamics_torque[i] + tick.feedback_torque[i];
        let limit = j.limits.effort[0];
        if raw.abs() > limit {
            expected += 1;
            assert_eq!(tau[i], limit * raw.signum(), "joint {}", j.name);
        } else {
            assert_eq!(tau[i], raw, "joint {}", j.name);
        }
    }
    assert!(expected >= 4, "the knees at least must saturate ({expected} clipped)");
    assert_eq!(tick.clipped_joints, expected);
    assert_eq!((c.stats().clipped_ticks, c.stats().clipped_joint_torques), (1, expected as u64));
    assert_eq!(c.stats().max_torque, 150.0);
}
