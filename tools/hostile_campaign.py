#!/usr/bin/env python3
"""Hostile inputs through the command line, as a user or a batch job would give them (issue 18).

Each case runs `legwork` with a deadline and an address-space cap, and is judged on what a
script can rely on: no crash (signal), no hang (deadline), bounded memory (peak resident
size), the expected exit code (0 met, 1 ran but missed, 2 bad input, 3 could not finish) and,
for a bad file, an error that names it.

    python3 tools/hostile_campaign.py --legwork target/release/legwork [--out DIR] [--json FILE]

Prints one line per case and a summary; exits 1 if any case fails its judgement.
"""

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DEADLINE_S = 120
ADDRESS_SPACE = 16 * 2**30


def read(rel):
    with open(os.path.join(ROOT, rel)) as f:
        return f.read()


def urdf_chain(n, wide=False):
    link = lambda name: f'<link name="{name}"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
    parts = ['<robot name="g">', link("l0")]
    for i in range(1, n + 1):
        parts.append(link(f"l{i}"))
        parent, kind, limit = ("l0", "fixed", "") if wide else (f"l{i-1}", "revolute", '<limit lower="-1" upper="1" effort="10" velocity="1"/>')
        parts.append(f'<joint name="j{i}" type="{kind}"><parent link="{parent}"/><child link="l{i}"/><axis xyz="0 0 1"/>{limit}</joint>')
    return "".join(parts) + "</robot>"


def cases():
    """(name, args with {file} for the case's file, file text or None, expected codes)."""
    a1 = read("robots/a1.toml")
    shift = "\n".join([
        'name = "shift"', 'summary = "move the base 5 cm forward"', 'robot = "hyq"', "duration = 0.3", "dt = 0.002", "iterations = 2",
        "[desired]", 'base_position = [0.05, "start", "start"]', "[running]", "base_position = [100.0, 100.0, 100.0]", "joint_position = 5.0",
        "[final]", "base_position = [1000.0, 1000.0, 1000.0]", "[input]", "weight = 1e-4", ""])
    scenario = read("scenarios/flat.toml")
    gap = read("scenarios/gap.toml")
    jump = read("jumps/lateral.toml")
    urdf = read("../shared/robots/a1/a1.urdf") if os.path.exists(os.path.join(ROOT, "../shared/robots/a1/a1.urdf")) else None
    out = []
    add = lambda name, args, text, codes: out.append((name, args, text, codes))
    # Robots: URDF and legwork descriptions.
    info = ["robot", "info", "{file}"]
    add("urdf: empty file", info, "", {2})
    add("urdf: not XML", info, "this is not xml", {2})
    add("urdf: wrong root", info, "<sdf><model/></sdf>", {2})
    add("urdf: nested 30,000 deep", info, "<robot name='r'>" + "<a>" * 30000 + "</a>" * 30000 + "</robot>", {2})
    add("urdf: 30,000-joint chain", info, urdf_chain(30000), {2})
    add("urdf: 200-joint chain", info, urdf_chain(200), {0})
    add("urdf: 100,000 fixed links (22 MB)", info, urdf_chain(100000, wide=True), {0})
    add("urdf: two roots", info, "<robot name='r'><link name='a'/><link name='b'/></robot>", {2})
    add("urdf: loop", info, "<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='fixed'><parent link='a'/><child link='b'/></joint><joint name='k' type='fixed'><parent link='b'/><child link='a'/></joint></robot>", {2})
    if urdf:
        add("urdf: a1 truncated", info, urdf[: len(urdf) // 2], {2})
        add("urdf: a1 NaN mass", info, urdf.replace('mass value="', 'mass value="nan', 1), {2})
        add("urdf: a1 negative mass", info, urdf.replace('mass value="', 'mass value="-', 1), {2})
        add("urdf: a1 unknown joint type", info, urdf.replace('type="revolute"', 'type="ball"', 1), {2})
    add("urdf: missing file", ["robot", "info", "/no/such/robot.urdf"], None, {2})
    add("robot toml: empty", info, "", {2})
    add("robot toml: unknown field", info, a1.replace("\n", "\ncolour = 1\n", 1), {2})
    add("robot toml: NaN", info, re.sub(r"mass = [0-9.]+", "mass = nan", a1, count=1), {2})
    add("robot toml: binary garbage", info, "\x00\x01\x02\xff" * 100, {2})
    # Tasks.
    solve = ["solve", "{file}", "--out", "{out}"]
    add("task: as given (2 iterations)", solve, shift, {0})
    add("task: unknown field", solve, shift.replace("dt = ", "colour = 1\ndt = "), {2})
    add("task: NaN duration", solve, shift.replace("duration = 0.3", "duration = nan"), {2})
    add("task: negative dt", solve, shift.replace("dt = 0.002", "dt = -0.002"), {2})
    add("task: dt 0.7 s", solve, shift.replace("duration = 0.3", "duration = 1.5").replace("dt = 0.002", "dt = 0.7"), {2})
    add("task: 1e6 knots", ["--memory-limit", "16"] + solve, shift.replace("duration = 0.3", "duration = 2000.0"), {2})
    add("task: 1e300 s", solve, shift.replace("duration = 0.3", "duration = 1e300"), {2})
    add("task: iterations 0", solve, shift.replace("iterations = 2", "iterations = 0"), {2})
    add("task: unknown joint", solve, shift.replace("joint_position = 5.0", 'joint_position = { "elbow" = 5.0 }'), {2})
    add("task: [contact] section", solve, shift + "\n[contact]\nnormal_stiffness = 30000.0\n", {2})
    add("task: x = 100 m target", solve, shift + '\n[[target]]\nbase_position = [100.0, "any", "any"]\nposition_tolerance = 0.05\n', {1})
    add("task: target without tolerance", solve, shift + '\n[[target]]\nbase_position = [100.0, "any", "any"]\n', {2})
    add("task: target on an unknown foot", solve, shift + '\n[[target]]\nfeet_up = ["paw"]\n', {2})
    add("task: empty", solve, "", {2})
    add("task: binary garbage", solve, "\x00\xff" * 500, {2})
    add("task: unknown embedded", ["solve", "moonwalk"], None, {2})
    add("task: --threads 100000", ["solve", "{file}", "--out", "{out}", "--threads", "100000"], shift, {0})
    add("task: --iterations 0", ["solve", "{file}", "--out", "{out}", "--iterations", "0"], shift, {2})
    # Scenarios.
    walk = ["walk", "{file}", "--out", "{out}"]
    add("walk: goal beyond the 1.5 m gap", walk, gap.replace("x = [1.5, 1.85]", "x = [1.5, 3.0]"), {1, 2})
    add("walk: goal inside a 1 m block", walk, scenario + '\n[[world.block]]\nname = "b"\nx = [2.5, 3.5]\ny = [-0.5, 0.5]\ntop = 1.0\n', {1, 2})
    add("walk: overlapping blocks", walk, scenario + '\n[[world.block]]\nname = "b"\nx = [1.0, 2.0]\ny = [-0.5, 0.5]\ntop = 0.1\n\n[[world.block]]\nname = "c"\nx = [1.5, 2.5]\ny = [-0.5, 0.5]\ntop = 0.2\n', {0, 1, 2})
    add("walk: world 1e7 m wide", walk, scenario.replace("size = [5.0, 3.0]", "size = [1e7, 1e7]"), {2})
    add("walk: negative time limit", walk, scenario.replace("time_limit = 60.0", "time_limit = -1.0"), {2})
    add("walk: NaN goal", walk, scenario.replace("goal = [3.0, 0.0, 0.0]", "goal = [nan, 0.0, 0.0]"), {2})
    add("walk: unknown field", walk, scenario.replace("time_limit", "colour = 2\ntime_limit"), {2})
    add("walk: empty", walk, "", {2})
    add("walk: goal outside the world", walk, scenario.replace("goal = [3.0, 0.0, 0.0]", "goal = [300.0, 0.0, 0.0]"), {2})
    add("walk: unknown embedded", ["walk", "moon"], None, {2})
    # Jumps.
    jmp = ["jump", "{file}", "--out", "{out}", "--knots", "6"]
    add("jump: unknown field", jmp, jump.replace("\n", "\ncolour = 1\n", 1), {2})
    add("jump: NaN", jmp, re.sub(r"angle_deg = [-0-9.]+", "angle_deg = nan", jump, count=1), {2})
    add("jump: both angle and turns", jmp, jump.replace("angle_deg = 0.0", "angle_deg = 0.0\nturns = 1.0"), {2})
    add("jump: empty", jmp, "", {2})
    add("jump: --knots 0", ["jump", "lateral", "--knots", "0", "--out", "{out}"], None, {2})
    add("jump: --knots 1e9", ["jump", "lateral", "--knots", "1000000000", "--out", "{out}"], None, {2})
    add("jump: unknown embedded", ["jump", "moonwalk"], None, {2})
    # Simulation flags.
    sim = ["simulate", "--out", "{out}"]
    add("simulate: as given", sim + ["--duration", "0.2"], None, {0})
    for flag, value, codes in [
        ("--duration", "-1", {2}), ("--duration", "nan", {2}), ("--duration", "1e9", {2}), ("--duration", "inf", {2}),
        ("--physics-rate", "0", {2}), ("--physics-rate", "nan", {2}), ("--physics-rate", "1e12", {2}), ("--physics-rate", "10", {2}),
        ("--control-rate", "3", {2}), ("--control-rate=-1", "", {2}), ("--record-rate", "0", {2}), ("--record-rate", "7", {2}),
        ("--drop-height", "-1", {2}), ("--drop-height", "1e6", {2}), ("--drop-height", "nan", {2}),
        ("--push", "1,2@3", {2}), ("--push", "nan,0,0@0.1:0.1", {2}), ("--push", "1e12,0,0@0.1:0.1", {0, 2, 3}),
        ("--threads", "100000", {2}), ("--robot", "moon", {2}), ("--terrain", "/no/such/map.toml", {2}),
    ]:
        add(f"simulate: {flag} {value}", sim + ([flag, value] if value else [flag]) + ([] if flag == "--duration" else ["--duration", "0.2"]), None, codes)
    add("simulate: --memory-limit 0", ["--memory-limit", "0"] + sim, None, {2})
    # Trajectories.
    track = ["simulate", "--robot", "a1", "--controller", "track", "--reference", "{file}", "--duration", "0.05", "--out", "{out}"]
    add("trajectory: empty", track, "", {2})
    add("trajectory: not JSON", track, "{not json", {2})
    add("trajectory: wrong shape", track, '{"metadata": {}, "knots": []}', {2})
    add("trajectory: view of garbage", ["view", "{file}", "--out", "{out}"], "\x00" * 100, {2})
    # More files and commands.
    add("task: dt 1e-9 (3e8 knots)", ["--memory-limit", "16"] + solve, shift.replace("dt = 0.002", "dt = 1e-9"), {2})
    add("task: waypoint after the end", solve, shift + "\n[[waypoint]]\ntime = 5.0\nrho = 100.0\nweights = { base_position = [0.0, 0.0, 1.0] }\n", {2})
    add("task: negative weight", solve, shift.replace("weight = 1e-4", "weight = -1.0"), {2})
    add("task: --robot moon", ["solve", "{file}", "--robot", "moon", "--out", "{out}"], shift, {2})
    add("task: a folder for a file", ["solve", "{out}"], None, {2})
    add("walk: 2,000 blocks", walk, scenario + "".join(f'\n[[world.block]]\nname = "b{i}"\nx = [{-0.9 + 0.002 * i:.4f}, {-0.899 + 0.002 * i:.4f}]\ny = [1.2, 1.3]\ntop = 0.01\n' for i in range(2000)), {0, 1, 2})
    add("walk: resolution 1e-9", walk, scenario.replace("size = [5.0, 3.0]", "size = [5.0, 3.0]\nresolution = 1e-9"), {2})
    add("walk: --seed 2^64-1", ["walk", "flat", "--seed", "18446744073709551615", "--out", "{out}"], None, {0, 1})
    add("jump: box 1e6 m high", jmp, jump + "\n[[box]]\nx = [-0.5, 0.5]\ny = [-0.5, 0.5]\ntop = 1e6\n", {2})
    add("jump: --trials 1000000", ["jump", "lateral", "--trials", "1000000", "--out", "{out}"], None, {2})
    add("export: mjcf of a bad robot", ["export", "mjcf", "{file}", "--out", "{out}.xml"], "<robot name='x'></robot>", {2})
    add("export: mjcf of an unknown task", ["export", "mjcf", "hyq", "--task", "moonwalk", "--out", "{out}.xml"], None, {2})
    add("check: mujoco on a missing folder", ["check", "mujoco", "/no/such/folder"], None, {2, 3})
    add("control: serve a missing reference", ["control", "serve", "--reference", "/no/such/trajectory.json"], None, {2})
    add("simulate: --integrator euler2", sim + ["--integrator", "euler2"], None, {2})
    add("simulate: a garbage height map", sim + ["--terrain", "{file}", "--duration", "0.1"], "cells = [[nan]]", {2})
    add("bench: slq --iterations 0", ["bench", "slq", "--iterations", "0"], None, {2})
    # Commands that need nothing.
    add("usage: no command", [], None, {2})
    add("usage: unknown command", ["fly"], None, {2})
    add("usage: --help", ["--help"], None, {0})
    add("bench: jumps --repeats 0", ["bench", "jumps", "--repeats", "0"], None, {2})
    add("bench: terrain --trials 0", ["bench", "terrain", "--trials", "0"], None, {2})
    return out


def run(legwork, out_dir, case, index):
    name, args, text, codes = case
    work = os.path.join(out_dir, f"case{index:03d}")
    os.makedirs(work, exist_ok=True)
    path = None
    if text is not None:
        ext = ".urdf" if name.startswith("urdf") else ".json" if name.startswith("trajectory") else ".toml"
        path = os.path.join(work, f"input{index:03d}{ext}")
        with open(path, "w", encoding="utf-8", errors="surrogateescape") as f:
            f.write(text)
    argv = [legwork] + [a.replace("{file}", path or "").replace("{out}", os.path.join(work, "out")) for a in args]

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))

    start = time.time()
    try:
        p = subprocess.run(argv, capture_output=True, timeout=DEADLINE_S, preexec_fn=limit, cwd=work)
        code, stderr = p.returncode, p.stderr.decode("utf-8", "replace")
    except subprocess.TimeoutExpired:
        code, stderr = None, ""
    wall = time.time() - start
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    problems = []
    if code is None:
        problems.append(f"no answer in {DEADLINE_S} s")
    elif code < 0 or code >= 128:
        problems.append(f"crashed (code {code})")
    elif code not in codes:
        problems.append(f"exit code {code}, expected {sorted(codes)}")
    if "panicked" in stderr:
        problems.append("panicked")
    # A bad file must be named; an error about a command-line option names the option.
    named_elsewhere = stderr.startswith("error: --") or any(f"'{a}'" in stderr for a in argv[1:])
    if code == 2 and path is not None and os.path.basename(path) not in stderr and not named_elsewhere:
        problems.append("the error does not name the file")
    first = next((l for l in stderr.splitlines() if l.startswith("error") or l.startswith("warning")), "")
    return {"case": name, "exit_code": code, "expected": sorted(codes), "wall_s": round(wall, 2), "problems": problems, "message": first[:200]}, usage.ru_maxrss


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--legwork", default=os.path.join(ROOT, "target", "release", "legwork"))
    parser.add_argument("--out", default=None)
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    out_dir = args.out or tempfile.mkdtemp(prefix="legwork-hostile-")
    results = []
    for i, case in enumerate(cases()):
        result, _ = run(os.path.abspath(args.legwork), out_dir, case, i)
        results.append(result)
        verdict = "ok" if not result["problems"] else "FAIL: " + "; ".join(result["problems"])
        print(f"{i:3d} {result['case']:<40} exit {result['exit_code']!s:<4} {result['wall_s']:7.2f} s  {verdict}  {result['message'][:110]}", flush=True)
    failed = [r for r in results if r["problems"]]
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f"{len(results)} cases, {len(results) - len(failed)} as expected, {len(failed)} not; largest peak resident size of a case {peak_mb:.0f} MB; longest {max(r['wall_s'] for r in results):.1f} s")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"cases": results, "largest_peak_rss_mb": peak_mb}, f, indent=1)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
