//! MuJoCo as the plant of a controller that runs in legwork (`legwork mpc --sim mujoco`):
//! the checker script's `plant` command (`python/legwork/mujoco_check.py`) stepped over a
//! pipe, one JSON line each way per physics step.
//!
//! Each step legwork asks the controller for torques at the measured state (clipped to the
//! effort limits as legwork's simulator does, [`controller_torques`]), sends them with the
//! pushes active at that time, and reads back MuJoCo's next state and the contact forces
//! of the step's start. The motion is MuJoCo's; legwork only measures it.
//!
//! legwork's contact model carries a hidden anchor per foot (where its contact began,
//! Neunert 2017 sec. III-B) that MuJoCo does not have. The plant estimates it as a
//! contact observer would: legwork's contact model evaluated on the measured feet, its
//! anchors moved by [`crate::contact::update_anchor`] every step, starting from the plan's
//! initial anchors. A controller whose state includes the anchors (the receding-horizon
//! SLQ with anchor states) reads that estimate.
//!
//! The feet's depth is estimated too ([`MujocoPlant::set_depth_matching`], on by default).
//! MuJoCo's contact holds HyQ's feet 1.0-1.3 mm deep, legwork's 4.3-5.0 mm
//! ([`crate::contact::ContactParams`]): on MuJoCo's measured feet legwork's contact model
//! would carry about 6 % of the robot's weight, and a controller that predicts with it sees a
//! robot in free fall at every measurement. The state the controllers read has the base
//! lowered by `delta`, the loaded feet's depth difference weighted by their load:
//!
//! ```text
//! delta = sum_i F_i (p_i* - p_i) / sum_i F_i,   p_i* = the depth where legwork's contact
//!         carries F_i at rest (ContactParams::static_penetration)
//! ```
//!
//! with `F_i` MuJoCo's normal force on foot `i` (the contacts of the step's start) and `p_i`
//! the foot's depth in legwork's model at the measured state; `delta = 0` with no foot
//! loaded. The recorded motion is MuJoCo's own.

use super::mjcf::{mjcf_model, MjcfSettings};
use super::mujoco_check::{MujocoCheck, MujocoCheckError, CHECKER_SCRIPT};
use crate::io::{Knot, Trajectory};
use crate::model::Model;
use crate::sim::{controller_torques, ContactModelWorkspace, Controller, Plant, Push, SimConfig, SimError, SimState};
use crate::terrain::Terrain;
use nalgebra::{DVector, Vector3};
use serde::Deserialize;
use std::fmt::Write as _;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

const SIMULATOR: &str = "MuJoCo (mujoco_check.py plant)";

/// The plant's first answer: its state and time step.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StartAnswer {
    t: f64,
    q: Vec<f64>,
    v: Vec<f64>,
    dt: f64,
}

/// The answer to a step: the new state, the contacts of the step's start, and why MuJoCo
/// stopped if it did.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StepAnswer {
    t: f64,
    q: Vec<f64>,
    v: Vec<f64>,
    forces: Vec<[f64; 3]>,
    touching: Vec<bool>,
    failed: Option<String>,
}

/// The contacts of the current state.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ContactsAnswer {
    forces: Vec<[f64; 3]>,
    touching: Vec<bool>,
}

/// MuJoCo behind a pipe, stepped by legwork's controllers (module docs).
pub struct MujocoPlant<'a> {
    model: &'a Model,
    config: SimConfig,
    child: Child,
    requests: BufWriter<ChildStdin>,
    answers: BufReader<ChildStdout>,
    stderr_path: PathBuf,
    line: String,
    request: String,
    /// The state the controllers read: MuJoCo's, the base lowered by `depth_offset`.
    state: SimState,
    /// MuJoCo's configuration as measured (recorded).
    measured_q: DVector<f64>,
    /// Whether the base is lowered to legwork's contact depth (module docs).
    depth_matching: bool,
    /// The last `delta` (m).
    depth_offset: f64,
    /// legwork's contact model on the measured motion: the anchors' estimate.
    contacts: ContactModelWorkspace<'a>,
    tau: DVector<f64>,
    pushes: Vec<Push>,
    control_every: u64,
    record_every: u64,
    step: u64,
}

impl<'a> MujocoPlant<'a> {
    /// Starts MuJoCo at `plan`'s first knot (its initial anchors as the anchors' first
    /// estimate), on `terrain` (written into the MJCF with the robot), at `config`'s
    /// physics step (MuJoCo's time step); writes `model.xml`, `start.json`,
    /// `mujoco_check.py` and the plant's `plant_stderr.txt` into `folder`.
    pub fn from_plan(check: &MujocoCheck, model: &'a Model, terrain: &'a dyn Terrain, plan: &Trajectory, config: SimConfig, folder: &Path) -> Result<Self, MujocoCheckError> {
        plan.check_against(model, "the plan")?;
        let first = plan.knots.first().ok_or_else(|| MujocoCheckError::Input("the plan has no knots".into()))?;
        let (control_every, record_every) = config.ratios(&model.contact).map_err(|e| MujocoCheckError::Input(e.to_string()))?;
        let io = |path: &Path| {
            let path = path.display().to_string();
            move |error| MujocoCheckError::Io { path, error }
        };
        std::fs::create_dir_all(folder).map_err(io(folder))?;
        let mjcf = folder.join("model.xml");
        let settings = MjcfSettings { timestep: config.physics_dt, ..MjcfSettings::default() };
        std::fs::write(&mjcf, mjcf_model(model, &terrain.spec(), &settings)?).map_err(io(&mjcf))?;
        let start = folder.join("start.json");
        let start_json = serde_json::json!({
            "joint_names": model.actuated_joint_names(),
            "foot_names": model.feet.iter().map(|f| f.name.as_str()).collect::<Vec<_>>(),
            "q": first.q,
            "v": first.v,
        });
        std::fs::write(&start, start_json.to_string()).map_err(io(&start))?;
        let script = folder.join("mujoco_check.py");
        std::fs::write(&script, CHECKER_SCRIPT).map_err(io(&script))?;
        let stderr_path = folder.join("plant_stderr.txt");
        let stderr = std::fs::File::create(&stderr_path).map_err(io(&stderr_path))?;
        let mut child = Command::new(check.python())
            .arg(&script)
            .args(["plant".as_ref(), "--mjcf".as_ref(), mjcf.as_os_str(), "--start".as_ref(), start.as_os_str()])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::from(stderr))
            .spawn()
            .map_err(io(check.python()))?;
        let (Some(stdin), Some(stdout)) = (child.stdin.take(), child.stdout.take()) else {
            return Err(MujocoCheckError::Input("the plant's pipes were not opened".into()));
        };
        let anchors: Vec<Option<Vector3<f64>>> = match &plan.metadata.initial_anchors {
            Some(a) => a.iter().map(|a| a.map(Vector3::from)).collect(),
            None => vec![None; model.feet.len()],
        };
        let contacts = ContactModelWorkspace::new(model, terrain).with_joint_limits(config.joint_limits);
        let mut plant = Self {
            model,
            child,
            requests: BufWriter::new(stdin),
            answers: BufReader::new(stdout),
            stderr_path,
            line: String::new(),
            request: String::new(),
            state: SimState { t: 0.0, q: DVector::from_column_slice(&first.q), v: DVector::from_column_slice(&first.v), anchors },
            measured_q: DVector::from_column_slice(&first.q),
            depth_matching: true,
            depth_offset: 0.0,
            contacts,
            tau: DVector::zeros(model.nv),
            pushes: Vec::new(),
            control_every: control_every as u64,
            record_every: record_every as u64,
            step: 0,
            config,
        };
        let answer: StartAnswer = plant.read_answer().map_err(|e| MujocoCheckError::Input(e.to_string()))?;
        if (answer.dt - plant.config.physics_dt).abs() > 1e-12 {
            return Err(MujocoCheckError::Input(format!("{}: MuJoCo's time step is {} s, expected the physics step {} s", mjcf.display(), answer.dt, plant.config.physics_dt)));
        }
        plant.set_measured(answer.t, &answer.q, &answer.v, None).map_err(|e| MujocoCheckError::Input(e.to_string()))?;
        Ok(plant)
    }

    /// Lower the base the controllers read to legwork's contact depth (`true`, the default;
    /// module docs) or hand them MuJoCo's state as it is (`false`).
    pub fn set_depth_matching(&mut self, on: bool) {
        self.depth_matching = on;
    }

    /// The base's last lowering (m): `delta` of the module docs.
    pub fn depth_offset(&self) -> f64 {
        self.depth_offset
    }

    /// Adds a push on the base (world frame, at the base frame's origin).
    pub fn add_push(&mut self, push: Push) {
        self.pushes.push(push);
    }

    fn external(&self, problem: String) -> SimError {
        SimError::External { simulator: SIMULATOR.into(), problem }
    }

    /// Reads one answer line; the plant's end (with its stderr) or a malformed line is an error.
    fn read_answer<T: for<'de> Deserialize<'de>>(&mut self) -> Result<T, SimError> {
        self.line.clear();
        let read = self.answers.read_line(&mut self.line).map_err(|e| self.external(format!("reading its answer: {e}")))?;
        if read == 0 {
            let status = self.child.wait().map(|s| s.to_string()).unwrap_or_else(|e| e.to_string());
            let stderr = std::fs::read_to_string(&self.stderr_path).unwrap_or_default();
            return Err(self.external(format!("the plant ended ({status}) at step {}:\n{}", self.step, stderr.trim())));
        }
        serde_json::from_str(&self.line).map_err(|e| self.external(format!("answer at step {}: {e}: {}", self.step, self.line.trim())))
    }

    /// Sends the request in `self.request` (one line).
    fn send_request(&mut self) -> Result<(), SimError> {
        self.request.push('\n');
        let sent = self.requests.write_all(self.request.as_bytes()).and_then(|_| self.requests.flush());
        sent.map_err(|e| self.external(format!("sending step {}: {e} (see {})", self.step, self.stderr_path.display())))
    }

    /// Takes MuJoCo's measured state, checked as legwork's simulator checks its own.
    /// `forces`: MuJoCo's contact forces per foot (world frame), for the depth's estimate.
    fn set_measured(&mut self, t: f64, q: &[f64], v: &[f64], forces: Option<&[[f64; 3]]>) -> Result<(), SimError> {
        if q.len() != self.model.nq || v.len() != self.model.nv {
            return Err(self.external(format!("a state of {} and {} entries, expected q of {} and v of {}", q.len(), v.len(), self.model.nq, self.model.nv)));
        }
        self.state.t = t;
        self.measured_q.copy_from_slice(q);
        self.state.q.copy_from_slice(q);
        self.state.v.copy_from_slice(v);
        let reason = if let Some(i) = q.iter().position(|x| !x.is_finite()) {
            Some(format!("q[{i}] is {}", q[i]))
        } else {
            v.iter().position(|x| !x.is_finite() || x.abs() > self.config.max_speed).map(|i| format!("|v[{i}]| = {:.3e} exceeds max_speed = {}", v[i].abs(), self.config.max_speed))
        };
        if let Some(reason) = reason {
            return Err(SimError::Diverged { step: self.step, t, reason: format!("in MuJoCo: {reason}"), q: q.to_vec(), v: v.to_vec() });
        }
        self.depth_offset = match forces {
            Some(forces) if self.depth_matching => self.depth_difference(forces),
            _ => 0.0,
        };
        self.state.q[2] -= self.depth_offset;
        Ok(())
    }

    /// `delta` of the module docs at the measured state in `self.state`.
    fn depth_difference(&mut self, forces: &[[f64; 3]]) -> f64 {
        self.contacts.evaluate_contacts(&self.state.q, &self.state.v, &self.state.anchors);
        let params = *self.contacts.params();
        let (mut weighted, mut total) = (0.0, 0.0);
        for (foot, force) in self.contacts.feet().iter().zip(forces) {
            let f_n = foot.normal.dot(&Vector3::from(*force));
            if f_n > 0.0 {
                weighted += f_n * (params.static_penetration(f_n) - foot.contact.penetration);
                total += f_n;
            }
        }
        if total > 0.0 {
            weighted / total
        } else {
            0.0
        }
    }

    fn knot(&self, forces: &[[f64; 3]], touching: &[bool]) -> Knot {
        let nj = self.model.nv - 6;
        Knot {
            t: self.state.t,
            q: self.measured_q.iter().copied().collect(),
            v: self.state.v.iter().copied().collect(),
            tau: self.tau.rows(6, nj).iter().copied().collect(),
            contact_force: forces.to_vec(),
            in_contact: touching.to_vec(),
            feedback_gain: None,
        }
    }
}

impl Plant for MujocoPlant<'_> {
    fn state(&self) -> &SimState {
        &self.state
    }

    fn physics_dt(&self) -> f64 {
        self.config.physics_dt
    }

    fn record_dt(&self) -> f64 {
        self.config.record_dt
    }

    fn step_recorded(&mut self, controller: &mut dyn Controller, trajectory: &mut Trajectory) -> Result<(), SimError> {
        if self.step % self.control_every == 0 {
            controller_torques(self.model, controller, &self.state, &mut self.tau, self.config.enforce_effort_limits)?;
        }
        // The anchors' estimate: legwork's contact model on the measured feet.
        self.contacts.evaluate_contacts(&self.state.q, &self.state.v, &self.state.anchors);
        let push: Vector3<f64> = self.pushes.iter().filter(|p| p.active(self.state.t)).map(|p| p.force).sum();
        self.request.clear();
        self.request.push_str("{\"tau\":[");
        for (k, tau) in self.tau.iter().skip(6).enumerate() {
            let _ = write!(self.request, "{}{tau}", if k > 0 { "," } else { "" });
        }
        let _ = write!(self.request, "],\"push\":[{},{},{}]}}", push.x, push.y, push.z);
        self.send_request()?;
        let answer: StepAnswer = self.read_answer()?;
        if answer.forces.len() != self.model.feet.len() || answer.touching.len() != self.model.feet.len() {
            return Err(self.external(format!("contacts of {} feet, expected {}", answer.forces.len(), self.model.feet.len())));
        }
        if self.step % self.record_every == 0 {
            trajectory.knots.push(self.knot(&answer.forces, &answer.touching));
        }
        self.contacts.update_anchors(&mut self.state.anchors);
        self.step += 1;
        if let Some(reason) = answer.failed {
            return Err(SimError::Diverged { step: self.step, t: answer.t, reason: format!("in MuJoCo: {reason}"), q: answer.q, v: answer.v });
        }
        self.set_measured(answer.t, &answer.q, &answer.v, Some(&answer.forces))
    }

    fn record_final(&mut self, trajectory: &mut Trajectory) -> Result<(), SimError> {
        if self.step % self.record_every != 0 {
            return Ok(());
        }
        self.request.clear();
        self.request.push_str("{\"contacts\":true}");
        self.send_request()?;
        let answer: ContactsAnswer = self.read_answer()?;
        trajectory.knots.push(self.knot(&answer.forces, &answer.touching));
        Ok(())
    }
}

impl Drop for MujocoPlant<'_> {
    fn drop(&mut self) {
        // The plant ends at the end of its input; a plant that hangs is killed.
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
