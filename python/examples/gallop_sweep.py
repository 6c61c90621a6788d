"""The gallop's goal distance from 0.5 to 3 m in 0.25 m steps, at three input weights: 33
solves as Ray tasks (`legwork.sweep`), the table in out/gallop_sweep/results.csv and a plot of
the solve cost and which solves met their target (out/gallop_sweep/sweep.png).

Run from the repository root after `pip install "./python[sweep]"` (and matplotlib for the
plot): `python python/examples/gallop_sweep.py [--address ray://head:10001]`. About 2-3
minutes on a 2-core machine (33 solves of 3-6 s, two at a time).
"""

import argparse
import os

import legwork

# The gallop file (tasks/gallop.toml) names its goal in three places: the desired base x, the
# goal waypoint's, and the target's.
GOAL_PATHS = ("desired.base_position[0]", "waypoint[0].desired.base_position[0]", "target[0].base_position[0]")


def gallop_goal(x: float) -> dict:
    """Overrides that move the gallop's goal to `x` metres ahead."""
    return {path: float(x) for path in GOAL_PATHS}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--address", default=None, help="a Ray cluster (default: a local Ray)")
    parser.add_argument("--out", default="out/gallop_sweep")
    args = parser.parse_args()
    goals = [0.5 + 0.25 * i for i in range(11)]
    weights = [0.001, 0.01, 0.1]  # the file's input weight is 0.01
    jobs = [legwork.sweep_job("gallop", {**gallop_goal(x), "input.weight": w}, name=f"x{x:.2f}-R{w:g}") for w in weights for x in goals]
    table = legwork.sweep(jobs, out=args.out, address=args.address)
    table["goal_m"] = table["override:desired.base_position[0]"]
    table["input_weight"] = table["override:input.weight"]
    print(table[["name", "goal_m", "input_weight", "verdict", "task_cost", "final_x_m", "solve_time_s"]].to_string(index=False))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plot (pip install matplotlib)")
        return
    fig, (cost, reach) = plt.subplots(1, 2, figsize=(11, 4))
    for w, rows in table.groupby("input_weight"):
        cost.semilogy(rows["goal_m"], rows["task_cost"], "-", label=f"input weight {w:g}")
        met = rows[rows["verdict"] == "met"]
        cost.semilogy(met["goal_m"], met["task_cost"], "o", color=cost.lines[-1].get_color())
        reach.plot(rows["goal_m"], rows["final_x_m"], "-", label=f"input weight {w:g}")
        reach.plot(met["goal_m"], met["final_x_m"], "o", color=reach.lines[-1].get_color())
    reach.plot([goals[0], goals[-1]], [goals[0], goals[-1]], "k:", label="goal")
    cost.set(xlabel="goal x [m]", ylabel="task cost", title="gallop: solve cost (dots: target met)")
    reach.set(xlabel="goal x [m]", ylabel="plan's final x [m]", title="gallop: reach (dots: target met)")
    cost.legend()
    reach.legend()
    fig.tight_layout()
    path = os.path.join(args.out, "sweep.png")
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
