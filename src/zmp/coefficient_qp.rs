//! Test reference: the ZMP QP in its first formulation (Winkler 2015, sec. IV, as written in
//! the paper): the unknowns are every spline's quintic coefficients (12 per spline, in
//! normalized time), tied by equality rows for the initial state, eq. (4) at every junction
//! and the goal at rest; eq. (6) at the same samples as [`super::qp`]. The same convex
//! problem as the junction-state form of [`super::ZmpQp`] over a different set of unknowns,
//! so both must reach the same optimum (eq. 7 is strictly convex on the feasible set: the
//! accelerations fix the path once the initial position and velocity are given).

use super::phases::PlannedPhase;
use super::quintic::{acceleration_row, position_row, squared_acceleration_gram, velocity_row, zmp_row, Quintic};
use super::trajectory::{CogSpline, CogState};
use super::ZmpSettings;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::Point2;

const PER_SPLINE: usize = 12;

/// Solves the coefficient-form QP over the given plan phases (four-leg phases already
/// inserted) and returns its splines, or Clarabel's status if it did not solve.
pub(crate) fn solve(
    phases: &[PlannedPhase],
    settings: &ZmpSettings,
    initial: &CogState,
    goal: Point2<f64>,
) -> Result<Vec<CogSpline>, SolverStatus> {
    // Same layout as ZmpQp.
    let mut slots = Vec::new();
    for (index, planned) in phases.iter().enumerate() {
        let count = ((planned.phase.duration / settings.max_spline_duration) - 1e-9).ceil().max(1.0) as usize;
        let piece = planned.phase.duration / count as f64;
        for j in 0..count {
            slots.push((index, planned.start_time + j as f64 * piece, piece, j == 0));
        }
    }
    let n = PER_SPLINE * slots.len();
    // Cost eq. (7): dense upper triangle per spline and axis.
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for (s, &(_, _, duration, _)) in slots.iter().enumerate() {
        let gram = squared_acceleration_gram(duration);
        for (axis, weight) in [settings.weight_x, settings.weight_y].into_iter().enumerate() {
            for k in 0..6 {
                for (j, row) in gram.iter().enumerate().take(k + 1) {
                    if row[k] != 0.0 {
                        rowval.push(PER_SPLINE * s + 6 * axis + j);
                        nzval.push(2.0 * weight * row[k]);
                    }
                }
                colptr.push(rowval.len());
            }
        }
    }
    let p = CscMatrix::new(n, n, colptr, rowval, nzval);
    // Rows, dense per row (small problems only).
    let mut rows: Vec<(Vec<(usize, f64)>, f64)> = Vec::new();
    let boundary = |tau: f64, t: f64| [position_row(tau), velocity_row(tau, t), acceleration_row(tau, t)];
    for axis in 0..2 {
        let values = [initial.position[axis], initial.velocity[axis], initial.acceleration[axis]];
        for (row, value) in boundary(0.0, slots[0].2).iter().zip(values) {
            rows.push(((0..6).map(|k| (6 * axis + k, row[k])).collect(), value));
        }
    }
    for s in 0..slots.len() - 1 {
        let (end, next) = (boundary(1.0, slots[s].2), boundary(0.0, slots[s + 1].2));
        for axis in 0..2 {
            for (e, x) in end.iter().zip(&next) {
                let mut entries: Vec<(usize, f64)> = (0..6).map(|k| (PER_SPLINE * s + 6 * axis + k, e[k])).collect();
                entries.extend((0..6).map(|k| (PER_SPLINE * (s + 1) + 6 * axis + k, -x[k])));
                rows.push((entries, 0.0));
            }
        }
    }
    let last = slots.len() - 1;
    for axis in 0..2 {
        for (row, value) in boundary(1.0, slots[last].2).iter().zip([goal[axis], 0.0, 0.0]) {
            rows.push(((0..6).map(|k| (PER_SPLINE * last + 6 * axis + k, row[k])).collect(), value));
        }
    }
    let equalities = rows.len();
    for (s, &(phase, _, duration, first)) in slots.iter().enumerate() {
        let planned = &phases[phase];
        let intervals = (duration / settings.sample_interval - 1e-9).ceil().max(1.0) as usize;
        for j in usize::from(!first)..=intervals {
            let zmp = zmp_row(j as f64 / intervals as f64, duration, planned.phase.cog_height, settings.gravity);
            for edge in planned.shrunk_support.edges() {
                let mut entries: Vec<(usize, f64)> = (0..6).map(|k| (PER_SPLINE * s + k, -edge.p * zmp[k])).collect();
                entries.extend((0..6).map(|k| (PER_SPLINE * s + 6 + k, -edge.q * zmp[k])));
                rows.push((entries, edge.r));
            }
        }
    }
    let m = rows.len();
    let mut columns: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    for (r, (entries, _)) in rows.iter().enumerate() {
        for &(c, v) in entries {
            if v != 0.0 {
                columns[c].push((r, v));
            }
        }
    }
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for column in &columns {
        for &(r, v) in column {
            rowval.push(r);
            nzval.push(v);
        }
        colptr.push(rowval.len());
    }
    let a = CscMatrix::new(m, n, colptr, rowval, nzval);
    let b: Vec<f64> = rows.iter().map(|(_, value)| *value).collect();
    let cones = [SupportedConeT::ZeroConeT(equalities), SupportedConeT::NonnegativeConeT(m - equalities)];
    let solver_settings = DefaultSettingsBuilder::default().verbose(false).build().expect("default settings");
    let mut solver = DefaultSolver::new(&p, &vec![0.0; n], &a, &b, &cones, solver_settings).expect("valid problem");
    solver.solve();
    if solver.solution.status != SolverStatus::Solved {
        return Err(solver.solution.status);
    }
    let alpha = &solver.solution.x;
    Ok(slots
        .iter()
        .enumerate()
        .map(|(s, &(phase, start_time, duration, _))| CogSpline {
            start_time,
            duration,
            phase,
            x: Quintic::from_normalized(&alpha[PER_SPLINE * s..PER_SPLINE * s + 6], duration),
            y: Quintic::from_normalized(&alpha[PER_SPLINE * s + 6..PER_SPLINE * (s + 1)], duration),
        })
        .collect())
}
