#!/usr/bin/env python3
"""Runs `totalgrad pilco propagate` and the original PILCO (compare_with_pilco.m under GNU
Octave) on the same scenarios and prints the max absolute and relative difference per field.

Pure Python (no numpy). Needs octave on PATH (or --octave) and a checkout of
UCL-SML/pilco-matlab (--pilco-dir or the environment variable PILCO_DIR). Run from the
repository root:

    PILCO_DIR=/path/to/pilco-matlab python3 docs/pilco-examples/compare.py \
        docs/pilco-examples/swingup_sincos_tip.json docs/pilco-examples/balance_raw_angle.json

Fields: mean, cov, cost_mean, cost_std, J and the gradient blocks.
 * A scenario with `policy.targets` (PILCO's pseudo-targets) is compared directly: our
   dJ_dcentres, dJ_dtargets, dJ_dlog_lengthscales are PILCO's parameterisation (docs/pilco.md).
 * A scenario with `policy.weights` w: the driver gives PILCO the pseudo-targets
   y = A w, A = K_cc + 0.01^2 I. Two comparisons are printed:
   [weights] our output as is against PILCO's gradients converted to (centres, weights, log l)
     with w held fixed: dJ/dw = A g, dJ/dc_kd += sum_j K_kj (c_jd - c_kd) / l_d^2 (g_k w_j + g_j w_k),
     dJ/dlog l_d += sum_ij g_i w_j K_ij (c_id - c_jd)^2 / l_d^2, with g = PILCO's dJ/dy;
   [targets] our command run again on a copy of the scenario with `targets` = y (a temporary
     file), compared with PILCO's gradients directly.
General-form scenarios (files with "angle_indices": several angles, several controls, FITC,
index sets into z; docs/pilco.md) go, with --reference auto (the default), to the original PILCO
as well when a PILCO checkout is given (compare_with_pilco.m builds plant.angi/dyni/poli, congp
with F outputs, gp0d or gp1d with the inducing inputs, lossSat on z per width); the same two
comparisons as above, the [weights] conversion per control column (y_j = A_j w_j with that
control's length-scales; shared length-scales: the F columns' gradients summed), and for a
`targets` file also our `weights` against the driver's (K_j + 0.01^2 I)^-1 y_j. Without a PILCO
checkout (or with --reference numpy) they are compared with pilco_reference.py, our independent
numpy implementation of PILCO's published equations (needs numpy; no Octave), whose gradients are
complex-step derivatives of its J: all fields, in the file's own parameterisation, under the
label `numpy`. --reference pilco insists on PILCO for them.
Relative difference: `rel` = max|ours - pilco| / max|pilco| over the field; `rel_elem` = max over
entries with |pilco| > 1e-6 max|pilco| of |ours - pilco| / |pilco|.
Exit code 1 when any `rel` exceeds --tol (default 1e-6).
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def flat(x):
    if isinstance(x, list):
        out = []
        for e in x:
            out.extend(flat(e))
        return out
    return [float(x)]


def diff(ours, ref):
    a, b = flat(ours), flat(ref)
    if len(a) != len(b):
        raise SystemExit("shape mismatch: %d vs %d entries" % (len(a), len(b)))
    scale = max(abs(v) for v in b) if b else 0.0
    dabs = max(abs(x - y) for x, y in zip(a, b)) if a else 0.0
    rel = dabs / scale if scale > 0 else (0.0 if dabs == 0 else math.inf)
    big = [(x, y) for x, y in zip(a, b) if abs(y) > 1e-6 * scale]
    rel_elem = max((abs(x - y) / abs(y) for x, y in big), default=0.0)
    return dabs, rel, rel_elem, len(b)


def run_ours(totalgrad, path):
    res = subprocess.run([totalgrad, "pilco", "propagate", path], capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit("totalgrad failed (%d): %s" % (res.returncode, res.stderr))
    return json.loads(res.stdout)


def run_pilco(octave, pilco_dir, path):
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "pilco.json")
        expr = "addpath('%s'); compare_with_pilco('%s', '%s', '%s');" % (
            HERE, os.path.abspath(path), pilco_dir, out)
        res = subprocess.run([octave, "--no-gui", "--no-window-system", "-q", "--eval", expr],
                             capture_output=True, text=True)
        if not os.path.exists(out):
            raise SystemExit("octave failed (%d): %s %s" % (res.returncode, res.stdout, res.stderr))
        with open(out) as f:
            return json.load(f)


def columns(v):
    """A C-vector -> [v]; a C x F nested list -> its F columns."""
    if v and isinstance(v[0], list):
        return [[float(row[j]) for row in v] for j in range(len(v[0]))]
    return [list(map(float, v))]


def to_weights_parameterisation(scenario, pilco):
    """PILCO's gradients (pseudo-targets y fixed) -> ours (weights w fixed), see module doc.
    Per control column j (y_j = A_j w_j, A_j with control j's length-scales); the centres'
    terms of all columns add up; shared length-scales get the sum of the columns' gradients."""
    pol = scenario["policy"]
    c = pol["centres"]
    ws = columns(pol["weights"])
    gs = columns(pilco["dJ_dtargets"])
    nf = len(ws)
    ll = pol["log_lengthscales"]
    shared = not (ll and isinstance(ll[0], list))
    ells = [[math.exp(v) for v in (ll if shared else ll[f])] for f in range(nf)]
    if "dJ_dlog_lengthscales_per_control" in pilco:
        pl = pilco["dJ_dlog_lengthscales_per_control"]
        pls = [list(map(float, flat(pl)))] if nf == 1 else [list(map(float, r)) for r in pl]
    else:
        pls = [list(map(float, flat(pilco["dJ_dlog_lengthscales"])))]
    n, ep = len(c), len(ells[0])
    dc = [list(map(float, row)) for row in pilco["dJ_dcentres"]]
    dws, dls = [], []
    for f in range(nf):
        ell, w, g, dl = ells[f], ws[f], gs[f], pls[f]
        k = [[math.exp(-0.5 * sum(((c[i][d] - c[j][d]) / ell[d]) ** 2 for d in range(ep)))
              for j in range(n)] for i in range(n)]
        dws.append([sum((k[i][j] + (1e-4 if i == j else 0.0)) * g[j] for j in range(n))
                    for i in range(n)])
        for a in range(n):
            for d in range(ep):
                dc[a][d] += sum(k[a][j] * (c[j][d] - c[a][d]) / ell[d] ** 2 *
                                (g[a] * w[j] + g[j] * w[a]) for j in range(n))
        for d in range(ep):
            dl[d] += sum(g[i] * w[j] * k[i][j] * (c[i][d] - c[j][d]) ** 2 / ell[d] ** 2
                         for i in range(n) for j in range(n))
        dls.append(dl)
    if nf == 1:
        dw = dws[0]
    else:
        dw = [[dws[f][i] for f in range(nf)] for i in range(n)]
    dl = [sum(dls[f][d] for f in range(nf)) for d in range(ep)] if shared else dls
    return {"dJ_dweights": dw, "dJ_dcentres": dc, "dJ_dlog_lengthscales": dl}


def report(name, rows, tol):
    worst = 0.0
    print("  %-10s %-22s %7s %12s %12s %12s" % ("", "field", "entries", "max abs", "rel", "rel_elem"))
    for field, ours, ref in rows:
        dabs, rel, rel_elem, n = diff(ours, ref)
        worst = max(worst, rel)
        print("  %-10s %-22s %7d %12.3e %12.3e %12.3e" % (name, field, n, dabs, rel, rel_elem))
    return worst <= tol


def compare_general(path, scenario, ours, tol):
    """A general-form scenario against the numpy reference (pilco_reference.py)."""
    sys.path.insert(0, HERE)
    import pilco_reference  # numpy; only needed for the general form
    ref = pilco_reference.run(scenario)
    p = scenario["policy"]
    f = len(p["targets" if "targets" in p else "weights"][0]) if isinstance(
        p["targets" if "targets" in p else "weights"][0], list) else 1
    print("%s (H = %d, D = %d, angles %s, F = %d, %s; numpy reference)" % (
        path, scenario["horizon"], len(scenario["mu0"]), scenario["angle_indices"], f,
        "FITC M = %d" % len(scenario["inducing_inputs"]) if "inducing_inputs" in scenario
        else "full GP"))
    rows = [(k, ours[k], ref[k]) for k in ref]
    return report("numpy", rows, tol)


def describe(scenario):
    p = scenario["policy"]
    vals = p["targets" if "targets" in p else "weights"]
    f = len(vals[0]) if isinstance(vals[0], list) else 1
    ll = p["log_lengthscales"]
    return "D = %d, angles %s, F = %d%s, %s" % (
        len(scenario["mu0"]), scenario["angle_indices"], f,
        " (length-scales per control)" if ll and isinstance(ll[0], list) else "",
        "FITC M = %d" % len(scenario["inducing_inputs"]) if "inducing_inputs" in scenario
        else "full GP")


def compare_with_pilco(path, scenario, ours, args):
    """Today's form, or the general form, against PILCO under Octave (compare_with_pilco.m)."""
    ok = True
    general = "angle_indices" in scenario
    pilco = run_pilco(args.octave, args.pilco_dir, path)
    if general:
        print("%s (H = %d, %s; PILCO under Octave %s)" % (
            path, scenario["horizon"], describe(scenario), pilco["octave_version"]))
    else:
        print("%s (H = %d, Octave %s)" % (path, scenario["horizon"], pilco["octave_version"]))
    print("  PILCO: value.m J = %.17g, step-loop sum = %.17g" % (pilco["J"], pilco["J_loop"]))
    common = [(f, ours[f], pilco[f]) for f in ("mean", "cov", "cost_mean", "cost_std", "J")]
    if "targets" in scenario["policy"]:
        grads = [(f, ours[f], pilco[f])
                 for f in ("dJ_dcentres", "dJ_dtargets", "dJ_dlog_lengthscales")]
        if general:
            grads.append(("weights", ours["weights"], pilco["weights_driver"]))
        ok &= report("targets", common + grads, args.tol)
    else:
        conv = to_weights_parameterisation(scenario, pilco)
        grads = [(f, ours[f], conv[f])
                 for f in ("dJ_dcentres", "dJ_dweights", "dJ_dlog_lengthscales")]
        ok &= report("weights", common + grads, args.tol)
        variant = json.loads(json.dumps(scenario))
        del variant["policy"]["weights"]
        variant["policy"]["targets"] = pilco["targets"] if general else flat(pilco["targets"])
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as tmp:
            json.dump(variant, tmp)
        try:
            ours_t = run_ours(args.totalgrad, tmp.name)
        finally:
            os.unlink(tmp.name)
        rows = [(f, ours_t[f], pilco[f]) for f in
                ("J", "dJ_dcentres", "dJ_dtargets", "dJ_dlog_lengthscales")]
        rows.append(("weights", ours_t["weights"], scenario["policy"]["weights"]))
        ok &= report("targets", rows, args.tol)
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenarios", nargs="+")
    ap.add_argument("--pilco-dir", default=os.environ.get("PILCO_DIR"))
    ap.add_argument("--totalgrad", default=os.path.join(ROOT, "build-gp", "client", "totalgrad"))
    ap.add_argument("--octave", default="octave")
    ap.add_argument("--tol", type=float, default=1e-6)
    ap.add_argument("--reference", choices=("auto", "pilco", "numpy"), default="auto",
                    help="for general-form files: PILCO when a checkout is given (auto), "
                         "always PILCO, or always the numpy reference")
    args = ap.parse_args()

    ok = True
    for path in args.scenarios:
        with open(path) as f:
            scenario = json.load(f)
        ours = run_ours(args.totalgrad, path)
        general = "angle_indices" in scenario
        if general and (args.reference == "numpy" or
                        (args.reference == "auto" and not args.pilco_dir)):
            ok &= compare_general(path, scenario, ours, args.tol)
            continue
        if not args.pilco_dir:
            raise SystemExit("give --pilco-dir or set PILCO_DIR (a checkout of UCL-SML/pilco-matlab)")
        ok &= compare_with_pilco(path, scenario, ours, args)
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
