"""A legwork jump in MuJoCo under legwork's own jump and landing controllers (Nguyen 2022,
sec. III): MuJoCo steps at 1 kHz, `legwork control serve` computes the torques, one JSON
line each way per step over a pipe (the controller is not ported to Python).

Usage:
  .venv-mujoco/bin/python tools/mujoco_jump.py --legwork target/release/legwork \
      --mjcf robot.xml --reference out/jump/lateral/trajectory.json [--settle 1.0] [--output run.json] \
      [--trials 20]

`robot.xml` is `legwork export mjcf a1 --jump <the jump> --out robot.xml` (the jump's
terrain, its box included). Prints and writes (JSON) the landing figures (position
and yaw error against the plan's last knot, roll and pitch, a fall) and the pipe's cost:
the round trip per step (write the state, read the torques) against MuJoCo's own step.

`--trials N` then runs issue 17's robustness trials in MuJoCo as legwork's `jump::trials` does
in its own simulator: trial `i` (seed 17 + i) scales every body's mass and rotational inertia
by independent factors uniform in 1 +- 5 % (the controller keeps the nominal model) and moves
the initial base uniformly within +-2 cm in x and y; success = no fall, |roll|, |pitch| < 10
deg, within 5 cm and 5 deg of yaw of the plan's last knot.

A run is judged as legwork's `jump::control::run_jump` judges it (issue 17): at touch-down
(the landing switch of the controller) + `--settle`; a fall is the base origin below 0.1 m
over the ground under it or |roll| or |pitch| beyond 60 deg at any instant *from touch-down
on* (a flip passes 60 deg in flight by design), a non-finite state, or no touch-down within
`--settle` after the plan's end ("never landed").
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time

import mujoco
import numpy as np

# The checker's module lives in the Python package's folder (python/legwork/); appended, not
# prepended, so that the package's own `mujoco.py` does not shadow MuJoCo's.
sys.path.append(os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "python", "legwork"))
from mujoco_check import Robot, load_json, quat_xyzw_to_matrix  # noqa: E402


def yaw_of(r):
    return math.atan2(r[1, 0], r[0, 0])


def roll_pitch(r):
    return math.atan2(r[2, 1], r[2, 2]), math.asin(max(-1.0, min(1.0, -r[2, 0])))


MIN_BASE_HEIGHT = 0.1  # m, legwork's FallCriteria::min_base_height
MAX_TILT = math.radians(60.0)  # legwork's FallCriteria::max_tilt


def ground_height(model, x, y):
    """Height of the terrain under (x, y): the ground plane and the tops of the boxes the
    MJCF export writes (`box<i>`). Height fields are not handled (no jump has one)."""
    h = 0.0
    for g in range(model.ngeom):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
        if name == "ground" and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
            h = model.geom_pos[g][2]
    for g in range(model.ngeom):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
        if name.startswith("box") and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            c, half = model.geom_pos[g], model.geom_size[g]
            if abs(x - c[0]) <= half[0] and abs(y - c[1]) <= half[1]:
                h = max(h, c[2] + half[2])
    return h


def fallen(model, data, robot):
    """Why the robot counts as fallen (legwork's `FallCriteria`), or None."""
    q, _ = robot.state(data)
    height = q[2] - ground_height(model, q[0], q[1])
    roll, pitch = roll_pitch(quat_xyzw_to_matrix(q[3:7]))
    if height < MIN_BASE_HEIGHT:
        return f"base {height:.3f} m above the ground"
    if abs(roll) > MAX_TILT or abs(pitch) > MAX_TILT:
        return f"roll {math.degrees(roll):.1f} deg, pitch {math.degrees(pitch):.1f} deg"
    return None


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--legwork", required=True, help="the legwork binary")
    parser.add_argument("--mjcf", required=True)
    parser.add_argument("--reference", required=True, help="the full-body plan (trajectory.json)")
    parser.add_argument("--settle", type=float, default=1.0, help="seconds simulated after touch-down (and how late after the plan's end a touch-down may come)")
    parser.add_argument("--output")
    parser.add_argument("--trials", type=int, default=0, help="robustness trials after the nominal run")
    args = parser.parse_args()

    plan = load_json(args.reference)
    result = run(args, plan)
    if args.trials > 0:
        outcomes = []
        for i in range(args.trials):
            rng = np.random.default_rng(17 + i)
            model = mujoco.MjModel.from_xml_path(args.mjcf)
            for b in range(1, model.nbody):
                model.body_mass[b] *= rng.uniform(0.95, 1.05)
                model.body_inertia[b] *= rng.uniform(0.95, 1.05)
            offset = rng.uniform(-0.02, 0.02, size=2)
            r = run(args, plan, model=model, base_offset=offset)
            r["success"] = r["failed"] is None and abs(r["roll_deg"]) < 10 and abs(r["pitch_deg"]) < 10 and r["position_error_m"] < 0.05 and abs(r["yaw_error_deg"]) < 5
            r["base_offset_m"] = offset.tolist()
            outcomes.append({k: r[k] for k in ("success", "failed", "position_error_m", "yaw_error_deg", "roll_deg", "pitch_deg", "base_offset_m")})
            print(f"trial {i}: {'ok' if r['success'] else 'FAIL'} {r['position_error_m'] * 1e3:.1f} mm, yaw {r['yaw_error_deg']:.2f}, roll {r['roll_deg']:.1f}, pitch {r['pitch_deg']:.1f} deg {r['failed'] or ''}", flush=True)
        errors = [o["position_error_m"] for o in outcomes]
        result["trials"] = {
            "successes": sum(o["success"] for o in outcomes),
            "count": len(outcomes),
            "position_error_m": {"mean": float(np.mean(errors)), "max": float(np.max(errors))},
            "yaw_error_deg_max": float(max(abs(o["yaw_error_deg"]) for o in outcomes)),
            "outcomes": outcomes,
        }
    text = json.dumps(result, indent=1)
    print(text)
    if args.output:
        with open(args.output, "w") as f:
            f.write(text)


def run(args, plan, model=None, base_offset=(0.0, 0.0)):
    """One run of the plan in MuJoCo under `legwork control serve`; the landing figures."""
    if model is None:
        model = mujoco.MjModel.from_xml_path(args.mjcf)
    data = mujoco.MjData(model)
    meta = plan["metadata"]
    robot = Robot(model, meta["joint_names"], meta["foot_names"])
    knots = plan["knots"]
    q0, v0 = np.array(knots[0]["q"]), np.array(knots[0]["v"])
    q0[0] += base_offset[0]
    q0[1] += base_offset[1]
    q_end = np.array(knots[-1]["q"])
    robot.set_state(data, q0, v0)
    mujoco.mj_forward(model, data)
    t0 = knots[0]["t"]
    dt = model.opt.timestep
    # At most the plan, a late touch-down and the settling after it; the loop ends at
    # touch-down + settle.
    steps = int(round((knots[-1]["t"] - t0 + 2.0 * args.settle) / dt))

    server = subprocess.Popen([args.legwork, "control", "serve", "--reference", args.reference], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
    round_trips, mujoco_steps = [], []
    failed = None
    landing_at = None
    for step in range(steps):
        t = t0 + step * dt
        q, v = robot.state(data)
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            failed = f"the state is not finite at t = {t:.3f} s"
            break
        forces, _ = robot.contact_forces(data)
        request = json.dumps({"t": t, "q": q.tolist(), "v": v.tolist(), "forces": forces.tolist()})
        start = time.perf_counter()
        server.stdin.write(request + "\n")
        server.stdin.flush()
        reply = json.loads(server.stdout.readline() or '{"error": "the server ended"}')
        round_trips.append(time.perf_counter() - start)
        if "error" in reply:
            failed = f"legwork control serve: {reply['error']}"
            break
        if reply["landing"] and landing_at is None:
            landing_at = t
        if landing_at is None and t > knots[-1]["t"] + args.settle:
            failed = f"never landed: still in the air {args.settle} s after the plan's end"
            break
        if landing_at is not None and t >= landing_at + args.settle:
            break
        data.ctrl[robot.actuator] = np.clip(np.array(reply["tau"]), -robot.effort, robot.effort)
        start = time.perf_counter()
        mujoco.mj_step(model, data)
        mujoco_steps.append(time.perf_counter() - start)
        if landing_at is not None:
            why = fallen(model, data, robot)
            if why:
                failed = f"fell at t = {t:.3f} s: {why}"
                break
    server.stdin.close()
    server.wait(timeout=10)
    q, _ = robot.state(data)
    r, r_end = quat_xyzw_to_matrix(q[3:7]), quat_xyzw_to_matrix(q_end[3:7])
    yaw_error = (yaw_of(r) - yaw_of(r_end) + math.pi) % (2 * math.pi) - math.pi
    roll, pitch = roll_pitch(r)
    us = lambda v: 1e6 * float(v)  # noqa: E731
    result = {
        "mujoco_version": mujoco.__version__,
        "steps": len(round_trips),
        "landing_switch_s": landing_at,
        "failed": failed,
        "position_error_m": float(np.linalg.norm(q[:2] - q_end[:2])),
        "yaw_error_deg": math.degrees(yaw_error),
        "roll_deg": math.degrees(roll),
        "pitch_deg": math.degrees(pitch),
        "round_trip_us": {"mean": us(np.mean(round_trips)), "median": us(np.median(round_trips)), "p99": us(np.percentile(round_trips, 99))} if round_trips else None,
        "mujoco_step_us": {"mean": us(np.mean(mujoco_steps)), "median": us(np.median(mujoco_steps))} if mujoco_steps else None,
    }
    return result


if __name__ == "__main__":
    main()
