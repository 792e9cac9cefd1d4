"""rliable's performance profiles (Agarwal et al. 2021) from an `arena eval` run: reads
its episodes.csv (docs/evaluation.md documents every column; `highway_arena.evaluate(...,
out=...)` writes the same file), normalises a figure per scenario to [0, 1] over every
policy's episodes (min-max, flipped for a figure where lower is better), and draws, per
policy, the fraction of episodes scoring above each threshold with stratified-bootstrap
95 % bands, the plot rliable recommends beside IQM tables.

    arena eval --scenario merge-random --scenario overtake-random --episodes 50 --out out/eval
    pip install -r examples/requirements-rliable.txt
    python examples/performance_profiles.py out/eval/episodes.csv --figure return --out out/profiles.png

rliable wants the same number of runs per scenario: each scenario is one task, each
episode (seed) one run.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys

import numpy as np

LOWER_IS_BETTER = {"collision", "at_fault", "off_road", "rms_safety", "rms_comfort", "rms_efficiency", "p95_jerk", "max_jerk"}


def scores(path: str, figure: str) -> dict:
    """{policy: runs x tasks} of `figure`, normalised per scenario over every policy."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{path} has no episodes")
    if figure not in rows[0]:
        sys.exit(f"{path} has no column {figure!r}; columns: {', '.join(rows[0])}")
    scenarios = sorted({r["scenario"] for r in rows})
    policies = list(dict.fromkeys(r["policy"] for r in rows))
    values: dict = {}
    for r in rows:
        value = float(r[figure])
        values.setdefault((r["policy"], r["scenario"]), []).append(-value if figure in LOWER_IS_BETTER else value)
    runs = {len(v) for v in values.values()}
    if len(runs) != 1:
        sys.exit(f"every policy and scenario needs the same number of episodes, found {sorted(runs)}")
    out = {}
    for policy in policies:
        columns = []
        for scenario in scenarios:
            mine = np.array(values[(policy, scenario)])
            every = np.concatenate([np.array(values[(p, scenario)]) for p in policies])
            every = every[np.isfinite(every)]
            low, high = (every.min(), every.max()) if every.size else (0.0, 1.0)
            span = high - low if high > low else 1.0
            columns.append(np.where(np.isfinite(mine), (mine - low) / span, 0.0))
        out[policy] = np.stack(columns, axis=1)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("episodes", help="an episodes.csv written by arena eval or highway_arena.evaluate")
    parser.add_argument("--figure", default="return", help="the column to profile (default return)")
    parser.add_argument("--reps", type=int, default=2000, help="bootstrap resamples of the bands (default 2000)")
    parser.add_argument("--out", default="performance_profiles.png", help="the PNG to write")
    args = parser.parse_args()
    try:
        import matplotlib
        import matplotlib.lines

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from rliable import library as rly
        from rliable import plot_utils
    except ImportError as error:
        sys.exit(f"{error}: pip install -r examples/requirements-rliable.txt")
    by_policy = scores(args.episodes, args.figure)
    thresholds = np.linspace(0.0, 1.0, 101)
    profiles, bands = rly.create_performance_profile(by_policy, thresholds, reps=args.reps)
    colors = dict(zip(by_policy, plt.cm.tab20(np.linspace(0, 1, max(len(by_policy), 2)))))
    fig, ax = plt.subplots(figsize=(8, 5))
    plot_utils.plot_performance_profiles(
        profiles, thresholds, performance_profile_cis=bands, colors=colors,
        xlabel=f"normalised {args.figure} (per scenario, min-max over every policy)", ax=ax,
    )
    # One entry per policy's line (rliable's bands are artists too, so no automatic labels).
    lines = [matplotlib.lines.Line2D([0], [0], color=colors[p], lw=2) for p in by_policy]
    ax.legend(lines, list(by_policy), loc="lower left", fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out)
    for policy, profile in profiles.items():
        area = float(np.trapezoid(profile, thresholds)) if hasattr(np, "trapezoid") else float(np.trapz(profile, thresholds))
        print(f"{policy:45} area under the profile {area:.3f}" + ("" if math.isfinite(area) else " (no finite scores)"))
    print(f"written: {args.out}")


if __name__ == "__main__":
    main()
