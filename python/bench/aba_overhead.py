"""The Python call overhead of `Robot.aba` on HyQ (issue 20: under 2 us over the Rust time).

Interleaved rounds, each timing (a) `aba` in Rust alone (`Robot._time_aba`: the same compiled
code, the robot's workspace, no Python between calls) and (b) `robot.aba(q, v, tau)` from
Python (new result array each call) and (c) with `out=` (written in place); the medians of
the rounds, per call. Run: `.venv-python/bin/python python/bench/aba_overhead.py [--json]`.
"""

import argparse
import json
import platform
import statistics
import timeit

import numpy as np

import legwork


def cpu() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--calls", type=int, default=200_000)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    hyq = legwork.Robot("hyq")
    rng = np.random.default_rng(0)
    q = hyq.integrate(hyq.standing, 0.1 * rng.standard_normal(hyq.nv))
    v, tau = rng.standard_normal(hyq.nv), 10 * rng.standard_normal(hyq.nv)
    out = np.empty(hyq.nv)
    rust, py, py_out = [], [], []
    for _ in range(args.rounds):
        rust.append(hyq._time_aba(q, v, tau, args.calls))
        py.append(timeit.timeit(lambda: hyq.aba(q, v, tau), number=args.calls) / args.calls)
        py_out.append(timeit.timeit(lambda: hyq.aba(q, v, tau, out=out), number=args.calls) / args.calls)
    m = {k: statistics.median(x) * 1e6 for k, x in (("rust_us", rust), ("python_us", py), ("python_out_us", py_out))}
    m["overhead_us"] = m["python_us"] - m["rust_us"]
    m["overhead_out_us"] = m["python_out_us"] - m["rust_us"]
    m.update(cpu=cpu(), rounds=args.rounds, calls=args.calls, numpy=np.__version__, python=platform.python_version())
    if args.json:
        print(json.dumps(m, indent=2))
    else:
        print(f"aba on HyQ, median of {args.rounds} interleaved rounds of {args.calls} calls ({m['cpu']}):")
        print(f"  Rust alone           {m['rust_us']:.3f} us")
        print(f"  Python, new array    {m['python_us']:.3f} us  (overhead {m['overhead_us']:.3f} us)")
        print(f"  Python, out=         {m['python_out_us']:.3f} us  (overhead {m['overhead_out_us']:.3f} us)")


if __name__ == "__main__":
    main()
