"""Figures for a paper from the results tables (matplotlib, Debian's
python3-matplotlib): each function draws on a new figure, or on `ax` when
given, and returns the figure; save it as SVG or PDF with
`fig.savefig("name.pdf")`, or call `save(fig, "name", ("svg", "pdf"))`.

    import totalgrad, totalgrad.figures as tf
    results = totalgrad.connect(db="t1.db")
    tf.success_rates(results.table1(["table1-tip-k1", "table1-tip-k001"]))
    tf.learning_curves(results.curves("table1-tip-k1"), results.curves("table1-tip-k1", top=5))
    tf.work_precision(totalgrad.study("docs/error-vs-time/study.json")["cells"])

The numbers drawn are the tables' own (the CLI's, computed by the results
library); nothing is recomputed here.
"""
import math

from . import _totalgrad

# The methods in the paper's order.
METHOD_ORDER = ["PILCO", "RP", "GR", "LR", "TP", "GLR", "GTP", "GTP+sn", "DEL"]


def method_colour(method):
    """The method's colour in every plot of the CLI and the dashboard
    (results/plot_style.h), so a method looks the same everywhere."""
    return _totalgrad._method_colour(method)


def _pyplot():
    import matplotlib.pyplot as plt  # the caller's backend (a notebook's inline one)
    return plt


def _methods(values):
    known = [m for m in METHOD_ORDER if m in set(values)]
    return known + sorted(set(values) - set(known))


def save(fig, stem, formats=("svg", "pdf")):
    """Writes `fig` as stem.svg, stem.pdf, ...; returns the paths."""
    paths = []
    for fmt in formats:
        path = f"{stem}.{fmt}"
        fig.savefig(path, bbox_inches="tight")
        paths.append(path)
    return paths


def success_rates(cells, ax=None, title=None):
    """Success rate per method and task with its 95 % Wilson interval, and
    the paper's rate as a marker where the table has one.

    `cells`: `Results.table1(...)` (cost, noise_k, method, success_rate,
    wilson95_low, wilson95_high, paper_success_rate) or
    `Results.success_table(...)` (variant, method, rate, low, high). Cells
    without trials are left out. One group of points per task, one colour per
    method."""
    plt = _pyplot()
    if "success_rate" in cells.columns:
        data = cells[cells["trials"] > 0].copy()
        data["task"] = data["cost"] + ", k = " + data["noise_k"].map(lambda k: f"{k:g}")
        rate, low, high = "success_rate", "wilson95_low", "wilson95_high"
        paper = "paper_success_rate"
    else:
        data = cells[cells["trials"] > 0].copy()
        data["task"] = data["variant"].where(data["variant"] != "", "all")
        rate, low, high, paper = "rate", "low", "high", None
    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 3.5))
    else:
        fig = ax.figure
    tasks = list(dict.fromkeys(data["task"]))
    methods = _methods(data["method"])
    width = 0.8 / max(1, len(methods))
    for j, method in enumerate(methods):
        rows = data[data["method"] == method]
        xs, ys, lows, highs, paper_xs, paper_ys = [], [], [], [], [], []
        for _, row in rows.iterrows():
            x = tasks.index(row["task"]) - 0.4 + width * (j + 0.5)
            xs.append(x)
            ys.append(row[rate])
            lows.append(row[rate] - row[low])
            highs.append(row[high] - row[rate])
            if paper and row[paper] is not None and not math.isnan(row[paper]):
                paper_xs.append(x)
                paper_ys.append(row[paper])
        colour = method_colour(method)
        ax.errorbar(xs, ys, yerr=[lows, highs], fmt="o", color=colour, capsize=3, label=method)
        if paper_xs:
            ax.plot(paper_xs, paper_ys, marker="x", linestyle="none", color=colour,
                    markersize=7, label="_paper")
    ax.set_xticks(range(len(tasks)))
    ax.set_xticklabels(tasks)
    ax.set_ylim(-0.05, 1.05)
    ax.set_ylabel("success rate (95 % Wilson interval)")
    if paper is not None:
        ax.plot([], [], marker="x", linestyle="none", color="black", label="paper")
    ax.legend(fontsize="small", ncol=2)
    if title:
        ax.set_title(title)
    return fig


def learning_curves(curves, best=None, axes=None):
    """The paper's Figure 3 panels from `Results.curves(sweep)`: per task
    variant, each method's median over runs per episode with the quartiles
    shaded, and its mean with +- one standard error; with `best` =
    `Results.curves(sweep, top=k)` a third panel, the median and quartiles of
    the k runs of lowest final cost. The numbers are the results library's
    (`results curves`); only the drawing is here."""
    plt = _pyplot()
    groups = list(dict.fromkeys(curves["variant"])) if len(curves) else [""]
    columns = 3 if best is not None else 2
    if axes is None:
        fig, axes = plt.subplots(len(groups), columns, figsize=(4 * columns, 3 * len(groups)),
                                 squeeze=False)
    else:
        fig = axes[0][0].figure

    def band(ax, rows, method):
        rows = rows.sort_values("episode")
        colour = method_colour(method)
        ax.plot(rows["episode"], rows["median"], color=colour, label=method)
        ax.fill_between(rows["episode"], rows["q25"], rows["q75"], color=colour, alpha=0.15)

    for r, group in enumerate(groups):
        rows = curves[curves["variant"] == group]
        label = f" ({group})" if group else ""
        for method in _methods(rows["method"]):
            mine = rows[rows["method"] == method].sort_values("episode")
            band(axes[r][0], mine, method)
            axes[r][1].errorbar(mine["episode"], mine["mean"], yerr=mine["standard_error"].fillna(0),
                                color=method_colour(method), capsize=2, label=method)
            if best is not None:
                top = best[(best["variant"] == group) & (best["method"] == method)]
                if len(top):
                    band(axes[r][2], top, method)
        axes[r][0].set_title("all runs: median, quartiles" + label)
        axes[r][1].set_title("all runs: mean +- standard error" + label)
        if best is not None:
            runs = int(best["trials"].max()) if len(best) else 0
            axes[r][2].set_title(f"the {runs} best runs: median, quartiles" + label)
        for ax in axes[r]:
            ax.set_xlabel("episode")
            ax.set_ylabel("evaluation cost")
        axes[r][0].legend(fontsize="small")
    fig.tight_layout()
    return fig


def work_precision(cells, error="rel_rmse", time="time_median_s", horizon=None, ax=None):
    """Gradient error against run time per estimator, one point per particle
    count P labelled with it (`totalgrad.study(...)["cells"]` or a DataFrame
    of them), log-log; `horizon` picks one H when the study has several
    (default: the largest)."""
    import pandas
    plt = _pyplot()
    data = pandas.DataFrame(cells)
    data = data[~data["omitted"] & data[error].notna() & data[time].notna() &
                (data["particles"] > 0)]
    if horizon is None:
        horizon = data["horizon"].max()
    data = data[data["horizon"] == horizon]
    if ax is None:
        fig, ax = plt.subplots(figsize=(5, 4))
    else:
        fig = ax.figure
    for estimator in _methods(data["estimator"]):
        rows = data[data["estimator"] == estimator].sort_values("particles")
        colour = method_colour(rows["method"].iloc[0])
        ax.plot(rows[time], rows[error], marker="o", color=colour, label=estimator)
        for _, row in rows.iterrows():
            ax.annotate(f"{row['particles']:g}", (row[time], row[error]), fontsize=6,
                        textcoords="offset points", xytext=(3, 3))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("seconds per gradient (median)")
    ax.set_ylabel(error)
    ax.set_title(f"gradient error against time, H = {horizon}")
    ax.legend(fontsize="small")
    return fig
