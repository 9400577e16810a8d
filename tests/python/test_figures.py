"""totalgrad.figures draws the tables' own numbers: the success-rate points
and Wilson bars are the Table-1 cells, the curve panels the medians, means
and standard errors of the episode rows, the work-precision points the study
cells; and every figure saves as SVG and PDF."""
import json
import math
import os
import statistics
import subprocess

import matplotlib

matplotlib.use("Agg")

import pytest  # noqa: E402

import totalgrad  # noqa: E402
import totalgrad.figures as tf  # noqa: E402

ARCHIVE = os.path.join(os.path.dirname(__file__), "..", "..", "docs", "results", "table1",
                       "table1-tip-k1.archive.json")


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("figures") / "t1.db")
    totalgrad.import_archive(ARCHIVE, path)
    return path


@pytest.fixture(scope="module")
def results(db):
    return totalgrad.connect(db=db)


def test_success_rates_draw_each_cell_with_its_interval_and_the_papers_rate(results, tmp_path):
    grid = results.table1("table1-tip-k1")
    fig = tf.success_rates(grid)
    ax = fig.axes[0]
    cells = grid[grid["trials"] > 0].set_index("method")
    for container in ax.containers:  # one errorbar per method
        method = container.get_label()
        line, _, (bars,) = container
        cell = cells.loc[method]
        assert list(line.get_ydata()) == [cell["success_rate"]]
        (segment,) = bars.get_segments()
        assert segment[0][1] == pytest.approx(cell["wilson95_low"], abs=1e-12)
        assert segment[1][1] == pytest.approx(cell["wilson95_high"], abs=1e-12)
    assert len(ax.containers) == 4  # PILCO, RP, TP, GTP
    papers = [l for l in ax.lines if l.get_label() == "_paper"]
    assert sorted(y for l in papers for y in l.get_ydata()) == \
        sorted(cells["paper_success_rate"])
    assert [t.get_text() for t in ax.get_xticklabels()] == ["tip, k = 1"]
    svg, pdf = tf.save(fig, str(tmp_path / "rates"))
    assert open(svg).read(5) == "<?xml" and open(pdf, "rb").read(4) == b"%PDF"


def test_the_curve_panels_are_the_runs_median_mean_and_best(results):
    episodes = results.episodes("table1-tip-k1")
    fig = tf.learning_curves(results.curves("table1-tip-k1"), results.curves("table1-tip-k1", top=3))
    all_runs, mean_panel, best_panel = fig.axes[:3]
    tp = episodes[(episodes["method"] == "TP") & episodes["final_attempt"]]
    at_5 = tp[tp["episode"] == 5]["eval_cost_mean"].tolist()
    median_line = next(l for l in all_runs.lines if l.get_label() == "TP")
    assert median_line.get_ydata()[list(median_line.get_xdata()).index(5)] == \
        pytest.approx(statistics.median(at_5), rel=1e-12)
    mean_bars = next(c for c in mean_panel.containers if c.get_label() == "TP")
    mean_line = mean_bars[0]
    assert mean_line.get_ydata()[list(mean_line.get_xdata()).index(5)] == \
        pytest.approx(statistics.mean(at_5), rel=1e-12)
    # The best 3 runs by final cost (each run's last evaluated episode).
    last = tp[tp["episode"] == tp["episode"].max()].sort_values(["eval_cost_mean", "job_id"])
    best_jobs = last["job_id"].tolist()[:3]
    best_at_5 = tp[(tp["episode"] == 5) & tp["job_id"].isin(best_jobs)]["eval_cost_mean"]
    best_line = next(l for l in best_panel.lines if l.get_label() == "TP")
    assert best_line.get_ydata()[list(best_line.get_xdata()).index(5)] == \
        pytest.approx(statistics.median(best_at_5), rel=1e-12)
    assert best_line.get_color() == tf.method_colour("TP") == "#4e79a7"
    assert best_panel.get_title().startswith("the 3 best runs")


def test_curves_are_the_clis(results, db):
    """`Results.curves` is `results curves -f json`, row for row."""
    frame = results.curves("table1-tip-k1")
    run = subprocess.run([os.environ["TOTALGRAD_BIN"], "results", "curves", "table1-tip-k1",
                          "--db", db, "-f", "json"], capture_output=True, text=True, check=False)
    assert run.returncode == 0, run.stderr
    rows = json.loads(run.stdout)
    assert len(frame) == len(rows)
    for column in ("median", "q25", "q75", "mean", "standard_error"):
        assert [r[column] for r in rows] == pytest.approx(frame[column].tolist(), rel=0, abs=0,
                                                          nan_ok=True)
    best = results.curves("table1-tip-k1", top=3)
    assert best["trials"].max() == 3


def test_work_precision_has_a_labelled_point_per_particle_count():
    result = totalgrad.study({
        "problem": {"synthetic": {"data": 60, "horizon": 8, "seed": 2, "basis_functions": 10}},
        "estimators": ["RP", "LR"], "particles": [10, 30], "horizons": [5], "replicates": 3,
        "cell_budget_seconds": 1e6, "ess_replicates": 0,
        "reference": {"particles": 50, "replicates": 4, "budget_seconds": 1e6}})
    fig = tf.work_precision(result["cells"])
    ax = fig.axes[0]
    lines = {l.get_label(): l for l in ax.lines}
    assert set(lines) == {"RP", "LR"}
    rp = [c for c in result["cells"] if c["estimator"] == "RP"]
    assert list(lines["RP"].get_ydata()) == [c["rel_rmse"] for c in rp]
    assert sorted(t.get_text() for t in ax.texts) == ["10", "10", "30", "30"]
    assert all(math.isfinite(y) for y in lines["LR"].get_ydata())
