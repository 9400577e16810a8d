#!/usr/bin/python3
"""The dashboard in a real browser: headless Debian chromium driven by
selenium (python3-selenium, chromium-driver) against the real coordinator
and worker binaries on loopback.

It submits a small sweep before any worker runs, opens the page (which asks
for the user token), starts one worker, and watches the sweep's page: the
stored-episode count and the learning curves must change while a trial is
running, and at the end the success table, the paper's Table 1 grid, a curve
panel per task variant and the comparison table must be there, with the CLI's
numbers under the CLI's names. It also checks over plain HTTP that
/healthz needs no token and the API refuses a missing or worker token.

Usage: dashboard_browser_test.py COORDINATOR WORKER CLI [--screenshot PNG]
Exit 0 pass, 1 fail, 77 skip (chromium or its driver cannot start: the
reason is printed).
"""
import argparse
import http.client
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

SKIP = 77
SOURCE_DIR = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
USER_TOKEN = "user-token-0123456789abcdef"
WORKER_TOKEN = "worker-token-0123456789abcdef"

SWEEP = """
name = "browser"
description = "RP and TP, two noise levels, 3 seeds: the dashboard's browser test"
[grid]
seed = { first = 1, count = 3 }
method = ["RP", "TP"]
noise_k = [0.01, 1.0]
[protocol]
scene = "cartpole-swingup"
cost = "angle"
episodes = 5
policy_steps = 120
particles = 50
eval_rollouts = 2
horizon = 25
"""

checks = []


def check(condition, what):
    checks.append((bool(condition), what))
    print(("ok   " if condition else "FAIL ") + what, flush=True)
    return condition


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def jobs_running(progress_text):
    """Jobs running, from the page's "N running" (0 when it says none)."""
    found = re.search(r"(\d+) running", progress_text)
    return int(found.group(1)) if found else 0


def wait_for(condition, timeout, interval=0.2):
    deadline = time.time() + timeout
    while time.time() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(interval)
    return None


def http_get(url, token=None):
    request = urllib.request.Request(url)
    if token:
        request.add_header("Authorization", "Bearer " + token)
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, response.read().decode()
    except urllib.error.HTTPError as error:
        return error.code, error.read().decode()
    except (OSError, http.client.HTTPException) as error:  # refused, reset, not HTTP
        return 0, str(error)


def start_browser(profile_dir):
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError as error:
        return None, f"python3-selenium is missing ({error})"
    chromium = shutil.which("chromium")
    driver_path = shutil.which("chromedriver") or "/usr/bin/chromedriver"
    if chromium is None or not os.path.exists(driver_path):
        return None, "chromium or chromium-driver is not installed (deploy/install-deps.sh installs them)"
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run",
                 "--disable-dev-shm-usage", f"--user-data-dir={profile_dir}",
                 "--window-size=1500,1200"):
        options.add_argument(flag)
    try:
        driver = webdriver.Chrome(service=Service(executable_path=driver_path), options=options)
    except Exception as error:  # the browser could not start here: skip, saying why
        return None, f"chromium did not start: {str(error).splitlines()[0]}"
    return driver, None


def cli_checks(args, work, connection, base):
    """`results compare` and `results curves --plot` on the same live sweep:
    the CLI's numbers are the dashboard's, and the plot has its panels."""
    compared = subprocess.run([args.cli, "results", "compare", "browser", "--baseline", "TP", "-f", "json"]
                              + connection, capture_output=True, text=True)
    if not check(compared.returncode == 0, "results compare --baseline TP -f json: " + compared.stderr.strip()):
        return
    rows = json.loads(compared.stdout)
    status, body = http_get(base + "/api/compare?name=browser&baseline=TP", USER_TOKEN)
    api = json.loads(body)["comparisons"] if status == 200 else []
    check(len(rows) == 2 and len(api) == 2, f"two comparisons from the CLI and the API ({len(rows)}, {len(api)})")
    same = all(r["variant"] == a["variant"] and r["method"] == "RP" and r["vs"] == "TP"
               and all(abs(r[k] - a[k]) < 1e-12 for k in ("mcnemar_p", "wilcoxon_p", "fisher_p",
                                                          "cost_shift_hl", "wilcoxon_power"))
               for r, a in zip(rows, api))
    check(same, "the CLI's and the dashboard's comparison numbers agree")
    check(all(a.get("success_verdict") in ("no evidence", "RP better", "TP better")
              and a.get("cost_verdict") in ("no evidence", "RP better", "TP better") for a in api)
          and all(r["success_verdict"] == a["success_verdict"] and r["cost_verdict"] == a["cost_verdict"]
                  for r, a in zip(rows, api)),
          "the API and the CLI give the same verdicts (the results library's)")
    # One name per statistic: the sweep's success table and the paper's
    # Table 1 have the same keys and numbers in the CLI's JSON and the API's.
    listed = subprocess.run([args.cli, "results", "table", "browser", "-f", "json"] + connection,
                            capture_output=True, text=True)
    status, body = http_get(base + "/api/sweep?name=browser", USER_TOKEN)
    if check(listed.returncode == 0 and status == 200, "results table -f json and /api/sweep answer"):
        cli_cells, api_cells = json.loads(listed.stdout), json.loads(body)["table"]["cells"]
        check(len(cli_cells) == 4 and [sorted(c) for c in cli_cells] == [sorted(c) for c in api_cells]
              and "wilson95_low" in cli_cells[0] and "wilson_low" not in api_cells[0],
              "the success table's cells have the same keys in the CLI and the API: "
              + ", ".join(api_cells[0]))
        check(cli_cells == api_cells, "and the same numbers")
    grid = subprocess.run([args.cli, "results", "table1", "browser", "-f", "json"] + connection,
                          capture_output=True, text=True)
    status, body = http_get(base + "/api/table1?name=browser", USER_TOKEN)
    if check(grid.returncode == 0 and status == 200, "results table1 -f json and /api/table1 answer: "
             + grid.stderr.strip()):
        cli_grid, api_grid = json.loads(grid.stdout), json.loads(body)["cells"]
        check(len(cli_grid) == 32 and cli_grid == api_grid,
              "the Table 1 grid is the same 32 cells from the CLI and the API")
        filled = [c for c in api_grid if c["trials"] > 0]
        check(len(filled) == 4 and all(c["trials"] == 3 and c["off_protocol_trials"] == 3
                                       and "episodes = 5 (paper 15)" in c["protocol_differences"]
                                       for c in filled),
              "RP and TP at angle k = 0.01 and k = 1, 3 trials each, marked off the paper's protocol")
    status, body = http_get(base + "/api/table1", USER_TOKEN)
    check(status == 400 and "'name'" in json.loads(body)["error"], f"/api/table1 without a name is 400 ({status})")
    table = subprocess.run([args.cli, "results", "compare", "browser", "--baseline", "PILCO"] + connection,
                           capture_output=True, text=True)
    check(table.returncode == 2 and "'PILCO'" in table.stderr and "RP, TP" in table.stderr,
          "an unknown baseline is refused naming the methods: " + table.stderr.strip())
    # Issue 27: one recorded trajectory, the same numbers from the CLI and the API.
    shown = subprocess.run([args.cli, "job", "trajectory", "1", "--episode", "5", "-f", "json"] + connection,
                           capture_output=True, text=True)
    status, body = http_get(base + "/api/trajectory?id=1&episode=5", USER_TOKEN)
    if check(shown.returncode == 0 and status == 200, "job trajectory -f json and /api/trajectory answer: "
             + shown.stderr.strip()):
        cli_view, api_view = json.loads(shown.stdout), json.loads(body)
        check(all(cli_view[k] == api_view[k] for k in ("states", "controls", "predicted_mean", "predicted_std",
                                                        "goal_distance", "real_cost"))
              and len(cli_view["states"]) == 26,
              "the CLI and the dashboard show the same trajectory (26 states)")
    # The estimator statistics per method and episode: one computation, the
    # same points from `results diagnostics` and /api/diagnostics.
    listed = subprocess.run([args.cli, "results", "diagnostics", "browser", "--statistic", "gradient_snr_mean",
                             "-f", "json"] + connection, capture_output=True, text=True)
    status, body = http_get(base + "/api/diagnostics?name=browser&statistic=gradient_snr_mean", USER_TOKEN)
    if check(listed.returncode == 0 and status == 200, "results diagnostics -f json and /api/diagnostics answer: "
             + listed.stderr.strip()):
        cli_points = json.loads(listed.stdout)
        api_points = [{k: v for k, v in p.items() if k != "n"}
                      for panel in json.loads(body)["panels"] for m in panel["methods"] for p in m["points"]]
        key = lambda p: (p["variant"], p["method"], p["episode"])
        check(len(cli_points) == 2 * 2 * 5 and sorted(cli_points, key=key) == sorted(api_points, key=key),
              f"the same {len(cli_points)} points (2 methods x 2 variants x 5 learned episodes) from the CLI and the API")
    wrong = subprocess.run([args.cli, "results", "diagnostics", "browser", "--statistic", "gradient_snr_man"]
                           + connection, capture_output=True, text=True)
    check(wrong.returncode == 2 and "did you mean 'gradient_snr_mean'" in wrong.stderr,
          "an unknown statistic is refused with the closest name: " + wrong.stderr.strip()[:120])
    status, body = http_get(base + "/api/trajectory?id=1&episode=9", USER_TOKEN)
    check(status == 404 and "episode 9 is not recorded" in json.loads(body)["error"],
          f"an episode the trial does not hold is 404, named ({status})")
    plot = os.path.join(work, "plot", "curves.svg")
    os.makedirs(os.path.dirname(plot))
    drawn = subprocess.run([args.cli, "results", "curves", "browser", "--plot", plot] + connection,
                           capture_output=True, text=True)
    if check(drawn.returncode == 0 and os.path.exists(plot), "results curves --plot draws " + plot):
        script = open(plot + ".gp").read()
        check(script.count("set title ") == 2 and script.count('"success threshold 15"') == 2,
              "the plot has a panel per variant, each with the threshold line")


def attribute_of(find, css, name):
    """Attribute `name` of the element at `css`, found again if the page
    redrew it between finding and reading (the playing animation redraws the
    scene every frame: StaleElementReferenceException); None if absent."""
    from selenium.common.exceptions import StaleElementReferenceException
    for _ in range(50):
        try:
            element = find(css)
            return element.get_attribute(name) if element is not None else None
        except StaleElementReferenceException:
            time.sleep(0.02)
    return None


def trajectory_checks(driver, find):
    """Issue 27: the job page draws the last episode's real trajectory against
    the model's prediction with its band, animates the scene (the drawn frame
    changes) and plots the estimator statistics."""
    from selenium.webdriver.common.by import By
    plots = wait_for(lambda: driver.find_elements(By.CSS_SELECTOR, "#trajectory-plots svg.state-plot"), 15) or []
    check(len(plots) == 5, f"a plot per state dimension and the goal distance ({len(plots)} of 5)")
    states = [p for p in plots if p.get_attribute("data-state")]
    check(len(states) == 4 and all(len(p.find_elements(By.CSS_SELECTOR, "polygon.band")) == 1 and
                                   len(p.find_elements(By.CSS_SELECTOR, "polyline.series")) == 2 for p in states),
          "each state's plot has the real trajectory, the predicted mean and its +-2 std band")
    scene = find("#scene")
    if check(scene is not None and scene.get_attribute("data-frame") == "0", "the scene is drawn at t = 0"):
        first = attribute_of(find, "#scene line.link", "x2")
        find("#scene-play").click()

        def frame_at_least_3():
            frame = attribute_of(find, "#scene", "data-frame")
            return frame if frame is not None and int(frame) >= 3 else None
        frames = wait_for(frame_at_least_3, 10)
        later = attribute_of(find, "#scene line.link", "x2") if frames else first
        check(frames and later != first, f"play animates the scene: frame {frames}, pole tip x {first} -> {later}")
    statistics = driver.find_elements(By.CSS_SELECTOR, "#statistics svg.statistic-plot")
    keys = [p.get_attribute("data-statistic") for p in statistics]
    check("gradient_snr_mean" in keys and "gradient_norm_mean" in keys,
          "the estimator statistics are plotted per episode: " + ", ".join(keys))


def tls_checks(args, work, driver, processes):
    """A coordinator with TLS and tokens serves the HTTP port over HTTPS with
    the same certificate and asks for the user token; a plaintext one off
    loopback serves /healthz alone."""
    import ssl
    from selenium.webdriver.common.by import By
    certs = os.path.join(work, "certs")
    made = subprocess.run(["bash", os.path.join(SOURCE_DIR, "deploy", "make-dev-certs.sh"), certs],
                          capture_output=True, text=True)
    if not check(made.returncode == 0, "development certificates made"):
        print(made.stderr)
        return
    http_port = free_port()
    port_file = os.path.join(work, "tls-port")
    log = open(os.path.join(work, "coordinator-tls.log"), "w")
    process = subprocess.Popen(
        [args.coordinator, "--db", os.path.join(work, "tls.db"), "--listen", "127.0.0.1:0",
         "--tls-cert", os.path.join(certs, "server.pem"), "--tls-key", os.path.join(certs, "server.key"),
         "--worker-token-file", os.path.join(certs, "worker.token"),
         "--user-token-file", os.path.join(certs, "user.token"), "--port-file", port_file,
         "--http-listen", f"127.0.0.1:{http_port}"],
        stdout=log, stderr=subprocess.STDOUT)
    processes.append(process)
    if not check(wait_for(lambda: os.path.exists(port_file), 30), "a TLS coordinator started"):
        return
    context = ssl.create_default_context(cafile=os.path.join(certs, "ca.pem"))
    user_token = open(os.path.join(certs, "user.token")).read().strip()

    def https_get(path, token=None):
        request = urllib.request.Request(f"https://127.0.0.1:{http_port}{path}")
        if token:
            request.add_header("Authorization", "Bearer " + token)
        try:
            with urllib.request.urlopen(request, timeout=10, context=context) as response:
                return response.status, response.read().decode()
        except urllib.error.HTTPError as error:
            return error.code, error.read().decode()

    status, body = https_get("/healthz")
    check(status == 200 and body == "ok\n", f"TLS: /healthz over HTTPS without a token ({status})")
    check(https_get("/api/overview")[0] == 401, "TLS: the API asks for the user token")
    status, body = https_get("/api/overview", user_token)
    check(status == 200 and json.loads(body)["sweeps"] == [], f"TLS: the API answers the user token ({status})")
    status, _ = http_get(f"http://127.0.0.1:{http_port}/healthz")
    check(status != 200, "TLS: no plaintext answer on the HTTPS port")
    # The page itself over HTTPS: chromium trusts the development CA only
    # with --ignore-certificate-errors, which this profile lacks; so the
    # browser part goes through chromium's own dump of the DOM with it.
    dump = subprocess.run(
        ["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run", "--ignore-certificate-errors",
         f"--user-data-dir={os.path.join(work, 'chromium-tls')}", "--virtual-time-budget=5000",
         "--dump-dom", f"https://127.0.0.1:{http_port}/"], capture_output=True, text=True, timeout=120)
    check('id="login"' in dump.stdout and 'id="login" hidden' not in dump.stdout,
          "TLS: the page, loaded over HTTPS by chromium, shows the token form")
    process.send_signal(signal.SIGTERM)
    process.wait(timeout=20)

    # Plaintext off loopback: /healthz only, the dashboard is not served.
    http_port = free_port()
    port_file = os.path.join(work, "open-port")
    log = open(os.path.join(work, "coordinator-open.log"), "w")
    process = subprocess.Popen(
        [args.coordinator, "--db", os.path.join(work, "open.db"), "--listen", "127.0.0.1:0",
         "--insecure", "--port-file", port_file, "--http-listen", f"0.0.0.0:{http_port}"],
        stdout=log, stderr=subprocess.STDOUT)
    processes.append(process)
    if check(wait_for(lambda: os.path.exists(port_file), 30), "a plaintext coordinator with 0.0.0.0 HTTP started"):
        check(http_get(f"http://127.0.0.1:{http_port}/healthz")[0] == 200, "plaintext 0.0.0.0: /healthz is served")
        check(http_get(f"http://127.0.0.1:{http_port}/")[0] == 404, "plaintext 0.0.0.0: the dashboard is not")
        check(http_get(f"http://127.0.0.1:{http_port}/api/overview")[0] == 404, "plaintext 0.0.0.0: nor its API")
        check("dashboard not served" in open(os.path.join(work, "coordinator-open.log")).read(),
              "plaintext 0.0.0.0: the log says why")
    process.send_signal(signal.SIGTERM)
    process.wait(timeout=20)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("coordinator")
    parser.add_argument("worker")
    parser.add_argument("cli")
    parser.add_argument("--screenshot", default="")
    args = parser.parse_args()

    work = tempfile.mkdtemp(prefix="totalgrad-dashboard-")
    processes = []
    driver = None
    try:
        for name, token in (("user.token", USER_TOKEN), ("worker.token", WORKER_TOKEN)):
            path = os.path.join(work, name)
            with open(path, "w") as f:
                f.write(token)
            os.chmod(path, 0o600)
        with open(os.path.join(work, "browser.toml"), "w") as f:
            f.write(SWEEP)
        http_port = free_port()
        port_file = os.path.join(work, "port")
        coordinator_log = open(os.path.join(work, "coordinator.log"), "w")
        processes.append(subprocess.Popen(
            [args.coordinator, "--db", os.path.join(work, "c.db"), "--listen", "127.0.0.1:0",
             "--insecure", "--worker-token-file", os.path.join(work, "worker.token"),
             "--user-token-file", os.path.join(work, "user.token"), "--port-file", port_file,
             "--http-listen", f"127.0.0.1:{http_port}", "--heartbeat-interval", "0.2",
             "--lease-timeout", "10"],
            stdout=coordinator_log, stderr=subprocess.STDOUT))
        port = wait_for(lambda: open(port_file).read().strip() if os.path.exists(port_file) else None, 30)
        if not check(port, "the coordinator started"):
            return 1
        base = f"http://127.0.0.1:{http_port}"
        connection = ["--coordinator", f"127.0.0.1:{port}", "--insecure",
                      "--token-file", os.path.join(work, "user.token")]
        submitted = subprocess.run([args.cli, "sweep", "submit", os.path.join(work, "browser.toml")]
                                   + connection, capture_output=True, text=True)
        if not check(submitted.returncode == 0, "the sweep was submitted: " + submitted.stdout.strip()
                     + submitted.stderr.strip()):
            return 1

        # The HTTP port without a browser: probes need no token, the API does.
        status, body = http_get(base + "/healthz")
        check(status == 200 and body == "ok\n", f"/healthz answers 200 without a token ({status})")
        status, body = http_get(base + "/api/overview")
        check(status == 401, f"/api/overview without a token is refused with 401 ({status})")
        status, body = http_get(base + "/api/overview", WORKER_TOKEN)
        check(status == 403, f"/api/overview with the worker token is refused with 403 ({status})")
        status, body = http_get(base + "/api/sweep?name=nope", USER_TOKEN)
        check(status == 404 and "nope" in json.loads(body)["error"], f"an unknown sweep is 404 ({status})")
        status, body = http_get(base + "/api/job?id=x", USER_TOKEN)
        check(status == 400 and "'id'" in json.loads(body)["error"], f"a malformed job id is 400 ({status})")

        profile = os.path.join(work, "chromium-profile")
        driver, reason = start_browser(profile)
        if driver is None:
            print("SKIP: " + reason, flush=True)
            return SKIP
        from selenium.webdriver.common.by import By

        def find(css):
            found = driver.find_elements(By.CSS_SELECTOR, css)
            return found[0] if found else None

        driver.get(base + "/")
        check(wait_for(lambda: find("#login:not([hidden])"), 15), "the page asks for the user token")
        find("#token").send_keys(USER_TOKEN)
        find("#login-form button").click()
        row = wait_for(lambda: find('#sweeps tr[data-sweep="browser"]'), 15)
        if not check(row, "the overview lists the sweep after the token is given"):
            return 1
        check("0/72 episodes" in row.text, "before any worker runs: 0/72 episodes stored (" + row.text + ")")

        worker_log = open(os.path.join(work, "worker.log"), "w")
        processes.append(subprocess.Popen(
            [args.worker, "--coordinator", f"127.0.0.1:{port}", "--insecure",
             "--token-file", os.path.join(work, "worker.token"), "--slots", "1",
             "--worker-id", "browser-worker", "--state-dir", os.path.join(work, "worker-state"),
             "--acquire-wait", "1"],
            stdout=worker_log, stderr=subprocess.STDOUT))

        row.find_element(By.CSS_SELECTOR, "a").click()
        check(wait_for(lambda: find("#sweep-progress .progress-text"), 15), "the sweep's page opens")

        # Watch the page while the worker runs: (episodes stored, jobs text, curve points).
        observations = []
        shot = False
        deadline = time.time() + 240
        while time.time() < deadline:
            try:
                progress = find("#sweep-progress .progress-text")
                text = find("#sweep-progress").text
                episodes = int(progress.get_attribute("data-episodes")) if progress else -1
                points = len(driver.find_elements(By.CSS_SELECTOR, "#curves svg.panel circle"))
                shape = "|".join(c.get_attribute("points") for c in
                                 driver.find_elements(By.CSS_SELECTOR, "#curves polyline.curve"))
            except Exception:  # the view was swapped under us: look again
                time.sleep(0.2)
                continue
            if not observations or observations[-1][:4] != (episodes, text, points, shape):
                observations.append((episodes, text, points, shape))
            # The picture for docs/: the page half-way, a trial running.
            if args.screenshot and not shot and 30 <= episodes <= 50 and jobs_running(text) > 0:
                height = driver.execute_script("return document.documentElement.scrollHeight")
                driver.set_window_size(1500, min(int(height) + 40, 4000))
                time.sleep(0.3)
                driver.save_screenshot(args.screenshot)
                driver.set_window_size(1500, 1200)
                shot = True
                print("screenshot (mid-run): " + args.screenshot)
            if "72/72 episodes" in text and jobs_running(text) == 0:
                break
            time.sleep(0.4)
        for episodes, text, points, _ in observations:
            print(f"     seen: {episodes:3d} episodes, {points:3d} curve points | {text}")
        running_changes = [
            (a, b) for a, b in zip(observations, observations[1:])
            if b[0] > a[0] > 0 and jobs_running(a[1]) > 0 and jobs_running(b[1]) > 0]
        check(running_changes, "the stored-episode count changed on the page while a trial was running")
        curve_changes = [(a, b) for a, b in zip(observations, observations[1:])
                         if a[3] and b[3] != a[3] and jobs_running(a[1]) > 0 and jobs_running(b[1]) > 0]
        check(curve_changes, "the learning curves were redrawn with new episodes while trials were running")
        check(any("≈" in t for _, t, _, _ in observations), "an estimated time to finish was shown")
        check(observations and "72/72 episodes" in observations[-1][1], "the sweep finished: 72/72 episodes")

        # After the last refresh: the Table 1 view, a plot per variant, the comparison.
        time.sleep(3.5)
        table = wait_for(lambda: find("#table1"), 15)
        if check(table, "the Table 1 view is there"):
            cells = table.find_elements(By.CSS_SELECTOR, "td .cell-rate")
            check(len(cells) == 4 and all("n=3" in c.text for c in cells),
                  "Table 1 has 2 methods x 2 variants, each with a Wilson interval and n=3: "
                  + " | ".join(c.text for c in cells))
        link = find("#table1-link")
        if check(link, "the sweep's page links to the paper's Table 1 layout"):
            link.click()

            def read_grid():  # None until the view is there (or while it is swapped)
                try:
                    grid, protocol = find("#table1-grid"), find("#table1-protocol")
                    if not grid:
                        return None
                    return (len(grid.find_elements(By.CSS_SELECTOR, "tbody tr")),
                            len(grid.find_elements(By.CSS_SELECTOR, "tbody td")),
                            [c.text for c in grid.find_elements(By.CSS_SELECTOR, "td.off-protocol .cell-rate")],
                            protocol.text if protocol else "")
                except Exception:
                    return None
            grid = wait_for(read_grid, 15)
            if check(grid, "the paper's Table 1 view opens"):
                rows, cells, marked, protocol = grid
                check(rows == 4 and cells == 32, f"4 tasks x 8 methods ({rows} rows, {cells} cells)")
                check(len(marked) == 4 and all("n=3*" in text for text in marked),
                      "the 4 cells with trials have n=3 and the protocol mark: " + " | ".join(marked))
                check("particles = 50 (paper 300)" in protocol,
                      "the view says which option differs from the paper's protocol")
                # The grid as a figure: a panel per task with trials, every
                # method in its place, a Wilson bar where there are trials and
                # the paper's rate as a diamond.
                panels = driver.find_elements(By.CSS_SELECTOR, "#success-chart svg.success-panel")
                bars = driver.find_elements(By.CSS_SELECTOR, "#success-chart g.rate")
                counts = driver.find_elements(By.CSS_SELECTOR, "#success-chart text.count")
                diamonds = driver.find_elements(By.CSS_SELECTOR, "#success-chart polygon.paper")
                check(len(panels) == 2 and len(bars) == 4 and len(counts) == 16 and len(diamonds) >= 14,
                      f"Table 1's figure: 2 task panels, 4 Wilson bars, 16 counts, the paper's rates "
                      f"({len(panels)}, {len(bars)}, {len(counts)}, {len(diamonds)})")
            driver.back()
            table = wait_for(lambda: find("#table1"), 15)
        rates = driver.find_elements(By.CSS_SELECTOR, "#success-chart svg.success-panel")
        counts = [t.text for t in driver.find_elements(By.CSS_SELECTOR, "#success-chart text.count")]
        check(len(rates) == 2 and len(counts) == 4 and all(c.endswith("/3") for c in counts),
              f"the success-rate figure: a panel per task variant, k/3 per method ({len(rates)}, {counts})")
        panels = driver.find_elements(By.CSS_SELECTOR, "#curves svg.panel")
        check(len(panels) == 2, f"one curve panel per task variant ({len(panels)})")
        curves = driver.find_elements(By.CSS_SELECTOR, "#curves svg.panel polyline.curve")
        check(len(curves) == 4, f"a median curve per method and panel ({len(curves)})")
        legend = " ".join(p.text for p in panels)
        check("RP (n=3)" in legend and "TP (n=3)" in legend, "the legends give n per method")
        compare = find("#compare")
        if check(compare, "the comparison table is there"):
            rows = compare.find_elements(By.CSS_SELECTOR, "tbody tr")
            check(len(rows) == 2, f"one comparison per variant ({len(rows)})")
            # Issue 29: a green row says which test and which method.
            headers = [h.text for h in compare.find_elements(By.CSS_SELECTOR, "thead th")]
            verdicts = [c.text for c in compare.find_elements(By.CSS_SELECTOR, "tbody td.verdict")]
            check(headers[-1:] == ["verdict"] and len(verdicts) == 2
                  and all(v == "no evidence" or "better" in v for v in verdicts),
                  f"a verdict column per comparison: {headers[-1:]} {verdicts}")
        statistic_panels = driver.find_elements(By.CSS_SELECTOR, "#diagnostics svg.panel")
        check(len(statistic_panels) == 2 and all(len(p.find_elements(By.CSS_SELECTOR, "polyline.curve")) == 2
                                                 for p in statistic_panels),
              f"the estimator statistic per method: a panel per variant with RP's and TP's curves "
              f"({len(statistic_panels)} panels)")
        multiples = driver.find_elements(By.CSS_SELECTOR, "#final-trajectories svg.multiple")
        check(len(multiples) == 12, f"one small plot of the final episode per trial ({len(multiples)} of 12)")
        check(all(m.get_attribute("data-held") in ("true", "false") and
                  len(m.find_elements(By.CSS_SELECTOR, "polyline.series")) == 1 and
                  len(m.find_elements(By.CSS_SELECTOR, "line.threshold")) == 1 for m in multiples),
              "each with its goal distance, the verdict distance and the rollout verdict")
        job_link = find("#jobs a")
        if check(job_link, "the jobs are listed"):
            job_link.click()
            episodes_table = wait_for(lambda: find("#episodes"), 15)
            if check(episodes_table, "a job's page shows its episodes"):
                check(len(episodes_table.find_elements(By.CSS_SELECTOR, "tbody tr")) == 6,
                      "all 6 episodes of the job are listed")
                check(find("#attempts") and find("#events"), "and its attempts and events (logs)")
                # Issue 29: absent parts (no error, no plot) left the text "null".
                view_text = find("#view").text
                check("null" not in view_text.split(), "the job page prints no literal null: "
                      + view_text[:200].replace("\n", " | "))
                trajectory_checks(driver, find)
            driver.back()
            wait_for(lambda: find("#table1"), 15)
        cli_checks(args, work, connection, base)
        tls_checks(args, work, driver, processes)
    finally:
        if driver is not None:
            driver.quit()
        for process in reversed(processes):
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
                try:
                    process.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()
        failed = [what for ok, what in checks if not ok]
        if failed:
            for name in ("coordinator.log", "worker.log"):
                path = os.path.join(work, name)
                if os.path.exists(path):
                    print(f"---- {name}\n" + open(path).read()[-6000:])
        shutil.rmtree(work, ignore_errors=True)
    failed = [what for ok, what in checks if not ok]
    print(f"{len(checks) - len(failed)} passed, {len(failed)} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
