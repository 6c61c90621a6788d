"""Experiment on a full-body plan's landing posture: the legs straighter at touch-down.

Usage:
  python3 tools/extend_prelanding.py PLAN.json OUT.json DELTA [KNOTS]

Every leg's foot is moved DELTA (m) further from its hip along the base's z axis (same x;
hip abduction kept) in the plan's pre-landing joint posture (the last knot's joint angles),
by a planar two-link inverse kinematics (A1: thigh and calf 0.2 m). The new angles replace
the joints of the pre-landing window (every trailing knot that holds the last knot's
angles) or, with KNOTS, of the last KNOTS knots only (the legs extend late in the flight);
the last knot's base rises by DELTA (the landing controller's CoM target). Nothing else of
the plan changes: the edited plan is not dynamically consistent (the flight's momentum is
the original's while the legs' inertia changes), it asks what the landing controller does
with a longer stroke (docs/experiments/jump-flip-4.md). `legwork jump` plans the same
posture consistently with the jump file's `[target] landing_extension`.
"""
import json
import math
import sys

THIGH = CALF = 0.2  # m, the A1's


def extended(thigh, calf, delta):
    """(thigh, calf) with the foot `delta` further down the base z, same x (knee bent backwards)."""
    x = -THIGH * math.sin(thigh) - CALF * math.sin(thigh + calf)
    z = -THIGH * math.cos(thigh) - CALF * math.cos(thigh + calf) - delta
    reach = math.hypot(x, z)
    if reach >= THIGH + CALF:
        raise SystemExit(f"extend_prelanding: a foot {delta} m further is out of reach ({reach:.3f} m)")
    knee = -math.acos((reach * reach - THIGH * THIGH - CALF * CALF) / (2 * THIGH * CALF))
    return math.atan2(-x, -z) - math.atan2(CALF * math.sin(knee), THIGH + CALF * math.cos(knee)), knee


def main():
    if len(sys.argv) not in (4, 5):
        raise SystemExit(__doc__)
    source, target, delta = sys.argv[1], sys.argv[2], float(sys.argv[3])
    plan = json.load(open(source))
    knots = plan["knots"]
    last = knots[-1]["q"][7:]
    first = len(knots) - 1
    while first > 0 and all(abs(a - b) < 1e-6 for a, b in zip(knots[first - 1]["q"][7:], last)):
        first -= 1
    if len(sys.argv) == 5:
        first = len(knots) - int(sys.argv[4])
    joints = list(last)
    for leg in range(len(last) // 3):
        joints[3 * leg + 1], joints[3 * leg + 2] = extended(last[3 * leg + 1], last[3 * leg + 2], delta)
    for k in knots[first:]:
        k["q"][7:] = joints
    knots[-1]["q"][2] += delta
    json.dump(plan, open(target, "w"))
    print(f"knots {first}..{len(knots) - 1} of {len(knots)}: leg 0 (thigh, calf) {last[1]:.3f}, {last[2]:.3f} -> {joints[1]:.3f}, {joints[2]:.3f} rad")


if __name__ == "__main__":
    main()
