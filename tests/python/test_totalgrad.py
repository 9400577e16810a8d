"""`import totalgrad` against the `totalgrad` binary built beside it: every
number Python gives must be the CLI's, bit for bit (the JSON both print reads
back to the same doubles), and long calls must leave Python responsive.

Run by ctest (`python_module`) with Debian's /usr/bin/python3 -m pytest, with
PYTHONPATH at the build's python/ folder and TOTALGRAD_BIN the CLI.
"""
import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy
import pytest

import totalgrad

BIN = os.environ["TOTALGRAD_BIN"]

# A trial of a few seconds: the CLI's flags and Python's keywords say the same.
TINY = {"episodes": 2, "policy_steps": 3, "particles": 8, "eval_rollouts": 2, "horizon": 10,
        "verdict_rollouts": 4}


def cli_json_lines(*args):
    run = subprocess.run([BIN, *args], capture_output=True, text=True, timeout=600, check=False)
    assert run.returncode == 0, run.stdout + run.stderr
    return [json.loads(line) for line in run.stdout.splitlines() if line.strip()]


def cli_json(*args):
    run = subprocess.run([BIN, *args], capture_output=True, text=True, timeout=600, check=False)
    assert run.returncode == 0, run.stdout + run.stderr
    return json.loads(run.stdout)


def flags(options):
    out = []
    for key, value in options.items():
        out += ["--" + key.replace("_", "-"), str(value)]
    return out


@pytest.mark.parametrize("method,seed", [("RP", 3), ("TP", 4), ("PILCO", 5)])
def test_a_trial_gives_the_clis_episodes_bit_for_bit(method, seed):
    options = dict(TINY, method=method, seed=seed)
    if method == "PILCO":
        options.update(pilco_line_searches=2, pilco_evaluations_per_line_search=4)
    cli = cli_json_lines("trial", "--json", *flags(options))
    run = totalgrad.trial(**options)
    episodes = list(run)
    assert len(episodes) == options["episodes"] + 1
    # Times differ run to run; every computed number must not.
    timing = {"optimisation_seconds", "cpu_seconds", "timing"}
    for ours, theirs in zip(episodes, cli[:-1]):
        assert {k: v for k, v in ours.items() if k not in timing} == \
               {k: v for k, v in theirs.items() if k not in timing}
    done = cli[-1]
    assert run.summary["final_eval_cost"] == done["final_eval_cost"]
    assert run.summary["success"] == done["success"]
    assert run.summary["held_fraction"] == done["held_fraction"]
    assert run.summary["options"] == done["options"]
    # One writer of the verdict (io::TrialSummaryJson): the CLI adds done and threads.
    assert {k: v for k, v in done.items() if k not in ("done", "threads")} == run.summary
    assert done["done"] is True and done["threads"] == 1


def test_a_trial_as_a_frame_has_one_row_per_episode():
    frame = totalgrad.trial(method="RP", seed=7, **TINY).run()
    assert list(frame["episode"]) == [0, 1, 2]
    assert frame["eval_cost_mean"].iloc[1:].notna().all()


def test_a_bad_option_names_itself_and_the_closest_key():
    with pytest.raises(ValueError, match="particle.*did you mean 'particles'"):
        totalgrad.trial(particle=8)
    with pytest.raises(ValueError, match="'particles'"):
        totalgrad.trial(particles=0)
    with pytest.raises(TypeError, match="'noise_k'"):
        totalgrad.trial(noise_k=[1])


def test_python_runs_while_a_trial_computes():
    """The wait for an episode releases the GIL: another Python thread keeps
    counting. Holding it would leave the counter near zero."""
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(1)
            time.sleep(0.001)

    counter = threading.Thread(target=count)
    counter.start()
    start = time.monotonic()
    # Long enough (about 1.5 s here) that a fast machine still takes well
    # over the 0.5 s below: 60 steps took 0.46 s on a quiet run.
    list(totalgrad.trial(method="RP", seed=1, episodes=2, policy_steps=200, particles=100,
                         eval_rollouts=2, horizon=30, verdict_rollouts=0))
    seconds = time.monotonic() - start
    stop.set()
    counter.join()
    assert seconds > 0.5, "the trial was too short to tell"
    # At 1 ms per tick a free thread gets hundreds a second; allow for a loaded machine.
    assert len(ticks) > 50 * seconds, (len(ticks), seconds)


def test_ctrl_c_stops_a_trial_and_raises_keyboard_interrupt():
    script = textwrap.dedent("""
        import sys, time, totalgrad
        run = totalgrad.trial(method="RP", seed=1, episodes=50, policy_steps=2000,
                              particles=300, horizon=30)
        try:
            for episode in run:
                print("episode", episode["episode"], flush=True)
        except KeyboardInterrupt:
            print("interrupted", flush=True)
            sys.exit(7)
        print("finished", flush=True)
        """)
    process = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=os.environ.copy())
    first = process.stdout.readline()
    assert first.startswith("episode 0"), first + process.stderr.read()
    time.sleep(0.5)  # inside episode 1's optimisation (2000 steps: many seconds)
    sent = time.monotonic()
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=60)
    waited = time.monotonic() - sent
    assert process.returncode == 7, out + err
    assert "interrupted" in out
    assert "finished" not in out
    assert waited < 10, f"Ctrl-C took {waited:.1f} s to stop the trial"


def test_scenes_and_trial_options_are_the_clis():
    assert totalgrad.scenes() == cli_json("scenes", "--json")
    options = totalgrad.trial_options()
    assert options["particles"] == "300"
    assert "scene" in options and "noise_k" in options


def test_simulate_is_the_clis():
    ours = totalgrad.simulate("pendulum", [0.0, 0.1], [0.5, -0.5, 1.0])
    theirs = cli_json("simulate", "--scene", "pendulum", "--start", "0,0.1",
                      "--forces", "0.5,-0.5,1", "--json")
    assert ours == theirs
    with pytest.raises(ValueError, match="start"):
        totalgrad.simulate("pendulum", [0.0], [0.5])


SWEEP = """name = "py"
[grid]
method = ["RP", "TP"]
seed = [3, 4, 5]
[protocol]
episodes = 2
policy_steps = 3
particles = 8
eval_rollouts = 2
horizon = 10
verdict_rollouts = 4
threshold = 1000
"""


@pytest.fixture(scope="module")
def database(tmp_path_factory):
    work = tmp_path_factory.mktemp("sweep")
    sweep_file = work / "py.toml"
    sweep_file.write_text(SWEEP)
    run = subprocess.run([BIN, "run", str(sweep_file), "--dir", str(work), "--workers", "2",
                          "--no-plot"], capture_output=True, text=True, timeout=600, check=False)
    assert run.returncode == 0, run.stdout + run.stderr
    return str(work / "py.db")


def records(frame):
    """A DataFrame's rows as the JSON objects they came from (NaN back to None)."""
    return [{k: (None if isinstance(v, float) and v != v else v) for k, v in row.items()}
            for row in frame.to_dict(orient="records")]


def test_results_of_a_database_file_are_the_clis(database):
    results = totalgrad.connect(db=database)
    db = ["--db", database, "-f", "json"]
    assert records(results.success_table("py")) == cli_json("results", "table", "py", *db)
    assert records(results.compare("py")) == cli_json("results", "compare", "py", *db)
    assert records(results.compare("py", baseline="TP", alpha=0.1)) == \
        cli_json("results", "compare", "py", "--baseline", "TP", "--alpha", "0.1", *db)
    assert records(results.jobs("py")) == cli_json("job", "list", "--sweep", "py", *db)
    sweeps = results.sweeps()
    assert list(sweeps["name"]) == ["py"]
    diagnostics = results.diagnostics("py")
    assert records(diagnostics) == cli_json("results", "diagnostics", "py", *db)
    assert len(diagnostics) > 0
    snr = results.diagnostics("py", statistic="gradient_snr_mean")
    assert set(snr["statistic"]) == {"gradient_snr_mean"} and set(snr["method"]) == {"RP", "TP"}
    with pytest.raises(ValueError, match="did you mean 'gradient_snr_mean'"):
        results.diagnostics("py", statistic="gradient_snr_man")


def test_episodes_are_the_clis_export(database):
    results = totalgrad.connect(db=database)
    frame = results.episodes("py")
    theirs = cli_json_lines("results", "export", "py", "--db", database, "-f", "jsonl")
    assert len(frame) == 6 * 3
    assert records(frame) == theirs
    assert set(frame["method"]) == {"RP", "TP"}
    # The job's columns: state, verdict, final cost and every option, typed.
    assert set(frame["job_state"]) == {"completed"}
    assert frame["success"].all()
    assert str(frame["particles"].dtype).startswith("int") and set(frame["particles"]) == {8}
    assert str(frame["noise_k"].dtype).startswith("float")
    assert set(frame["scene"]) == {"cartpole-swingup"}
    last = frame[frame["episode"] == 2]
    assert (last["final_eval_cost"] == last["eval_cost_mean"]).all()
    assert len(results.episodes("py", completed=True)) == len(frame)
    # The CSV export has the same columns, the same values as text.
    csv_run = subprocess.run([BIN, "results", "export", "py", "--db", database, "-f", "csv"],
                             capture_output=True, text=True, check=True)
    import csv
    import io
    rows = list(csv.DictReader(io.StringIO(csv_run.stdout)))
    assert len(rows) == len(frame)
    for column in ("job_state", "success", "final_eval_cost", "particles", "noise_k", "scene"):
        assert column in rows[0], column
    assert rows[0]["job_state"] == "completed" and rows[0]["success"] == "1"
    assert float(rows[-1]["final_eval_cost"]) == frame["final_eval_cost"].iloc[-1]
    assert float(rows[0]["noise_k"]) == frame["noise_k"].iloc[0] == 1.0


def test_trials_count_each_completed_job_once(database):
    trials = totalgrad.connect(db=database).trials("py")
    assert len(trials) == 6
    assert sorted(trials["seed"].astype(int)) == [3, 3, 4, 4, 5, 5]
    assert trials["success"].all()  # threshold 1000


def test_a_missing_sweep_or_file_says_which(database, tmp_path):
    results = totalgrad.connect(db=database)
    with pytest.raises(KeyError, match="nosuch"):
        results.success_table("nosuch")
    with pytest.raises(Exception, match="missing.db"):
        totalgrad.connect(db=str(tmp_path / "missing.db"))


ARCHIVES = os.path.join(os.path.dirname(__file__), "..", "..", "docs", "results", "table1")


def test_table1_from_a_committed_archive_is_the_clis(tmp_path):
    db = str(tmp_path / "table1.db")
    archive = os.path.join(ARCHIVES, "table1-tip-k1.archive.json")
    summary = totalgrad.import_archive(archive, db)
    assert summary.startswith("created sweep table1-tip-k1: 40 jobs taken over"), summary
    again = totalgrad.import_archive(archive, db)
    assert again.startswith("into existing sweep table1-tip-k1: 0 jobs taken over"), again
    results = totalgrad.connect(db=db)
    for view in ("grid", "sensitivity", "comparisons"):
        assert records(results.table1("table1-tip-k1", view=view)) == \
            cli_json("results", "table1", "table1-tip-k1", "--view", view, "--db", db, "-f", "json")
    grid = results.table1("table1-tip-k1")
    tp = grid[(grid["method"] == "TP") & (grid["cost"] == "tip") & (grid["noise_k"] == 1)].iloc[0]
    assert (tp["successes"], tp["trials"]) == (5, 10)


def test_a_malformed_archive_is_refused_naming_it(tmp_path):
    bad = tmp_path / "bad.archive.json"
    bad.write_text('{"format": "not an archive"')
    with pytest.raises(Exception, match="bad.archive.json"):
        totalgrad.import_archive(str(bad), str(tmp_path / "x.db"))


SYNTHETIC = {"data": 60, "horizon": 8, "seed": 2, "basis_functions": 10}


def test_gradients_are_numpy_repeatable_and_share_random_numbers():
    problem = totalgrad.Problem(synthetic=SYNTHETIC)
    assert problem.scene == "cartpole-swingup" and problem.horizon == 8
    rp = problem.gradients("RP", particles=20, replicates=4, seed=5)
    assert rp["gradients"].shape[0] == 4 and rp["gradients"].shape[1] > 10
    again = problem.gradients("RP", particles=20, replicates=4, seed=5)
    assert (rp["gradients"] == again["gradients"]).all()
    other_seed = problem.gradients("RP", particles=20, replicates=4, seed=6)
    assert (rp["gradients"] != other_seed["gradients"]).any()
    # Common random numbers: the forward pass of TP is RP's, so the objectives agree.
    tp = problem.gradients("TP", particles=20, replicates=4, seed=5)
    assert (tp["objectives"] == rp["objectives"]).all()
    assert (tp["gradients"] != rp["gradients"]).any()
    # PILCO is deterministic: every replicate is the same moment-matched gradient.
    pilco = problem.gradients("PILCO", replicates=3)
    assert pilco["gradients"].shape == (3, rp["gradients"].shape[1])
    assert (pilco["gradients"] == pilco["gradients"][0]).all()
    assert len(set(pilco["objectives"].tolist())) == 1 and pilco["nonfinite"] == 0
    with pytest.raises(ValueError, match="PILCO takes no estimator options"):
        problem.gradients("PILCO", lr_weights="plain")
    with pytest.raises(ValueError, match="lr_weight"):
        problem.gradients("LR", particles=20, replicates=2, lr_weight="plain")


def test_the_study_is_the_clis_and_its_cells_are_the_problems_gradients(tmp_path):
    document = {"problem": {"synthetic": SYNTHETIC}, "estimators": ["RP", "LR", "PILCO"],
                "particles": [10, 30], "horizons": [5], "replicates": 3, "seed": 4,
                "cell_budget_seconds": 1e6, "ess_replicates": 0,
                "reference": {"particles": 50, "replicates": 4, "budget_seconds": 1e6}}
    path = tmp_path / "study.json"
    path.write_text(json.dumps(document))
    ours = totalgrad.study(document)
    theirs = cli_json("study", str(path), "--format", "json", "--quiet")
    timing = {"time_min_s", "time_median_s", "seconds"}

    def untimed(cells):
        return [{k: v for k, v in c.items() if k not in timing} for c in cells]
    assert untimed(ours["cells"]) == untimed(theirs["cells"])
    # RP and LR at two particle counts; PILCO's moment matching has no particles.
    assert [(c["estimator"], c["particles"]) for c in ours["cells"]] == \
        [("RP", 10), ("RP", 30), ("LR", 10), ("LR", 30), ("PILCO", 0)]
    problem = totalgrad.Problem(synthetic=SYNTHETIC)
    lr = problem.gradients("LR", particles=30, replicates=3, seed=4, horizon=5)
    cell = next(c for c in ours["cells"] if c["estimator"] == "LR" and c["particles"] == 30)
    total = 0.0
    for value in lr["objectives"]:
        total += value
    assert total / 3 == cell["objective_mean"]
    # PILCO's cell is the problem's PILCO gradient: its J bit for bit, and its
    # error against the study's reference gradient.
    pilco = problem.gradients("PILCO", replicates=2, horizon=5)
    pilco_cell = next(c for c in ours["cells"] if c["estimator"] == "PILCO")
    assert pilco["objectives"][0] == pilco_cell["objective_mean"]
    reference = numpy.array(next(r for r in ours["references"] if r["horizon"] == 5)["gradient"])
    rel_bias = numpy.linalg.norm(pilco["gradients"][0] - reference) / numpy.linalg.norm(reference)
    assert rel_bias == pytest.approx(pilco_cell["rel_bias"], rel=1e-12)


@pytest.fixture()
def coordinator(tmp_path):
    """A coordinator on loopback (plaintext, tokens) and one worker, as the
    README's "sweep on two workers" starts them."""
    (tmp_path / "worker.token").write_text("w" * 32 + "\n")
    (tmp_path / "user.token").write_text("u" * 32 + "\n")
    os.chmod(tmp_path / "worker.token", 0o600)
    os.chmod(tmp_path / "user.token", 0o600)
    port_file = tmp_path / "port"
    processes = [subprocess.Popen(
        [os.environ["TOTALGRAD_COORDINATOR_BIN"], "--db", str(tmp_path / "c.db"), "--listen",
         "127.0.0.1:0", "--insecure", "--worker-token-file", str(tmp_path / "worker.token"),
         "--user-token-file", str(tmp_path / "user.token"), "--port-file", str(port_file)],
        stdout=subprocess.DEVNULL, stderr=open(tmp_path / "coordinator.log", "w"))]
    deadline = time.monotonic() + 30
    while not (port_file.exists() and port_file.read_text().strip()):
        assert time.monotonic() < deadline, (tmp_path / "coordinator.log").read_text()
        time.sleep(0.1)
    address = "127.0.0.1:" + port_file.read_text().strip()
    processes.append(subprocess.Popen(
        [os.environ["TOTALGRAD_WORKER_BIN"], "--coordinator", address, "--insecure",
         "--token-file", str(tmp_path / "worker.token"), "--slots", "1", "--worker-id", "py",
         "--state-dir", str(tmp_path / "state"), "--acquire-wait", "1"],
        stdout=subprocess.DEVNULL, stderr=open(tmp_path / "worker.log", "w")))
    yield address, str(tmp_path / "user.token")
    for process in reversed(processes):
        process.terminate()
        process.wait(timeout=60)


def test_a_sweep_submitted_waited_and_exported_from_python(coordinator, tmp_path):
    address, token = coordinator
    results = totalgrad.connect(coordinator=address, token_file=token, insecure=True)
    sweep = {"name": "client", "grid": {"method": ["RP", "TP"], "seed": [1, 2]},
             "protocol": {"episodes": 1, "policy_steps": 2, "particles": 8,
                          "eval_rollouts": 2, "horizon": 8, "verdict_rollouts": 0}}
    dry = results.submit(sweep, dry_run=True)
    assert dry["dry_run"] and dry["sweep"]["jobs_total"] == 4
    submitted = results.submit(sweep)
    assert submitted["created"] and submitted["sweep"]["name"] == "client"
    assert results.submit(sweep)["created"] is False  # the same file again: no change
    final = results.wait("client", progress=False, poll_seconds=0.2)
    assert final["jobs_completed"] == 4
    cli = ["--coordinator", address, "--token-file", token, "--insecure", "-f", "json"]
    assert records(results.success_table("client")) == cli_json("results", "table", "client", *cli)
    archive = tmp_path / "client.archive.json"
    results.export_archive("client", archive, checkpoints=True)
    summary = totalgrad.import_archive(archive, tmp_path / "copy.db")
    assert summary.startswith("created sweep client: 4 jobs taken over"), summary
    copy = totalgrad.connect(db=str(tmp_path / "copy.db"))
    assert records(copy.success_table("client")) == records(results.success_table("client"))
    # Cancel a sweep that would run for minutes.
    long = dict(sweep, name="long", protocol=dict(sweep["protocol"], episodes=30,
                                                 policy_steps=2000, particles=300, horizon=30))
    results.submit(long)
    assert results.cancel("long")["state"] == "cancelled"
    with pytest.raises(KeyError, match="nosuch"):
        results.status("nosuch")
    with pytest.raises(ValueError, match="particle"):
        results.submit(dict(sweep, name="bad", protocol={"particle": 3}))


def test_the_sweep_toml_of_a_dict_is_what_the_file_would_say():
    text = totalgrad.sweep_toml({"name": "x", "grid": {"method": ["RP"], "noise_k": [0.01, 1.0]},
                                 "protocol": {"episodes": 3, "cost": "tip"}})
    assert text == ('name = "x"\n\n[grid]\n"method" = ["RP"]\n"noise_k" = [0.01, 1.0]\n\n'
                    '[protocol]\n"episodes" = 3\n"cost" = "tip"\n')


def test_trial_help_types_every_option_from_the_option_table():
    run = subprocess.run([BIN, "trial", "--help"], capture_output=True, text=True, check=True)
    lines = {line.split()[0]: line for line in run.stdout.splitlines() if line.strip().startswith("--")}
    assert "NUMBER" in lines["--noise-k"]
    assert "INT" in lines["--particles"]
    assert "true|false" in lines["--gp-penalty"]
    assert "RP|GR|LR|TP" in lines["--method"]
    assert "TEXT" not in lines["--horizon"]
