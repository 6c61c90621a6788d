"""Straight drops in MuJoCo: which landing posture of the legs takes which touch-down speed.

Usage:
  .venv-mujoco/bin/python tools/landing_drop.py --mjcf a1.xml [--posture 0.8,-1.81 ...] \
      [--speeds 1:7:0.5] [--output drops.json]

`a1.xml` is `legwork export mjcf a1 --out a1.xml` (flat ground; only the feet collide). For
every sagittal posture `thigh,calf` (rad; hip abduction 0) the robot starts upright with its
four feet 1 mm above the ground, falling at speed `v` with no rotation, and every motor
holds the posture with a joint PD clipped at its effort limit (Kp 100 N m/rad, Kd 2 N m s/rad:
at the 10-40 rad/s a landing folds the legs at, the damping alone asks 20-80 N m, so the
torque sits at the limit while the legs fold; higher damping chatters at the 1 ms step on the
light calves). This is not legwork's landing controller (which lands barrel_roll at 3.4 m/s
and 11 rad/s of roll) and not a bound: it compares postures under one simple brake.

A drop "holds" when the base origin stays at least 0.1 m above the ground (legwork's
`FallCriteria::min_base_height`; the trunk's underside is then ~4 cm above it) and no joint
runs into its mechanical stop faster than 1 rad/s. Prints one line per posture and speed.
"""
import argparse
import json

import mujoco
import numpy as np

MIN_BASE_HEIGHT = 0.1  # m, legwork's FallCriteria::min_base_height
KP, KD = 100.0, 2.0


def legs(model):
    """(hip, thigh, calf) joint ids per leg, in the MJCF's order."""
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]
    return [tuple(names.index(f"{n[:-len('_hip_joint')]}_{part}_joint") for part in ("hip", "thigh", "calf"))
            for n in names if n and n.endswith("_hip_joint")]


def drop(model, posture, speed, duration=0.6):
    """One drop at `speed` (m/s, downwards) in `posture`; the landing's figures."""
    data = mujoco.MjData(model)
    target = {}
    for hip, thigh, calf in legs(model):
        target[hip], target[thigh], target[calf] = 0.0, posture[0], posture[1]
    for j, q in target.items():
        data.qpos[model.jnt_qposadr[j]] = q
    data.qpos[3:7] = [1, 0, 0, 0]
    data.qpos[2] = 1.0
    mujoco.mj_kinematics(model, data)
    feet = [g for g in range(model.ngeom) if (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "").endswith("_foot")]
    data.qpos[2] += 0.001 - min(data.geom_xpos[g][2] - model.geom_size[g][0] for g in feet)
    data.qvel[2] = -speed
    mujoco.mj_forward(model, data)
    kinetic = float(data.energy[1])
    actuator_of = {model.actuator_trnid[a, 0]: a for a in range(model.nu)}
    lowest, motor_work, stop = data.qpos[2], 0.0, None
    for _ in range(int(duration / model.opt.timestep)):
        for j, q_target in target.items():
            q, qd = data.qpos[model.jnt_qposadr[j]], data.qvel[model.jnt_dofadr[j]]
            effort = model.actuator_forcerange[actuator_of[j], 1]
            tau = float(np.clip(KP * (q_target - q) - KD * qd, -effort, effort))
            data.ctrl[actuator_of[j]] = tau
            motor_work += tau * qd * model.opt.timestep
        mujoco.mj_step(model, data)
        lowest = min(lowest, data.qpos[2])
        for j in target:
            lo, hi = model.jnt_range[j]
            q, qd = data.qpos[model.jnt_qposadr[j]], data.qvel[model.jnt_dofadr[j]]
            if stop is None and (q <= lo + 1e-3 or q >= hi - 1e-3) and abs(qd) > 1.0:
                stop = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
    return {"posture_rad": list(posture), "speed_m_s": speed, "holds": bool(lowest >= MIN_BASE_HEIGHT and stop is None),
            "kinetic_energy_j": kinetic, "motor_work_j": float(motor_work), "lowest_base_m": float(lowest), "joint_stop": stop}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mjcf", required=True)
    parser.add_argument("--posture", action="append", help="thigh,calf in rad (repeatable; default: legwork's pre-landing 0.8,-1.81 and 0.5,-1.0)")
    parser.add_argument("--speeds", default="1:7:0.5", help="first:last:step, m/s")
    parser.add_argument("--output")
    args = parser.parse_args()
    model = mujoco.MjModel.from_xml_path(args.mjcf)
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    if not all(model.actuator_forcelimited[a] for a in range(model.nu)):
        raise SystemExit(f"landing_drop: {args.mjcf}: every motor needs a force range (its effort limit)")
    postures = [tuple(float(x) for x in p.split(",")) for p in (args.posture or ["0.8,-1.81", "0.5,-1.0"])]
    first, last, step = (float(x) for x in args.speeds.split(":"))
    runs = []
    for posture in postures:
        for v in np.arange(first, last + 1e-9, step):
            r = drop(model, posture, float(v))
            runs.append(r)
            print(f"thigh {posture[0]:.2f} calf {posture[1]:.2f} at {v:.2f} m/s: {'holds' if r['holds'] else 'FAILS'} "
                  f"(kinetic {r['kinetic_energy_j']:.0f} J, motors {r['motor_work_j']:.0f} J, lowest base {r['lowest_base_m']:.3f} m, "
                  f"stop {r['joint_stop'] or 'none'})")
    if args.output:
        with open(args.output, "w") as f:
            json.dump(runs, f, indent=1)


if __name__ == "__main__":
    main()
