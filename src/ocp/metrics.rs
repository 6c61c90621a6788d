//! Figures of a motion that the targets of the paper's tasks are stated in: where the base
//! ended, how high it went, when feet were off the ground, which feet moved together.

use crate::dynamics::{base_orientation, forward_kinematics, frame_position, Data};
use crate::io::Trajectory;
use crate::model::Model;
use crate::sim::JointStops;
use nalgebra::DVector;
use serde::Serialize;

/// Figures of one trajectory (a plan or a closed-loop re-run).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MotionMetrics {
    /// Base position at the last knot (m, world).
    pub final_base_position: [f64; 3],
    /// Base roll, pitch, yaw at the last knot (deg).
    pub final_base_rpy_deg: [f64; 3],
    /// Highest base position and when (m, s).
    pub apex_base_height: f64,
    pub apex_time: f64,
    /// Base pitch at the apex (deg).
    pub apex_pitch_deg: f64,
    /// Which feet touch the ground at the apex.
    pub apex_in_contact: Vec<bool>,
    /// Total time with all feet off the ground (s).
    pub flight_time: f64,
    /// Per foot: how many times it left the ground.
    pub liftoffs: Vec<usize>,
    /// Per foot: fraction of the time in contact.
    pub duty_factor: Vec<f64>,
    /// Fraction of the knots with every foot on the ground: near 1 for a motion that
    /// stands, or slides its feet, for most of its horizon.
    pub all_feet_down: f64,
    /// When the first foot left the ground (s), `None` if none did. With `all_feet_down`
    /// it tells a gait spread over the horizon from contacts that appear only near the end.
    pub first_liftoff_time: Option<f64>,
    /// Per foot: fraction of the final 2 s (the whole motion if shorter) spent off the
    /// ground. The humanoid walk's target is both front feet at 1.0 (Neunert 2017, V-A6:
    /// on the hind legs until the end).
    pub off_ground_final_2s: Vec<f64>,
    /// Per foot: how far it slid on the ground while loaded (load above 10 % of its share of
    /// the weight): the net horizontal displacement from touch-down to lift-off, summed over
    /// its loaded phases (m). Zero for feet that never slip.
    pub slide: Vec<f64>,
    /// Correlation of the contact flags of the diagonal pairs (first with fourth foot, second
    /// with third: LF-RH and RF-LH in legwork's leg order), `None` when a foot never changes.
    pub diagonal_correlation: [Option<f64>; 2],
    /// The same for the lateral pairs (LF-RF, LH-RH): near -1 in a trot, near +1 in a
    /// pronk or bound, which a diagonal correlation alone does not tell apart from a trot.
    pub lateral_correlation: [Option<f64>; 2],
    /// The farthest any joint went past its position limit, `None` if every joint stayed
    /// in its range. The joint stops are optional ([`crate::sim::SimConfig::joint_limits`],
    /// off by default): this says whether the motion is one the hardware could make.
    pub joint_limit_excess: Option<LimitExcess>,
}

/// A joint past its position limit: which, by how much (deg) and when (s).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LimitExcess {
    pub joint: String,
    pub excess_deg: f64,
    pub t: f64,
}

/// The largest excursion of a joint past its position limit over the knots of `traj` (a
/// motion of `model`), `None` if every joint stayed in its range.
pub fn joint_limit_excess(model: &Model, traj: &Trajectory) -> Option<LimitExcess> {
    // The stops' own test of which coordinate is past a limit, with the stops off.
    let limits = JointStops::new(model, None);
    let mut worst: Option<(usize, f64, f64)> = None;
    for knot in &traj.knots {
        if let Some((idx_v, excess)) = limits.worst_excess(&knot.q) {
            if worst.is_none_or(|(_, w, _)| excess > w) {
                worst = Some((idx_v, excess, knot.t));
            }
        }
    }
    worst.map(|(idx_v, excess, t)| {
        let joint = model.joints.iter().find(|j| j.nv > 0 && (j.idx_v..j.idx_v + j.nv).contains(&idx_v)).map_or_else(|| format!("v[{idx_v}]"), |j| j.name.clone());
        LimitExcess { joint, excess_deg: excess.to_degrees(), t }
    })
}

/// The final window of [`MotionMetrics::off_ground_final_2s`] (s).
const FINAL_WINDOW: f64 = 2.0;

fn rpy(q: &[f64]) -> [f64; 3] {
    let (r, p, y) = base_orientation(q).euler_angles();
    [r.to_degrees(), p.to_degrees(), y.to_degrees()]
}

/// The state of a trajectory at one time (the knot nearest to it).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Snapshot {
    pub t: f64,
    pub base_position: [f64; 3],
    pub base_rpy_deg: [f64; 3],
    pub in_contact: Vec<bool>,
    /// World positions of the foot-sphere centres, in `Model::feet` order.
    pub feet: Vec<[f64; 3]>,
}

impl Snapshot {
    /// The knot of `traj` (a motion of `model`) nearest to `t`.
    pub fn at(model: &Model, traj: &Trajectory, t: f64) -> Self {
        let knot = traj.knots.iter().min_by(|a, b| (a.t - t).abs().total_cmp(&(b.t - t).abs())).expect("a trajectory has knots (validated)");
        let feet = feet_at(model, &mut Data::new(model), &knot.q);
        Self { t: knot.t, base_position: [knot.q[0], knot.q[1], knot.q[2]], base_rpy_deg: rpy(&knot.q), in_contact: knot.in_contact.clone(), feet }
    }
}

/// Pearson correlation of two 0/1 sequences.
fn correlation(a: &[f64], b: &[f64]) -> Option<f64> {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    (saa > 0.0 && sbb > 0.0).then(|| sab / (saa * sbb).sqrt())
}

/// World positions of the feet (sphere centres, `Model::feet` order) in configuration `q`.
fn feet_at(model: &Model, data: &mut Data, q: &[f64]) -> Vec<[f64; 3]> {
    forward_kinematics(model, data, &DVector::from_column_slice(q));
    model.feet.iter().map(|f| frame_position(model, data, f.frame).into()).collect()
}

/// World positions of every foot at every knot.
fn foot_positions(model: &Model, traj: &Trajectory) -> Vec<Vec<[f64; 3]>> {
    let mut data = Data::new(model);
    traj.knots.iter().map(|k| feet_at(model, &mut data, &k.q)).collect()
}

impl MotionMetrics {
    /// The figures of `traj`, a motion of `model` (at least one knot).
    pub fn of(model: &Model, traj: &Trajectory) -> Self {
        let knots = &traj.knots;
        let last = knots.last().expect("a trajectory has knots (validated)");
        let apex = knots.iter().max_by(|a, b| a.q[2].total_cmp(&b.q[2])).unwrap_or(last);
        let nfeet = traj.metadata.foot_names.len();
        let mut liftoffs = vec![0; nfeet];
        let mut in_contact = vec![0usize; nfeet];
        let mut flight_time = 0.0;
        let mut all_down_knots = 0usize;
        let mut first_liftoff_time = None;
        for (k, knot) in knots.iter().enumerate() {
            for f in 0..nfeet {
                in_contact[f] += knot.in_contact[f] as usize;
                if k > 0 && knots[k - 1].in_contact[f] && !knot.in_contact[f] {
                    liftoffs[f] += 1;
                    first_liftoff_time.get_or_insert(knot.t);
                }
            }
            all_down_knots += knot.in_contact.iter().all(|&c| c) as usize;
            if k + 1 < knots.len() && knot.in_contact.iter().all(|c| !c) {
                flight_time += knots[k + 1].t - knot.t;
            }
        }
        // Net slide per loaded phase.
        let feet = foot_positions(model, traj);
        let loaded_force = 0.1 * model.total_mass() * 9.81 / nfeet.max(1) as f64;
        let mut slide = vec![0.0; nfeet];
        for (f, total) in slide.iter_mut().enumerate() {
            let mut start: Option<usize> = None;
            for k in 0..=knots.len() {
                let loaded = k < knots.len() && knots[k].contact_force[f][2] > loaded_force;
                match (loaded, start) {
                    (true, None) => start = Some(k),
                    (false, Some(s)) => {
                        let (a, b) = (feet[s][f], feet[k - 1][f]);
                        *total += (b[0] - a[0]).hypot(b[1] - a[1]);
                        start = None;
                    }
                    _ => {}
                }
            }
        }
        let final_window: Vec<_> = knots.iter().filter(|k| k.t >= last.t - FINAL_WINDOW).collect();
        let off_ground_final_2s = (0..nfeet).map(|f| final_window.iter().filter(|k| !k.in_contact[f]).count() as f64 / final_window.len() as f64).collect();
        let flags = |f: usize| -> Vec<f64> { knots.iter().map(|k| k.in_contact[f] as u8 as f64).collect() };
        let diagonal_correlation = if nfeet == 4 { [correlation(&flags(0), &flags(3)), correlation(&flags(1), &flags(2))] } else { [None, None] };
        let lateral_correlation = if nfeet == 4 { [correlation(&flags(0), &flags(1)), correlation(&flags(2), &flags(3))] } else { [None, None] };
        Self {
            final_base_position: [last.q[0], last.q[1], last.q[2]],
            final_base_rpy_deg: rpy(&last.q),
            apex_base_height: apex.q[2],
            apex_time: apex.t,
            apex_pitch_deg: rpy(&apex.q)[1],
            apex_in_contact: apex.in_contact.clone(),
            flight_time,
            liftoffs,
            off_ground_final_2s,
            duty_factor: in_contact.iter().map(|&c| c as f64 / knots.len() as f64).collect(),
            all_feet_down: all_down_knots as f64 / knots.len() as f64,
            first_liftoff_time,
            slide,
            diagonal_correlation,
            lateral_correlation,
            joint_limit_excess: joint_limit_excess(model, traj),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::Knot;
    use crate::terrain::TerrainSpec;
    use crate::model::embedded;

    /// Three knots of HyQ in its default stance, the second with the LF knee 0.3 rad past
    /// its upper limit and the RH HAA 0.1 rad past its lower one.
    #[test]
    fn the_worst_joint_limit_excess_is_named_with_its_time() {
        let model = embedded::load("hyq").unwrap();
        let stance = model.reference_configuration("standing").unwrap().clone();
        let mut traj = Trajectory::new(&model, "limits", 0.1, TerrainSpec::flat());
        let knot = |t: f64, q: &DVector<f64>| Knot { t, q: q.iter().copied().collect(), v: vec![0.0; model.nv], tau: vec![0.0; model.nv - 6], contact_force: vec![[0.0; 3]; 4], in_contact: vec![true; 4], feedback_gain: None };
        traj.knots.push(knot(0.0, &stance));
        assert_eq!(MotionMetrics::of(&model, &traj).joint_limit_excess, None);
        let mut bent = stance.clone();
        let (kfe, haa) = (model.q_index("lf_kfe_joint").unwrap(), model.q_index("rh_haa_joint").unwrap());
        let joint = |name: &str| model.joints.iter().find(|j| j.name == name).unwrap();
        bent[kfe] = joint("lf_kfe_joint").limits.upper[0] + 0.3;
        bent[haa] = joint("rh_haa_joint").limits.lower[0] - 0.1;
        traj.knots.push(knot(0.1, &bent));
        traj.knots.push(knot(0.2, &stance));
        let excess = MotionMetrics::of(&model, &traj).joint_limit_excess.unwrap();
        assert_eq!(excess.joint, "lf_kfe_joint");
        assert!((excess.excess_deg - 0.3f64.to_degrees()).abs() < 1e-9, "{excess:?}");
        assert_eq!(excess.t, 0.1);
    }

    /// 3 s at 0.5 s per knot: the front feet leave the ground at t = 1.5 s and stay off; the
    /// hind feet are off at one knot of the final 2 s.
    #[test]
    fn off_ground_shares_and_the_first_liftoff() {
        let flags: Vec<[bool; 4]> = (0..=6).map(|k| {
            let (front, hind) = ((0.5 * k as f64) < 1.5, k != 4);
            [front, front, hind, hind]
        }).collect();
        // The final 2 s: knots at 1.0 .. 3.0 s (five); the front feet are down at 1.0 only.
        let metrics = with_contacts(0.5, &flags);
        assert_eq!(metrics.off_ground_final_2s, vec![0.8, 0.8, 0.2, 0.2]);
        // Every foot is down at 0.0, 0.5 and 1.0 s only; the front feet leave first, at 1.5 s.
        assert_eq!(metrics.all_feet_down, 3.0 / 7.0);
        assert_eq!(metrics.first_liftoff_time, Some(1.5));
    }

    /// The metrics of knots of HyQ's stance every `dt` seconds with the given contact flags.
    fn with_contacts(dt: f64, flags: &[[bool; 4]]) -> MotionMetrics {
        let model = embedded::load("hyq").unwrap();
        let stance = model.reference_configuration("standing").unwrap().clone();
        let mut traj = Trajectory::new(&model, "gait", dt, TerrainSpec::flat());
        for (k, c) in flags.iter().enumerate() {
            traj.knots.push(Knot { t: dt * k as f64, q: stance.iter().copied().collect(), v: vec![0.0; model.nv], tau: vec![0.0; model.nv - 6], contact_force: vec![[0.0; 3]; 4], in_contact: c.to_vec(), feedback_gain: None });
        }
        MotionMetrics::of(&model, &traj)
    }

    /// A trot (diagonal pairs in turn, LF-RF-LH-RH order) and a pronk (all four together)
    /// both have diagonal correlation 1; the lateral pairs tell them apart.
    #[test]
    fn lateral_correlation_tells_a_trot_from_a_pronk() {
        let (down, first, second, up) = ([true; 4], [false, true, true, false], [true, false, false, true], [false; 4]);
        let trot = with_contacts(0.1, &[down, first, down, second, down, first, down, second]);
        assert_eq!(trot.diagonal_correlation.map(|c| (c.unwrap() * 1e9).round() / 1e9), [1.0, 1.0]);
        let lateral = trot.lateral_correlation.map(|c| c.unwrap());
        assert!(lateral.iter().all(|&c| c < -0.3), "{lateral:?}");
        let pronk = with_contacts(0.1, &[down, up, down, up, down, up, down, up]);
        assert_eq!(pronk.diagonal_correlation.map(|c| (c.unwrap() * 1e9).round() / 1e9), [1.0, 1.0]);
        assert_eq!(pronk.lateral_correlation.map(|c| (c.unwrap() * 1e9).round() / 1e9), [1.0, 1.0]);
    }
}
