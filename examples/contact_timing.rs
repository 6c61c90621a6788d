//! Nguyen 2022's contact-timing optimization (sec. II-B) of the seven jumps with ipocp,
//! timed, and compared with the reference script's optima when its results file is given.
//!
//! ```text
//! cargo run --release --example contact_timing -- [--exp taylor4|exact] [--repeats 5]
//!     [--reference ../shared/anchors/nguyen2022/results_srb_costdt.json]
//!     [--barrier monotone|probing|quality-function|loqo] [--bound-push 1e-2] [--bound-frac 1e-2]
//!     [--threads 1] [jump ...]
//! ```
//!
//! `--threads N` (N > 1) turns on ipocp's parallel stage work on a rayon pool of N threads
//! (capped at the machine's cores); 1 (the default) is sequential.
//!
//! ```text
//! ```

use legwork::ipocp::Settings;
use legwork::jump::embedded_jumps;
use legwork::srb::{ContactTimingProblem, ContactTimingSettings, ExpMap, SrbParams};
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let mut exp_map = ExpMap::Taylor4;
    let mut repeats = 5;
    let mut reference: Option<serde_json::Value> = None;
    let mut names = Vec::new();
    let mut verbose = false;
    let mut barrier_update = ContactTimingProblem::solver_settings().barrier_update;
    let defaults = Settings::default();
    let (mut bound_push, mut bound_frac) = (defaults.bound_push, defaults.bound_frac);
    let mut threads = 1usize;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--exp" => {
                exp_map = match args.next().as_deref() {
                    Some("exact") => ExpMap::Exact,
                    Some("taylor4") => ExpMap::Taylor4,
                    other => anyhow::bail!("--exp: expected exact or taylor4, got {other:?}"),
                }
            }
            "--repeats" => repeats = args.next().ok_or_else(|| anyhow::anyhow!("--repeats: a number"))?.parse()?,
            "--reference" => {
                let path = args.next().ok_or_else(|| anyhow::anyhow!("--reference: a path"))?;
                reference = Some(serde_json::from_str(&std::fs::read_to_string(&path).map_err(|e| anyhow::anyhow!("{path}: {e}"))?)?);
            }
            "--verbose" => verbose = true,
            "--barrier" => barrier_update = args.next().ok_or_else(|| anyhow::anyhow!("--barrier: a rule"))?.parse().map_err(anyhow::Error::msg)?,
            "--bound-push" => bound_push = args.next().ok_or_else(|| anyhow::anyhow!("--bound-push: a number"))?.parse()?,
            "--threads" => threads = args.next().ok_or_else(|| anyhow::anyhow!("--threads: a number"))?.parse()?,
            "--bound-frac" => bound_frac = args.next().ok_or_else(|| anyhow::anyhow!("--bound-frac: a number"))?.parse()?,
            _ => names.push(a),
        }
    }
    let threads = threads.clamp(1, std::thread::available_parallelism().map_or(1, |n| n.get()));
    rayon::ThreadPoolBuilder::new().num_threads(threads).build_global()?;
    let params = SrbParams::a1()?;
    let all = embedded_jumps()?;
    let selected: Vec<_> = if names.is_empty() { all.clone() } else { all.iter().filter(|j| names.contains(&j.name)).cloned().collect() };
    println!("jump                 status      iters  cost          ref cost      rel.diff   T (10 ms)        ref T          viol      median s  (min s)  eval s  kkt s  solves");
    for file in &selected {
        // With a results file: the script's own problem, to compare like with like.
        let jump = if reference.is_some() { file.reference_srb() } else { file.srb() };
        // The script has no stance-speed bound.
        let max_stance_speed = if reference.is_some() { f64::INFINITY } else { file.contact_timing.max_stance_speed };
        let settings = ContactTimingSettings { exp_map, max_stance_speed, ..file.contact_timing.clone() };
        let ct = ContactTimingProblem::new(&jump, &params, &settings)?;
        let mut solver = ct.solver(Settings { verbose, barrier_update, bound_push, bound_frac, parallel: threads > 1, ..Settings::default() })?;
        let mut times = Vec::new();
        let mut result = None;
        for _ in 0..repeats.max(1) {
            let t = Instant::now();
            let r = ct.solve(&mut solver)?;
            times.push(t.elapsed().as_secs_f64());
            result = Some(r);
        }
        let r = result.expect("at least one solve");
        times.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        let t = ct.durations(&r.last.primal);
        let (ref_cost, ref_t) = reference
            .as_ref()
            .and_then(|v| v["results"].as_array()?.iter().find(|x| x["jump"].as_str() == file.anchor).cloned())
            .map(|x| (x["runs"][0]["cost"].as_f64().unwrap_or(f64::NAN), format!("{:?}", x["T_opt_10ms"].as_array().map(|a| a.iter().filter_map(|v| v.as_f64()).collect::<Vec<_>>()).unwrap_or_default())))
            .unwrap_or((f64::NAN, String::new()));
        println!(
            "{:20} {:11} {:5}  {:.10}  {:.10}  {:+.1e}  {:16} {:14} {:.1e}   {:.4}  ({:.4})  {:.4}  {:.4}  {}",
            jump.name,
            format!("{:?}", r.status),
            r.iterations,
            r.objective,
            ref_cost,
            (r.objective - ref_cost) / ref_cost,
            format!("{:?}", t.iter().map(|x| (x * 1000.0).round() / 10.0).collect::<Vec<_>>()),
            ref_t,
            r.primal_infeasibility,
            median,
            times[0],
            r.timings.evaluation.as_secs_f64(),
            r.timings.kkt.as_secs_f64(),
            r.kkt_solves
        );
    }
    Ok(())
}
