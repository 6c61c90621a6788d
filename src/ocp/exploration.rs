//! Exploration: SLQ from many initial control laws, the best kept (issue 19).
//!
//! SLQ is a local method: from Neunert 2017's single initial law (joint PD around the
//! stance, no feedforward) it converges to the basin nearest that law's rollout, which for
//! the trot is "stand and slide" (issue 4). Exploration solves the same problem from
//! `starts` initial laws in parallel, each the standing PD with random, smooth changes that
//! carry no gait, contact or timing information:
//!
//! ```text
//! u_j(t, x) = kp_j (q*_j + d_j + a_j sin(2 pi t / T + phi_j) - q_j) - kd_j v_j + f_j(t)
//! ```
//!
//! with, per start, set-point offsets `d_j ~ U(-setpoint_noise, setpoint_noise)`,
//! oscillation amplitudes `a_j ~ U(0, oscillation_amplitude)` and phases `phi_j ~ U(0, 2 pi)`
//! on one period `T ~ U(oscillation_period)`, and a feedforward torque `f_j(t)` linear
//! between knots every `torque_knot_interval` seconds, each knot's value
//! `~ U(-1, 1) torque_noise effort_j`. Start 0 is the unperturbed law. Each start runs
//! `screen_iterations` SLQ iterations on one thread (its own solver and workspaces), as
//! many starts at once as the pool has threads; with `rounds > 1`, successive halving: the
//! cheaper half goes on from its solution for another `screen_iterations`, and so on. The
//! start of lowest cost after the last round (ties: the lower index) is kept and the solve
//! continues from its policy; if that is not start 0, the single start's own solve runs
//! beside it to the end and the plan of lower task cost is returned
//! ([`ExplorationSpec::keep_single_start`]). Start `i`'s random numbers come from `seed` and `i` alone
//! ([`start_seed`]), so the same settings give the same starts, and the same pick, on any
//! number of threads.

use super::{RobotState, WholeBodyProblem};
use crate::control::JointPd;
use crate::slq::{input_boxes, rollout, InputBox, Policy, Slq, SlqError, SlqSettings, SlqSolution, SolutionPolicy, Termination};
use nalgebra::DVector;
use rand::rngs::Xoshiro256PlusPlus;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Deserialize;
use std::sync::Mutex;
use std::time::Instant;

/// The `[exploration]` table of a task file (defaults in parentheses).
///
/// ```
/// use legwork::ocp::ExplorationSpec;
/// let spec: ExplorationSpec = toml::from_str("starts = 8\nseed = 3").unwrap();
/// assert_eq!((spec.starts, spec.seed, spec.screen_iterations), (8, 3, 10));
/// spec.validate().unwrap();
/// ```
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ExplorationSpec {
    /// Initial control laws solved, the unperturbed one among them (8).
    pub starts: usize,
    /// Seed of every start's random numbers (0).
    pub seed: u64,
    /// SLQ iterations each start gets per round (10); the kept start's count towards the
    /// task's iteration limit.
    pub screen_iterations: usize,
    /// Rounds of successive halving (1): after each round the cheaper half of its starts
    /// (rounded up) goes on, from its solution, to the next; the last round's cheapest is
    /// kept. Each round is `screen_iterations` long.
    pub rounds: usize,
    /// Half-width of the uniform joint set-point offsets, rad (0.15).
    pub setpoint_noise: f64,
    /// Largest joint oscillation amplitude, rad (0.15).
    pub oscillation_amplitude: f64,
    /// Range of the oscillation period, s ([0.25, 1.0]).
    pub oscillation_period: [f64; 2],
    /// Feedforward torque noise as a fraction of each joint's effort limit (0.05).
    pub torque_noise: f64,
    /// Spacing of the feedforward torque's knots, s (0.1).
    pub torque_knot_interval: f64,
    /// A sampling stage whose cheapest samples join the starts (absent: none).
    pub sampling: Option<SamplingSpec>,
    /// If the kept start is not the single start (start 0), solve both to the end, side
    /// by side, and keep the plan of lower task cost (true): a start's cost after screening
    /// is only a forecast of its final cost, and this way an exploration never ends worse
    /// than the single start. Costs the single start's solve on half the threads.
    pub keep_single_start: bool,
}

impl Default for ExplorationSpec {
    fn default() -> Self {
        Self { starts: 8, seed: 0, screen_iterations: 10, rounds: 1, setpoint_noise: 0.15, oscillation_amplitude: 0.15, oscillation_period: [0.25, 1.0], torque_noise: 0.05, torque_knot_interval: 0.1, sampling: None, keep_single_start: true }
    }
}

/// Most starts one solve takes: each holds a solution while the best is chosen.
pub const MAX_STARTS: usize = 256;

impl ExplorationSpec {
    /// `Err((field, expectation))` for settings that cannot be used.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let finite_non_negative = |v: f64| v.is_finite() && v >= 0.0;
        if !(1..=MAX_STARTS).contains(&self.starts) {
            return Err(("starts", format!("expected 1 to {MAX_STARTS}, got {}", self.starts)));
        }
        if self.screen_iterations == 0 || self.screen_iterations > 1000 {
            return Err(("screen_iterations", format!("expected 1 to 1000, got {}", self.screen_iterations)));
        }
        if !(1..=16).contains(&self.rounds) {
            return Err(("rounds", format!("expected 1 to 16, got {}", self.rounds)));
        }
        for (field, value) in [("setpoint_noise", self.setpoint_noise), ("oscillation_amplitude", self.oscillation_amplitude), ("torque_noise", self.torque_noise)] {
            if !finite_non_negative(value) {
                return Err((field, format!("expected a finite number >= 0, got {value}")));
            }
        }
        let [lo, hi] = self.oscillation_period;
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi) {
            return Err(("oscillation_period", format!("expected [shortest, longest] with 0 < shortest <= longest, got [{lo}, {hi}]")));
        }
        if !(self.torque_knot_interval.is_finite() && self.torque_knot_interval > 0.0) {
            return Err(("torque_knot_interval", format!("expected a number of seconds > 0, got {}", self.torque_knot_interval)));
        }
        if let Some(sampling) = &self.sampling {
            sampling.validate()?;
        }
        Ok(())
    }
}

/// Start `index`'s seed: SplitMix64's finalizer over `seed` and the index, so neighbouring
/// starts get unrelated streams.
pub fn start_seed(seed: u64, index: u64) -> u64 {
    let mut z = seed.wrapping_add(index.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The standing PD with one start's set-point offsets, oscillations and feedforward
/// torques (the module's equation); start 0 is the standing PD itself. The set-point
/// offsets and the feedforward are linear between knots `knot_interval` apart (constant
/// offsets for the random starts; the sampling stage's splines vary them).
#[derive(Clone, Debug)]
pub struct PerturbedStanding<'a> {
    pd: &'a JointPd,
    /// Set-point offset knots, `setpoint[m][j]` at `t = m knot_interval` (rad), per actuated
    /// joint in input order.
    setpoint: Vec<Vec<f64>>,
    /// Feedforward torque knots, as `setpoint` (N m).
    feedforward: Vec<Vec<f64>>,
    knot_interval: f64,
    /// Oscillation amplitude and phase per actuated joint.
    amplitude: Vec<f64>,
    phase: Vec<f64>,
    /// Angular frequency `2 pi / T`, rad/s.
    omega: f64,
}

/// Knots `interval` apart that cover `problem`'s horizon (at least two).
fn spline_knots(problem: &WholeBodyProblem<'_>, interval: f64) -> usize {
    ((problem.knots as f64 * problem.dt / interval).ceil() as usize + 1).max(2)
}

/// A number in [0, 1) from 53 random bits.
fn unit(rng: &mut Xoshiro256PlusPlus) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

/// A standard normal number (Box-Muller).
fn normal(rng: &mut Xoshiro256PlusPlus) -> f64 {
    let (u1, u2) = (1.0 - unit(rng), unit(rng));
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

impl<'a> PerturbedStanding<'a> {
    /// Start `index` of `spec` for `problem` (horizon and effort limits) around `pd`.
    pub fn new(problem: &WholeBodyProblem<'_>, pd: &'a JointPd, spec: &ExplorationSpec, index: usize) -> Self {
        let nu = problem.effort_limits.len();
        let knots = spline_knots(problem, spec.torque_knot_interval);
        if index == 0 {
            return Self::splines(pd, vec![vec![0.0; nu]; knots], vec![vec![0.0; nu]; knots], spec.torque_knot_interval);
        }
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(start_seed(spec.seed, index as u64));
        let mut uniform = |lo: f64, hi: f64| lo + (hi - lo) * unit(&mut rng);
        let offset: Vec<f64> = (0..nu).map(|_| uniform(-spec.setpoint_noise, spec.setpoint_noise)).collect();
        let amplitude = (0..nu).map(|_| uniform(0.0, spec.oscillation_amplitude)).collect();
        let phase = (0..nu).map(|_| uniform(0.0, std::f64::consts::TAU)).collect();
        let period = uniform(spec.oscillation_period[0], spec.oscillation_period[1]);
        let feedforward = (0..knots).map(|_| problem.effort_limits.iter().map(|effort| uniform(-1.0, 1.0) * spec.torque_noise * effort).collect()).collect();
        Self { pd, setpoint: vec![offset; knots], feedforward, knot_interval: spec.torque_knot_interval, amplitude, phase, omega: std::f64::consts::TAU / period }
    }

    /// The standing PD with set-point offset and feedforward splines (knots
    /// `knot_interval` apart, at least two, both of the same length: the callers here build
    /// them with [`spline_knots`]), no oscillation.
    fn splines(pd: &'a JointPd, setpoint: Vec<Vec<f64>>, feedforward: Vec<Vec<f64>>, knot_interval: f64) -> Self {
        let nu = setpoint.first().map_or(0, Vec::len);
        Self { pd, setpoint, feedforward, knot_interval, amplitude: vec![0.0; nu], phase: vec![0.0; nu], omega: 0.0 }
    }
}

impl<'p> Policy<WholeBodyProblem<'p>> for PerturbedStanding<'_> {
    fn control(&self, problem: &WholeBodyProblem<'p>, k: usize, x: &RobotState, u: &mut DVector<f64>) {
        let t = k as f64 * problem.dt;
        // Knot interval [m, m + 1] and the fraction s into it (the last value held after).
        let position = t / self.knot_interval;
        let m = (position.floor() as usize).min(self.feedforward.len() - 2);
        let s = (position - m as f64).min(1.0);
        let lerp = |knots: &[Vec<f64>], i: usize| (1.0 - s) * knots[m][i] + s * knots[m + 1][i];
        let target = self.pd.target();
        let gains = self.pd.gains();
        for j in problem.model.actuated_joints() {
            let (iq, iv, i) = (j.idx_q, j.idx_v, j.idx_v - 6);
            let set_point = target[iq] + lerp(&self.setpoint, i) + self.amplitude[i] * (self.omega * t + self.phase[i]).sin();
            u[i] = gains.kp[iv] * (set_point - x.q[iq]) - gains.kd[iv] * x.v[iv] + lerp(&self.feedforward, i);
        }
    }
}

/// The sampling stage of an exploration (`[exploration.sampling]`; defaults in
/// parentheses): the cross-entropy method over set-point offset and feedforward splines of
/// the standing PD (as MuJoCo MPC's samplers search spline-parameterized controls), by
/// rollout cost alone; its cheapest samples join the SLQ starts.
///
/// Each iteration draws `population` parameter vectors from a normal distribution
/// (iteration 0: mean zero, the standing PD; standard deviations `setpoint_std` rad and
/// `torque_std` times each joint's effort limit), rolls each out through the task's
/// dynamics and cost, and refits the mean and standard deviation to the `elite` cheapest
/// (the deviation kept at least a tenth of its initial value, so the search does not
/// collapse). The first sample of each iteration is the mean itself.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SamplingSpec {
    /// Samples per iteration (32).
    pub population: usize,
    /// Samples the distribution is refitted to (4).
    pub elite: usize,
    /// Iterations (8).
    pub iterations: usize,
    /// Spacing of the spline knots, s (0.25).
    pub knot_interval: f64,
    /// Initial standard deviation of the set-point offsets, rad (0.3).
    pub setpoint_std: f64,
    /// Initial standard deviation of the feedforward torques, fraction of the effort limit (0.1).
    pub torque_std: f64,
    /// Cheapest samples (over all iterations) that become SLQ starts (2).
    pub starts: usize,
}

impl Default for SamplingSpec {
    fn default() -> Self {
        Self { population: 32, elite: 4, iterations: 8, knot_interval: 0.25, setpoint_std: 0.3, torque_std: 0.1, starts: 2 }
    }
}

impl SamplingSpec {
    fn validate(&self) -> Result<(), (&'static str, String)> {
        if !(2..=4096).contains(&self.population) {
            return Err(("sampling.population", format!("expected 2 to 4096, got {}", self.population)));
        }
        if !(1..=self.population).contains(&self.elite) {
            return Err(("sampling.elite", format!("expected 1 to the population ({}), got {}", self.population, self.elite)));
        }
        if !(1..=1000).contains(&self.iterations) {
            return Err(("sampling.iterations", format!("expected 1 to 1000, got {}", self.iterations)));
        }
        if !(1..=MAX_STARTS).contains(&self.starts) {
            return Err(("sampling.starts", format!("expected 1 to {MAX_STARTS}, got {}", self.starts)));
        }
        if !(self.knot_interval.is_finite() && self.knot_interval > 0.0) {
            return Err(("sampling.knot_interval", format!("expected a number of seconds > 0, got {}", self.knot_interval)));
        }
        for (field, value) in [("sampling.setpoint_std", self.setpoint_std), ("sampling.torque_std", self.torque_std)] {
            if !(value.is_finite() && value >= 0.0) {
                return Err((field, format!("expected a finite number >= 0, got {value}")));
            }
        }
        Ok(())
    }
}

/// Rollout buffers of one thread.
struct RolloutScratch<'a> {
    ws: super::WholeBodyWorkspace<'a>,
    states: Vec<RobotState>,
    inputs: Vec<DVector<f64>>,
}

/// The sampling stage ([`SamplingSpec`]): the `sampling.starts` cheapest samples' policies
/// and costs, cheapest first.
fn sample_starts<'a, 'p>(problem: &WholeBodyProblem<'p>, pd: &'a JointPd, spec: &ExplorationSpec, sampling: &SamplingSpec, pool: &rayon::ThreadPool) -> Vec<(f64, PerturbedStanding<'a>)> {
    use crate::slq::Problem as _;
    let nu = problem.effort_limits.len();
    let knots = spline_knots(problem, sampling.knot_interval);
    let half = knots * nu;
    // Parameters: set-point offsets then feedforward torques, knot by knot.
    let initial_std: Vec<f64> = (0..2 * half).map(|p| if p < half { sampling.setpoint_std } else { sampling.torque_std * problem.effort_limits[(p - half) % nu] }).collect();
    let mut mean = vec![0.0; 2 * half];
    let mut std = initial_std.clone();
    let policy_of = |theta: &[f64]| {
        let rows = |part: &[f64]| part.chunks(nu).map(<[f64]>::to_vec).collect::<Vec<_>>();
        PerturbedStanding::splines(pd, rows(&theta[..half]), rows(&theta[half..]), sampling.knot_interval)
    };
    let (lower, upper) = input_boxes(problem);
    let bounds = InputBox { lower: &lower, upper: &upper };
    let mut best: Vec<(f64, Vec<f64>)> = Vec::new();
    for iteration in 0..sampling.iterations {
        // Its own stream per iteration, apart from the random starts' (index >= 2^32).
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(start_seed(spec.seed, (1u64 << 32) + iteration as u64));
        let samples: Vec<Vec<f64>> = (0..sampling.population).map(|i| if i == 0 { mean.clone() } else { mean.iter().zip(&std).map(|(m, s)| m + s * normal(&mut rng)).collect() }).collect();
        // SLQ's own rollout (inputs projected onto their boxes); a diverged sample costs infinity.
        let costs: Vec<f64> = pool.install(|| {
            samples
                .par_iter()
                .map_init(
                    || RolloutScratch { ws: problem.workspace(), states: vec![problem.initial.clone(); problem.knots + 1], inputs: vec![DVector::zeros(nu); problem.knots] },
                    |RolloutScratch { ws, states, inputs }, theta| rollout(problem, ws, &policy_of(theta), bounds, states, inputs).unwrap_or(f64::INFINITY),
                )
                .collect()
        });
        let mut order: Vec<usize> = (0..samples.len()).collect();
        order.sort_by(|&a, &b| costs[a].total_cmp(&costs[b]).then(a.cmp(&b)));
        let elite: Vec<&Vec<f64>> = order.iter().take(sampling.elite).filter(|&&i| costs[i].is_finite()).map(|&i| &samples[i]).collect();
        for &i in order.iter().take(sampling.starts) {
            if costs[i].is_finite() {
                best.push((costs[i], samples[i].clone()));
            }
        }
        best.sort_by(|a, b| a.0.total_cmp(&b.0));
        best.truncate(sampling.starts);
        if elite.is_empty() {
            continue;
        }
        let n = elite.len() as f64;
        for p in 0..mean.len() {
            let m = elite.iter().map(|e| e[p]).sum::<f64>() / n;
            let variance = elite.iter().map(|e| (e[p] - m).powi(2)).sum::<f64>() / n;
            mean[p] = m;
            std[p] = variance.sqrt().max(0.1 * initial_std[p]);
        }
    }
    best.into_iter().map(|(cost, theta)| (cost, policy_of(&theta))).collect()
}

/// One start's outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct StartReport {
    pub index: usize,
    /// [`start_seed`] of the spec's seed and the index (0 for start 0 and sampled starts).
    pub seed: u64,
    /// For a start from the sampling stage (indices from [`ExplorationSpec::starts`] on):
    /// its rollout cost there.
    pub sampled_cost: Option<f64>,
    /// Cost of the start's first rollout, and after the last round it took part in.
    pub initial_cost: f64,
    pub cost: f64,
    /// SLQ iterations over all its rounds.
    pub iterations: usize,
    /// Screening rounds it took part in (1 to [`ExplorationSpec::rounds`]).
    pub rounds: usize,
    /// Why its last SLQ run stopped, or why it could not start (an initial rollout that
    /// diverged).
    pub outcome: Result<Termination, SlqError>,
    /// Wall time of its solves, s.
    pub time: f64,
    /// Seconds from the exploration's start to the end of its last round.
    pub finished_at: f64,
    /// Whether its plan after its last round meets the task's targets (`None`: not judged).
    pub met: Option<bool>,
}

/// The exploration's outcome: every start, the kept one's index and solution.
#[derive(Debug)]
pub struct Exploration {
    pub starts: Vec<StartReport>,
    pub best: usize,
    pub solution: SlqSolution<RobotState>,
    /// Wall time of the whole exploration, s.
    pub time: f64,
}

/// One start's SLQ run in one round.
struct RoundOutcome {
    initial_cost: f64,
    cost: f64,
    iterations: usize,
    termination: Termination,
    /// Judged only in the last round.
    met: bool,
}

/// Starts that go on to round `round` (0-based) of `starts`: all in round 0, then half
/// (rounded up) each round.
pub fn survivors(starts: usize, round: usize) -> usize {
    (0..round).fold(starts, |n, _| n.div_ceil(2))
}

/// The `keep` cheapest solutions seen so far, cheapest first (ties: the lower index), so
/// the pick does not depend on the order the threads finish in.
struct Cheapest {
    keep: usize,
    entries: Vec<(f64, usize, SlqSolution<RobotState>)>,
}

impl Cheapest {
    fn offer(&mut self, cost: f64, index: usize, solution: SlqSolution<RobotState>) {
        if cost.is_nan() {
            return;
        }
        let at = self.entries.partition_point(|(c, i, _)| *c < cost || (*c == cost && *i < index));
        if at < self.keep {
            self.entries.insert(at, (cost, index, solution));
            self.entries.truncate(self.keep);
        }
    }
}

/// Solves `problem` from every start of `spec` with `settings` (its `threads` replaced by
/// one per start, `threads` starts at once) and keeps the cheapest: successive halving
/// over [`ExplorationSpec::rounds`] rounds of [`ExplorationSpec::screen_iterations`]
/// iterations, each round's starts continuing from their last solution. `judge` says
/// whether a start's solution meets the task (for the report; it does not choose). A
/// start whose solve fails is reported with an infinite cost; if every start fails, the
/// first error is returned.
pub fn explore(
    problem: &WholeBodyProblem<'_>,
    pd: &JointPd,
    spec: &ExplorationSpec,
    settings: &SlqSettings,
    threads: usize,
    judge: &(dyn Fn(&SlqSolution<RobotState>) -> bool + Sync),
) -> Result<Exploration, SlqError> {
    let started = Instant::now();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build().map_err(|e| SlqError::Settings { field: "threads", problem: e.to_string() })?;
    let per_start = SlqSettings { threads: 1, max_iterations: spec.screen_iterations, normalized_cost_tolerance: 0.0, ..settings.clone() };
    let mut policies: Vec<PerturbedStanding> = (0..spec.starts).map(|index| PerturbedStanding::new(problem, pd, spec, index)).collect();
    let mut sampled_costs = vec![None; spec.starts];
    if let Some(sampling) = &spec.sampling {
        for (cost, policy) in sample_starts(problem, pd, spec, sampling, &pool) {
            policies.push(policy);
            sampled_costs.push(Some(cost));
        }
    }
    let sampling_time = started.elapsed().as_secs_f64();
    let mut reports: Vec<StartReport> = (0..policies.len())
        .map(|index| StartReport { index, seed: if index == 0 || index >= spec.starts { 0 } else { start_seed(spec.seed, index as u64) }, sampled_cost: sampled_costs[index], initial_cost: f64::INFINITY, cost: f64::INFINITY, iterations: 0, rounds: 0, outcome: Ok(Termination::MaxIterations), time: 0.0, finished_at: sampling_time, met: None })
        .collect();
    let mut first_error: Option<(usize, SlqError)> = None;
    // Round r's starts and the solutions they continue from (none in round 0).
    let starts = policies.len();
    let mut entrants: Vec<(usize, Option<SlqSolution<RobotState>>)> = (0..starts).map(|i| (i, None)).collect();
    for round in 0..spec.rounds {
        let last = round + 1 == spec.rounds || survivors(starts, round + 1) == entrants.len();
        // Only the solutions of the next round's starts are kept (a trot's is about 20 MB).
        let keep = if last { 1 } else { survivors(starts, round + 1) };
        let cheapest = Mutex::new(Cheapest { keep, entries: Vec::with_capacity(keep + 1) });
        let outcomes: Vec<(usize, f64, Result<RoundOutcome, SlqError>)> = pool.install(|| {
            entrants
                .par_iter()
                .map(|(index, previous)| {
                    let t = Instant::now();
                    let outcome = Slq::new(problem, per_start.clone()).and_then(|solver| match previous {
                        None => solver.solve(&policies[*index], |_| {}),
                        Some(previous) => solver.solve(&SolutionPolicy::new(problem, previous, &policies[*index]), |_| {}),
                    });
                    let time = t.elapsed().as_secs_f64();
                    let outcome = outcome.map(|solution| {
                        let cost = *solution.cost_history.last().unwrap_or(&f64::INFINITY);
                        let summary = RoundOutcome { initial_cost: solution.cost_history[0], cost, iterations: solution.iterations.len(), termination: solution.termination.clone(), met: last && judge(&solution) };
                        cheapest.lock().unwrap_or_else(|p| p.into_inner()).offer(cost, *index, solution);
                        summary
                    });
                    (*index, time, outcome)
                })
                .collect()
        });
        let now = started.elapsed().as_secs_f64();
        for (index, time, outcome) in outcomes {
            let report = &mut reports[index];
            report.rounds += 1;
            report.time += time;
            report.finished_at = now;
            match outcome {
                Ok(RoundOutcome { initial_cost, cost, iterations, termination, met }) => {
                    if round == 0 {
                        report.initial_cost = initial_cost;
                    }
                    report.cost = cost;
                    report.iterations += iterations;
                    report.outcome = Ok(termination);
                    report.met = last.then_some(met);
                }
                Err(error) => {
                    if first_error.as_ref().is_none_or(|(i, _)| index < *i) {
                        first_error = Some((index, error.clone()));
                    }
                    report.outcome = Err(error);
                }
            }
        }
        let cheapest = cheapest.into_inner().unwrap_or_else(|p| p.into_inner()).entries;
        if last {
            return match cheapest.into_iter().next() {
                Some((_, best, solution)) => Ok(Exploration { starts: reports, best, solution, time: started.elapsed().as_secs_f64() }),
                None => Err(first_error.map_or(SlqError::Settings { field: "exploration", problem: "every start's cost was NaN".into() }, |(_, e)| e)),
            };
        }
        entrants = cheapest.into_iter().map(|(_, index, solution)| (index, Some(solution))).collect();
    }
    Err(SlqError::Settings { field: "rounds", problem: "expected at least 1 round".into() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn start_seeds_differ_and_repeat() {
        let seeds: Vec<u64> = (0..64).map(|i| start_seed(7, i)).collect();
        let mut unique = seeds.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), seeds.len());
        assert_eq!(seeds, (0..64).map(|i| start_seed(7, i)).collect::<Vec<_>>());
        assert_ne!(start_seed(7, 1), start_seed(8, 1));
    }

    #[test]
    fn bad_settings_name_their_field() {
        let bad = [
            (ExplorationSpec { starts: 0, ..Default::default() }, "starts"),
            (ExplorationSpec { starts: MAX_STARTS + 1, ..Default::default() }, "starts"),
            (ExplorationSpec { screen_iterations: 0, ..Default::default() }, "screen_iterations"),
            (ExplorationSpec { rounds: 0, ..Default::default() }, "rounds"),
            (ExplorationSpec { setpoint_noise: f64::NAN, ..Default::default() }, "setpoint_noise"),
            (ExplorationSpec { torque_noise: -1.0, ..Default::default() }, "torque_noise"),
            (ExplorationSpec { oscillation_period: [1.0, 0.5], ..Default::default() }, "oscillation_period"),
            (ExplorationSpec { oscillation_period: [0.0, 0.5], ..Default::default() }, "oscillation_period"),
            (ExplorationSpec { torque_knot_interval: 0.0, ..Default::default() }, "torque_knot_interval"),
        ];
        for (spec, field) in bad {
            assert_eq!(spec.validate().unwrap_err().0, field, "{spec:?}");
        }
        ExplorationSpec::default().validate().unwrap();
    }

    #[test]
    fn halving_keeps_half_rounded_up() {
        assert_eq!((0..5).map(|r| survivors(16, r)).collect::<Vec<_>>(), [16, 8, 4, 2, 1]);
        assert_eq!((0..4).map(|r| survivors(5, r)).collect::<Vec<_>>(), [5, 3, 2, 1]);
        assert_eq!(survivors(1, 3), 1);
    }

    #[test]
    fn unknown_fields_are_refused() {
        let err = toml::from_str::<ExplorationSpec>("starts = 4\nnoise = 1").unwrap_err().to_string();
        assert!(err.contains("noise"), "{err}");
    }
}
