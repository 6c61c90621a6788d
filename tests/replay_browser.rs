//! The HTML replay in a real browser: Debian's `chromium`, headless (installed by
//! `scripts/install-test-deps.sh`). The page must load with no console error, mark that it
//! drew its first frame (`<body data-drawn="1">`), keep its error box hidden, and the
//! screenshot must show the robot in the 3D view (varied pixels, leg colours present).
//!
//! With a plan overlay (planned footholds, a CoG and a ZMP path, a support polygon) the page
//! must also say so (`<body data-overlay="N">`, N the items drawn) and the screenshot show the
//! path's and the footholds' colours; without one it must not.
//!
//! Without chromium the tests fail when `CI` is set, and otherwise say they skipped.
//! `LEGWORK_REPLAY_ARTIFACTS=DIR` keeps the page, the DOM, the screenshot, chromium's logs,
//! the trajectory and its SVG plots in DIR (to look at them).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const WIDTH: u32 = 1280;
const HEIGHT: u32 = 800;

fn find_chromium() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    ["chromium", "chromium-browser"]
        .iter()
        .flat_map(|name| std::env::split_paths(&path).map(move |dir| dir.join(name)))
        .find(|p| p.is_file())
}

/// Runs chromium headless on `page` with `extra` arguments; stdout and stderr go to files
/// (a dumped DOM is larger than a pipe's buffer). Returns (stdout, stderr).
fn run_chromium(chromium: &Path, dir: &Path, tag: &str, page: &Path, extra: &[String]) -> (String, String) {
    run_chromium_sized(chromium, dir, tag, page, extra, (WIDTH, HEIGHT))
}

/// [`run_chromium`] in a window of `size` (width, height) pixels.
fn run_chromium_sized(chromium: &Path, dir: &Path, tag: &str, page: &Path, extra: &[String], size: (u32, u32)) -> (String, String) {
    let out = dir.join(format!("{tag}.stdout"));
    let err = dir.join(format!("{tag}.stderr"));
    let profile = dir.join(format!("{tag}-profile"));
    let mut child = Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--hide-scrollbars",
            "--enable-logging=stderr",
            "--v=0",
            &format!("--user-data-dir={}", profile.display()),
            &format!("--window-size={},{}", size.0, size.1),
            "--virtual-time-budget=2500",
        ])
        .args(extra)
        .arg(format!("file://{}", page.display()))
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start {}: {e}", chromium.display()));
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let (stdout, stderr) = (std::fs::read_to_string(&out).unwrap_or_default(), std::fs::read_to_string(&err).unwrap_or_default());
            assert!(status.success(), "chromium ({tag}) failed with {status}:\n{stderr}");
            return (stdout, stderr);
        }
        if started.elapsed() > Duration::from_secs(90) {
            child.kill().ok();
            child.wait().ok();
            panic!("chromium ({tag}) did not finish in 90 s:\n{}", std::fs::read_to_string(&err).unwrap_or_default());
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Console messages chromium logged (`...:CONSOLE...] "message", source: ...`) that are errors:
/// the page logs its own errors as `legwork replay error: ...`; uncaught exceptions come as
/// `Uncaught ...`.
fn console_errors(stderr: &str) -> Vec<&str> {
    stderr
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .filter(|l| {
            let lower = l.to_lowercase();
            lower.contains("error") || lower.contains("uncaught")
        })
        .collect()
}

/// Chromium, or `None` (the test skips) when it is missing outside CI.
fn chromium_or_skip() -> Option<PathBuf> {
    let found = find_chromium();
    if found.is_none() {
        if std::env::var_os("CI").is_some() {
            panic!("chromium is not installed, and CI is set: run scripts/install-test-deps.sh");
        }
        eprintln!("SKIPPED replay_browser: chromium is not on PATH (install it with scripts/install-test-deps.sh)");
    }
    found
}

/// The folder for a test's files: `LEGWORK_REPLAY_ARTIFACTS/<tag>` (kept) or a temporary one.
fn work_dir(tag: &str) -> (PathBuf, bool) {
    let keep = std::env::var_os("LEGWORK_REPLAY_ARTIFACTS").map(|d| PathBuf::from(d).join(tag));
    let dir = keep.clone().unwrap_or_else(|| std::env::temp_dir().join(format!("legwork-replay-browser-{}-{tag}", std::process::id())));
    std::fs::create_dir_all(&dir).unwrap();
    (dir.canonicalize().unwrap(), keep.is_some())
}

/// The page's error box must be hidden and empty.
fn assert_no_error_box(dom: &str) {
    let errors_box = dom.find("id=\"errors\"").map(|i| &dom[i..]).and_then(|s| s.find("</div>").map(|j| &s[..j])).expect("the error box");
    let tag_end = errors_box.find('>').unwrap_or(0);
    assert!(errors_box[..tag_end].contains("hidden") && errors_box[tag_end + 1..].trim().is_empty(), "the page reports errors: {errors_box}");
}

#[test]
fn replay_loads_in_chromium_without_errors_and_draws_the_robot() {
    let Some(chromium) = chromium_or_skip() else { return };
    let (dir, keep) = work_dir("plain");

    let (model, traj) = common::hyq_trot(3.0);
    let page = dir.join("replay.html");
    legwork::viz::write_replay(&model, &traj, &page).unwrap();

    let started = Instant::now();
    let (dom, log_dom) = run_chromium(&chromium, &dir, "dom", &page, &["--dump-dom".into()]);
    let shot = dir.join("screenshot.png");
    let (_, log_shot) = run_chromium(&chromium, &dir, "screenshot", &page, &[format!("--screenshot={}", shot.display())]);
    eprintln!("chromium: two headless runs in {:.1} s", started.elapsed().as_secs_f64());
    if keep {
        std::fs::write(dir.join("dom.html"), &dom).unwrap();
        traj.save_file(dir.join("trajectory.json")).unwrap();
        legwork::viz::write_plots(&traj, dir.join("plots")).unwrap();
    }

    // No console error in either run.
    let errors: Vec<&str> = console_errors(&log_dom).into_iter().chain(console_errors(&log_shot)).collect();
    assert!(errors.is_empty(), "console errors:\n{}", errors.join("\n"));

    // The page drew its first frame and shows no error.
    assert!(dom.contains("data-drawn=\"1\""), "the page never marked its first frame drawn; DOM starts:\n{}", &dom[..dom.len().min(3000)]);
    assert_no_error_box(&dom);
    // No overlay given, none drawn.
    assert!(!dom.contains("data-overlay"), "a page without an overlay says it drew one");

    // The screenshot: the 3D view (left part, between the header and the controls) is not
    // blank, and shows the legs (their colours, shaded: orange left, blue right).
    let (w, h, px) = common::decode_png(&shot);
    assert_eq!((w, h), (WIDTH, HEIGHT));
    let (x0, x1, y0, y1) = (120usize, 680usize, 140usize, 700usize);
    let region: Vec<[u8; 3]> = (y0..y1).flat_map(|y| px[y * w as usize + x0..y * w as usize + x1].to_vec()).collect();
    let luma: Vec<f64> = region.iter().map(|p| 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64).collect();
    let mean = luma.iter().sum::<f64>() / luma.len() as f64;
    let std = (luma.iter().map(|l| (l - mean) * (l - mean)).sum::<f64>() / luma.len() as f64).sqrt();
    let near = |p: &[u8; 3], c: [i32; 3], tol: i32| p.iter().zip(c).all(|(&a, b)| (a as i32 - b).abs() <= tol);
    let orange = region.iter().filter(|p| near(p, [224, 123, 57], 45)).count();
    let blue = region.iter().filter(|p| near(p, [59, 127, 196], 45)).count();
    eprintln!("3D view: luminance mean {mean:.1}, std {std:.1}; {orange} orange and {blue} blue pixels; page {} kB", std::fs::metadata(&page).unwrap().len() / 1000);
    assert!(std > 10.0, "the 3D view looks blank (luminance std {std:.1})");
    assert!(orange > 300 && blue > 300, "the legs are not visible ({orange} orange, {blue} blue pixels)");

    if !keep {
        std::fs::remove_dir_all(&dir).ok();
    }
}

/// Pixels of `region` within `tol` of the colour `c` in every channel.
fn count_near(region: &[[u8; 3]], c: [i32; 3], tol: i32) -> usize {
    region.iter().filter(|p| p.iter().zip(c).all(|(&a, b)| (a as i32 - b).abs() <= tol)).count()
}

#[test]
fn replay_draws_a_plan_overlay() {
    use legwork::dynamics::{forward_kinematics, update_frame_placements, Data};
    use legwork::viz::{OverlayFoothold, OverlayPath, OverlaySupport, ReplayOverlay};
    let Some(chromium) = chromium_or_skip() else { return };
    let (dir, keep) = work_dir("overlay");

    let (model, traj) = common::hyq_trot(3.0);
    // Footholds 15 cm (replaced, drawn hollow) and 30 cm ahead of the feet; a CoG path at base
    // height swaying in y, from behind the robot to ahead of it (where the trunk does not
    // hide it); a ZMP path on the ground; the support polygon of the four feet.
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &nalgebra::DVector::from_column_slice(&traj.knots[0].q));
    update_frame_placements(&model, &mut data);
    let feet: Vec<[f64; 3]> = model.feet.iter().map(|f| data.o_m_f[f.frame].translation).map(|p| [p.x, p.y, 0.0]).collect();
    let footholds = (0..feet.len())
        .flat_map(|k| [0.15, 0.3].map(|dx| OverlayFoothold { foot: k, position: [feet[k][0] + dx, feet[k][1], 0.0], t: 0.5 + dx, executed: dx > 0.2 }))
        .collect();
    let t: Vec<f64> = (0..=150).map(|i| i as f64 * 0.02).collect();
    let sway = |t: f64| 0.06 * (2.0 * std::f64::consts::PI * t / 1.5).sin();
    let cog = OverlayPath { name: "planned CoG".into(), color: "#8e24aa".into(), t: t.clone(), points: t.iter().map(|&t| [-1.0 + 0.7 * t, sway(t), 0.55]).collect() };
    let zmp = OverlayPath { name: "planned ZMP".into(), color: "#2e7d32".into(), t: t.clone(), points: t.iter().map(|&t| [-1.0 + 0.7 * t, 1.5 * sway(t), 0.0]).collect() };
    let hull = vec![feet[0], feet[2], feet[3], feet[1]];
    let shrunk = hull.iter().map(|p| [0.8 * p[0], 0.8 * p[1], 0.0]).collect();
    let overlay = ReplayOverlay { footholds, paths: vec![cog, zmp], supports: vec![OverlaySupport { t0: 0.0, t1: 3.0, polygon: hull, shrunk }] };
    let page = dir.join("replay.html");
    legwork::viz::write_replay_with_overlay(&model, &traj, Some(&overlay), &page).unwrap();

    let (dom, log_dom) = run_chromium(&chromium, &dir, "dom", &page, &["--dump-dom".into()]);
    let shot = dir.join("screenshot.png");
    // Paused at 1.2 s: the paths' markers are drawn at that instant.
    let paused = PathBuf::from(format!("{}#t=1.2&paused", page.display()));
    let (_, log_shot) = run_chromium(&chromium, &dir, "screenshot", &paused, &[format!("--screenshot={}", shot.display())]);
    let errors: Vec<&str> = console_errors(&log_dom).into_iter().chain(console_errors(&log_shot)).collect();
    assert!(errors.is_empty(), "console errors:\n{}", errors.join("\n"));
    assert!(dom.contains("data-drawn=\"1\""), "the page never marked its first frame drawn");
    assert_no_error_box(&dom);
    // 8 footholds, 2 paths, 1 support polygon; the legend names them.
    assert!(dom.contains("data-overlay=\"11\""), "the page did not draw the overlay; DOM starts:\n{}", &dom[..dom.len().min(3000)]);
    for needle in ["planned footholds", "planned CoG", "planned ZMP", "support polygon, shrunk"] {
        assert!(dom.contains(needle), "the legend lacks {needle:?}");
    }

    let (w, _, px) = common::decode_png(&shot);
    // Below the legend (which has the same colours), above the controls.
    let (x0, x1, y0, y1) = (20usize, 730usize, 260usize, 740usize);
    let region: Vec<[u8; 3]> = (y0..y1).flat_map(|y| px[y * w as usize + x0..y * w as usize + x1].to_vec()).collect();
    let purple = count_near(&region, [142, 36, 170], 30);
    let green = count_near(&region, [46, 125, 50], 30);
    let red = count_near(&region, [214, 39, 40], 30);
    let cyan = count_near(&region, [23, 190, 207], 30);
    eprintln!("overlay: {purple} CoG (purple), {green} ZMP (green), {red} LF foothold (red), {cyan} RH foothold (cyan) pixels");
    assert!(purple > 100 && green > 100, "the paths are not visible ({purple} purple, {green} green pixels)");
    assert!(red > 40 && cyan > 40, "the footholds are not visible ({red} red, {cyan} cyan pixels)");
    if !keep {
        std::fs::remove_dir_all(&dir).ok();
    }
}

/// A solve's replay as a new user opens it, at 1400 x 900: the verdict and the target checks
/// side by side as a table (met and missed marked), the raw summary behind a disclosure, the
/// 3D view at least half the window, no sideways scrolling. The layout is measured by the
/// page itself (`<body data-layout=...>`); the screenshot is kept in the test's target
/// folder (`target/tmp/replay-layout.png`).
#[test]
fn replay_header_is_a_target_table_and_leaves_the_view_half_the_window() {
    let Some(chromium) = chromium_or_skip() else { return };
    let (dir, keep) = work_dir("layout");
    let (model, mut traj) = common::hyq_trot(3.0);
    // A summary as `legwork solve` writes one, with a long tail of numbers (the gallop's
    // continuation stages) that used to fill the header.
    let check = |what: &str, value: &str, required: &str, met: bool| serde_json::json!({ "what": what, "value": value, "required": required, "met": met });
    let plan = vec![check("base x at the end", "1.838 m", "2.000 +- 0.050 m", false), check("lift-offs per foot", "6/8/8/6", "each >= 5", true)];
    let rerun = vec![check("base x at the end", "1.835 m", "2.000 +- 0.100 m", false), check("lift-offs per foot", "5/7/10/8", "each >= 5", true)];
    traj.summary.insert("task".into(), "gallop".into());
    traj.summary.insert("verdict".into(), "missed".into());
    traj.summary.insert("target".into(), serde_json::json!({ "plan": plan, "SLQ policy": rerun, "tracking ctrl": rerun, "MuJoCo track": "failed", "MuJoCo policy": rerun }));
    let stages: Vec<serde_json::Value> = (0..40).map(|i| serde_json::json!({ "horizon_s": 0.5 * i as f64, "initial_cost": 13812.123456789012 / (i + 1) as f64, "final_cost": 96.942_123_456_789, "solve_time_s": 0.123456789012345 })).collect();
    traj.summary.insert("continuation_stages".into(), serde_json::Value::Array(stages));
    traj.summary.insert("a_very_long_key_without_spaces".into(), "x".repeat(3000).into());
    let page = dir.join("replay.html");
    legwork::viz::write_replay(&model, &traj, &page).unwrap();

    let size = (1400, 900);
    let (dom, log_dom) = run_chromium_sized(&chromium, &dir, "dom", &page, &["--dump-dom".into()], size);
    let shot = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("replay-layout.png");
    let (_, log_shot) = run_chromium_sized(&chromium, &dir, "screenshot", &page, &[format!("--screenshot={}", shot.display())], size);
    let errors: Vec<&str> = console_errors(&log_dom).into_iter().chain(console_errors(&log_shot)).collect();
    assert!(errors.is_empty(), "console errors:\n{}", errors.join("\n"));
    assert_no_error_box(&dom);

    // The table: a header row with the runs, a row per check, cells marked met or missed.
    for needle in ["<th>MuJoCo policy</th>", "<td>base x at the end</td>", "class=\"value missed\">1.838 m</td>", "class=\"value met\">6/8/8/6</td>", ">failed</td>", "target missed"] {
        assert!(dom.contains(needle), "the page lacks {needle}");
    }
    // The gait diagram is among the plots.
    assert!(dom.contains("Gait: contact per foot"), "no gait diagram");
    // The raw summary is there, but closed.
    assert!(dom.contains("<details id=\"raw\">") && dom.contains("continuation_stages"), "no raw summary disclosure");

    // The layout the page measured.
    let layout = dom.split("data-layout=\"").nth(1).and_then(|s| s.split('"').next()).expect("the page did not record its layout").replace("&quot;", "\"");
    let layout: serde_json::Value = serde_json::from_str(&layout).unwrap();
    let get = |k: &str| layout[k].as_f64().unwrap_or_else(|| panic!("{k} missing in {layout}"));
    eprintln!("layout at 1400 x 900: {layout}");
    // Headless chromium's --window-size counts its own (invisible) window frame: the page
    // gets the full width and 757 of the 900 pixels' height (Chromium 156 on Debian 12).
    assert_eq!(get("window_width"), 1400.0);
    let viewport = get("window_height");
    assert!(viewport > 700.0 && viewport <= 900.0, "viewport {viewport} px high");
    assert!(get("view_height") >= 450.0 && get("view_height") >= 0.5 * viewport, "the 3D view is {} px high of {viewport}", get("view_height"));
    assert!(get("scroll_width") <= get("client_width"), "the page scrolls sideways: {} > {}", get("scroll_width"), get("client_width"));
    let (w, h, _) = common::decode_png(&shot);
    assert_eq!((w, h), size);
    if !keep {
        std::fs::remove_dir_all(&dir).ok();
    }
}

/// The layout the page measured (`data-layout`) at `size`, with no console error and no
/// error box: the 3D view keeps at least half the viewport and the page does not scroll
/// sideways.
fn assert_layout(chromium: &Path, dir: &Path, tag: &str, page: &Path, size: (u32, u32)) {
    let (dom, log) = run_chromium_sized(chromium, dir, tag, page, &["--dump-dom".into()], size);
    let errors = console_errors(&log);
    assert!(errors.is_empty(), "{tag}: console errors:\n{}", errors.join("\n"));
    assert_no_error_box(&dom);
    let layout = dom.split("data-layout=\"").nth(1).and_then(|s| s.split('"').next()).unwrap_or_else(|| panic!("{tag}: the page did not record its layout")).replace("&quot;", "\"");
    let layout: serde_json::Value = serde_json::from_str(&layout).unwrap();
    let get = |k: &str| layout[k].as_f64().unwrap_or_else(|| panic!("{tag}: {k} missing in {layout}"));
    let viewport = get("window_height");
    eprintln!("{tag}: 3D view {} of {viewport} px, page {} of {} px wide", get("view_height"), get("scroll_width"), get("client_width"));
    assert!(get("view_height") >= 0.5 * viewport, "{tag}: the 3D view is {} px high of {viewport}", get("view_height"));
    assert!(get("scroll_width") <= get("client_width"), "{tag}: the page scrolls sideways: {} > {}", get("scroll_width"), get("client_width"));
}

#[test]
fn every_embedded_tasks_and_scenarios_replay_passes_the_layout_test() {
    let Some(chromium) = chromium_or_skip() else { return };
    let (dir, keep) = work_dir("every-replay");
    let legwork = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_legwork")).args(args).output().unwrap();
        assert!(matches!(out.status.code(), Some(0 | 1)), "legwork {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    };
    let mut pages = Vec::new();
    // Each task solved briefly (one iteration on the full horizon, after its continuation
    // stages): the replay's header is the task's own targets over the plan and its re-runs.
    for (name, _) in legwork::ocp::EMBEDDED_TASKS {
        let spec = legwork::ocp::TaskSpec::embedded(name).unwrap();
        let iterations = spec.continuation.as_ref().map_or(0, |c| c.horizons.len() * c.iterations) + 1;
        let out = dir.join(name);
        legwork(&["solve", name, "--iterations", &iterations.to_string(), "--starts", "1", "--out", out.to_str().unwrap()]);
        pages.push((name.to_string(), out.join("replay.html")));
    }
    for (name, _) in legwork::walk::EMBEDDED_SCENARIOS {
        let out = dir.join(format!("walk-{name}"));
        legwork(&["walk", name, "--out", out.to_str().unwrap()]);
        pages.push((format!("walk-{name}"), out.join("replay.html")));
    }
    for (tag, page) in &pages {
        assert_layout(&chromium, &dir, tag, page, (1400, 900));
    }
    if !keep {
        std::fs::remove_dir_all(&dir).ok();
    }
}
