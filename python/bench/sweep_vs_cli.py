"""A 20-solve sweep on a local Ray against the same solves run one after another by the
`legwork` command on two threads (issue 20: Ray at most 1.15x the command's time).

The solves: the gallop with its goal x from 0.5 to 2.875 m in 0.125 m steps (`--set` /
`overrides` on the goal's three places). Interleaved rounds: the command (each solve
`legwork solve gallop --threads 2 --set ...`), then the sweep (`legwork.sweep`, one CPU and
one SLQ thread per solve, two at a time); Ray's start-up (`ray.init` to ready, and
shutdown) is timed apart. Run from the repository root:
`.venv-python/bin/python python/bench/sweep_vs_cli.py [--rounds 2] [--json]`.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "examples"))
from gallop_sweep import gallop_goal  # noqa: E402

import legwork  # noqa: E402
from aba_overhead import cpu  # noqa: E402


def command_line(binary: str, goals, out: str) -> float:
    started = time.perf_counter()
    for x in goals:
        sets = [a for path, value in gallop_goal(x).items() for a in ("--set", f"{path}={value}")]
        done = subprocess.run([binary, "solve", "gallop", "--threads", "2", "--out", os.path.join(out, f"x{x:.3f}"), *sets], capture_output=True, text=True)
        if done.returncode not in (0, 1):
            sys.exit(f"legwork solve failed: {done.stderr}")
    return time.perf_counter() - started


def on_ray(goals, out: str) -> tuple:
    import ray

    started = time.perf_counter()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    ready = time.perf_counter()
    table = legwork.sweep([legwork.sweep_job("gallop", gallop_goal(x), name=f"x{x:.3f}") for x in goals], out=out, threads=1, progress=False)
    solved = time.perf_counter()
    ray.shutdown()
    return solved - ready, (ready - started) + (time.perf_counter() - solved), table


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--solves", type=int, default=20)
    parser.add_argument("--binary", default="target/release/legwork")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    goals = [0.5 + 0.125 * i for i in range(args.solves)]
    cli, ray_times, startup = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            cli.append(command_line(args.binary, goals, os.path.join(tmp, f"cli{r}")))
            solve, start, table = on_ray(goals, os.path.join(tmp, f"ray{r}"))
            ray_times.append(solve)
            startup.append(start)
            errors = table["error"].dropna()
            if len(errors):
                sys.exit(f"sweep errors: {list(errors)}")
            print(f"round {r + 1}: command line {cli[-1]:.1f} s, Ray {solve:.1f} s (+ {start:.1f} s start-up and shutdown), ratio {solve / cli[-1]:.3f}", file=sys.stderr)
    m = dict(
        cpu=cpu(), solves=args.solves, rounds=args.rounds,
        command_line_s=statistics.median(cli), ray_s=statistics.median(ray_times), ray_startup_s=statistics.median(startup),
        ratios=[r / c for r, c in zip(ray_times, cli)],
    )
    m["ratio"] = m["ray_s"] / m["command_line_s"]
    print(json.dumps(m, indent=2) if args.json else f"{args.solves} gallop solves: command line (2 threads, serial) {m['command_line_s']:.1f} s, Ray (2 x 1 thread) {m['ray_s']:.1f} s, ratio {m['ratio']:.3f}; Ray start-up and shutdown {m['ray_startup_s']:.1f} s ({m['cpu']})")


if __name__ == "__main__":
    main()
