# Loaded-foot sliding in a trajectory.json: per foot, the distance a foot's centre moves
# in the ground plane while its normal contact force exceeds a share of body weight.
import json, sys, numpy as np, mujoco
traj, model_xml = sys.argv[1], sys.argv[2]
thr = float(sys.argv[3]) if len(sys.argv) > 3 else 0.1
d = json.load(open(traj)); meta = d['metadata']
m = mujoco.MjModel.from_xml_path(model_xml); data = mujoco.MjData(m)
qadr = [m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in meta['joint_names']]
gid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n) for n in meta['foot_names']]
weight = sum(m.body_mass) * 9.81
prev = [None]*4; slide = np.zeros(4); loaded_time = np.zeros(4); dt = meta['dt']
worst = np.zeros(4)
t0=float(sys.argv[4]) if len(sys.argv)>4 else 0; t1=float(sys.argv[5]) if len(sys.argv)>5 else 1e9
for k in [k for k in d['knots'] if t0<=k['t']<=t1]:
    q = k['q']
    data.qpos[:3] = q[:3]; data.qpos[3:7] = [q[6], q[3], q[4], q[5]]; data.qpos[qadr] = q[7:]
    mujoco.mj_kinematics(m, data)
    for i in range(4):
        p = data.geom_xpos[gid[i]].copy()
        f = k['contact_force'][i] if 'contact_force' in k else None
        fn = f[2] if f is not None else 0.0
        if fn > thr * weight:
            if prev[i] is not None:
                s = np.linalg.norm(p[:2] - prev[i][:2]); slide[i] += s; worst[i] = max(worst[i], s/dt)
            loaded_time[i] += dt; prev[i] = p
        else:
            prev[i] = None
print(f"{traj}: loaded (> {thr:.0%} of weight) slide per foot (m):", np.round(slide,3), "loaded time (s):", np.round(loaded_time,2), "max loaded foot speed (m/s):", np.round(worst,2))
