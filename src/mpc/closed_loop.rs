//! The receding-horizon controller in closed loop with a plant: legwork's simulator or
//! MuJoCo ([`crate::sim::Plant`]).
//!
//! The solver runs in its own thread; the plant in the calling thread, in simulated
//! time, in lock step with it as a robot's control loop is with the wall clock:
//!
//! ```text
//! tick i at t_i: the plant's state goes to the solver (the "measurement")
//! its policy comes L_i seconds later (measured wall time, or a fixed latency)
//! [t_i, t_i + L_i): the robot runs the previous policy
//! from t_i + L_i: the new one
//! t_{i+1} = t_i + period * max(1, ceil(L_i / period))   (an overrun skips ticks)
//! ```
//!
//! With [`super::MpcSettings::prepare_ahead`] the solver moves the window on to `t_{i+1}`
//! and prepares that tick's model and backward pass ([`Mpc::prepare`]) right after tick
//! `i`'s policy is out, so `L_i` is the feedback phase's time (the rollouts from the
//! measurement) plus whatever of the preparation was still running at `t_i`; without it,
//! the whole tick's. The next tick then also leaves the solver time to prepare it (tick
//! `i`'s own preparation time `P_i` as the estimate; a fixed latency assumes it fits):
//!
//! ```text
//! t_{i+1} = t_i + period * max(1, ceil((L_i + P_i) / period))
//! ```
//!
//! so a solver slower than the rate skips ticks rather than keep measurements waiting.
//!
//! A tick that fails keeps the previous policy running (a tick whose measurement is not a
//! valid state fails at once, the solver's solution left as it was); its `L_i` is still its
//! wall time (or the fixed latency), and its solve time counts in the tick-time percentiles.
//!
//! While the solver works the plant waits (its steps take microseconds; a robot's
//! physics would not wait, which the latency above accounts for): the solver has the
//! machine's cores to itself, as it would on the robot's computer.

use super::{Mpc, MpcError, MpcPolicy, MpcPolicyController, TickReport};
use crate::io::Trajectory;
use crate::ocp::RobotState;
use crate::sim::{Plant, SimError};
use crate::slq::{set_realtime_priority, RealtimePriorityError};
use std::sync::mpsc;
use std::time::Instant;

/// When a tick's solution reaches the robot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PolicyLatency {
    /// After the solve's measured wall time (as on a robot; the run depends on the machine).
    /// The next tick starts as soon as the plant has stepped to its time: the solver runs
    /// tick after tick with no pause, faster than real time.
    Measured,
    /// As [`Self::Measured`], and each tick starts no earlier than its time on the wall
    /// clock (tick `i` at `t_i` seconds after the loop's start), as a robot's control loop:
    /// the solver idles for the rest of each period, and the run takes the task's duration.
    Paced,
    /// After this many seconds whatever the solve took (reproducible runs).
    Fixed(f64),
}

impl PolicyLatency {
    /// `measured`, `paced` or the seconds (the summaries' `latency`).
    pub fn to_json(self) -> serde_json::Value {
        match self {
            Self::Measured => "measured".into(),
            Self::Paced => "paced".into(),
            Self::Fixed(l) => l.into(),
        }
    }
}

/// One tick of a closed-loop run.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TickRecord {
    /// The tick's time (s).
    pub t: f64,
    /// Wall time of the solve (s), a failed one's too; with the tick prepared ahead, its
    /// preparation's too.
    pub solve_time: f64,
    /// The solve's two parts (s): its preparation before the measurement (0 if not prepared
    /// ahead) and the rest, from the measurement's arrival at the solver to the policy.
    pub preparation_time: f64,
    pub feedback_time: f64,
    /// When after `t` its policy took over (s): its feedback time, after the rest of the
    /// previous tick's preparation if that was still running at `t`; for a failed tick, when
    /// the solver was free again (the next tick waits for it as for a policy).
    pub latency: f64,
    /// Cost of the kept trajectory, its step size, iterations run; `None` if the tick failed
    /// or kept a trajectory held after [`Self::held_after_knot`] (no finite cost).
    pub cost: Option<f64>,
    pub alpha: Option<f64>,
    /// The Levenberg-Marquardt regularization of `H` after the tick.
    pub regularization: Option<f64>,
    pub iterations: usize,
    /// The tick restarted from the plan's policy (the shifted solution had failed).
    pub restarted: bool,
    /// Seconds in the tick's linearizations, backward passes (overlapped with them on two
    /// or more threads: the pass's own time) and trial rollouts.
    pub linearization_time: f64,
    pub backward_pass_time: f64,
    pub rollout_time: f64,
    /// Why the tick gave no policy (the previous one kept running).
    pub failure: Option<String>,
    /// Every trial of the tick left the valid states (a joint past the speed limit); the
    /// kept one did after this window knot, its later knots held there
    /// ([`crate::slq::RealTimeIteration::held_after`]). Its policy runs.
    pub held_after_knot: Option<usize>,
}

/// A closed-loop run: the recorded motion, every tick, and how it ended.
pub struct ClosedLoopRun {
    pub trajectory: Trajectory,
    pub ticks: Vec<TickRecord>,
    /// `Some(reason)` if the simulation stopped early (diverged).
    pub stopped: Option<String>,
}

impl ClosedLoopRun {
    /// The `p`-th percentile (0-100) of the ticks' solve times (s), nearest rank.
    pub fn tick_time_percentile(&self, p: f64) -> f64 {
        percentile(self.ticks.iter().map(|t| t.solve_time).collect(), p)
    }
}

/// The `p`-th percentile (0-100) of `values`, nearest rank (0 for none).
pub fn percentile(mut values: Vec<f64>, p: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    let rank = ((p / 100.0) * values.len() as f64).ceil().max(1.0) as usize;
    values[rank.min(values.len()) - 1]
}

struct Request {
    t: f64,
    x: RobotState,
    policy: MpcPolicy,
}

struct Reply {
    x: RobotState,
    policy: MpcPolicy,
    report: Result<TickReport, MpcError>,
    /// Wall time of the tick (s), measured around it (a failed tick has no report).
    elapsed: f64,
    /// When after the tick's time its policy was out, or the solver free after a failed
    /// tick (s): the tick after any wait for the last preparation (module docs); the fixed
    /// latency with [`PolicyLatency::Fixed`].
    latency: f64,
    /// The next tick's time (s), the one the solver prepared (module docs).
    next_tick: f64,
    /// The tick's preparation before its measurement (s; 0 without).
    preparation: f64,
}

/// The tick after one at `t` whose policy came `latency` seconds later: the next period
/// boundary from then on, at least one period on (an overrun skips ticks).
fn next_tick(t: f64, latency: f64, period: f64) -> f64 {
    t + (latency / period - 1e-9).ceil().max(1.0) * period
}

/// Runs `mpc` on `sim` for `duration` seconds (module docs), recording the motion at the
/// simulator's recording rate; `on_tick` sees every tick.
pub fn run_closed_loop(mut mpc: Mpc<'_, '_>, sim: &mut dyn Plant, duration: f64, latency: PolicyLatency, mut on_tick: impl FnMut(&TickRecord)) -> Result<ClosedLoopRun, MpcError> {
    if !(duration.is_finite() && duration > 0.0) {
        return Err(MpcError::Settings { field: "duration", problem: format!("expected a positive number of seconds, got {duration}") });
    }
    if let PolicyLatency::Fixed(l) = latency {
        if !(l.is_finite() && l >= 0.0) {
            return Err(MpcError::Settings { field: "latency", problem: format!("expected a finite number of seconds >= 0, got {l}") });
        }
    }
    let problem = mpc.problem();
    let period = mpc.settings().period();
    let physics_dt = sim.physics_dt();
    let mut first = MpcPolicy::for_problem(problem);
    mpc.write_policy(&mut first);
    let mut controller = MpcPolicyController::new(problem, first, mpc.settings().feedback);
    let mut spare = Some(MpcPolicy::for_problem(problem));
    let mut measured = Some(problem.initial.clone());
    let mut trajectory = Trajectory::new(problem.model, format!("mpc at {} Hz", mpc.settings().rate), sim.record_dt(), problem.terrain.spec());
    let mut ticks = Vec::new();
    let mut stopped = None;
    // Steps until the simulator's time reaches `t` (within half a physics step).
    let step_until = |sim: &mut dyn Plant, controller: &mut MpcPolicyController<'_, '_>, trajectory: &mut Trajectory, t: f64| -> Result<(), SimError> {
        while sim.state().t < t.min(duration) - 0.5 * physics_dt {
            sim.step_recorded(controller, trajectory)?;
        }
        Ok(())
    };
    let (to_solver, requests) = mpsc::sync_channel::<Request>(1);
    let (to_loop, replies) = mpsc::sync_channel::<Reply>(1);
    let priority = mpc.settings().realtime_priority;
    let (to_starter, started) = mpsc::sync_channel::<Result<(), RealtimePriorityError>>(1);
    std::thread::scope(|scope| -> Result<(), MpcError> {
        scope.spawn(move || {
            // The solver's own thread runs the tick's serial parts; its pool's threads
            // already run at the priority (Slq::new).
            let scheduled = priority.map_or(Ok(()), set_realtime_priority);
            let refused = scheduled.is_err();
            if to_starter.send(scheduled).is_err() || refused {
                return;
            }
            let prepare_ahead = mpc.settings().prepare_ahead;
            // The first tick's, before the robot starts (it waits for its first plan).
            let mut last_preparation = if prepare_ahead { mpc.prepare(0.0) } else { 0.0 };
            // When the solver was free again after its last preparation, in the task's time:
            // the last tick's time, its latency and the preparation after it. (Paced too: a
            // request that reaches the solver after its time on the wall clock because the
            // simulated plant took long to step does not make the solver late, as a robot's
            // physics would not have.)
            let mut free_at = 0.0;
            let loop_started = Instant::now();
            for Request { t, x, mut policy } in requests {
                if latency == PolicyLatency::Paced {
                    // Tick i's measurement is due t_i after the loop's start.
                    let due = loop_started + std::time::Duration::from_secs_f64(t);
                    std::thread::sleep(due.saturating_duration_since(Instant::now()));
                }
                let started = Instant::now();
                let report = mpc.tick(t, &x);
                let elapsed = started.elapsed().as_secs_f64();
                if report.is_ok() {
                    mpc.write_policy(&mut policy);
                }
                // A measurement due while the solver still prepared waited for it.
                let policy_latency = match latency {
                    PolicyLatency::Measured | PolicyLatency::Paced => (free_at - t).max(0.0) + elapsed,
                    PolicyLatency::Fixed(l) => l,
                };
                // The next tick leaves the solver time to prepare it (this tick's preparation
                // time as the estimate), and is prepared before the reply: the plant steps
                // after it, the solver having the cores to itself meanwhile, as without it.
                let preparation = last_preparation;
                let busy = match latency {
                    PolicyLatency::Fixed(_) => policy_latency,
                    _ => policy_latency + preparation,
                };
                let next = next_tick(t, busy, period);
                if prepare_ahead && next < duration - 0.5 * physics_dt {
                    last_preparation = mpc.prepare(next);
                    free_at = t + policy_latency + last_preparation;
                }
                if to_loop.send(Reply { x, policy, report, elapsed, latency: policy_latency, next_tick: next, preparation }).is_err() {
                    break;
                }
            }
        });
        if let Ok(Err(e)) = started.recv() {
            return Err(MpcError::Settings { field: "realtime_priority", problem: e.to_string() });
        }
        let mut t_tick = 0.0;
        let result = (|| -> Result<(), SimError> {
            while t_tick < duration - 0.5 * physics_dt {
                let mut x = measured.take().expect("the measurement buffer is back from the solver");
                let s = sim.state();
                x.q.copy_from(&s.q);
                x.v.copy_from(&s.v);
                x.anchors.clone_from(&s.anchors);
                let policy = spare.take().expect("the policy buffer is back from the solver");
                if to_solver.send(Request { t: t_tick, x, policy }).is_err() {
                    break;
                }
                let Ok(reply) = replies.recv() else { break };
                measured = Some(reply.x);
                let reply_next_tick = reply.next_tick;
                let (record, new_policy) = match reply.report {
                    Ok(report) => {
                        let last = report.iterations.last();
                        (TickRecord { t: t_tick, solve_time: report.solve_time, preparation_time: report.preparation_time, feedback_time: report.feedback_time, latency: reply.latency, cost: report.cost.is_finite().then_some(report.cost), held_after_knot: report.iterations.iter().rev().find_map(|i| i.held_after).filter(|_| !report.cost.is_finite()), alpha: last.map(|i| i.alpha), regularization: last.map(|i| i.regularization), iterations: report.iterations.len(), restarted: report.restarted, linearization_time: report.iterations.iter().map(|i| i.timing.linearization).sum(), backward_pass_time: report.iterations.iter().map(|i| i.timing.backward_pass).sum(), rollout_time: report.iterations.iter().map(|i| i.timing.line_search).sum(), failure: None }, Some(reply.policy))
                    }
                    Err(e) => {
                        spare = Some(reply.policy);
                        // The solver was busy for the failed tick's time: the next tick
                        // comes after it, as after a policy.
                        (TickRecord { t: t_tick, solve_time: reply.preparation + reply.elapsed, preparation_time: reply.preparation, feedback_time: reply.elapsed, latency: reply.latency, cost: None, alpha: None, regularization: None, iterations: 0, restarted: false, linearization_time: 0.0, backward_pass_time: 0.0, rollout_time: 0.0, failure: Some(e.to_string()), held_after_knot: None }, None)
                    }
                };
                step_until(sim, &mut controller, &mut trajectory, t_tick + record.latency)?;
                if let Some(mut policy) = new_policy {
                    controller.swap_policy(&mut policy);
                    spare = Some(policy);
                }
                t_tick = reply_next_tick;
                on_tick(&record);
                ticks.push(record);
                step_until(sim, &mut controller, &mut trajectory, t_tick)?;
            }
            Ok(())
        })();
        drop(to_solver);
        if let Err(e) = result {
            stopped = Some(match e {
                SimError::Diverged { step, t, reason, .. } => format!("diverged at t = {t:.3} s (step {step}): {reason}"),
                SimError::External { .. } => return Err(MpcError::Plant(e)),
                e => e.to_string(),
            });
        }
        Ok(())
    })?;
    if stopped.is_none() {
        sim.record_final(&mut trajectory).map_err(MpcError::Plant)?;
    }
    Ok(ClosedLoopRun { trajectory, ticks, stopped })
}

#[cfg(test)]
mod tests {
    use super::percentile;

    #[test]
    fn percentiles_are_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(percentile(v.clone(), 50.0), 50.0);
        assert_eq!(percentile(v.clone(), 99.0), 99.0);
        assert_eq!(percentile(v, 100.0), 100.0);
        assert_eq!(percentile(vec![3.0, 1.0, 2.0], 50.0), 2.0);
        assert_eq!(percentile(vec![], 99.0), 0.0);
    }
}
