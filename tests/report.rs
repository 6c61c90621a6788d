//! `legwork report` and the report pages of the benches: one self-contained page per run or
//! set of runs, with the verdicts, the target checks side by side, the key figures inline and
//! links to the replays; bad folders named.

mod common;

use legwork::viz::{self, report};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::Command;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("legwork-report-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A run folder as `legwork solve` writes one: trajectory.json with a summary, replay.html,
/// plots.
fn run_folder(dir: &Path, verdict: &str, apex: (&str, bool)) {
    let (model, mut traj) = common::hyq_trot(0.5);
    let check = |value: &str, met: bool| json!([{ "what": "base z at the apex", "required": "0.800 +- 0.010 m", "value": value, "met": met }, { "what": "lift-offs per foot", "required": ">= 1", "value": "2/2/2/2", "met": true }]);
    let summary = json!({
        "task": "trot_like", "robot": "hyq", "verdict": verdict, "task_cost": 1234.5678, "iterations": 12, "solve_time_s": 1.5,
        "target": { "plan": check(apex.0, apex.1), "SLQ policy": check("0.700 m", false), "tracking ctrl": "failed" },
    });
    traj.summary = summary.as_object().unwrap().clone();
    std::fs::create_dir_all(dir).unwrap();
    traj.save_file(dir.join("trajectory.json")).unwrap();
    viz::write_replay(&model, &traj, dir.join("replay.html")).unwrap();
    viz::write_plots(&traj, dir.join("plots")).unwrap();
    viz::write_cost_plot(&[10.0, 5.0, 1.0], "cost", dir.join("plots").join("cost.svg")).unwrap();
}

#[test]
fn a_set_of_runs_is_one_self_contained_page() {
    let dir = temp_dir("set");
    run_folder(&dir.join("bench").join("a"), "met", ("0.801 m", true));
    run_folder(&dir.join("bench").join("b"), "missed", ("0.650 m", false));
    let runs = report::find_runs(&[dir.join("bench")]).unwrap();
    assert_eq!(runs.iter().map(|r| r.folder.file_name().unwrap().to_str().unwrap()).collect::<Vec<_>>(), ["a", "b"]);
    let page = dir.join("bench").join("report.html");
    report::write_report(&page, "two runs <&>", &runs, &[report::ReportSection { heading: "A bench's table".into(), html: "<table><tr><td>42</td></tr></table>".into() }]).unwrap();
    let html = std::fs::read_to_string(&page).unwrap();
    // One file: no scripts, styles or images from elsewhere (the SVGs' xmlns is a name, not a request).
    let lower = html.to_lowercase();
    for needle in ["src=\"http", "href=\"http", "<script", "<link", "@import", "url("] {
        assert!(!lower.contains(needle), "the page references '{needle}'");
    }
    assert!(html.contains("<title>two runs &lt;&amp;&gt;</title>"));
    assert!(html.find("A bench&#39;s table").unwrap() < html.find("<h2>Runs</h2>").unwrap());
    // The summary table: each run's verdict, checks met by the plan, figures, replay link.
    assert!(html.contains("<span class=met>met</span>") && html.contains("<span class=missed>missed</span>"));
    assert!(html.contains("<td>2 / 2</td>") && html.contains("<td>1 / 2</td>"));
    assert!(html.contains("<td class=num>1235</td>"), "task cost to 4 significant digits");
    assert!(html.contains("<a href=\"a/replay.html\">replay</a>") && html.contains("<a href=\"b/replay.html\">"));
    // Each run: the target checks of the plan and the re-runs side by side, met or not.
    assert!(html.contains("<td class=met>0.801 m &#10003;</td>") && html.contains("<td class=missed>0.650 m &#10007;</td>"));
    assert!(html.contains("<td class=missed>failed</td>"), "a failed re-run is a column of 'failed'");
    // The key figures inline (cost, gait, base pose per run), the others linked.
    assert_eq!(html.matches("<figure><svg").count(), 2 * 3, "{}", html.matches("<figcaption>").count());
    assert!(html.contains("More figures: <a href=\"a/plots/base_twist.svg\">"));
    assert!(html.contains("<details><summary>Raw summary</summary>"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_folder_without_runs_is_named() {
    let dir = temp_dir("empty");
    let err = report::find_runs(std::slice::from_ref(&dir)).unwrap_err().to_string();
    assert!(err.contains(&dir.display().to_string()) && err.contains("trajectory.json"), "{err}");
    let out = Command::new(env!("CARGO_BIN_EXE_legwork")).args(["report", dir.to_str().unwrap()]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("trajectory.json"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn legwork_report_writes_the_page_beside_the_runs() {
    let dir = temp_dir("cli");
    run_folder(&dir.join("one"), "met", ("0.801 m", true));
    let out = Command::new(env!("CARGO_BIN_EXE_legwork")).args(["report", dir.join("one").to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let html = std::fs::read_to_string(dir.join("one").join("report.html")).unwrap();
    assert!(html.contains("<a href=\"replay.html\">replay</a>"), "the run's own folder: a link beside the page");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bench_terrain_writes_table_i_beside_legworks() {
    let dir = temp_dir("terrain");
    let out = Command::new(env!("CARGO_BIN_EXE_legwork")).args(["bench", "terrain", "--trials", "1", "--out", dir.to_str().unwrap()]).output().unwrap();
    assert!(matches!(out.status.code(), Some(0 | 1)), "{}", String::from_utf8_lossy(&out.stderr));
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(html.contains("Winkler 2015, Table I") && !html.to_lowercase().contains("<script"));
    // The paper's four rows, each with the paper's speed and success beside legwork's.
    for (terrain, speed, success) in [("stepping_stones", "7.3", "60 %"), ("pallet", "9.5", "100 %"), ("two_pallets", "10.2", "90 %"), ("gap", "12.7", "90 %")] {
        let row = html.split("<tr><td>").find(|r| r.starts_with(&format!("{terrain}<"))).unwrap_or_else(|| panic!("no row for {terrain}"));
        assert!(row.contains(&format!("<td class=num>{speed}</td><td class=num>{success}</td>")), "{row}");
        assert!(row.contains("(1/1)") || row.contains("(0/1)"), "{row}");
    }
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["terrains"].as_array().unwrap().len(), 4);
    std::fs::remove_dir_all(&dir).unwrap();
}
