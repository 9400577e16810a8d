"""totalgrad from Python: trials, scenes and simulations in-process, and the
results of a coordinator or of its database file as pandas DataFrames.

    import totalgrad
    for episode in totalgrad.trial(scene="cartpole-swingup", method="TP", seed=10):
        print(episode["episode"], episode["eval_cost_mean"])

    results = totalgrad.connect(db="sweeps.db")        # or coordinator="host:7070"
    results.success_table("table1-tip-k1")             # the CLI's `results table`
    results.episodes("table1-tip-k1")                  # one row per episode

Everything runs in the C++ library the `totalgrad` binaries are built from:
a trial here gives the CLI's numbers bit for bit (with the same OpenBLAS
kernels: see `blas_kernels()`), and every table is the one `totalgrad results
... -f json` prints, computed by the same results library. Long calls release
the GIL; Ctrl-C stops a trial (its thread ends before KeyboardInterrupt is
raised). docs/python.md has the whole interface.
"""
import json
import os
import subprocess
import sys
import warnings


def _choose_blas_kernels():
    """Sets OPENBLAS_CORETYPE as the totalgrad binaries would (core/common/
    blas.h), before OpenBLAS loads with the extension module: they re-execute
    themselves with it set, which a Python process cannot. The choice depends
    on the kernels OpenBLAS would load by itself, so a child interpreter
    loads the extension once and says (one short process per import)."""
    # As the binaries: an inherited OPENBLAS_CORETYPE does not decide unless
    # TOTALGRAD_BLAS_CORE=env (the child below sees it and says what they run).
    if os.environ.get("TOTALGRAD_BLAS_CORE") == "env":
        return
    try:
        with open("/proc/self/maps") as maps:
            if "openblas" in maps.read():
                return  # already loaded (numpy): too late; blas_kernels() tells
    except OSError:
        return
    probe = ("import sys; sys.path.insert(0, sys.argv[1]); import _totalgrad; "
             "print(_totalgrad._blas()[1])")
    try:
        wanted = subprocess.run([sys.executable, "-c", probe, os.path.dirname(__file__)],
                                capture_output=True, text=True, timeout=60,
                                check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return
    if wanted:
        os.environ["OPENBLAS_CORETYPE"] = wanted


_choose_blas_kernels()

from . import _totalgrad  # noqa: E402 (after the kernels are chosen)

__all__ = ["trial", "Trial", "scenes", "simulate", "trial_options", "connect", "Results",
           "import_archive", "Problem", "study", "sweep_toml", "blas_kernels", "build"]

build = _totalgrad.build


def _option_text(key, value):
    """An option value as the option table parses it: shortest round-trip
    text for floats (repr), true/false for bools, decimal for integers."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (int, str)):
        return str(value)
    raise TypeError(f"option '{key}': {type(value).__name__} is not a number, bool or text")


def blas_kernels():
    """(loaded, wanted): the OpenBLAS kernels this process loaded, and the
    kernels the totalgrad binaries would run here ('' when they are the same).
    A trial's last bits depend on them (docs/python.md, "Same bits")."""
    return _totalgrad._blas()


_loaded, _wanted = blas_kernels()
if _wanted:
    warnings.warn(
        f"OpenBLAS loaded its {_loaded} kernels, the totalgrad binaries run {_wanted} here: "
        f"trials will differ from the CLI's in their last bits. For the same bits import "
        f"totalgrad before numpy, or start Python with OPENBLAS_CORETYPE={_wanted}.",
        RuntimeWarning, stacklevel=2)


def trial_options():
    """Every trial option and its default, as {key: default text}, in the
    option table's order (the CLI's `trial --KEY` flags and sweep keys)."""
    return dict(_totalgrad._trial_options())


class Trial:
    """One trial running in this process; iterate it for its episodes (dicts
    with the keys of `totalgrad trial --json`'s lines). After the last
    episode, `summary` holds success, final_eval_cost, threshold,
    held_fraction and the options used."""

    def __init__(self, options, threads=1):
        self._run = _totalgrad._TrialRun(options, threads)
        self.summary = None
        self.episodes = []

    def __iter__(self):
        return self

    def __next__(self):
        text = self._run.next_episode()
        if text is None:
            if self.summary is None:
                self.summary = json.loads(self._run.summary())
            raise StopIteration
        episode = json.loads(text)
        self.episodes.append(episode)
        return episode

    def run(self):
        """Runs the trial to its end; returns the episodes as a DataFrame."""
        for _ in self:
            pass
        return self.frame()

    def frame(self):
        """The episodes so far as a pandas DataFrame, one row per episode."""
        import pandas
        return pandas.DataFrame(self.episodes)


def trial(threads=1, **options):
    """Starts a trial and returns it (a Trial: iterate it for its episodes).

    Options are the trial options by key (`trial_options()` lists them with
    their defaults), e.g. scene="pendulum", method="TP", seed=10, episodes=5,
    noise_k=0.01; a bad key or value raises ValueError with the CLI's message
    ("did you mean ..."). `threads` spreads the trial over more threads
    without changing a bit of it."""
    return Trial([(k, _option_text(k, v)) for k, v in options.items()], threads)


def scenes():
    """The scene catalog as `totalgrad scenes --json` lists it: a list of dicts."""
    return json.loads(_totalgrad._scenes_json())


def simulate(scene, start, forces, dt=None):
    """`totalgrad simulate --json`: integrates the scene's noise-free plant from
    `start` (D numbers) under `forces` (K x F numbers, step by step) and
    returns {"dt", "states", "forces", "energy"}."""
    def numbers(values):
        return ",".join(repr(float(v)) for v in values)
    flat = []
    for f in forces:
        flat.extend(f if isinstance(f, (list, tuple)) else [f])
    return json.loads(_totalgrad._simulate_json(scene, numbers(start), numbers(flat),
                                                "" if dt is None else repr(float(dt))))


class Problem:
    """A frozen gradient problem: a GP model, an RBF policy at fixed
    parameters, a start distribution and a cost, from a trial snapshot
    (`totalgrad trial --snapshot-episodes`) or synthetic on a scene; the
    "problem" of a study file (docs/error-vs-time.md)."""

    def __init__(self, snapshot=None, episode=None, policy="before", synthetic=None,
                 base_dir="."):
        if (snapshot is None) == (synthetic is None):
            raise ValueError("give either snapshot (a snapshot file) or synthetic (a dict)")
        if snapshot is not None:
            problem = {"snapshot": str(snapshot), "policy": policy}
            if episode is not None:
                problem["episode"] = int(episode)
        else:
            problem = {"synthetic": dict(synthetic)}
        self._problem = _totalgrad._Problem(json.dumps({"problem": problem}), str(base_dir))

    @property
    def source(self):
        return self._problem.source

    @property
    def scene(self):
        return self._problem.scene

    @property
    def horizon(self):
        return self._problem.horizon

    def gradients(self, method, particles=300, replicates=10, seed=1, horizon=None, **options):
        """`replicates` gradient estimates of a particle method (RP, GR, LR,
        TP, GLR, GTP, GTP+sn, DEL) with `particles` particles: a dict with
        "gradients" (replicates x n numpy array), "objectives", "seconds" and
        "nonfinite" (estimates dropped for non-finite values). The random
        numbers are those of a study's cell at (particles, horizon), the same
        for every method. Options: lr_weights, lr_baseline, gs_derivative,
        sn_noise_multiplier, forced_k_lr. "PILCO": the moment-matched
        gradient of the study's PILCO cell (deterministic, no particles:
        `replicates` timed runs, equal rows)."""
        pairs = [(k, _option_text(k, v)) for k, v in options.items()]
        return self._problem.gradients(method, int(particles), int(replicates), int(seed),
                                       0 if horizon is None else int(horizon), pairs)


def study(document, base_dir="."):
    """`totalgrad study FILE --format json` for a study document (a dict, or
    a path to a study file): gradient error against run time for every
    estimator. Returns the parsed result; its "cells" as a DataFrame with
    `pandas.DataFrame(result["cells"])`."""
    import os
    if isinstance(document, (str, os.PathLike)):
        with open(document) as f:
            text = f.read()
        base_dir = os.path.dirname(os.path.abspath(document))
    else:
        text = json.dumps(document)
    return json.loads(_totalgrad._study_json(text, str(base_dir)))


def connect(db=None, coordinator=None, token_file=None, ca_cert=None, insecure=None,
            timeout=60.0):
    """Results of a coordinator database file (`db`, read-only, safe while a
    coordinator writes it) or of a coordinator (`coordinator` host:port, with
    the CLI's TLS and token options). Unset arguments take the CLI's
    environment defaults: TOTALGRAD_DB, TOTALGRAD_COORDINATOR,
    TOTALGRAD_TOKEN_FILE, TOTALGRAD_CA_CERT, TOTALGRAD_INSECURE=1."""
    return Results(_totalgrad._Connection(db, coordinator, token_file, ca_cert, insecure,
                                          float(timeout)))


def import_archive(archive, db):
    """`totalgrad results import ARCHIVE --db DB`: takes a sweep archive
    (`results export -f json`) into the database file `db` (created when
    missing; refused while a coordinator holds it), to read with
    `connect(db=db)`. Returns the CLI's summary line."""
    return _totalgrad._import_archive(str(archive), str(db))


def _toml_value(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string is a JSON string
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"{type(value).__name__} has no TOML form here")


def sweep_toml(sweep):
    """A sweep file's TOML text for a dict such as
    {"name": "demo", "grid": {"method": ["RP", "TP"], "seed": [1, 2]},
     "protocol": {"episodes": 5}, "study": [{...}, ...]}:
    top-level scalars, then a [table] per dict and [[table]] per list of dicts."""
    lines, tables = [], []
    for key, value in sweep.items():
        if isinstance(value, dict) or (isinstance(value, list) and value and
                                       all(isinstance(v, dict) for v in value)):
            tables.append((key, value))
        else:
            lines.append(f"{key} = {_toml_value(value)}")
    for key, value in tables:
        for entry in ([value] if isinstance(value, dict) else value):
            lines.append("")
            lines.append(f"[{key}]" if isinstance(value, dict) else f"[[{key}]]")
            for inner, v in entry.items():
                if isinstance(v, dict):
                    raise TypeError(f"{key}.{inner}: nested tables are not written; "
                                    "give the sweep as TOML text")
                lines.append(f"{json.dumps(inner)} = {_toml_value(v)}")
    return "\n".join(lines) + "\n"


def _names(sweeps):
    return [sweeps] if isinstance(sweeps, str) else list(sweeps)


class Results:
    """The results library's tables over one connection, as DataFrames. Each
    equals the JSON of the CLI command named in its docstring."""

    def __init__(self, connection):
        self._connection = connection

    @staticmethod
    def _frame(text):
        import pandas
        return pandas.DataFrame(json.loads(text))

    def submit(self, sweep, dry_run=False):
        """`totalgrad sweep submit`: `sweep` is a sweep file's path, its TOML
        text, or a dict (sweep_toml). Resubmitting adds only new jobs. Returns
        {"created", "jobs_added", "dry_run", "sweep": the sweep's record}."""
        import os
        if isinstance(sweep, dict):
            text, source = sweep_toml(sweep), "<dict>"
        elif isinstance(sweep, os.PathLike) or ("\n" not in sweep and os.path.exists(sweep)):
            with open(sweep) as f:
                text, source = f.read(), str(sweep)
        else:
            text, source = sweep, "<text>"
        return json.loads(self._connection.submit(text, source, bool(dry_run)))

    def status(self, sweep):
        """`totalgrad sweep status SWEEP -f json`: the sweep's record (job counts, state)."""
        return json.loads(self._connection.sweep(sweep))

    def wait(self, sweep, progress=True, poll_seconds=1.0):
        """Waits until the sweep has finished, printing a progress line to
        stderr unless `progress` is False; returns its final record. Ctrl-C
        ends only the wait: the sweep goes on at the coordinator."""
        import sys
        import time
        while True:
            info = self.status(sweep)
            done = info["jobs_completed"] + info["jobs_failed"] + info["jobs_cancelled"]
            total = max(1, info["jobs_total"])
            if progress:
                bar = "#" * (30 * done // total)
                print(f"\r[{bar:.<30}] jobs {done}/{info['jobs_total']} "
                      f"({info['jobs_running']} running, {info['jobs_failed']} failed)",
                      end="", file=sys.stderr, flush=True)
            if info["finished"]:
                if progress:
                    print(file=sys.stderr)
                return info
            time.sleep(poll_seconds)

    def cancel(self, sweep):
        """`totalgrad sweep cancel`: queued jobs cancelled, running trials stopped."""
        return json.loads(self._connection.cancel(sweep))

    def pause(self, sweep):
        """`totalgrad sweep pause`: no more jobs handed out; running ones go on."""
        return json.loads(self._connection.pause(sweep))

    def resume(self, sweep):
        """`totalgrad sweep resume`."""
        return json.loads(self._connection.resume(sweep))

    def export_archive(self, sweep, path, checkpoints=False):
        """`totalgrad results export SWEEP -f json -o PATH [--checkpoints]`: the
        sweep's archive (complete under `path` or not there at all)."""
        self._connection.export_archive(sweep, str(path), bool(checkpoints))

    def sweeps(self):
        """`totalgrad sweep list -f json`."""
        return self._frame(self._connection.sweeps())

    def jobs(self, sweep):
        """`totalgrad job list --sweep SWEEP -f json`."""
        return self._frame(self._connection.jobs(sweep))

    def episodes(self, sweep, all_attempts=False, completed=False):
        """`totalgrad results export SWEEP -f jsonl`: one row per episode of
        each job's counting attempt (every attempt with all_attempts), with
        its job's columns: job_state, success, final_eval_cost and every
        option by its key, typed (numbers as numbers). `completed`: only the
        rows of completed jobs (what a learning curve of finished trials
        wants; running and cancelled jobs' rows are otherwise included)."""
        import pandas
        lines = self._connection.episodes(sweep, all_attempts).splitlines()
        frame = pandas.DataFrame([json.loads(line) for line in lines])
        if completed and len(frame):
            frame = frame[frame["job_state"] == "completed"].reset_index(drop=True)
        return frame

    def trials(self, sweeps):
        """The completed trials (one per completed trial job, superseded ones
        replaced) that every table below is computed from."""
        return self._frame(self._connection.trials(_names(sweeps)))

    def success_table(self, sweeps):
        """`totalgrad results table SWEEP -f json`: success rate with its 95 %
        Wilson interval per method and task variant (sweeps pooled)."""
        return self._frame(self._connection.success_table(_names(sweeps)))

    def compare(self, sweeps, baseline="", alpha=0.05):
        """`totalgrad results compare SWEEP -f json`: paired comparisons by seed."""
        return self._frame(self._connection.compare(_names(sweeps), baseline, float(alpha)))

    def diagnostics(self, sweep, statistic=""):
        """`totalgrad results diagnostics SWEEP -f json [--statistic S]`: what the
        estimators did (gradient norms and SNR, step norms, ESS, ...), the
        median and quartiles over trials per method, variant and episode
        (docs/diagnostics.md)."""
        return self._frame(self._connection.diagnostics(sweep, statistic))

    def curves(self, sweep, top=None):
        """`totalgrad results curves SWEEP -f json`: per method, variant and
        episode the median, quartiles, mean and standard error of the
        evaluation cost over the completed trials; with `top` = k over each
        method's and variant's k runs of lowest final cost (the paper's
        Figure 3 "top runs"; `results curves --top k` draws them)."""
        return self._frame(self._connection.curves(sweep, 0 if top is None else int(top)))

    def table1(self, sweeps, view="grid", thresholds=()):
        """`totalgrad results table1 SWEEP... -f json --view VIEW`: the paper's
        Table 1 (grid), its threshold sensitivity, or its claims compared."""
        return self._frame(self._connection.table1(_names(sweeps), view,
                                                   [float(t) for t in thresholds]))
