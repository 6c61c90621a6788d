//! `legwork control serve`: legwork's jump and landing controllers (Nguyen 2022, sec. III)
//! for another simulator, over a pipe, so that one controller runs in both simulators
//! (tools/mujoco_jump.py steps MuJoCo with it).
//!
//! The protocol is one JSON object per line. The client sends, every control period,
//! `{"t": s, "q": [nq], "v": [nv], "forces": [[fx, fy, fz] per foot]}` in legwork's
//! conventions (`q` with the base quaternion (x, y, z, w), `v` with the base twist in the base
//! frame, the ground's force on each foot in the world frame); the server answers
//! `{"tau": [one torque per actuated joint], "landing": bool}`, or `{"error": "..."}` and
//! ends. End of input ends the server.

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use legwork::contact::ContactForce;
use legwork::io::Trajectory;
use legwork::jump::control::{JumpController, JumpSettings};
use legwork::sim::{Controller, FootState, SimState};
use nalgebra::{DVector, Vector3};
use serde::Deserialize;
use std::fmt::Write as _;
use std::io::{BufRead, Write};
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum ControlCommand {
    /// Serve the jump and landing controllers of a full-body plan on stdin/stdout (JSON
    /// lines; see the module documentation).
    Serve(ServeArgs),
}

#[derive(Debug, Args)]
pub struct ServeArgs {
    /// The full-body plan (`trajectory.json` of `legwork jump`).
    #[arg(long)]
    reference: PathBuf,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Request {
    t: f64,
    q: Vec<f64>,
    v: Vec<f64>,
    forces: Vec<[f64; 3]>,
}

pub fn run(cmd: ControlCommand) -> Result<()> {
    match cmd {
        ControlCommand::Serve(args) => serve(args),
    }
}

fn serve(args: ServeArgs) -> Result<()> {
    let reference = Trajectory::load_file(&args.reference)?;
    let (model, _) = super::robot::load(&reference.metadata.robot)?;
    reference.check_against(&model, &args.reference.display().to_string())?;
    let settings = JumpSettings::default();
    let jump_reference = settings.reference(&model, &reference)?;
    let mut controller = JumpController::new(&model, jump_reference, settings.jump_gains, settings.landing, settings.extension)?;
    let nfeet = model.feet.len();
    let mut feet: Vec<FootState> = (0..nfeet)
        .map(|_| FootState { position: Vector3::zeros(), velocity: Vector3::zeros(), normal: Vector3::z(), contact: ContactForce::none(Vector3::zeros(), 0.0) })
        .collect();
    let mut state = SimState { t: 0.0, q: DVector::zeros(model.nq), v: DVector::zeros(model.nv), anchors: vec![None; nfeet] };
    let mut tau = DVector::zeros(model.nv);
    let stdin = std::io::stdin();
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let mut line = String::new();
    let mut reply = String::new();
    loop {
        line.clear();
        if stdin.lock().read_line(&mut line).context("reading a request")? == 0 {
            return Ok(());
        }
        let request: Request = match serde_json::from_str(&line) {
            Ok(r) => r,
            Err(e) => return answer_error(&mut out, &format!("request: {e}")),
        };
        if request.q.len() != model.nq || request.v.len() != model.nv || request.forces.len() != nfeet {
            let expected = format!("q of {}, v of {}, forces of {} feet; got {}, {}, {}", model.nq, model.nv, nfeet, request.q.len(), request.v.len(), request.forces.len());
            return answer_error(&mut out, &format!("request: expected {expected}"));
        }
        state.t = request.t;
        state.q.copy_from_slice(&request.q);
        state.v.copy_from_slice(&request.v);
        for (foot, f) in feet.iter_mut().zip(&request.forces) {
            // Flat ground and box tops: the normal is world z.
            foot.contact.force = Vector3::from(*f);
            foot.contact.normal_force = f[2].max(0.0);
        }
        controller.sense(&feet);
        if let Err(e) = controller.compute(&model, &state, &mut tau) {
            return answer_error(&mut out, &e.to_string());
        }
        reply.clear();
        reply.push_str("{\"tau\":[");
        for (i, x) in tau.iter().skip(6).enumerate() {
            if i > 0 {
                reply.push(',');
            }
            let _ = write!(reply, "{x}");
        }
        let _ = writeln!(reply, "],\"landing\":{}}}", controller.switch().switched_at().is_some());
        out.write_all(reply.as_bytes()).and_then(|_| out.flush()).context("writing a reply")?;
    }
}

fn answer_error(out: &mut impl Write, message: &str) -> Result<()> {
    writeln!(out, "{}", serde_json::json!({ "error": message })).and_then(|_| out.flush()).context("writing the error")?;
    anyhow::bail!("{message}")
}
