#!/usr/bin/env python3
"""Side-by-side table of legwork (criterion) and Pinocchio (C++ anchor) timings.

Usage:
    python3 benches/compare_pinocchio.py PINOCCHIO.jsonl [CRITERION_DIR]

PINOCCHIO.jsonl: the JSON lines printed by ../shared/anchors/run_pinocchio_bench.sh (one per
robot). CRITERION_DIR: criterion's output folder (default target/criterion), after
`cargo bench --bench dynamics`. Prints a Markdown table of median ns per call and the ratio
legwork / Pinocchio (below 1.0 = legwork faster).
"""
import json
import pathlib
import sys

OPS = [
    "aba", "rnea", "crba", "nonLinearEffects", "computeMinverse", "fk_updateFramePlacements",
    "computeJointJacobians", "feet_jacobians_lwa", "centerOfMass", "computeABADerivatives",
    "computeRNEADerivatives",
]
ROBOTS = {"hyq": "HyQ", "a1": "A1"}


def criterion_median_ns(root: pathlib.Path, robot: str, op: str):
    for source in ("urdf", "embedded"):
        est = root / f"{robot}_{source}" / op / "new" / "estimates.json"
        if est.exists():
            return json.loads(est.read_text())["median"]["point_estimate"], source
    return None, None


def main() -> int:
    if len(sys.argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    pin = {}
    for line in pathlib.Path(sys.argv[1]).read_text().splitlines():
        line = line.strip()
        if line.startswith("{"):
            row = json.loads(line)
            pin[row["robot"]] = row
    root = pathlib.Path(sys.argv[2] if len(sys.argv) > 2 else "target/criterion")
    head = "| op |" + "".join(f" {ROBOTS[r]} legwork | {ROBOTS[r]} Pinocchio | ratio |" for r in ROBOTS)
    print(head)
    print("|---|" + "---:|---:|---:|" * len(ROBOTS))
    for op in OPS:
        cells = [f"| {op} |"]
        for r in ROBOTS:
            ours, _ = criterion_median_ns(root, r, op)
            theirs = pin.get(r, {}).get("timings_ns", {}).get(op, {}).get("median")
            o = f"{ours:.0f}" if ours is not None else "-"
            t = f"{theirs:.0f}" if theirs is not None else "-"
            ratio = f"{ours / theirs:.2f}" if ours is not None and theirs else "-"
            cells.append(f" {o} | {t} | {ratio} |")
        print("".join(cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
