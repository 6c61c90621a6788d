//! The feedback gains `legwork solve` exports (trajectory.json's `feedback_gain`, on the
//! physical state only) hold a plan in legwork's simulator under a push; the feedforward
//! torques alone do not. They also hold it when a planned stance foot starts off the
//! ground: in a stiff contact (MuJoCo, a robot) a lightly loaded foot loses its contact,
//! and gains that counted on the ground holding the leg threw that leg away
//! (docs/experiments/policy-mujoco.md).

use legwork::control::FeedbackPolicy;
use legwork::dynamics::{compute_joint_jacobians, forward_kinematics, frame_jacobian, frame_position, Data, ReferenceFrame};
use legwork::io::Trajectory;
use legwork::model::embedded;
use legwork::ocp::{solve_task, SolveOptions, TaskSpec};
use legwork::sim::{Push, SimConfig, Simulator};
use legwork::terrain::Plane;
use nalgebra::{DVector, Matrix3, Matrix6xX, Vector3};
use std::sync::OnceLock;

const HOLD: &str = r#"
name = "hold"
summary = "stand still for 1.5 s"
robot = "hyq"
duration = 1.5
dt = 0.002
iterations = 5
[desired]
base_position = ["start", "start", "start"]
[running]
base_position = [100.0, 100.0, 100.0]
base_orientation = [100.0, 100.0, 100.0]
joint_position = 1.0
[final]
base_position = [1000.0, 1000.0, 1000.0]
[input]
weight = 1e-4
"#;

/// Replays `plan` with its exported policy and a 300 N sideways push of 0.2 s (a third of
/// HyQ's weight); returns the largest and the final distance of the base from the plan's,
/// or `None` if the run diverged.
fn pushed_replay(plan: &Trajectory) -> Option<(f64, f64)> {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let mut sim = Simulator::from_plan(&model, &ground, plan, SimConfig::default()).unwrap();
    sim.add_push(Push { force: Vector3::new(0.0, 300.0, 0.0), start: 0.4, duration: 0.2 });
    let mut policy = FeedbackPolicy::new(&model, plan).unwrap();
    let duration = plan.knots.last().unwrap().t;
    let run = sim.run(duration, &mut policy, |_| {}).ok()?;
    let base = |q: &[f64]| Vector3::new(q[0], q[1], q[2]);
    let planned_at = |t: f64| {
        let k = ((t / plan.metadata.dt).round() as usize).min(plan.knots.len() - 1);
        base(&plan.knots[k].q)
    };
    let errors: Vec<f64> = run.trajectory.knots.iter().map(|k| (base(&k.q) - planned_at(k.t)).norm()).collect();
    Some((errors.iter().copied().fold(0.0, f64::max), *errors.last().unwrap()))
}

/// The hold plan, solved once for the tests of this file.
fn hold_plan() -> &'static Trajectory {
    static PLAN: OnceLock<Trajectory> = OnceLock::new();
    PLAN.get_or_init(|| {
        let model = embedded::load("hyq").unwrap();
        let ground = Plane::flat(0.0);
        let spec = TaskSpec::from_toml(HOLD, "hold.toml").unwrap();
        solve_task(&spec, &model, &ground, "hold.toml", &SolveOptions::default(), |_| {}).unwrap().plan
    })
}

#[test]
fn the_exported_gains_hold_the_plan_under_a_push() {
    let plan = hold_plan();
    // Gains on the physical state: 12 x 36 at every knot.
    assert!(plan.knots.iter().all(|k| k.feedback_gain.as_ref().is_some_and(|g| g.len() == 12 && g.iter().all(|r| r.len() == 36))));

    let (worst, last) = pushed_replay(plan).expect("the policy keeps the run finite");
    assert!(worst > 0.01, "the push moves the base ({worst} m)");
    assert!(worst < 0.08 && last < 0.01, "the policy brings the base back: worst {worst:.4} m, final {last:.4} m from the plan");

    // The same plan without its gains: the push throws the robot off the plan.
    let mut open_loop = plan.clone();
    for k in &mut open_loop.knots {
        for row in k.feedback_gain.as_mut().unwrap() {
            row.fill(0.0);
        }
    }
    match pushed_replay(&open_loop) {
        None => {}
        Some((worst_open, last_open)) => assert!(last_open > 5.0 * last.max(0.002), "feedforward alone should not recover: final {last_open:.4} m vs {last:.4} m (worst {worst_open:.4})"),
    }
}

/// Replays `plan` with its exported policy from its first knot with the LF foot lifted
/// `lift` m by its own leg's joints (the base and the other legs as planned); returns the
/// largest distance of the base from the plan's, the LF foot's height at the end, and the
/// largest LF joint deviation from the plan over the last 0.5 s (rad), or `None` if the
/// run diverged.
fn lifted_foot_replay(plan: &Trajectory, lift: f64) -> Option<(f64, f64, f64)> {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let lf = &model.feet[0];
    let leg = 6..9; // LF's haa, hfe, kfe velocity indices (configuration indices + 1)
    let mut q0 = DVector::from_column_slice(&plan.knots[0].q);
    let mut data = Data::new(&model);
    let mut jacobian = Matrix6xX::zeros(model.nv);
    forward_kinematics(&model, &mut data, &q0);
    let target = frame_position(&model, &data, lf.frame) + Vector3::new(0.0, 0.0, lift);
    // Newton on the LF leg's joints: the foot `lift` above its planned place.
    for _ in 0..10 {
        forward_kinematics(&model, &mut data, &q0);
        let error = target - frame_position(&model, &data, lf.frame);
        compute_joint_jacobians(&model, &mut data, &q0);
        frame_jacobian(&model, &data, lf.frame, ReferenceFrame::LocalWorldAligned, &mut jacobian);
        let j_leg: Matrix3<f64> = jacobian.fixed_view::<3, 3>(0, leg.start).into_owned();
        let step = j_leg.try_inverse().unwrap() * error;
        for (i, dof) in leg.clone().enumerate() {
            q0[dof + 1] += step[i];
        }
    }
    let config = SimConfig { joint_limits: plan.metadata.joint_stops, ..SimConfig::default() };
    let mut sim = Simulator::new(&model, &ground, config, q0, Some(DVector::from_column_slice(&plan.knots[0].v))).unwrap();
    let mut anchors: Vec<Option<Vector3<f64>>> = plan.metadata.initial_anchors.as_ref().unwrap().iter().map(|a| a.map(Vector3::from)).collect();
    anchors[0] = None; // the lifted foot has no contact
    sim.set_contact_anchors(&anchors).unwrap();
    let mut policy = FeedbackPolicy::new(&model, plan).unwrap();
    let duration = plan.knots.last().unwrap().t;
    let run = sim.run(duration, &mut policy, |_| {}).ok()?;
    let planned = |t: f64| &plan.knots[((t / plan.metadata.dt).round() as usize).min(plan.knots.len() - 1)];
    let base = |q: &[f64]| Vector3::new(q[0], q[1], q[2]);
    let worst = run.trajectory.knots.iter().map(|k| (base(&k.q) - base(&planned(k.t).q)).norm()).fold(0.0, f64::max);
    let last = run.trajectory.knots.last()?;
    forward_kinematics(&model, &mut data, &DVector::from_column_slice(&last.q));
    let foot_height = frame_position(&model, &data, lf.frame).z - lf.radius;
    let joint_error = run.trajectory.knots.iter().filter(|k| k.t > duration - 0.5).flat_map(|k| leg.clone().map(move |dof| (k.q[dof + 1] - planned(k.t).q[dof + 1]).abs())).fold(0.0, f64::max);
    Some((worst, foot_height, joint_error))
}

/// A planned stance foot that starts 3 cm off the ground (its contact lost, as a lightly
/// loaded foot loses it in a stiff contact): the exported policy puts it back and holds the
/// plan. Gains that kept the optimizer's reaction to a stance leg's own joints (a negative
/// stiffness on the leg, which the soft contact's spring held) swing that leg away.
#[test]
fn the_exported_gains_put_a_lifted_stance_foot_back() {
    let plan = hold_plan();
    let (worst, foot_height, joint_error) = lifted_foot_replay(plan, 0.03).expect("the policy keeps the run finite");
    assert!(worst < 0.03, "the base stays near the plan: worst {worst:.4} m");
    assert!(foot_height < 0.002, "the LF foot is back on the ground: {foot_height:.4} m above it");
    assert!(joint_error < 0.05, "the LF leg is back on its plan: {joint_error:.4} rad off over the last 0.5 s");
}

/// The cause of the exported policy's falls in MuJoCo (docs/experiments/policy-mujoco.md):
/// the optimizer's gain of a stance leg on its own joints is a negative stiffness, which its
/// soft ground's spring holds and a stiff ground does not once the foot loses its load. At
/// every knot of the plan, every planted foot's leg, left to itself (its foot off the
/// ground), is not pushed further from the plan by the exported gains: the symmetric part
/// of the leg's own position gain has no positive eigenvalue (tau = K dx with dx = q - q*:
/// a restoring gain is negative).
#[test]
fn a_stance_leg_left_to_itself_is_not_pushed_away() {
    let plan = hold_plan();
    let legs = [6..9, 9..12, 12..15, 15..18];
    let mut checked = 0;
    for (k, knot) in plan.knots.iter().enumerate() {
        let gain = knot.feedback_gain.as_ref().unwrap();
        let scale = gain.iter().flatten().fold(0.0_f64, |m, x| m.max(x.abs()));
        for (f, leg) in legs.iter().enumerate() {
            if !knot.in_contact[f] {
                continue;
            }
            let block = Matrix3::from_fn(|i, j| gain[leg.start - 6 + i][leg.start + j]);
            let symmetric = 0.5 * (block + block.transpose());
            let largest = symmetric.symmetric_eigenvalues().max();
            assert!(largest <= 1e-9 * scale, "knot {k}, foot {f}: the leg's own position gain has the eigenvalue {largest:.3} N m/rad > 0");
            checked += 1;
        }
    }
    assert!(checked > plan.knots.len(), "stance legs were checked ({checked})");
}
