//! Figures of a motion that the targets of the paper's tasks are stated in: where the base
//! ended, how high it went, when feet were off the ground, which feet moved together.

use crate::dynamics::{base_orientation, forward_kinematics, frame_position, Data};
use crate::io::{Knot, Trajectory};
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
    /// Torques, friction, sliding and penetration: whether the motion is physically feasible
    /// (issue 16).
    pub feasibility: Feasibility,
}

/// The friction margin the feasibility figures are stated against: a loaded foot's
/// tangential force within `FRICTION_MARGIN mu F_n` (issue 16's target, 0.75).
pub const FRICTION_MARGIN: f64 = 0.75;

/// A loaded foot slides when its horizontal speed exceeds this (m/s; issue 16's 0.1 m/s).
pub const SLIDE_SPEED: f64 = 0.1;

/// How physically feasible a motion is: torques against the effort limits, contact forces
/// against the friction cone, loaded feet that move, feet in the ground. "Loaded" is the
/// load of [`MotionMetrics::slide`]: a normal force above 10 % of the foot's share of the
/// weight.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Feasibility {
    /// The largest `|tau_i| / effort_i` over knots and joints (1 = at a limit).
    pub max_torque_ratio: f64,
    /// The largest `|tau_i| - effort_i` (N m), 0 when every torque is within its limit.
    pub max_torque_excess: f64,
    /// Fraction of the knots with some torque at (within 0.1 % of) or past its limit.
    pub knots_at_torque_limit: f64,
    /// The largest `|v_i| / velocity_i` of the joints (1 = at a velocity limit).
    pub max_joint_velocity_ratio: f64,
    /// The largest `|F_t| / F_n` over loaded feet and knots (`mu` at the cone's edge).
    pub max_friction_ratio: f64,
    /// Fraction of the loaded foot-knots with `|F_t| > FRICTION_MARGIN mu F_n`.
    pub friction_margin_excess: f64,
    /// Per foot: fraction of its loaded knots at which it moves faster than [`SLIDE_SPEED`]
    /// horizontally (knot-to-knot differences).
    pub sliding_share: Vec<f64>,
    /// The deepest penetration of a foot sphere into the terrain (m).
    pub max_penetration: f64,
}

impl Feasibility {
    /// The figures of `traj`, a motion of `model` on its recorded terrain, for friction
    /// coefficient `mu`. `feet` are the foot positions at every knot, `loaded_force` the load
    /// threshold (N).
    fn of(model: &Model, traj: &Trajectory, mu: f64, feet: &[Vec<[f64; 3]>], loaded_force: f64) -> Self {
        let knots = &traj.knots;
        let effort: Vec<f64> = model.actuated_joints().map(|j| j.limits.effort[0]).collect();
        let velocity_limit: Vec<f64> = model.actuated_joints().map(|j| j.limits.velocity[0]).collect();
        let (mut max_torque_ratio, mut max_torque_excess, mut at_limit) = (0.0f64, 0.0f64, 0usize);
        let mut max_joint_velocity_ratio = 0.0f64;
        for knot in knots {
            let mut any = false;
            for (tau, limit) in knot.tau.iter().zip(&effort) {
                max_torque_ratio = max_torque_ratio.max(tau.abs() / limit);
                max_torque_excess = max_torque_excess.max(tau.abs() - limit);
                any |= tau.abs() >= 0.999 * limit;
            }
            at_limit += any as usize;
            for (v, limit) in knot.v[6..].iter().zip(&velocity_limit) {
                max_joint_velocity_ratio = max_joint_velocity_ratio.max(v.abs() / limit);
            }
        }
        // Friction and penetration against the recorded terrain (a spec that does not build
        // gives NaN: no terrain, no figure).
        let terrain = traj.metadata.terrain.build("the trajectory's terrain").ok();
        let nfeet = traj.metadata.foot_names.len();
        let (mut max_friction_ratio, mut over_margin, mut loaded_samples) = (0.0f64, 0usize, 0usize);
        let (mut sliding, mut loaded_knots) = (vec![0usize; nfeet], vec![0usize; nfeet]);
        let mut max_penetration = if terrain.is_some() { f64::NEG_INFINITY } else { f64::NAN };
        for (k, knot) in knots.iter().enumerate() {
            for f in 0..nfeet {
                let p = feet[k][f];
                let normal = match &terrain {
                    Some(t) => {
                        let (h, n) = t.surface(p[0], p[1]);
                        let radius = model.feet.get(f).map_or(0.0, |foot| foot.radius);
                        // Depth of the sphere below the tangent plane through (x, y, h).
                        max_penetration = max_penetration.max(radius - n.z * (p[2] - h));
                        n
                    }
                    None => nalgebra::Vector3::z(),
                };
                let force = nalgebra::Vector3::from(knot.contact_force[f]);
                let normal_force = force.dot(&normal);
                if normal_force <= loaded_force {
                    continue;
                }
                let ratio = (force - normal * normal_force).norm() / normal_force;
                max_friction_ratio = max_friction_ratio.max(ratio);
                over_margin += (ratio > FRICTION_MARGIN * mu) as usize;
                loaded_samples += 1;
                if k + 1 < knots.len() {
                    let (a, b) = (p, feet[k + 1][f]);
                    let speed = (b[0] - a[0]).hypot(b[1] - a[1]) / (knots[k + 1].t - knot.t);
                    loaded_knots[f] += 1;
                    sliding[f] += (speed > SLIDE_SPEED) as usize;
                }
            }
        }
        Self {
            max_torque_ratio,
            max_torque_excess: max_torque_excess.max(0.0),
            knots_at_torque_limit: at_limit as f64 / knots.len() as f64,
            max_joint_velocity_ratio,
            max_friction_ratio,
            friction_margin_excess: if loaded_samples == 0 { 0.0 } else { over_margin as f64 / loaded_samples as f64 },
            sliding_share: sliding.iter().zip(&loaded_knots).map(|(&s, &n)| if n == 0 { 0.0 } else { s as f64 / n as f64 }).collect(),
            max_penetration: max_penetration.max(0.0),
        }
    }
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

/// Whether `foot`, in contact at `before`, is off the ground at `after` (the next knot).
fn lifts_off(before: &Knot, after: &Knot, foot: usize) -> bool {
    before.in_contact[foot] && !after.in_contact[foot]
}

/// Lift-offs of every foot over `knots`.
pub(super) fn liftoffs(knots: &[Knot]) -> Vec<usize> {
    let feet = knots.first().map_or(0, |k| k.in_contact.len());
    (0..feet).map(|f| knots.windows(2).filter(|pair| lifts_off(&pair[0], &pair[1], f)).count()).collect()
}

/// Time with every foot off the ground: the knot intervals that start with no foot down.
pub(super) fn flight_time(knots: &[Knot]) -> f64 {
    knots.windows(2).filter(|pair| pair[0].in_contact.iter().all(|&c| !c)).map(|pair| pair[1].t - pair[0].t).sum()
}

/// Contact-flag correlations of a four-footed motion (feet in LF, RF, LH, RH order): the
/// diagonal pairs (LF-RH, RF-LH) and the lateral pairs (LF-RF, LH-RH); `None` for a pair
/// with a foot that never changes, and for other numbers of feet.
pub(super) fn pair_correlations(knots: &[Knot]) -> ([Option<f64>; 2], [Option<f64>; 2]) {
    if knots.first().map_or(0, |k| k.in_contact.len()) != 4 {
        return ([None, None], [None, None]);
    }
    let flags = |f: usize| -> Vec<f64> { knots.iter().map(|k| k.in_contact[f] as u8 as f64).collect() };
    ([correlation(&flags(0), &flags(3)), correlation(&flags(1), &flags(2))], [correlation(&flags(0), &flags(1)), correlation(&flags(2), &flags(3))])
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
    /// The figures of `traj`, a motion of `model` (at least one knot), its contact forces
    /// judged against the friction coefficient `mu`.
    pub fn of(model: &Model, traj: &Trajectory, mu: f64) -> Self {
        let knots = &traj.knots;
        let last = knots.last().expect("a trajectory has knots (validated)");
        let apex = knots.iter().max_by(|a, b| a.q[2].total_cmp(&b.q[2])).unwrap_or(last);
        let nfeet = traj.metadata.foot_names.len();
        let mut in_contact = vec![0usize; nfeet];
        let mut all_down_knots = 0usize;
        for knot in knots {
            for (count, &down) in in_contact.iter_mut().zip(&knot.in_contact) {
                *count += down as usize;
            }
            all_down_knots += knot.in_contact.iter().all(|&c| c) as usize;
        }
        let first_liftoff_time = knots.windows(2).find(|pair| (0..nfeet).any(|f| lifts_off(&pair[0], &pair[1], f))).map(|pair| pair[1].t);
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
        let (diagonal_correlation, lateral_correlation) = pair_correlations(knots);
        Self {
            final_base_position: [last.q[0], last.q[1], last.q[2]],
            final_base_rpy_deg: rpy(&last.q),
            apex_base_height: apex.q[2],
            apex_time: apex.t,
            apex_pitch_deg: rpy(&apex.q)[1],
            apex_in_contact: apex.in_contact.clone(),
            flight_time: flight_time(knots),
            liftoffs: liftoffs(knots),
            off_ground_final_2s,
            duty_factor: in_contact.iter().map(|&c| c as f64 / knots.len() as f64).collect(),
            all_feet_down: all_down_knots as f64 / knots.len() as f64,
            first_liftoff_time,
            slide,
            diagonal_correlation,
            lateral_correlation,
            joint_limit_excess: joint_limit_excess(model, traj),
            feasibility: Feasibility::of(model, traj, mu, &feet, loaded_force),
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
        assert_eq!(MotionMetrics::of(&model, &traj, 0.8).joint_limit_excess, None);
        let mut bent = stance.clone();
        let (kfe, haa) = (model.q_index("lf_kfe_joint").unwrap(), model.q_index("rh_haa_joint").unwrap());
        let joint = |name: &str| model.joints.iter().find(|j| j.name == name).unwrap();
        bent[kfe] = joint("lf_kfe_joint").limits.upper[0] + 0.3;
        bent[haa] = joint("rh_haa_joint").limits.lower[0] - 0.1;
        traj.knots.push(knot(0.1, &bent));
        traj.knots.push(knot(0.2, &stance));
        let excess = MotionMetrics::of(&model, &traj, 0.8).joint_limit_excess.unwrap();
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
        MotionMetrics::of(&model, &traj, 0.8)
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
