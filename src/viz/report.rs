//! Report pages (`legwork report <dir>...`, and the pages `legwork bench slq` and `bench
//! terrain` write): one self-contained HTML file for one run or a set of runs, readable at a
//! glance. A summary table (one row per run: verdict, target checks met, the run's key
//! figures), then per run its target checks (the plan and every re-run side by side), its
//! key figures inline (the SVG plots, embedded: the page opens offline, with no other file),
//! a link to its replay, and the raw summary behind a disclosure. Extra sections (a bench's
//! own tables) come before the runs.

use super::VizError;
use serde_json::{Map, Value};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// The plots embedded in the page, in this order, when a run has them; the others are linked.
const KEY_PLOTS: [&str; 5] = ["cost.svg", "gait.svg", "base_pose.svg", "torque_limits.svg", "ground_forces.svg"];

/// The summary fields shown as figures in the summary table, when a run has them, with
/// their labels and how they are rounded.
const FIGURES: [(&str, &str, Rounding); 9] = [
    ("task_cost", "task cost", Rounding::Significant4),
    ("iterations", "iterations", Rounding::Decimals(0)),
    ("solve_time_s", "solve [s]", Rounding::Decimals(2)),
    ("final_base_height_m", "final z [m]", Rounding::Decimals(3)),
    ("final_horizontal_drift_m", "drift [m]", Rounding::Decimals(3)),
    ("goal_error_m", "goal error [m]", Rounding::Decimals(3)),
    ("speed_cm_s", "speed [cm/s]", Rounding::Decimals(1)),
    ("walking_time_s", "walking [s]", Rounding::Decimals(1)),
    ("max_torque_nm", "max torque [N m]", Rounding::Decimals(1)),
];

/// One run: a folder with a `trajectory.json` (from solve, simulate, walk or jump).
#[derive(Clone, Debug)]
pub struct ReportRun {
    /// The folder as given or found (its name in the page).
    pub name: String,
    pub folder: PathBuf,
    /// The summary of its `trajectory.json`.
    pub summary: Map<String, Value>,
    /// Its SVG plots (`plots/*.svg`), sorted.
    pub plots: Vec<PathBuf>,
    /// Its `replay.html`, if there is one.
    pub replay: Option<PathBuf>,
}

/// A section of a report before the runs: a heading and its HTML (a bench's table).
#[derive(Clone, Debug)]
pub struct ReportSection {
    pub heading: String,
    pub html: String,
}

/// The runs in `dirs`: each folder with a `trajectory.json` is a run; a folder without one
/// (a bench's output) contributes each sub-folder that has one, sorted by name. A folder
/// with neither is an error that names it.
pub fn find_runs(dirs: &[PathBuf]) -> Result<Vec<ReportRun>, VizError> {
    let mut runs = Vec::new();
    for dir in dirs {
        if dir.join("trajectory.json").is_file() {
            runs.push(read_run(dir, &dir.display().to_string())?);
            continue;
        }
        let entries = std::fs::read_dir(dir).map_err(|e| VizError::io(dir, e))?;
        let mut subs: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.join("trajectory.json").is_file()).collect();
        subs.sort();
        if subs.is_empty() {
            return Err(VizError::Report { path: dir.display().to_string(), problem: "neither it nor a folder in it has a trajectory.json (expected the output folder of legwork solve, simulate, walk or jump, or a folder of them)".into() });
        }
        for sub in subs {
            let name = sub.display().to_string();
            runs.push(read_run(&sub, &name)?);
        }
    }
    Ok(runs)
}

fn read_run(dir: &Path, name: &str) -> Result<ReportRun, VizError> {
    let path = dir.join("trajectory.json");
    let text = std::fs::read_to_string(&path).map_err(|e| VizError::io(&path, e))?;
    let value: Value = serde_json::from_str(&text).map_err(|e| VizError::Report { path: path.display().to_string(), problem: format!("not JSON: {e}") })?;
    let summary = match value.get("summary") {
        Some(Value::Object(map)) => map.clone(),
        None => Map::new(),
        Some(_) => return Err(VizError::Report { path: path.display().to_string(), problem: "summary: expected an object".into() }),
    };
    let mut plots: Vec<PathBuf> = std::fs::read_dir(dir.join("plots")).map(|entries| entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.extension().is_some_and(|x| x == "svg")).collect()).unwrap_or_default();
    plots.sort();
    let replay = Some(dir.join("replay.html")).filter(|p| p.is_file());
    Ok(ReportRun { name: name.to_string(), folder: dir.to_path_buf(), summary, plots, replay })
}

/// Text for HTML.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// `path` relative to `base` (both made absolute), with `/` separators, for a link.
fn relative_link(path: &Path, base: &Path) -> String {
    let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let (path, base) = (absolute(path), absolute(base));
    let (p, b): (Vec<_>, Vec<_>) = (path.components().collect(), base.components().collect());
    let common = p.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut parts: Vec<String> = std::iter::repeat_n("..".to_string(), b.len() - common).collect();
    parts.extend(p[common..].iter().map(|c| c.as_os_str().to_string_lossy().into_owned()));
    parts.join("/")
}

/// How a figure is rounded in the summary table.
#[derive(Clone, Copy, Debug)]
enum Rounding {
    /// This many decimal places.
    Decimals(usize),
    /// Four significant digits (costs, which span decades), exponent notation outside
    /// 0.01-10^4.
    Significant4,
}

/// A number rounded as `rounding` says, or the text as it is.
fn figure(value: &Value, rounding: Rounding) -> String {
    match (value.as_f64(), rounding) {
        (Some(x), Rounding::Significant4) if x != 0.0 && (x.abs() >= 1e4 || x.abs() < 1e-2) => format!("{x:.3e}"),
        (Some(x), Rounding::Significant4) => {
            let places = (3 - x.abs().log10().floor() as i32).clamp(0, 4) as usize;
            format!("{x:.places$}")
        }
        (Some(x), Rounding::Decimals(decimals)) => format!("{x:.decimals$}"),
        (None, _) => match value {
            Value::Null => "-".into(),
            Value::String(s) => s.clone(),
            other => other.to_string(),
        },
    }
}

/// One target check: `what (required)` and per run its value and whether it met the check
/// (`None`: the run failed).
type CheckRow = (String, Vec<Option<(String, bool)>>);

/// The target checks of a run: the runs' names and a row per check, from the summary's
/// `target` (`{run: [{what, required, value, met}] or "failed"}`).
fn target_rows(summary: &Map<String, Value>) -> (Vec<String>, Vec<CheckRow>) {
    let Some(Value::Object(target)) = summary.get("target") else { return (Vec::new(), Vec::new()) };
    let runs: Vec<String> = target.keys().cloned().collect();
    let first = target.values().find_map(Value::as_array).cloned().unwrap_or_default();
    let rows = first
        .iter()
        .enumerate()
        .map(|(i, check)| {
            let label = format!("{} ({})", check["what"].as_str().unwrap_or("?"), check["required"].as_str().unwrap_or("?"));
            let cells = target.values().map(|r| r.as_array().and_then(|a| a.get(i)).map(|c| (c["value"].as_str().unwrap_or("?").to_string(), c["met"].as_bool().unwrap_or(false)))).collect();
            (label, cells)
        })
        .collect();
    (runs, rows)
}

/// Checks met by the first run of the target (the plan) out of all: `(met, all)`.
fn plan_checks(summary: &Map<String, Value>) -> Option<(usize, usize)> {
    let Some(Value::Object(target)) = summary.get("target") else { return None };
    let plan = target.values().next()?.as_array()?;
    Some((plan.iter().filter(|c| c["met"].as_bool() == Some(true)).count(), plan.len()))
}

fn verdict_cell(summary: &Map<String, Value>) -> String {
    match summary.get("verdict").and_then(Value::as_str) {
        Some("met") => "<span class=met>met</span>".into(),
        Some(other) => format!("<span class=missed>{}</span>", escape(other)),
        None => "-".into(),
    }
}

/// The run's identity: its task, scenario or jump (a simulation: its controller), and robot.
fn what_ran(summary: &Map<String, Value>) -> String {
    let controller = summary.get("controller").and_then(Value::as_str).map(|c| format!("simulation, {c} controller"));
    let name = ["task", "scenario", "jump"].iter().find_map(|k| summary.get(*k).and_then(Value::as_str).map(String::from)).or(controller).unwrap_or_else(|| "-".into());
    let robot = summary.get("robot").and_then(Value::as_str).unwrap_or("");
    escape(&format!("{name}{}", if robot.is_empty() { String::new() } else { format!(" ({robot})") }))
}

/// A run's folder as seen from the page (`squat_jump`, `../out/gallop`).
fn display_name(run: &ReportRun, page_dir: &Path) -> String {
    match relative_link(&run.folder, page_dir) {
        empty if empty.is_empty() => run.name.clone(),
        name => name,
    }
}

/// The report page of `runs`, with `sections` before them; links are relative to
/// `page_dir`, the folder the page is written to.
pub fn report_html(title: &str, runs: &[ReportRun], sections: &[ReportSection], page_dir: &Path) -> Result<String, VizError> {
    let mut html = String::new();
    let _ = write!(
        html,
        "<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8><meta name=viewport content=\"width=device-width\"><title>{}</title><style>{CSS}</style></head><body>\n<h1>{}</h1>\n",
        escape(title),
        escape(title)
    );
    for s in sections {
        let _ = write!(html, "<section><h2>{}</h2>\n{}\n</section>\n", escape(&s.heading), s.html);
    }
    if !runs.is_empty() {
        let shown: Vec<&(&str, &str, Rounding)> = FIGURES.iter().filter(|(key, _, _)| runs.iter().any(|r| r.summary.contains_key(*key))).collect();
        html.push_str("<section><h2>Runs</h2>\n<table class=summary><thead><tr><th>run</th><th>what</th><th>verdict</th><th>target checks (plan)</th>");
        for (_, label, _) in &shown {
            let _ = write!(html, "<th>{}</th>", escape(label));
        }
        html.push_str("<th>replay</th></tr></thead><tbody>\n");
        for (i, run) in runs.iter().enumerate() {
            let checks = plan_checks(&run.summary).map_or("-".to_string(), |(met, all)| format!("{met} / {all}"));
            let _ = write!(html, "<tr><td><a href=\"#run{i}\">{}</a></td><td>{}</td><td>{}</td><td>{checks}</td>", escape(&display_name(run, page_dir)), what_ran(&run.summary), verdict_cell(&run.summary));
            for (key, _, rounding) in &shown {
                let _ = write!(html, "<td class=num>{}</td>", run.summary.get(*key).map_or("-".to_string(), |v| escape(&figure(v, *rounding))));
            }
            let replay = run.replay.as_ref().map_or("-".to_string(), |r| format!("<a href=\"{}\">replay</a>", escape(&relative_link(r, page_dir))));
            let _ = writeln!(html, "<td>{replay}</td></tr>");
        }
        html.push_str("</tbody></table></section>\n");
    }
    for (i, run) in runs.iter().enumerate() {
        run_section(&mut html, i, run, page_dir)?;
    }
    html.push_str("</body></html>\n");
    Ok(html)
}

fn run_section(html: &mut String, index: usize, run: &ReportRun, page_dir: &Path) -> Result<(), VizError> {
    let _ = writeln!(html, "<section id=run{index}><h2>{}: {} {}</h2>", escape(&display_name(run, page_dir)), what_ran(&run.summary), verdict_cell(&run.summary));
    if let Some(replay) = &run.replay {
        let _ = writeln!(html, "<p><a href=\"{}\">Open the replay</a> (3D view and plots with a time cursor).</p>", escape(&relative_link(replay, page_dir)));
    }
    let (columns, rows) = target_rows(&run.summary);
    if !rows.is_empty() {
        html.push_str("<table class=targets><thead><tr><th>target (plan; the runs at twice the tolerances)</th>");
        for c in &columns {
            let _ = write!(html, "<th>{}</th>", escape(c));
        }
        html.push_str("</tr></thead><tbody>\n");
        for (label, cells) in rows {
            let _ = write!(html, "<tr><td>{}</td>", escape(&label));
            for cell in cells {
                match cell {
                    Some((value, met)) => {
                        let _ = write!(html, "<td class={}>{} {}</td>", if met { "met" } else { "missed" }, escape(&value), if met { "&#10003;" } else { "&#10007;" });
                    }
                    None => html.push_str("<td class=missed>failed</td>"),
                }
            }
            html.push_str("</tr>\n");
        }
        html.push_str("</tbody></table>\n");
    }
    let key: Vec<&PathBuf> = KEY_PLOTS.iter().filter_map(|k| run.plots.iter().find(|p| p.file_name().is_some_and(|n| n == *k))).collect();
    if !key.is_empty() {
        html.push_str("<div class=figures>\n");
        for plot in &key {
            let svg = std::fs::read_to_string(plot).map_err(|e| VizError::io(plot, e))?;
            // Inline: the page stays one file. An XML declaration is not allowed mid-document.
            let body = svg.trim_start().strip_prefix("<?xml").and_then(|rest| rest.find("?>").map(|end| &rest[end + 2..])).unwrap_or(&svg);
            let _ = writeln!(html, "<figure>{}<figcaption>{}</figcaption></figure>", body.trim(), escape(&plot.file_name().unwrap_or_default().to_string_lossy()));
        }
        html.push_str("</div>\n");
    }
    let others: Vec<&PathBuf> = run.plots.iter().filter(|p| !key.contains(p)).collect();
    if !others.is_empty() {
        let links: Vec<String> = others.iter().map(|p| format!("<a href=\"{}\">{}</a>", escape(&relative_link(p, page_dir)), escape(&p.file_name().unwrap_or_default().to_string_lossy()))).collect();
        let _ = writeln!(html, "<p>More figures: {}</p>", links.join(", "));
    }
    let raw = serde_json::to_string_pretty(&run.summary).unwrap_or_default();
    let _ = writeln!(html, "<details><summary>Raw summary</summary><pre>{}</pre></details>\n</section>", escape(&raw));
    Ok(())
}

/// Writes the report page of `runs` (and `sections`) to `path`.
pub fn write_report(path: impl AsRef<Path>, title: &str, runs: &[ReportRun], sections: &[ReportSection]) -> Result<(), VizError> {
    let path = path.as_ref();
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| VizError::io(dir, e))?;
    let html = report_html(title, runs, sections, dir)?;
    std::fs::write(path, html).map_err(|e| VizError::io(path, e))
}

const CSS: &str = "body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:1.5em auto;max-width:1400px;padding:0 1em;color:#222}\
h1{font-size:1.5em}h2{font-size:1.15em;margin-top:1.8em;border-bottom:1px solid #ddd}\
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}th,td{border:1px solid #ddd;padding:.25em .55em;text-align:left;vertical-align:top}\
th{background:#f4f4f4}td.num{text-align:right;font-variant-numeric:tabular-nums}\
.met{color:#16803c}.missed{color:#b42318;font-weight:600}td.met{background:#eef8f0}td.missed{background:#fdf0ef}\
.figures{display:flex;flex-wrap:wrap;gap:1em}figure{margin:0;flex:1 1 600px;max-width:100%}figure svg{width:100%;height:auto}figcaption{font-size:.8em;color:#666}\
pre{background:#f8f8f8;padding:.6em;overflow-x:auto;font-size:.8em}";
