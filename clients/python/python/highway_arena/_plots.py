"""The PNG plots of ``Evaluation.write`` (matplotlib), as ``arena eval`` draws them: box
plots of the three cost RMS per policy on a log axis, and success and collision rates
with their 95 % Wilson intervals."""

import matplotlib

matplotlib.use("Agg")  # files only: no display needed
import matplotlib.pyplot as plt  # noqa: E402

COSTS = [("rms_safety", "RMS safety"), ("rms_comfort", "RMS comfort"), ("rms_efficiency", "RMS efficiency")]
FLOOR = 1e-3


def _policies(items, scenario):
    return list(dict.fromkeys(x["policy"] for x in items if x["scenario"] == scenario))


def plot_costs(result, scenario, path):
    keys = [key for key, *_ in result.figures]
    names = _policies(result.episodes, scenario)
    fig, axes = plt.subplots(3, 1, figsize=(3 + 1.1 * len(names), 9))
    for ax, (key, label) in zip(axes, COSTS):
        k = keys.index(key)
        data = []
        for name in names:
            values = [e["figures"][k] for e in result.episodes if e["scenario"] == scenario and e["policy"] == name]
            data.append([max(v, FLOOR) for v in values if v is not None])
        ax.boxplot(data, tick_labels=names)
        ax.set_yscale("log")
        ax.set_ylabel(f"{label} (log)")
    fig.suptitle(f"{scenario}: RMS of the cost components per episode")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def plot_rates(result, scenario, path):
    names = _policies(result.summaries, scenario)
    fig, axes = plt.subplots(2, 1, figsize=(3 + 1.1 * len(names), 6.5))
    for ax, (key, colour) in zip(axes, [("success", "tab:blue"), ("collision", "tab:red")]):
        estimates = [result.summary(scenario, name)[key] for name in names]
        means = [e["mean"] or 0.0 for e in estimates]
        errors = [
            [max(0.0, (e["mean"] or 0.0) - (e["low"] or 0.0)) for e in estimates],
            [max(0.0, (e["high"] or 0.0) - (e["mean"] or 0.0)) for e in estimates],
        ]
        ax.bar(names, means, color=colour, alpha=0.6, yerr=errors, capsize=6)
        ax.set_ylim(0, 1.05)
        ax.set_ylabel(f"{key} rate")
    fig.suptitle(f"{scenario}: rates per policy, 95 % intervals")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


LOWER_IS_BETTER = {"at_fault"}


def plot_crossplay(crossplay, scenario, figure, path):
    """One cross-play matrix as a heatmap: a row per policy, a column per opponent, from the
    matrix's worst cell (red) to its best (green), each labelled with its estimate."""
    cells = [c for c in crossplay.cells if c[0] == scenario and c[1] == figure]
    policies = list(dict.fromkeys(c[2] for c in cells))
    opponents = list(dict.fromkeys(c[3] for c in cells))
    grid = [[None] * len(opponents) for _ in policies]
    labels = [[""] * len(opponents) for _ in policies]
    for _, _, policy, opponent, value, low, high, one in cells:
        i, j = policies.index(policy), opponents.index(opponent)
        grid[i][j] = float("nan") if value is None else value
        rate = figure != "return"
        show = (lambda v: f"{100 * v:.0f} %") if rate else (lambda v: f"{v:.3g}")
        labels[i][j] = "-" if value is None else show(value) + ("" if one else f"\n[{show(low)}, {show(high)}]")
    cmap = "RdYlGn_r" if figure in LOWER_IS_BETTER else "RdYlGn"
    fig, ax = plt.subplots(figsize=(2 + 1.6 * len(opponents), 1.2 + 0.7 * len(policies)))
    ax.imshow(grid, cmap=cmap, aspect="auto")
    ax.set_xticks(range(len(opponents)), [f"vs {o}" for o in opponents], rotation=20, ha="right")
    ax.set_yticks(range(len(policies)), policies)
    for i in range(len(policies)):
        for j in range(len(opponents)):
            ax.text(j, i, labels[i][j], ha="center", va="center", fontsize=8)
    ax.set_title(f"{scenario}: {figure}, policy (rows) against opponents (columns)")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
