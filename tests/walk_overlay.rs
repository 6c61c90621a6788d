//! The drawings of a walk trial (`viz::walk`) against the trial's own plans, on the scenario
//! that re-plans (`pallet_appears`: the pallet is placed after the first plan): the
//! executed windows tile the plans in order, the overlay has every planned foothold, the
//! planned CoG and ZMP sampled over the windows, the ZMP inside the overlay's shrunk support
//! polygon at every sample (by the plan's own worst margin), and the figures are written.
//! The trial may fail (the walk is still being tuned): only the drawings are checked.

use legwork::model::embedded;
use legwork::terrain::Terrain;
use legwork::viz::walk::{executed_windows, plan_overlay, write_walk_plots, PATH_SAMPLE_INTERVAL};
use legwork::walk::trial::{run_trial, TrialSetup, WalkConfig};
use legwork::walk::ScenarioSpec;
use legwork::zmp::ConvexPolygon;
use nalgebra::Point2;

#[test]
fn overlay_and_figures_follow_the_trials_plans() {
    let model = embedded::load("hyq").unwrap();
    let spec = ScenarioSpec::embedded("pallet_appears").unwrap();
    let config = WalkConfig::hyq(&model).unwrap();
    let outcome = run_trial(&model, &spec, &config, TrialSetup::nominal(1), |_, _| {}).unwrap();
    let plans = &outcome.plans;
    assert!(!plans.is_empty(), "no plan: {:?}", outcome.failure);
    let end = outcome.trajectory.knots.last().unwrap().t;

    // Windows: from each plan's start to the next plan's start at the latest, in order.
    let windows = executed_windows(plans, end);
    assert_eq!(windows.len(), plans.len());
    for (k, &(a, b)) in windows.iter().enumerate() {
        let plan = &plans[k].plan;
        assert_eq!(a, plan.start_time);
        assert!(a <= b && b <= end && b <= plan.end_time() + 1e-12, "window {k}: {a}..{b}");
        if let Some(next) = windows.get(k + 1) {
            assert!(b <= next.0, "window {k} overlaps the next");
        }
    }

    let world = spec.world_at(f64::INFINITY);
    let overlay = plan_overlay(plans, &world, end);
    overlay.validate(model.feet.len()).unwrap();

    // Every footstep of every plan, in order, at its target; stepped on when its swing ended
    // within the plan's window.
    let steps: Vec<_> = plans.iter().zip(&windows).flat_map(|(r, w)| r.plan.footsteps.iter().map(move |s| (s, w.1))).collect();
    assert_eq!(overlay.footholds.len(), steps.len());
    for (f, (s, window_end)) in overlay.footholds.iter().zip(&steps) {
        assert_eq!((f.foot, f.position), (s.leg, [s.to.x, s.to.y, s.to.z]));
        assert_eq!(f.executed, f.t <= window_end + 1e-9);
    }

    // The CoG and the ZMP every 20 ms over each window, both ends included.
    let samples: usize = windows.iter().filter(|w| w.1 > w.0).map(|&(a, b)| ((b - a) / PATH_SAMPLE_INTERVAL).ceil() as usize + 1).sum();
    let [cog, zmp] = [&overlay.paths[0], &overlay.paths[1]];
    assert_eq!((cog.name.as_str(), zmp.name.as_str()), ("planned CoG", "planned ZMP (cart-table)"));
    assert_eq!((cog.t.len(), zmp.t.len()), (samples, samples));
    for (k, (&t, p)) in cog.t.iter().zip(&cog.points).enumerate() {
        let w = windows.iter().rposition(|w| w.0 <= t).unwrap();
        let c = plans[w].plan.cog_state(t).position;
        assert!((p[0] - c.x).abs() < 1e-12 && (p[1] - c.y).abs() < 1e-12, "CoG sample {k}");
    }

    // The ZMP lies on the ground, inside the shrunk support polygon the overlay shows at that
    // instant, by at least the plan's worst margin (the trial's 1 ms grid, and the QP's check
    // of both phases at each switch).
    for (&t, p) in zmp.t.iter().zip(&zmp.points) {
        let w = windows.iter().rposition(|w| w.0 <= t).unwrap();
        let plan = &plans[w].plan;
        let worst = plans[w].zmp_min_margin.min(plan.cog.check_zmp(0.001).worst_margin);
        assert_eq!(p[2], world.height(p[0], p[1]));
        let point = Point2::new(p[0], p[1]);
        let shown: Vec<f64> = overlay
            .supports
            .iter()
            .filter(|s| s.t0 <= t + 1e-9 && t <= s.t1 + 1e-9)
            .map(|s| ConvexPolygon::hull(&s.shrunk.iter().map(|v| Point2::new(v[0], v[1])).collect::<Vec<_>>()).unwrap().margin(point))
            .collect();
        assert!(!shown.is_empty(), "no support polygon shown at t = {t}");
        let margin = shown.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert!(margin >= worst - 1e-6, "t = {t}: ZMP margin {margin} in the shown polygon, plan's worst {worst}");
    }
    // The supports shown tile each window.
    for &(a, b) in windows.iter().filter(|w| w.1 > w.0) {
        let mut mine: Vec<(f64, f64)> = overlay.supports.iter().filter(|s| s.t0 >= a && s.t1 <= b).map(|s| (s.t0, s.t1)).collect();
        mine.sort_by(|x, y| x.0.total_cmp(&y.0));
        assert_eq!(mine.first().map(|s| s.0), Some(a));
        assert!((mine.last().unwrap().1 - b).abs() < 1e-9);
        assert!(mine.windows(2).all(|p| (p[0].1 - p[1].0).abs() < 1e-9), "gaps between the supports of window {a}..{b}");
    }

    // The figures: Fig. 8 shows the first plan's first three swings.
    let dir = std::env::temp_dir().join(format!("legwork-walk-overlay-{}", std::process::id()));
    let traj = outcome.trajectory.clone();
    assert!(traj.knots.windows(2).all(|w| w[0].t < w[1].t), "knot times increase strictly");
    let files = write_walk_plots(&model, plans, &traj, &dir).unwrap();
    assert_eq!(files.iter().map(|f| f.file_name().unwrap().to_str().unwrap()).collect::<Vec<_>>(), ["cog_zmp_support.svg", "cog_tracking.svg"]);
    let fig8 = std::fs::read_to_string(&files[0]).unwrap();
    let swings = plans[0].plan.swings.iter().flatten().count().min(3);
    let legend = fig8.lines().filter(|l| l.trim().starts_with("phase ") && l.trim().ends_with(" swings")).count();
    assert_eq!(legend, swings, "Fig. 8 legend");
    let tracking = std::fs::read_to_string(&files[1]).unwrap();
    assert!(tracking.contains("CoG tracking error"));
    std::fs::remove_dir_all(&dir).ok();
}
