//! Support phases: which feet stand where, for how long, and the four-leg support phases
//! Winkler 2015 inserts between disjoint support triangles (sec. IV-B, Fig. 5 and 8).
//!
//! A footstep sequence becomes an ordered list of [`SupportPhase`]s: three stance feet
//! while one leg swings, four during a four-leg support phase. With a stability margin
//! `d > 0` the shrunk support triangles of two consecutive swing phases can be disjoint
//! (always so when the swing moves to the diagonally opposite leg: both triangles have the
//! diagonal as an edge and lie on either side of it); the ZMP, continuous in time, could
//! not pass from one to the other. [`insert_four_leg_phases`] puts a short phase on all
//! four feet there, and only there: elsewhere the ZMP crosses directly through the
//! intersection of the two shrunk triangles.

use super::polygon::ConvexPolygon;
use super::ZmpError;
use nalgebra::Point2;
use std::fmt;

/// A foot that stays in stance across consecutive phases may not move by more than this (m).
pub const STANCE_FOOT_TOLERANCE: f64 = 1e-6;

/// A leg, in legwork's order LF, RF, LH, RH.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Leg {
    LF,
    RF,
    LH,
    RH,
}

impl Leg {
    /// All legs, in legwork's order (the index of each is [`Leg::index`]).
    pub const ALL: [Leg; 4] = [Leg::LF, Leg::RF, Leg::LH, Leg::RH];

    /// Position in [`Leg::ALL`] (and in per-leg arrays).
    pub fn index(self) -> usize {
        self as usize
    }

    /// The diagonally opposite leg (LF-RH, RF-LH).
    pub fn diagonal(self) -> Leg {
        match self {
            Leg::LF => Leg::RH,
            Leg::RF => Leg::LH,
            Leg::LH => Leg::RF,
            Leg::RH => Leg::LF,
        }
    }

    pub fn name(self) -> &'static str {
        crate::model::description::LEG_ORDER[self.index()]
    }
}

impl fmt::Display for Leg {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One support phase of the footstep sequence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SupportPhase {
    /// Ground position (x, y) of each foot in stance, indexed by [`Leg::index`]; `None` for
    /// the swinging leg. Three or four entries are `Some`.
    pub stance: [Option<Point2<f64>>; 4],
    /// Duration (s).
    pub duration: f64,
    /// Height of the CoG above the stance feet (m): `z_cog` of the cart-table model
    /// (eq. 5), constant during the phase (so `z̈_cog = 0`).
    pub cog_height: f64,
}

impl SupportPhase {
    /// All four feet in stance.
    pub fn four_leg(feet: [Point2<f64>; 4], duration: f64, cog_height: f64) -> Self {
        Self { stance: feet.map(Some), duration, cog_height }
    }

    /// `swing` in the air, the other three feet at `feet` (`feet[swing]` is ignored).
    pub fn swing(feet: [Point2<f64>; 4], swing: Leg, duration: f64, cog_height: f64) -> Self {
        let mut stance = feet.map(Some);
        stance[swing.index()] = None;
        Self { stance, duration, cog_height }
    }

    /// The leg in the air, `None` in a four-leg support phase (and for malformed phases with
    /// two legs in the air, which [`SupportPhase::validate`] rejects).
    pub fn swing_leg(&self) -> Option<Leg> {
        let mut swinging = Leg::ALL.into_iter().filter(|l| self.stance[l.index()].is_none());
        match (swinging.next(), swinging.next()) {
            (Some(leg), None) => Some(leg),
            _ => None,
        }
    }

    /// Number of feet in stance.
    pub fn stance_count(&self) -> usize {
        self.stance.iter().flatten().count()
    }

    /// Checks the numbers: 3 or 4 finite stance feet, positive finite duration and height.
    /// `index` names the phase in the error.
    pub fn validate(&self, index: usize) -> Result<(), ZmpError> {
        let bad = |field: String, expected: &'static str, got: String| ZmpError::InvalidPhase {
            phase: index,
            field,
            expected,
            got,
        };
        let count = self.stance_count();
        if !(3..=4).contains(&count) {
            return Err(bad("stance".into(), "3 or 4 feet in stance", format!("{count}")));
        }
        for leg in Leg::ALL {
            if let Some(foot) = self.stance[leg.index()] {
                if !(foot.x.is_finite() && foot.y.is_finite()) {
                    return Err(bad(
                        format!("stance[{leg}]"),
                        "a finite position",
                        format!("({}, {})", foot.x, foot.y),
                    ));
                }
            }
        }
        if !(self.duration > 0.0 && self.duration.is_finite()) {
            return Err(bad("duration".into(), "a positive number of seconds", format!("{}", self.duration)));
        }
        if !(self.cog_height > 0.0 && self.cog_height.is_finite()) {
            return Err(bad("cog_height".into(), "a positive number of metres", format!("{}", self.cog_height)));
        }
        Ok(())
    }

    /// The support polygon: convex hull of the stance feet.
    pub fn support_polygon(&self) -> Result<ConvexPolygon, super::polygon::PolygonError> {
        let mut points = [Point2::origin(); 4];
        let mut n = 0;
        for foot in self.stance.iter().flatten() {
            points[n] = *foot;
            n += 1;
        }
        ConvexPolygon::hull(&points[..n])
    }

    /// "swing LF" or "four-leg support".
    pub fn describe(&self) -> String {
        match self.swing_leg() {
            Some(leg) => format!("swing {leg}"),
            None => "four-leg support".into(),
        }
    }
}

/// Where a phase of the plan comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PhaseOrigin {
    /// Phase `index` of the given sequence.
    Given(usize),
    /// A four-leg support phase inserted between given phases `before - 1` and `before`
    /// because their shrunk support polygons are disjoint.
    Inserted { before: usize },
}

/// A phase of the plan actually optimized: the support phase, its place in time, and its
/// support polygon before and after shrinking by the stability margin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannedPhase {
    pub phase: SupportPhase,
    pub origin: PhaseOrigin,
    /// Start time (s) from the start of the plan.
    pub start_time: f64,
    /// Convex hull of the stance feet.
    pub support: ConvexPolygon,
    /// `support` shrunk by the stability margin `d`: the ZMP's allowed region (eq. 6).
    pub shrunk_support: ConvexPolygon,
}

impl PlannedPhase {
    pub fn end_time(&self) -> f64 {
        self.start_time + self.phase.duration
    }
}

impl fmt::Display for PlannedPhase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let origin = match self.origin {
            PhaseOrigin::Given(i) => format!("given phase {i}"),
            PhaseOrigin::Inserted { before } => format!("inserted before given phase {before}"),
        };
        write!(f, "{}, {origin}, t = {:.3}..{:.3} s", self.phase.describe(), self.start_time, self.end_time())
    }
}

/// True when the two shrunk support polygons do not overlap (touching counts as disjoint):
/// the ZMP cannot move from one to the other at a phase switch.
pub fn shrunk_supports_disjoint(before: &ConvexPolygon, after: &ConvexPolygon) -> bool {
    // Support polygons have at most 4 vertices, so the intersection always fits.
    !matches!(before.intersection(after), Ok(Some(_)))
}

/// The four-leg support phase between `before` and `after`: every foot where it stands in
/// `after`, or, for the leg about to swing in `after`, where it stood in `before`.
pub fn transition_phase(before: &SupportPhase, after: &SupportPhase, duration: f64) -> SupportPhase {
    let mut stance = after.stance;
    for leg in Leg::ALL {
        if stance[leg.index()].is_none() {
            stance[leg.index()] = before.stance[leg.index()];
        }
    }
    // Height: the phase it leads into (it starts shifting the body towards that phase).
    SupportPhase { stance, duration, cog_height: after.cog_height }
}

/// The phase list that is optimized: `phases` with a four-leg support phase of
/// `four_leg_duration` inserted wherever two consecutive shrunk support polygons are
/// disjoint (Winkler 2015, sec. IV-B), each phase with its start time and its support
/// polygon shrunk by `margin` (eq. 6).
///
/// Errors name the given phase: a malformed phase, a stance foot that moves between two
/// phases, or a support polygon too small for the margin.
pub fn insert_four_leg_phases(
    phases: &[SupportPhase],
    margin: f64,
    four_leg_duration: f64,
) -> Result<Vec<PlannedPhase>, ZmpError> {
    let mut planned = Vec::with_capacity(phases.len() * 2);
    insert_four_leg_phases_into(phases, margin, four_leg_duration, &mut planned)?;
    Ok(planned)
}

/// [`insert_four_leg_phases`] into a reused vector (cleared first).
pub fn insert_four_leg_phases_into(
    phases: &[SupportPhase],
    margin: f64,
    four_leg_duration: f64,
    planned: &mut Vec<PlannedPhase>,
) -> Result<(), ZmpError> {
    planned.clear();
    if !(margin >= 0.0 && margin.is_finite()) {
        return Err(ZmpError::InvalidSetting {
            field: "stability_margin",
            expected: "a finite number >= 0",
            value: margin,
        });
    }
    if !(four_leg_duration > 0.0 && four_leg_duration.is_finite()) {
        let expected = "a finite number > 0";
        return Err(ZmpError::InvalidSetting { field: "four_leg_duration", expected, value: four_leg_duration });
    }
    if phases.is_empty() {
        return Err(ZmpError::NoPhases);
    }
    let mut time = 0.0;
    for (index, phase) in phases.iter().enumerate() {
        phase.validate(index)?;
        let (support, shrunk_support) = support_and_shrunk(phase, margin, || format!("given phase {index}"))?;
        if let Some(previous) = planned.last().copied() {
            check_stance_feet_stay(&previous.phase, phase, index)?;
            if shrunk_supports_disjoint(&previous.shrunk_support, &shrunk_support) {
                let transition = transition_phase(&previous.phase, phase, four_leg_duration);
                let (t_support, t_shrunk) = support_and_shrunk(&transition, margin, || {
                    format!("four-leg phase inserted before given phase {index}")
                })?;
                planned.push(PlannedPhase {
                    phase: transition,
                    origin: PhaseOrigin::Inserted { before: index },
                    start_time: time,
                    support: t_support,
                    shrunk_support: t_shrunk,
                });
                time += four_leg_duration;
            }
        }
        planned.push(PlannedPhase {
            phase: *phase,
            origin: PhaseOrigin::Given(index),
            start_time: time,
            support,
            shrunk_support,
        });
        time += phase.duration;
    }
    Ok(())
}

fn support_and_shrunk(
    phase: &SupportPhase,
    margin: f64,
    // Only called on failure: no string is built on the way to a plan.
    describe: impl Fn() -> String,
) -> Result<(ConvexPolygon, ConvexPolygon), ZmpError> {
    let support = phase.support_polygon().map_err(|error| ZmpError::DegenerateSupport { phase: describe(), error })?;
    let shrunk = support.shrink(margin).ok_or_else(|| ZmpError::SupportTooSmall {
        phase: format!("{} ({})", describe(), phase.describe()),
        margin,
        inscribed_radius: support.inscribed_radius(),
    })?;
    Ok((support, shrunk))
}

/// A foot in stance in two consecutive phases cannot have moved.
fn check_stance_feet_stay(before: &SupportPhase, after: &SupportPhase, index: usize) -> Result<(), ZmpError> {
    for leg in Leg::ALL {
        if let (Some(a), Some(b)) = (before.stance[leg.index()], after.stance[leg.index()]) {
            if (a - b).norm() > STANCE_FOOT_TOLERANCE {
                return Err(ZmpError::StanceFootMoved { phase: index, leg, before: a, after: b });
            }
        }
    }
    Ok(())
}

/// One step of a footstep sequence: `leg` swings to `target`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footstep {
    pub leg: Leg,
    pub target: Point2<f64>,
}

/// Durations of the phases built by [`phases_from_footsteps`] (s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepTiming {
    /// Four-leg support before the first step (the robot starts standing).
    pub initial_stance: f64,
    /// Each swing phase.
    pub swing: f64,
    /// Four-leg support after the last step, during which the CoG comes to rest at the goal.
    pub final_stance: f64,
}

/// The support phases of a footstep sequence, starting from `initial_feet` (indexed by
/// [`Leg::index`]): a four-leg phase, one swing phase per step (the other three feet in
/// stance where they stand), and a final four-leg phase with every foot on its last target.
/// Four-leg transition phases are not inserted here: [`insert_four_leg_phases`] does it.
pub fn phases_from_footsteps(
    initial_feet: [Point2<f64>; 4],
    steps: &[Footstep],
    timing: StepTiming,
    cog_height: f64,
) -> Vec<SupportPhase> {
    let mut feet = initial_feet;
    let mut phases = Vec::with_capacity(steps.len() + 2);
    phases.push(SupportPhase::four_leg(feet, timing.initial_stance, cog_height));
    for step in steps {
        phases.push(SupportPhase::swing(feet, step.leg, timing.swing, cog_height));
        feet[step.leg.index()] = step.target;
    }
    phases.push(SupportPhase::four_leg(feet, timing.final_stance, cog_height));
    phases
}

#[cfg(test)]
mod tests {
    use super::*;

    /// HyQ's nominal stance: feet at (±0.37, ±0.33) m.
    fn hyq_feet() -> [Point2<f64>; 4] {
        [Point2::new(0.37, 0.33), Point2::new(0.37, -0.33), Point2::new(-0.37, 0.33), Point2::new(-0.37, -0.33)]
    }

    fn swing(leg: Leg) -> SupportPhase {
        SupportPhase::swing(hyq_feet(), leg, 0.6, 0.6)
    }

    fn inserted(planned: &[PlannedPhase]) -> Vec<usize> {
        planned
            .iter()
            .filter_map(|p| match p.origin {
                PhaseOrigin::Inserted { before } => Some(before),
                PhaseOrigin::Given(_) => None,
            })
            .collect()
    }

    /// On a nominal stance, the geometric test agrees with the paper's rule: a four-leg
    /// phase between two swing phases exactly when the second swing leg is the diagonal of
    /// the first.
    #[test]
    fn four_leg_phase_only_between_diagonal_swings_on_nominal_stance() {
        for a in Leg::ALL {
            for b in Leg::ALL {
                if a == b {
                    continue;
                }
                let planned = insert_four_leg_phases(&[swing(a), swing(b)], 0.05, 0.2).unwrap();
                let expect = b == a.diagonal();
                assert_eq!(inserted(&planned), if expect { vec![1] } else { vec![] }, "{a} -> {b}");
                if expect {
                    // All four feet at their places, inserted between the two, times shifted.
                    let t = &planned[1];
                    assert_eq!(t.phase.stance, hyq_feet().map(Some));
                    assert_eq!((t.start_time, planned[2].start_time), (0.6, 0.8));
                    // It contains both shrunk triangles.
                    for v in planned[0].shrunk_support.vertices().iter().chain(planned[2].shrunk_support.vertices()) {
                        assert!(t.shrunk_support.margin(*v) > -1e-12);
                    }
                }
            }
        }
    }

    /// Same-side swings (RH then RF) share the triangle (LF, LH, centre) of the nominal
    /// stance: its inradius r* = 2A / perimeter is the largest margin for which the shrunk
    /// triangles still overlap. Below it no phase is inserted; above it one is, although
    /// the legs are not diagonal (the geometric test is the general form of the paper's).
    #[test]
    fn four_leg_phase_for_same_side_swings_only_when_margin_exceeds_overlap_inradius() {
        let (lf, lh, centre) = (Point2::new(0.37, 0.33), Point2::new(-0.37, 0.33), Point2::new(0.0, 0.0));
        let area = 0.5 * 0.74 * 0.33;
        let r_star: f64 = 2.0 * area / ((lf - lh).norm() + (lf - centre).norm() + (lh - centre).norm());
        assert!((r_star - 0.14102).abs() < 1e-4, "{r_star}");
        let pair = [swing(Leg::RH), swing(Leg::RF)];
        assert_eq!(inserted(&insert_four_leg_phases(&pair, r_star - 1e-4, 0.2).unwrap()), Vec::<usize>::new());
        assert_eq!(inserted(&insert_four_leg_phases(&pair, r_star + 1e-4, 0.2).unwrap()), vec![1]);
    }

    /// Irregular sequences: after a four-leg phase nothing is inserted (its polygon contains
    /// every triangle of its feet), and only the diagonal switches of a crawl get one.
    #[test]
    fn crawl_gets_a_four_leg_phase_at_each_diagonal_switch() {
        let step = 0.15;
        let order = [Leg::RH, Leg::RF, Leg::LH, Leg::LF, Leg::RH, Leg::RF, Leg::LH, Leg::LF];
        let mut feet = hyq_feet();
        let steps: Vec<Footstep> = order
            .iter()
            .map(|&leg| {
                feet[leg.index()].x += step;
                Footstep { leg, target: feet[leg.index()] }
            })
            .collect();
        let timing = StepTiming { initial_stance: 0.8, swing: 0.6, final_stance: 0.8 };
        let phases = phases_from_footsteps(hyq_feet(), &steps, timing, 0.6);
        assert_eq!(phases.len(), 10);
        let planned = insert_four_leg_phases(&phases, 0.05, 0.25).unwrap();
        // Given phase i + 1 swings order[i]: RF -> LH (given 2 -> 3), LF -> RH (4 -> 5), ...
        assert_eq!(inserted(&planned), vec![3, 5, 7]);
        let total: f64 = phases.iter().map(|p| p.duration).sum::<f64>() + 3.0 * 0.25;
        let last = planned.last().unwrap();
        assert!((last.end_time() - total).abs() < 1e-12);
        for pair in planned.windows(2) {
            assert!(!shrunk_supports_disjoint(&pair[0].shrunk_support, &pair[1].shrunk_support));
            assert_eq!(pair[0].end_time(), pair[1].start_time);
        }
    }

    #[test]
    fn errors_name_the_phase_and_the_field() {
        let mut bad = swing(Leg::LF);
        bad.duration = f64::NAN;
        let e = insert_four_leg_phases(&[swing(Leg::RH), bad], 0.05, 0.2).unwrap_err().to_string();
        assert!(e.contains("phase 1") && e.contains("duration") && e.contains("NaN"), "{e}");

        let mut two_up = swing(Leg::LF);
        two_up.stance[Leg::RF.index()] = None;
        let e = insert_four_leg_phases(&[two_up], 0.05, 0.2).unwrap_err().to_string();
        assert!(e.contains("phase 0") && e.contains("3 or 4 feet"), "{e}");

        let e = insert_four_leg_phases(&[swing(Leg::LF)], 0.25, 0.2).unwrap_err().to_string();
        assert!(e.contains("given phase 0") && e.contains("swing LF") && e.contains("0.204"), "{e}");

        let mut moved = swing(Leg::RF);
        moved.stance[Leg::LH.index()] = Some(Point2::new(-0.30, 0.33));
        let e = insert_four_leg_phases(&[swing(Leg::LF), moved], 0.05, 0.2).unwrap_err();
        assert!(matches!(e, ZmpError::StanceFootMoved { phase: 1, leg: Leg::LH, .. }), "{e}");

        assert!(matches!(insert_four_leg_phases(&[], 0.05, 0.2), Err(ZmpError::NoPhases)));
        let e = insert_four_leg_phases(&[swing(Leg::LF)], f64::NAN, 0.2).unwrap_err().to_string();
        assert!(e.contains("`stability_margin`"), "{e}");
    }
}
