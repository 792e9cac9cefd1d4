"""The PNG plots of ``Evaluation.write`` (matplotlib), as ``arena eval`` draws them: box
plots of the three cost RMS per policy on log axes, the share of each way the episodes
ended with the success rate's 95 % Wilson interval, and cross-play heatmaps. Policies are
rows with their names left of the plot, so no count of policies or length of name makes
labels collide."""

import matplotlib

matplotlib.use("Agg")  # files only: no display needed
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.colors import LinearSegmentedColormap  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402

COSTS = [("rms_safety", "RMS safety"), ("rms_comfort", "RMS comfort"), ("rms_efficiency", "RMS efficiency")]
FLOOR = 1e-3
# arena_eval::OUTCOMES, in order, with the colours `arena eval` draws them in.
OUTCOMES = [
    ("success", "success", "#3c9650"),
    ("collision", "collision", "#c82828"),
    ("off_road", "off-road", "#f09628"),
    ("lane_end", "lane end", "#9650aa"),
    ("no_success", "time-out without success", "#969696"),
]
# From red (worst) to green (best), as `arena eval` colours its heatmaps.
RED_GREEN = LinearSegmentedColormap.from_list("red_green", ["#e65a5a", "#50dc5a"])
LOWER_IS_BETTER = {"at_fault"}
RATES = {"success", "at_fault"}


def _policies(items, scenario):
    return list(dict.fromkeys(x["policy"] for x in items if x["scenario"] == scenario))


def _height(rows):
    return 1.2 + 0.42 * rows


def plot_costs(result, scenario, path):
    keys = [key for key, *_ in result.figures]
    names = _policies(result.episodes, scenario)
    fig, axes = plt.subplots(3, 1, figsize=(11, 3 * _height(len(names)) + 0.6))
    for ax, (key, label) in zip(axes, COSTS):
        k = keys.index(key)
        data = []
        for name in names:
            values = [e["figures"][k] for e in result.episodes if e["scenario"] == scenario and e["policy"] == name]
            data.append([max(v, FLOOR) for v in values if v is not None] or [float("nan")])
        ax.boxplot(data, tick_labels=names, orientation="horizontal")
        ax.invert_yaxis()  # the first policy on top, as it ran
        ax.set_xscale("log")
        ax.set_xlabel(f"{label} (log)")
    fig.suptitle(f"{scenario}: RMS of the cost components per episode")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def plot_rates(result, scenario, path):
    """A stacked bar per policy of how its episodes ended (``outcomes``: so a policy that
    only stops shows as time-out), with the success rate's Wilson interval where its
    episodes are not all one (one distinct episode has no interval)."""
    summaries = [s for s in result.summaries if s["scenario"] == scenario]
    # Room for the longest name left of the bars and the episode counts right of them.
    longest = max((len(s["policy"]) for s in summaries), default=10)
    fig, ax = plt.subplots(figsize=(9 + 0.09 * longest, _height(len(summaries)) + 0.8))
    rows = range(len(summaries))
    left = [0.0] * len(summaries)
    for key, label, colour in OUTCOMES:
        shares = [dict(s["outcomes"])[key] for s in summaries]
        ax.barh(rows, shares, left=left, color=colour, label=label, height=0.7)
        for i, share in enumerate(shares):
            if share >= 0.06:
                ax.text(left[i] + 0.01, i, f"{100 * share:.0f} %", va="center", color="white", fontsize=9)
        left = [a + b for a, b in zip(left, shares)]
    for i, s in enumerate(summaries):
        success = dict(s["figures"])["success"]
        if s["distinct"] > 1 and success["n"]:
            ax.errorbar(
                # max(0, ...): at 0 % or 100 % an end can sit a rounding error beyond the mean.
                success["mean"], i,
                xerr=[[max(0.0, success["mean"] - success["low"])], [max(0.0, success["high"] - success["mean"])]],
                color="black", capsize=5, linewidth=1.5,
            )
        note = f"{s['episodes']} episodes" + (", 1 distinct: no interval" if s["distinct"] == 1 and s["episodes"] > 1 else "")
        ax.text(1.02, i, note, va="center", fontsize=9, transform=ax.get_yaxis_transform())
    ax.set_yticks(list(rows), [s["policy"] for s in summaries])
    ax.set_ylim(len(summaries) - 0.5, -0.5)  # the first policy on top, no empty margin
    ax.set_xlim(0, 1)
    ax.xaxis.set_major_formatter(lambda v, _: f"{100 * v:.0f} %")
    ax.legend(ncols=3, loc="lower left", bbox_to_anchor=(0, 1.0), fontsize=9, frameon=False)
    ax.set_title(f"{scenario}: how the episodes ended (bar: success's 95 % interval)", pad=40)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def plot_crossplay(crossplay, scenario, figure, path):
    """One cross-play matrix as a heatmap: a row per policy, a column per opponent, each
    labelled with its estimate; rates coloured on a fixed 0-100 % scale (the return from
    the matrix's worst to its best cell), the cells whose interval overlaps the best
    cell's framed."""
    cells = [c for c in crossplay.cells if c[0] == scenario and c[1] == figure]
    policies = list(dict.fromkeys(c[2] for c in cells))
    opponents = list(dict.fromkeys(c[3] for c in cells))
    grid = [[float("nan")] * len(opponents) for _ in policies]
    labels = [[""] * len(opponents) for _ in policies]
    rate = figure in RATES
    show = (lambda v: f"{100 * v:.0f} %") if rate else (lambda v: f"{v:.3g}")
    fig, ax = plt.subplots(figsize=(2.5 + 1.9 * len(opponents), 1.6 + 0.6 * len(policies)))
    for _, _, policy, opponent, value, low, high, one, near in cells:
        i, j = policies.index(policy), opponents.index(opponent)
        if value is not None:
            grid[i][j] = value
        labels[i][j] = "-" if value is None else show(value) + ("" if one else f"\n[{show(low)}, {show(high)}]")
        if near:
            ax.add_patch(Rectangle((j - 0.48, i - 0.46), 0.96, 0.92, fill=False, linewidth=2.5, edgecolor="black"))
    cmap = RED_GREEN.reversed() if figure in LOWER_IS_BETTER else RED_GREEN
    scale = dict(vmin=0.0, vmax=1.0) if rate else {}
    ax.imshow(grid, cmap=cmap, aspect="auto", **scale)
    ax.set_xticks(range(len(opponents)), [f"vs {o}" for o in opponents], rotation=30, ha="right")
    ax.set_yticks(range(len(policies)), policies)
    for i in range(len(policies)):
        for j in range(len(opponents)):
            ax.text(j, i, labels[i][j], ha="center", va="center", fontsize=8)
    if not rate:
        colours = "this matrix's worst (red) to best (green)"
    elif figure in LOWER_IS_BETTER:
        colours = "0 % green to 100 % red (lower is better)"
    else:
        colours = "0 % red to 100 % green"
    ax.set_title(
        f"{scenario}: {figure}, policy (rows) against opponents (columns)\n"
        f"colour: {colours}; framed: the interval overlaps the best cell's",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
