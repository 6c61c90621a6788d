//! The replay page and the plots without a browser (`tests/replay_browser.rs` opens the
//! page in one), and `legwork view` run as a user would.

mod common;

use legwork::terrain::{HeightMap, Terrain, TerrainSpec};
use legwork::viz::{self, VizError};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("legwork-viz-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The JSON embedded in the page.
fn embedded_data(html: &str) -> serde_json::Value {
    let open = "<script type=\"application/json\" id=\"legwork-data\">";
    let start = html.find(open).expect("data element") + open.len();
    let end = start + html[start..].find("</script>").expect("end of data element");
    serde_json::from_str(&html[start..end]).expect("the embedded data is JSON")
}

#[test]
fn the_replay_loads_nothing_from_anywhere() {
    let (model, traj) = common::hyq_trot(1.5);
    let html = viz::replay_html(&model, &traj).unwrap();
    let lower = html.to_lowercase();
    for needle in ["http://", "https://", "src=", "href=", "@import", "url(", "//cdn", "fonts.g"] {
        assert!(!lower.contains(needle), "the page references '{needle}'");
    }
    assert!(!html.contains("/*LEGWORK_DATA*/"), "the data slot was not filled");
    assert!(html.contains("document.body.dataset.drawn = \"1\""));

    let data = embedded_data(&html);
    let frames = &data["frames"];
    let n = frames["t"].as_array().unwrap().len();
    // 1.5 s at most 100 frames per second (plus the last knot), from 751 knots.
    assert!((140..=152).contains(&n), "{n} frames");
    let n_points = data["skeleton"]["n_points"].as_u64().unwrap() as usize;
    assert_eq!(n_points, model.njoints() + 4 + 8);
    assert!(frames["points"].as_array().unwrap().iter().all(|p| p.as_array().unwrap().len() == 3 * n_points));
    assert_eq!(frames["forces"][0].as_array().unwrap().len(), 12);
    // 12 leg links (HAA-HFE, HFE-KFE, KFE-foot per leg), the hips on the trunk.
    assert_eq!(data["skeleton"]["links"].as_array().unwrap().len(), 12);
    assert_eq!(data["force_scale_label"], "1 mm per 2 N");
    let plots: Vec<&str> = data["plots"].as_array().unwrap().iter().map(|p| p["title"].as_str().unwrap()).collect();
    assert_eq!(plots.len(), 6, "{plots:?}");
    assert!(plots[5].contains("normal forces"));
    // The stance feet's normal force carries the weight: about 86.8 kg * 9.81 / 4 = 213 N.
    let lf = data["plots"][5]["series"][0]["y"][0].as_f64().unwrap();
    assert!((lf - 212.8).abs() < 3.0, "{lf}");
}

#[test]
fn names_in_the_file_cannot_break_out_of_the_page() {
    let (model, mut traj) = common::hyq_trot(0.2);
    traj.metadata.scenario = "</script><script>alert('x')</script> <!--".into();
    let html = viz::replay_html(&model, &traj).unwrap();
    assert!(!html.contains("<script>alert"));
    assert!(!html.contains("<!--\""));
    assert_eq!(embedded_data(&html)["scenario"], traj.metadata.scenario.as_str());
}

#[test]
fn a_height_map_is_drawn_as_a_mesh_of_bounded_size() {
    let model = legwork::model::embedded::load("hyq").unwrap();
    let mut map = HeightMap::flat([-3.0, -3.0], 0.01, 601, 601, 0.0);
    map.set_rect([0.6, 1.2], [-0.5, 0.5], 0.1);
    let traj = common::trot(&model, 0.3, map.spec());
    let data = embedded_data(&viz::replay_html(&model, &traj).unwrap());
    let t = &data["terrain"];
    assert_eq!(t["kind"], "height_map");
    let (nx, ny) = (t["nx"].as_u64().unwrap(), t["ny"].as_u64().unwrap());
    assert!(nx <= 92 && ny <= 92 && nx > 10 && ny > 10, "{nx} x {ny}");
    assert_eq!(t["z"].as_array().unwrap().len() as u64, nx * ny);
    assert!(t["z"].as_array().unwrap().iter().any(|z| z.as_f64() == Some(0.1)), "the step is on the patch");
}

#[test]
fn a_trajectory_that_does_not_fit_is_an_error_naming_the_field() {
    let (model, traj) = common::hyq_trot(0.2);
    let a1 = legwork::model::embedded::load("a1").unwrap();
    let e = viz::replay_html(&a1, &traj).unwrap_err();
    assert!(matches!(e, VizError::Trajectory(_)));
    assert!(e.to_string().contains("metadata.joint_names[0]"), "{e}");

    let mut bad = traj.clone();
    bad.knots[5].q.pop();
    let e = viz::replay_html(&model, &bad).unwrap_err().to_string();
    assert!(e.contains("knots[5].q"), "{e}");
    let dir = temp_dir("bad-plots");
    let e = viz::write_plots(&bad, &dir).unwrap_err().to_string();
    std::fs::remove_dir_all(&dir).ok();
    assert!(e.contains("knots[5].q"), "{e}");

    let mut wall = traj;
    wall.metadata.terrain = TerrainSpec::Plane { elevation: 0.0, normal: [1.0, 0.0, 0.0] };
    let e = viz::replay_html(&model, &wall).unwrap_err().to_string();
    assert!(e.starts_with("metadata.terrain") && e.contains("normal"), "{e}");
}

#[test]
fn a_single_knot_and_a_fixed_base_robot() {
    let (model, mut traj) = common::hyq_trot(0.1);
    traj.knots.truncate(1);
    let data = embedded_data(&viz::replay_html(&model, &traj).unwrap());
    assert_eq!(data["frames"]["t"].as_array().unwrap().len(), 1);
    let dir = temp_dir("one-knot");
    assert_eq!(viz::write_plots(&traj, &dir).unwrap().len(), 5);
    std::fs::remove_dir_all(&dir).ok();

    // A robot arm (no free flyer) with the same joint names cannot play a legged motion.
    let mut arm = legwork::model::Model::new("arm");
    let mut parent = 0;
    for name in &traj.metadata.joint_names {
        let axis = nalgebra::Vector3::y();
        parent = arm.add_joint(parent, name, legwork::model::JointKind::revolute(axis), legwork::spatial::SE3::identity(), legwork::model::JointLimits::unbounded(1)).unwrap();
    }
    let feet: Vec<&str> = traj.metadata.foot_names.iter().map(String::as_str).collect();
    for f in &feet {
        arm.add_frame(legwork::model::Frame { name: f.to_string(), kind: legwork::model::FrameKind::Operational, parent_joint: parent, placement: legwork::spatial::SE3::identity() }).unwrap();
    }
    arm.set_feet(&feet, 0.02).unwrap();
    let e = viz::replay_html(&arm, &traj).unwrap_err().to_string();
    assert!(e.contains("metadata.robot") && e.contains("no free-flying base"), "{e}");
}

#[test]
fn plots_are_nonempty_svg_files() {
    let (_, traj) = common::hyq_trot(1.5);
    let dir = temp_dir("plots");
    let files = viz::write_plots(&traj, dir.join("figures")).unwrap();
    let names: Vec<String> = files.iter().map(|f| f.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["base_pose.svg", "base_twist.svg", "joint_torques.svg", "contact_forces.svg", "gait.svg"]);
    for (file, expected) in files.iter().zip(["Base roll, pitch, yaw", "Base linear velocity", "Joint torques, leg lf", "Contact force on rh_foot", "Contact schedule"]) {
        let svg = std::fs::read_to_string(file).unwrap();
        assert!(svg.len() > 5_000, "{} has {} bytes", file.display(), svg.len());
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"), "{}", file.display());
        assert!(svg.contains("<text") && svg.contains(expected), "{} lacks '{expected}'", file.display());
        assert!(svg.contains("<polyline") || svg.contains("<rect"), "{} draws nothing", file.display());
    }
    // The gait diagram gives each foot's duty factor: trotting from 0.6 s to 1.1 s, each
    // foot swings 0.2 s of the 1.5 s.
    let gait = std::fs::read_to_string(&files[4]).unwrap();
    assert!(gait.contains("lf_foot 87%") && gait.contains("rh_foot 87%"), "duty factors missing");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn limit_plots_draw_torques_and_friction_against_the_robots_limits() {
    let (model, traj) = common::hyq_trot(1.5);
    let dir = temp_dir("limit-plots");
    let files = viz::write_limit_plots(&model, &traj, &dir).unwrap();
    let names: Vec<String> = files.iter().map(|f| f.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["torque_limits.svg", "ground_forces.svg"]);
    let torques = std::fs::read_to_string(&files[0]).unwrap();
    let texts: Vec<&str> = torques.split("</text>").filter_map(|t| t.rsplit('>').next()).map(str::trim).collect();
    assert!(texts.contains(&"lf: |torque| / limit") && texts.contains(&"limit"), "no limit line: {texts:?}");
    let forces = std::fs::read_to_string(&files[1]).unwrap();
    let mu = format!("mu = {}", model.contact.friction);
    assert!(forces.contains("friction use |F_t| / F_n") && forces.contains(&mu), "no friction cone '{mu}'");
    // A long recording is drawn at most MAX_POINTS knots per curve.
    let mut long = traj.clone();
    let last = long.knots.last().unwrap().clone();
    for k in 1..=20_000 {
        let mut knot = last.clone();
        knot.t += 1e-3 * k as f64;
        long.knots.push(knot);
    }
    let files = viz::write_limit_plots(&model, &long, &dir).unwrap();
    let svg = std::fs::read_to_string(&files[0]).unwrap();
    let most_points = svg.split("<polyline").skip(1).map(|p| p.split("points=\"").nth(1).map_or(0, |pts| pts.split('"').next().unwrap_or("").split(' ').count())).max().unwrap_or(0);
    assert!(most_points <= 4001, "{most_points} points in a curve");
    std::fs::remove_dir_all(&dir).ok();
}

fn legwork(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_legwork")).args(args).current_dir(dir).output().unwrap()
}

#[test]
fn legwork_view_writes_the_replay_and_the_plots_and_says_where() {
    let dir = temp_dir("cli");
    let (_, traj) = common::hyq_trot(0.5);
    traj.save_file(dir.join("trajectory.json")).unwrap();
    let o = legwork(&["view", "trajectory.json", "--out", "out/replay.html", "--plots", "plots"], &dir);
    let (stdout, stderr) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{stderr}");
    assert!(stdout.contains("replay: out/replay.html") && stdout.contains("robot hyq") && stdout.contains("plot:   plots/gait.svg"), "{stdout}");
    assert!(std::fs::read_to_string(dir.join("out/replay.html")).unwrap().contains("legwork-data"));
    assert!(dir.join("plots/base_pose.svg").is_file());
    // Default output name, robot given explicitly.
    let o = legwork(&["view", "trajectory.json", "--robot", "hyq"], &dir);
    assert!(o.status.success() && dir.join("replay.html").is_file(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn legwork_view_names_the_file_and_the_field_of_a_bad_trajectory() {
    let dir = temp_dir("cli-bad");
    let (_, traj) = common::hyq_trot(0.1);
    let mut json: serde_json::Value = serde_json::to_value(&traj).unwrap();
    json["knots"][3]["tau"] = serde_json::json!([1.0, 2.0]);
    std::fs::write(dir.join("bad.json"), json.to_string()).unwrap();
    let check = |args: &[&str], expected: &[&str]| {
        let o = legwork(args, &dir);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(!stderr.contains("panicked"), "{stderr}");
        for e in expected {
            assert!(stderr.contains(e), "{args:?}: '{e}' missing in: {stderr}");
        }
    };
    check(&["view", "bad.json"], &["bad.json", "knots[3].tau", "expected 12 numbers"]);
    check(&["view", "missing.json"], &["missing.json"]);

    let mut other = traj.clone();
    other.metadata.robot = "my_dog".into();
    other.save_file(dir.join("other.json")).unwrap();
    check(&["view", "other.json"], &["other.json", "metadata.robot", "'my_dog' is not an embedded robot", "--robot"]);
    traj.save_file(dir.join("hyq.json")).unwrap();
    check(&["view", "hyq.json", "--robot", "a1"], &["hyq.json", "metadata.joint_names[0]"]);
    check(&["view", "hyq.json", "--robot", "spot"], &["'spot' is neither an embedded robot"]);
    assert!(!dir.join("replay.html").exists());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_synthetic_trajectory_is_valid_and_keeps_stance_feet_on_the_ground() {
    let (model, traj) = common::hyq_trot(1.5);
    traj.validate("synthetic").unwrap();
    traj.check_against(&model, "synthetic").unwrap();
    let ground = legwork::terrain::Plane::flat(0.0);
    let mut data = legwork::dynamics::Data::new(&model);
    for knot in traj.knots.iter().step_by(25) {
        legwork::dynamics::forward_kinematics(&model, &mut data, &nalgebra::DVector::from_column_slice(&knot.q));
        legwork::dynamics::update_frame_placements(&model, &mut data);
        for (f, foot) in model.feet.iter().enumerate() {
            let gap = data.o_m_f[foot.frame].translation.z - foot.radius - ground.height(0.0, 0.0);
            if knot.in_contact[f] {
                assert!(gap.abs() < 1e-6, "t = {}: foot {f} {gap} m off the ground", knot.t);
            } else {
                assert!(gap > 0.0, "t = {}: swing foot {f} in the ground", knot.t);
            }
        }
    }
}

#[test]
fn png_copies_are_twice_the_size_with_their_text_drawn() {
    let (_, traj) = common::hyq_trot(0.5);
    let dir = temp_dir("png");
    let svgs = viz::write_plots(&traj, &dir).unwrap();
    let pngs = viz::png::write_pngs(&svgs, viz::png::PNG_SCALE).unwrap();
    assert_eq!(pngs.len(), svgs.len());
    // base_pose.svg is 960 x 540 units: 1920 x 1080 pixels.
    let (w, h, pixels) = common::decode_png(&dir.join("base_pose.png"));
    assert_eq!((w, h), (1920, 1080));
    // The title's text (the top 40 px, centred, black on white) is drawn with the embedded
    // font: dark pixels in its band, none in the empty margin at its far left.
    let dark = |x0: u32, x1: u32, y0: u32, y1: u32| (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))).filter(|&(x, y)| pixels[(y * w + x) as usize].iter().all(|&c| c < 100)).count();
    assert!(dark(600, 1320, 0, 40) > 200, "no title text drawn: {} dark pixels", dark(600, 1320, 0, 40));
    assert_eq!(dark(0, 100, 0, 20), 0);
    // A scale outside (0, 8] is refused with the figure's name.
    let err = viz::png::svg_png(&std::fs::read_to_string(&svgs[0]).unwrap(), 0.0, "fig.svg").unwrap_err().to_string();
    assert!(err.contains("fig.svg") && err.contains("scale"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn legwork_view_writes_pngs_on_request() {
    let dir = temp_dir("view-png");
    let (_, traj) = common::hyq_trot(0.3);
    let file = dir.join("trajectory.json");
    traj.save_file(&file).unwrap();
    let out = legwork(&["view", file.to_str().unwrap(), "--out", dir.join("replay.html").to_str().unwrap(), "--plots", dir.join("plots").to_str().unwrap(), "--png"], &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for name in ["base_pose", "base_twist", "joint_torques", "contact_forces", "gait"] {
        assert!(dir.join("plots").join(format!("{name}.png")).is_file(), "{name}.png");
    }
    // --png needs --plots.
    let out = legwork(&["view", file.to_str().unwrap(), "--png"], &dir);
    assert_eq!(out.status.code(), Some(2));
    std::fs::remove_dir_all(&dir).ok();
}
