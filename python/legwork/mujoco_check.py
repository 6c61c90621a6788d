#!/usr/bin/env python3
"""legwork's MuJoCo checker (issue 16, item 5): a legwork trajectory replayed in MuJoCo.

Standard library + numpy + mujoco only (install: scripts/install-mujoco.sh, which makes
.venv-mujoco/ with the pinned versions). Normally run by legwork itself
(`legwork solve <task> --check mujoco`, `legwork check mujoco <folder>`), which writes the
MJCF (`legwork export mjcf`), the controller settings and reads the result back.

Commands:

  run      --mjcf M --reference trajectory.json --controller track|policy|stand
           --settings controller.json --output run.json [--duration T] [--record-dt T]
      Starts MuJoCo at the reference's first knot and runs the controller at every
      physics step (1 kHz at MuJoCo's 1 ms step):
        track   Neunert 2017 sec. IV-B / eq. 12, as legwork's src/control/tracking.rs:
                tau = tau_ff + Kp (q* - q) + Kd (v* - v) - sum_i J_i^T f_i over the planned
                stance feet, f = G^T (G G^T + eps I)^-1 [F; T] the base PD wrench of eq. 12.
        policy  the exported feedback policy: tau = tau_k + K_k [q (-) q*; v - v*], the
                reference (q*, v*) interpolated between knots as the tracking controller
                does, the feedforward tau_k and gain K_k of the knot interval held over it
                (legwork's src/control/feedback_policy.rs).
        stand   joint PD to a fixed pose (legwork's `--controller stand`).
      Writes the run as a legwork trajectory.json (legwork's conventions: quaternion
      x, y, z, w; base velocities in the base frame), the contact force on each foot from
      MuJoCo's contacts (mj_contactForce, summed per foot, world frame) and in_contact
      flags (a contact of the foot with positive normal force). A run that MuJoCo flags as
      unstable stops there; its summary says `mujoco_failed`.

  torques  --mjcf M --reference R --controller C [--settings S] --input states.json --output out.json
      The controller's torques (legwork's joint order, before the effort clip) at each
      state {t, q, v} of the input: the test set's comparison with legwork's controllers.

  inspect  --mjcf M --input states.json --output out.json
      The model's sizes and total mass and, at each state {q, v, a} of the input (legwork's
      conventions), the feet's positions, the mass matrix (mj_fullM) and the inverse
      dynamics (mj_inverse) both in legwork's velocity coordinates: the test set's
      comparison with legwork's CRBA, RNEA and forward kinematics; and the ground's height
      under each of the input's `ground_points` [x, y] (a ray cast onto the `ground` geom).

  plant    --mjcf M --start start.json
      MuJoCo as the plant of a controller that runs elsewhere (`legwork mpc --sim mujoco`),
      one JSON object per line on stdin/stdout. start.json holds the robot's joint_names,
      foot_names and the first state {q, v} (legwork's conventions). The plant answers
      first with {t, q, v, dt}; then, for every request {"tau": [nj], "push": [fx, fy, fz]}
      (joint torques, clipped to the actuators' force range; a world-frame force on the base
      at its frame's origin, as legwork's pushes), it takes one physics step and answers
      {t, q, v, forces, touching, failed}: the new state and the contacts of the step's
      start (the ground's force on each foot, world frame), `failed` a reason or null. A
      request {"contacts": true} answers {forces, touching} of the current state. End of
      input ends the plant.
"""

import argparse
import json
import math
import sys

import numpy as np
import mujoco


# --------------------------------------------------------------------------------------
# Lie-group helpers in legwork's (Pinocchio's) conventions.

def skew(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


# The plant's state and contacts go through the three functions below, written out in
# Python's floats: numpy hands even a 3-vector's norm or a 3 x 3 product to BLAS, whose
# kernels (picked per CPU) round differently, and a closed loop in MuJoCo then differs
# from one CPU to another (docs/experiments/mpc-15.md).

def unit_wxyz(w, x, y, z):
    """The quaternion divided by its norm, as a numpy array (w, x, y, z)."""
    w, x, y, z = float(w), float(x), float(y), float(z)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return np.array([w / n, x / n, y / n, z / n])


def mat_vec3(r, x):
    """r x for a 3 x 3 r, each row summed left to right."""
    return np.array([float(r[i, 0]) * float(x[0]) + float(r[i, 1]) * float(x[1]) + float(r[i, 2]) * float(x[2]) for i in range(3)])


def mat_t_vec3(r, x):
    """r^T x for a 3 x 3 r, each column summed top to bottom."""
    return np.array([float(r[0, j]) * float(x[0]) + float(r[1, j]) * float(x[1]) + float(r[2, j]) * float(x[2]) for j in range(3)])


def quat_xyzw_to_matrix(q):
    wxyz = unit_wxyz(q[3], q[0], q[1], q[2])
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, wxyz)
    return mat.reshape(3, 3)


def matrix_to_quat_xyzw(r):
    wxyz = np.zeros(4)
    mujoco.mju_mat2Quat(wxyz, np.ascontiguousarray(r).reshape(9))
    return np.array([wxyz[1], wxyz[2], wxyz[3], wxyz[0]])


def exp3(w):
    theta = np.linalg.norm(w)
    k = skew(w)
    if theta < 1e-8:
        return np.eye(3) + k + 0.5 * k @ k
    return np.eye(3) + math.sin(theta) / theta * k + (1.0 - math.cos(theta)) / theta**2 * k @ k


def log3(r):
    """The rotation vector of r (angle in [0, pi])."""
    wxyz = np.zeros(4)
    mujoco.mju_mat2Quat(wxyz, np.ascontiguousarray(r).reshape(9))
    if wxyz[0] < 0.0:
        wxyz = -wxyz
    s = np.linalg.norm(wxyz[1:])
    if s < 1e-12:
        return 2.0 * wxyz[1:]
    angle = 2.0 * math.atan2(s, wxyz[0])
    return wxyz[1:] / s * angle


def left_jacobian(w):
    """V(w) of SE(3)'s exponential: t = V(w) v."""
    theta = np.linalg.norm(w)
    k = skew(w)
    if theta < 1e-6:
        return np.eye(3) + 0.5 * k + k @ k / 6.0
    return np.eye(3) + (1.0 - math.cos(theta)) / theta**2 * k + (theta - math.sin(theta)) / theta**3 * k @ k


def exp6(nu):
    """SE(3) exponential of the twist nu = [v; w]: (R, t)."""
    v, w = nu[:3], nu[3:]
    return exp3(w), left_jacobian(w) @ v


def log6(r, t):
    """SE(3) logarithm of (R, t): the twist [v; w]."""
    w = log3(r)
    v = np.linalg.solve(left_jacobian(w), t)
    return np.concatenate([v, w])


class LegworkState:
    """legwork's q and v of the robot: q = [p, quat (x,y,z,w), joints], v = [v_B, w_B, qd]."""

    @staticmethod
    def integrate(q, dv, nj):
        """q (+) dv: the base by SE(3)'s exponential in the base frame, joints plainly."""
        r = quat_xyzw_to_matrix(q[3:7])
        dr, dt = exp6(dv[:6])
        out = np.empty(7 + nj)
        out[:3] = q[:3] + r @ dt
        out[3:7] = matrix_to_quat_xyzw(r @ dr)
        out[7:] = q[7:] + dv[6:]
        return out

    @staticmethod
    def difference(q0, q1, nj):
        """q1 (-) q0: log6(M0^-1 M1) for the base, q1 - q0 for the joints."""
        r0, r1 = quat_xyzw_to_matrix(q0[3:7]), quat_xyzw_to_matrix(q1[3:7])
        out = np.empty(6 + nj)
        out[:6] = log6(r0.T @ r1, r0.T @ (q1[:3] - q0[:3]))
        out[6:] = q1[7:] - q0[7:]
        return out


# --------------------------------------------------------------------------------------
# The robot in MuJoCo, addressed in legwork's order.

class Robot:
    def __init__(self, model, joint_names, foot_names):
        self.m = model
        if model.njnt < 1 or model.jnt_type[0] != mujoco.mjtJoint.mjJNT_FREE:
            sys.exit("mujoco_check: the MJCF's first joint must be the robot's free joint")
        self.nj = len(joint_names)
        self.joint_qadr, self.joint_dadr, self.actuator = [], [], []
        for name in joint_names:
            jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if jid < 0:
                sys.exit(f"mujoco_check: the MJCF has no joint '{name}' (from the trajectory's joint_names)")
            self.joint_qadr.append(model.jnt_qposadr[jid])
            self.joint_dadr.append(model.jnt_dofadr[jid])
            act = [a for a in range(model.nu) if model.actuator_trnid[a, 0] == jid]
            if len(act) != 1:
                sys.exit(f"mujoco_check: joint '{name}' has {len(act)} actuators in the MJCF, expected one motor")
            self.actuator.append(act[0])
        self.joint_qadr = np.array(self.joint_qadr)
        self.joint_dadr = np.array(self.joint_dadr)
        self.actuator = np.array(self.actuator)
        self.feet = []
        for name in foot_names:
            gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
            if gid < 0:
                sys.exit(f"mujoco_check: the MJCF has no geom '{name}' (from the trajectory's foot_names)")
            self.feet.append(gid)
        self.foot_index = {g: i for i, g in enumerate(self.feet)}
        self.effort = np.array([model.actuator_forcerange[a, 1] if model.actuator_forcelimited[a] else np.inf for a in self.actuator])
        self.nv = 6 + self.nj

    def set_state(self, d, q, v):
        q, v = np.asarray(q, float), np.asarray(v, float)
        d.qpos[:3] = q[:3]
        d.qpos[3:7] = [q[6], q[3], q[4], q[5]]
        d.qpos[self.joint_qadr] = q[7:]
        r = quat_xyzw_to_matrix(q[3:7])
        d.qvel[:3] = mat_vec3(r, v[:3])
        d.qvel[3:6] = v[3:6]
        d.qvel[self.joint_dadr] = v[6:]

    def state(self, d):
        wxyz = unit_wxyz(*d.qpos[3:7])
        q = np.concatenate([d.qpos[:3], [wxyz[1], wxyz[2], wxyz[3], wxyz[0]], d.qpos[self.joint_qadr]])
        r = quat_xyzw_to_matrix(q[3:7])
        v = np.concatenate([mat_t_vec3(r, d.qvel[:3]), d.qvel[3:6], d.qvel[self.joint_dadr]])
        return q, v

    def tangent_map(self, d):
        """T with qvel = T v (legwork's v), for the current orientation."""
        t = np.zeros((self.m.nv, self.nv))
        q, _ = self.state(d)
        t[:3, :3] = quat_xyzw_to_matrix(q[3:7])
        t[3:6, 3:6] = np.eye(3)
        for k, adr in enumerate(self.joint_dadr):
            t[adr, 6 + k] = 1.0
        return t

    def foot_positions(self, d):
        return np.array([d.geom_xpos[g] for g in self.feet])

    def foot_jacobian(self, d, i):
        """d(foot centre, world)/d(joint velocities), legwork's joint order (3 x nj)."""
        g = self.feet[i]
        jacp = np.zeros((3, self.m.nv))
        mujoco.mj_jac(self.m, d, jacp, None, d.geom_xpos[g], self.m.geom_bodyid[g])
        return jacp[:, self.joint_dadr]

    def contact_forces(self, d):
        """Force of the ground on each foot (world frame, summed over its contacts) and
        whether it touches (a contact with positive normal force)."""
        forces = np.zeros((len(self.feet), 3))
        touching = [False] * len(self.feet)
        f6 = np.zeros(6)
        for c in range(d.ncon):
            con = d.contact[c]
            for geom, sign in ((con.geom2, 1.0), (con.geom1, -1.0)):
                i = self.foot_index.get(int(geom))
                if i is None:
                    continue
                mujoco.mj_contactForce(self.m, d, c, f6)
                # The contact frame's rows are its axes (normal first, from geom1 to geom2);
                # f6 is the force geom1 exerts on geom2 in that frame.
                frame = np.asarray(con.frame).reshape(3, 3)
                forces[i] += sign * mat_t_vec3(frame, f6[:3])
                if f6[0] > 0.0:
                    touching[i] = True
        return forces, touching


# --------------------------------------------------------------------------------------
# The reference, sampled as legwork's TrackingController::sample does.

class Reference:
    def __init__(self, traj, nj):
        self.nj = nj
        knots = traj["knots"]
        self.t = np.array([k["t"] for k in knots])
        self.q = [np.array(k["q"], float) for k in knots]
        self.v = [np.array(k["v"], float) for k in knots]
        self.tau = [np.array(k["tau"], float) for k in knots]
        self.stance = [list(k["in_contact"]) for k in knots]
        self.gain = [np.array(k["feedback_gain"], float) if k.get("feedback_gain") is not None else None for k in knots]

    def sample(self, t):
        """q*, v*, tau_ff, planned stance at t, and the index of the knot interval."""
        n = len(self.t)
        k = max(int(np.searchsorted(self.t, t, side="right")) - 1, 0)
        k = min(k, n - 1)
        if k + 1 >= n or t <= self.t[0]:
            k = 0 if t <= self.t[0] else n - 1
            return self.q[k], self.v[k], self.tau[k], self.stance[k], k
        s = min(max((t - self.t[k]) / (self.t[k + 1] - self.t[k]), 0.0), 1.0)
        dq = LegworkState.difference(self.q[k], self.q[k + 1], self.nj)
        q = LegworkState.integrate(self.q[k], s * dq, self.nj)
        v = (1.0 - s) * self.v[k] + s * self.v[k + 1]
        tau = (1.0 - s) * self.tau[k] + s * self.tau[k + 1]
        stance = self.stance[k if s < 0.5 else k + 1]
        return q, v, tau, stance, k


# --------------------------------------------------------------------------------------
# Controllers: each returns the joint torques (legwork's joint order) at time t.

class Tracking:
    """Neunert 2017 sec. IV-B, eq. 12, as src/control/tracking.rs."""

    def __init__(self, robot, reference, settings):
        self.robot, self.ref = robot, reference
        self.kp = np.array(settings["joint_kp"], float)
        self.kd = np.array(settings["joint_kd"], float)
        self.px = np.array(settings["base_position_p"], float)
        self.dx = np.array(settings["base_position_d"], float)
        self.po = np.array(settings["base_orientation_p"], float)
        self.do = np.array(settings["base_orientation_d"], float)

    def torques(self, d, t):
        robot, nj = self.robot, self.robot.nj
        q_ref, v_ref, tau_ff, stance, _ = self.ref.sample(t)
        q, v = robot.state(d)
        tau = tau_ff + self.kp * (q_ref[7:] - q[7:]) + self.kd * (v_ref[6:] - v[6:])
        if not any(stance):
            return tau
        # eq. 12: the base PD wrench in the world frame, about the base origin.
        r, r_ref = quat_xyzw_to_matrix(q[3:7]), quat_xyzw_to_matrix(q_ref[3:7])
        x, x_ref = q[:3], q_ref[:3]
        xd, w = r @ v[:3], r @ v[3:6]
        xd_ref, w_ref = r_ref @ v_ref[:3], r_ref @ v_ref[3:6]
        force = self.px * (x_ref - x) + self.dx * (xd_ref - xd)
        torque = self.po * log3(r_ref @ r.T) + self.do * (w_ref - w)
        wrench = np.concatenate([force, torque])
        # f = G^T (G G^T + eps I)^-1 W over the planned stance feet.
        feet = robot.foot_positions(d)
        nfeet = len(robot.feet)
        grasp = np.zeros((6, 3 * nfeet))
        for i in range(nfeet):
            if stance[i]:
                grasp[:3, 3 * i:3 * i + 3] = np.eye(3)
                grasp[3:, 3 * i:3 * i + 3] = skew(feet[i] - x)
        ggt = grasp @ grasp.T
        ggt += 1e-8 * np.trace(ggt) * np.eye(6)
        try:
            y = np.linalg.solve(ggt, wrench)
        except np.linalg.LinAlgError:
            y = np.zeros(6)
        f = grasp.T @ y
        # tau_fb = -sum_i J_i^T f_i: the legs push the ground with -f_i.
        for i in range(nfeet):
            if stance[i]:
                tau -= robot.foot_jacobian(d, i).T @ f[3 * i:3 * i + 3]
        return tau


class Policy:
    """The exported feedback policy: tau = tau_ff + K [q (-) q*; v - v*]."""

    def __init__(self, robot, reference, dt):
        self.robot, self.ref, self.dt = robot, reference, dt
        missing = [k for k, g in enumerate(reference.gain) if g is None]
        if missing:
            sys.exit(f"mujoco_check: the reference has no feedback_gain at knot {missing[0]}; the policy needs one at every knot")

    def torques(self, d, t):
        nj = self.robot.nj
        q_ref, v_ref, _, _, _ = self.ref.sample(t)
        # The feedforward and the gain of the knot interval, held over it as the optimizer
        # holds its input (src/control/feedback_policy.rs); only (q*, v*) are interpolated.
        n = len(self.ref.gain)
        k = max(min(int(math.floor((t - self.ref.t[0]) / self.dt + 1e-9)), n - 1), 0)
        q, v = self.robot.state(d)
        dx = np.concatenate([LegworkState.difference(q_ref, q, nj), v - v_ref])
        return self.ref.tau[k] + self.ref.gain[k] @ dx


class Stand:
    """Joint PD to a fixed pose, no feedforward: legwork's JointPd."""

    def __init__(self, robot, settings):
        self.robot = robot
        self.kp = np.array(settings["joint_kp"], float)
        self.kd = np.array(settings["joint_kd"], float)
        self.target = np.array(settings["stand_target"], float)

    def torques(self, d, t):
        q, v = self.robot.state(d)
        return self.kp * (self.target - q[7:]) - self.kd * v[6:]


# --------------------------------------------------------------------------------------

def load_json(path):
    with open(path) as f:
        return json.load(f)


def write_json(path, value):
    with open(path, "w") as f:
        json.dump(value, f)


def setup(args):
    """The MuJoCo model and data, the reference's metadata, the robot's index maps, the
    reference and the controller that `args` name (shared by `run` and `torques`)."""
    model = mujoco.MjModel.from_xml_path(args.mjcf)
    data = mujoco.MjData(model)
    traj = load_json(args.reference)
    meta = traj["metadata"]
    robot = Robot(model, meta["joint_names"], meta["foot_names"])
    reference = Reference(traj, robot.nj)
    settings = load_json(args.settings) if args.settings else {}
    if args.controller == "track":
        controller = Tracking(robot, reference, settings)
    elif args.controller == "policy":
        controller = Policy(robot, reference, meta["dt"])
    else:
        controller = Stand(robot, settings)
    return model, data, meta, robot, reference, controller


def run(args):
    model, data, meta, robot, reference, controller = setup(args)
    dt = model.opt.timestep
    t0 = reference.t[0]
    duration = args.duration if args.duration is not None else reference.t[-1] - t0
    steps = int(round(duration / dt))
    record_every = max(int(round(args.record_dt / dt)), 1)
    robot.set_state(data, reference.q[0], reference.v[0])
    mujoco.mj_forward(model, data)
    knots, failed = [], None

    def knot(t, q, v, tau, forces, touching):
        return {"t": t, "q": q.tolist(), "v": v.tolist(), "tau": tau.tolist(), "contact_force": forces.tolist(), "in_contact": touching}

    tau = np.zeros(robot.nj)
    for step in range(steps + 1):
        t = t0 + step * dt
        q, v = robot.state(data)
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            failed = f"the state is not finite at t = {t:.3f} s (step {step})"
            break
        if step == steps:
            # The last knot: the final state with its contacts (no step after it).
            mujoco.mj_forward(model, data)
            forces, touching = robot.contact_forces(data)
            knots.append(knot(t, q, v, tau, forces, touching))
            break
        # Kinematics of the current state for the controller (feet, Jacobians).
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        tau = np.clip(controller.torques(data, t), -robot.effort, robot.effort)
        if not np.all(np.isfinite(tau)):
            failed = f"the controller's torques are not finite at t = {t:.3f} s (step {step})"
            break
        data.ctrl[robot.actuator] = tau
        mujoco.mj_step(model, data)
        # After mj_step, the contacts and their forces are those of the step's start.
        if step % record_every == 0:
            forces, touching = robot.contact_forces(data)
            knots.append(knot(t, q, v, tau, forces, touching))
        bad = data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number
        if bad > 0:
            failed = f"MuJoCo's accelerations are not finite (mjWARN_BADQACC) at t = {t:.3f} s (step {step})"
            break
    out = {
        "metadata": dict(meta, dt=args.record_dt, scenario=f"mujoco {args.controller}: {meta.get('scenario', '')}"),
        "knots": knots,
        "summary": {
            "simulator": f"MuJoCo {mujoco.__version__}",
            "controller": args.controller,
            "physics_dt_s": dt,
            "control_dt_s": dt,
        },
    }
    if failed:
        out["summary"]["mujoco_failed"] = failed
    if not knots:
        sys.exit(f"mujoco_check: {failed}")
    write_json(args.output, out)


def inspect(args):
    model = mujoco.MjModel.from_xml_path(args.mjcf)
    data = mujoco.MjData(model)
    spec = load_json(args.input)
    robot = Robot(model, spec["joint_names"], spec["foot_names"])
    out = {
        "nq": int(model.nq),
        "nv": int(model.nv),
        "nu": int(model.nu),
        "nbody": int(model.nbody),
        "total_mass": float(np.sum(model.body_mass)),
        "timestep": float(model.opt.timestep),
        "states": [],
    }
    for s in spec["states"]:
        q, v, a = (np.array(s[k], float) for k in ("q", "v", "a"))
        robot.set_state(data, q, v)
        t = robot.tangent_map(data)
        # MuJoCo's qacc of legwork's a: the base's world linear acceleration is
        # d/dt (R v_B) = R (a_B + w_B x v_B).
        r = t[:3, :3]
        qacc = t @ a
        qacc[:3] = r @ (a[:3] + np.cross(v[3:6], v[:3]))
        data.qacc[:] = qacc
        mujoco.mj_inverse(model, data)
        full = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, full)
        out["states"].append({
            "feet": robot.foot_positions(data).tolist(),
            "mass_matrix": (t.T @ full @ t).tolist(),
            "inverse_dynamics": (t.T @ data.qfrc_inverse).tolist(),
            "ncon": int(data.ncon),
        })
    # Ground heights under given points: a ray cast straight down onto the ground geom.
    ground = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "ground")
    data.qpos[:] = model.qpos0
    data.qpos[2] = 1000.0  # the robot far above the rays
    mujoco.mj_forward(model, data)
    heights = []
    geomid = np.zeros(1, dtype=np.int32)
    for x, y in spec.get("ground_points", []):
        top = 100.0
        group = np.zeros(6, dtype=np.uint8)
        group[model.geom_group[ground]] = 1
        dist = mujoco.mj_ray(model, data, np.array([x, y, top]), np.array([0.0, 0.0, -1.0]), group, 1, -1, geomid)
        heights.append(top - dist if dist >= 0 and geomid[0] == ground else None)
    out["ground_heights"] = heights
    write_json(args.output, out)


def torques(args):
    """The controller's torques (before the effort clip) at given states {t, q, v}."""
    model, data, _, robot, reference, controller = setup(args)
    out = []
    for s in load_json(args.input)["states"]:
        robot.set_state(data, s["q"], s["v"])
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        out.append(controller.torques(data, s["t"]).tolist())
    write_json(args.output, {"torques": out})


def plant(args):
    """MuJoCo stepped by a controller over a pipe (see the module docstring)."""
    model = mujoco.MjModel.from_xml_path(args.mjcf)
    data = mujoco.MjData(model)
    start = load_json(args.start)
    robot = Robot(model, start["joint_names"], start["foot_names"])
    robot.set_state(data, start["q"], start["v"])
    mujoco.mj_forward(model, data)
    base = model.jnt_bodyid[0]
    dt = model.opt.timestep
    step = 0
    out = sys.stdout

    def answer(value):
        out.write(json.dumps(value))
        out.write("\n")
        out.flush()

    q, v = robot.state(data)
    answer({"t": 0.0, "q": q.tolist(), "v": v.tolist(), "dt": dt})
    for line in sys.stdin:
        request = json.loads(line)
        if request.get("contacts"):
            mujoco.mj_forward(model, data)
            forces, touching = robot.contact_forces(data)
            answer({"forces": forces.tolist(), "touching": touching})
            continue
        tau = np.asarray(request["tau"], float)
        if tau.shape != (robot.nj,) or not np.all(np.isfinite(tau)):
            sys.exit(f"mujoco_check plant: request {step}: expected {robot.nj} finite torques, got {request['tau']}")
        push = np.asarray(request.get("push", [0.0, 0.0, 0.0]), float)
        # xfrc_applied acts at the body's centre of mass: the push at the base frame's
        # origin is that force plus the moment (origin - com) x F.
        data.xfrc_applied[base, :3] = push
        data.xfrc_applied[base, 3:] = np.cross(data.xpos[base] - data.xipos[base], push)
        data.ctrl[robot.actuator] = np.clip(tau, -robot.effort, robot.effort)
        mujoco.mj_step(model, data)
        step += 1
        # After mj_step, the contacts and their forces are those of the step's start.
        forces, touching = robot.contact_forces(data)
        q, v = robot.state(data)
        failed = None
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0:
            failed = f"MuJoCo's accelerations are not finite (mjWARN_BADQACC) at step {step}"
        elif not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            failed = f"the state is not finite at step {step}"
        answer({"t": step * dt, "q": q.tolist(), "v": v.tolist(), "forces": forces.tolist(), "touching": touching, "failed": failed})
        if failed:
            return


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("run", help="replay a trajectory in MuJoCo with a controller")
    p.add_argument("--mjcf", required=True)
    p.add_argument("--reference", required=True)
    p.add_argument("--controller", required=True, choices=["track", "policy", "stand"])
    p.add_argument("--settings", help="controller settings (JSON): gains, stand target")
    p.add_argument("--output", required=True)
    p.add_argument("--duration", type=float)
    p.add_argument("--record-dt", type=float, default=0.001)
    p = sub.add_parser("torques", help="a controller's torques at given states (tests)")
    p.add_argument("--mjcf", required=True)
    p.add_argument("--reference", required=True)
    p.add_argument("--controller", required=True, choices=["track", "policy", "stand"])
    p.add_argument("--settings")
    p.add_argument("--input", required=True)
    p.add_argument("--output", required=True)
    p = sub.add_parser("inspect", help="sizes, feet, mass matrix and inverse dynamics at given states")
    p.add_argument("--mjcf", required=True)
    p.add_argument("--input", required=True)
    p.add_argument("--output", required=True)
    p = sub.add_parser("plant", help="MuJoCo stepped by a controller over stdin/stdout (JSON lines)")
    p.add_argument("--mjcf", required=True)
    p.add_argument("--start", required=True)
    args = parser.parse_args()
    if args.command == "plant":
        plant(args)
    elif args.command == "run":
        if args.controller in ("track", "stand") and not args.settings:
            parser.error(f"--controller {args.controller} needs --settings")
        run(args)
    elif args.command == "torques":
        torques(args)
    else:
        inspect(args)


if __name__ == "__main__":
    main()
