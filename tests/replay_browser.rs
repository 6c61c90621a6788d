//! The HTML replay in a real browser: Debian's `chromium`, headless (installed by
//! `scripts/install-test-deps.sh`). The page must load with no console error, mark that it
//! drew its first frame (`<body data-drawn="1">`), keep its error box hidden, and the
//! screenshot must show the robot in the 3D view (varied pixels, leg colours present).
//!
//! Without chromium the test fails when `CI` is set, and otherwise says it skipped.
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
            &format!("--window-size={WIDTH},{HEIGHT}"),
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

/// The RGB pixels of a PNG.
fn decode_png(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    assert_eq!(info.bit_depth, png::BitDepth::Eight, "unexpected PNG bit depth");
    let pixels = buf[..info.buffer_size()]
        .chunks(channels)
        .map(|c| if channels >= 3 { [c[0], c[1], c[2]] } else { [c[0]; 3] })
        .collect();
    (info.width, info.height, pixels)
}

#[test]
fn replay_loads_in_chromium_without_errors_and_draws_the_robot() {
    let Some(chromium) = find_chromium() else {
        if std::env::var_os("CI").is_some() {
            panic!("chromium is not installed, and CI is set: run scripts/install-test-deps.sh");
        }
        eprintln!("SKIPPED replay_browser: chromium is not on PATH (install it with scripts/install-test-deps.sh)");
        return;
    };
    let keep = std::env::var_os("LEGWORK_REPLAY_ARTIFACTS").map(PathBuf::from);
    let dir = keep.clone().unwrap_or_else(|| std::env::temp_dir().join(format!("legwork-replay-browser-{}", std::process::id())));
    std::fs::create_dir_all(&dir).unwrap();
    let dir = dir.canonicalize().unwrap();

    let (model, traj) = common::hyq_trot(3.0);
    let page = dir.join("replay.html");
    legwork::viz::write_replay(&model, &traj, &page).unwrap();

    let started = Instant::now();
    let (dom, log_dom) = run_chromium(&chromium, &dir, "dom", &page, &["--dump-dom".into()]);
    let shot = dir.join("screenshot.png");
    let (_, log_shot) = run_chromium(&chromium, &dir, "screenshot", &page, &[format!("--screenshot={}", shot.display())]);
    eprintln!("chromium: two headless runs in {:.1} s", started.elapsed().as_secs_f64());
    if keep.is_some() {
        std::fs::write(dir.join("dom.html"), &dom).unwrap();
        traj.save_file(dir.join("trajectory.json")).unwrap();
        legwork::viz::write_plots(&traj, dir.join("plots")).unwrap();
    }

    // No console error in either run.
    let errors: Vec<&str> = console_errors(&log_dom).into_iter().chain(console_errors(&log_shot)).collect();
    assert!(errors.is_empty(), "console errors:\n{}", errors.join("\n"));

    // The page drew its first frame and shows no error.
    assert!(dom.contains("data-drawn=\"1\""), "the page never marked its first frame drawn; DOM starts:\n{}", &dom[..dom.len().min(3000)]);
    let errors_box = dom.find("id=\"errors\"").map(|i| &dom[i..]).and_then(|s| s.find("</div>").map(|j| &s[..j])).expect("the error box");
    let tag_end = errors_box.find('>').unwrap_or(0);
    assert!(errors_box[..tag_end].contains("hidden") && errors_box[tag_end + 1..].trim().is_empty(), "the page reports errors: {errors_box}");

    // The screenshot: the 3D view (left part, between the header and the controls) is not
    // blank, and shows the legs (their colours, shaded: orange left, blue right).
    let (w, h, px) = decode_png(&shot);
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

    if keep.is_none() {
        std::fs::remove_dir_all(&dir).ok();
    }
}
