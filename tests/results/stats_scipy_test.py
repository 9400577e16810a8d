#!/usr/bin/python3
"""The comparison statistics (results/hypothesis_tests.h)
against values computed independently: SciPy (Debian's python3-scipy) where
it has the test, brute-force enumeration in this file where it does not
(exact Wilcoxon with ties or zeros, the exact power sums), and a simulation
for Noether's power approximation.

Usage: stats_scipy_test.py STATS_CASES_BINARY
Prints one line per family and "N passed, N failed"; exits non-zero on any
failure. Deterministic (fixed seeds).
"""
import itertools
import json
import math
import subprocess
import sys

import numpy as np
from scipy import stats

failures = []
checked = 0


def run_cases(binary, cases):
    text = "\n".join(json.dumps(c) for c in cases) + "\n"
    out = subprocess.run([binary], input=text, capture_output=True, text=True, check=True).stdout
    answers = [json.loads(line) for line in out.splitlines()]
    assert len(answers) == len(cases), (len(answers), len(cases))
    for case, answer in zip(cases, answers):
        if "error" in answer:
            raise RuntimeError(f"{case}: {answer['error']}")
    return answers


def close(actual, expected, rel=1e-9, abs_tol=1e-13):
    if expected is None or actual is None:
        return expected is None and actual is None
    if isinstance(expected, float) and math.isinf(expected):
        return actual == "inf"
    return math.isclose(actual, expected, rel_tol=rel, abs_tol=abs_tol)


def expect(family, case, name, actual, expected, rel=1e-9, abs_tol=1e-13):
    global checked
    checked += 1
    if not close(actual, expected, rel, abs_tol):
        failures.append(f"{family}: {case}: {name} = {actual}, expected {expected}")


def midrank_exact_wilcoxon(d):
    """Two-sided exact p of the signed-rank test by enumerating all 2^n signs
    on SciPy's midranks of |d| (zeros dropped)."""
    d = [x for x in d if x != 0]
    n = len(d)
    if n == 0:
        return 1.0
    ranks = stats.rankdata(np.abs(d))
    observed = sum(r for r, x in zip(ranks, d) if x > 0)
    below = above = 0
    for signs in itertools.product((0, 1), repeat=n):
        w = sum(r for r, s in zip(ranks, signs) if s)
        below += w <= observed + 1e-9
        above += w >= observed - 1e-9
    total = 2 ** n
    if abs(2 * observed - n * (n + 1) / 2) < 1e-9:
        return 1.0
    return min(1.0, 2 * min(below, above) / total)


def main(binary):
    rng = np.random.default_rng(20240611)

    # Binomial test: SciPy's binomtest.
    cases = []
    for _ in range(300):
        n = int(rng.integers(0, 200))
        k = int(rng.integers(0, n + 1))
        p = 0.5 if rng.random() < 0.5 else float(rng.uniform(0.02, 0.98))
        cases.append({"test": "binom", "k": k, "n": n, "p": p})
    for case, answer in zip(cases, run_cases(binary, cases)):
        expected = 1.0 if case["n"] == 0 else stats.binomtest(case["k"], case["n"], case["p"]).pvalue
        expect("binomial", case, "p", answer["p"], float(expected))

    # Fisher's exact test: SciPy's fisher_exact (p and sample odds ratio).
    cases = [{"test": "fisher", "table": [int(x) for x in rng.integers(0, 40, size=4)]}
             for _ in range(400)]
    cases += [{"test": "fisher", "table": t} for t in ([0, 0, 3, 4], [5, 0, 0, 5], [0, 7, 0, 9])]
    for case, answer in zip(cases, run_cases(binary, cases)):
        a, b, c, d = case["table"]
        odds, p = stats.fisher_exact([[a, b], [c, d]])
        expect("fisher", case, "p", answer["p"], float(p))
        expected_odds = None if (a * d == 0 and b * c == 0) else float(odds)
        expect("fisher", case, "odds_ratio", answer["odds_ratio"], expected_odds)

    # Wilcoxon, exact, no ties or zeros: SciPy's wilcoxon(method="exact").
    cases = []
    for _ in range(200):
        n = int(rng.integers(1, 51))
        d = rng.normal(float(rng.uniform(-1, 1)), 1.0, size=n)
        cases.append({"test": "wilcoxon", "d": [float(x) for x in d]})
    for case, answer in zip(cases, run_cases(binary, cases)):
        result = stats.wilcoxon(case["d"], method="exact")
        expect("wilcoxon-exact", len(case["d"]), "p", answer["p"], float(result.pvalue))
        expect("wilcoxon-exact", len(case["d"]), "min(W+, W-)",
               min(answer["w_plus"], answer["w_minus"]), float(result.statistic))
        if not answer["exact"]:
            failures.append(f"wilcoxon-exact: n={len(case['d'])} not computed exactly")

    # Wilcoxon, large n with ties and zeros: SciPy's normal approximation
    # (zeros dropped, tie-corrected variance, no continuity correction).
    cases = []
    for _ in range(100):
        n = int(rng.integers(51, 400))
        d = np.round(rng.normal(float(rng.uniform(-0.5, 0.5)), 2.0, size=n))
        cases.append({"test": "wilcoxon", "d": [float(x) for x in d]})
    for case, answer in zip(cases, run_cases(binary, cases)):
        d = np.array(case["d"])
        if np.count_nonzero(d) <= 50:
            continue  # we would be exact there; SciPy would not
        result = stats.wilcoxon(d, method="approx", zero_method="wilcox", correction=False)
        expect("wilcoxon-normal", len(d), "p", answer["p"], float(result.pvalue), rel=1e-8)

    # Wilcoxon, exact with ties and zeros (SciPy has no exact test there):
    # enumeration of every sign assignment; Hodges-Lehmann and rank-biserial
    # from their definitions.
    cases = []
    for _ in range(60):
        n = int(rng.integers(1, 15))
        d = rng.integers(-3, 4, size=n).astype(float)
        cases.append({"test": "wilcoxon", "d": [float(x) for x in d]})
    for case, answer in zip(cases, run_cases(binary, cases)):
        d = case["d"]
        expect("wilcoxon-ties", d, "p", answer["p"], midrank_exact_wilcoxon(d), rel=1e-12)
        walsh = [(d[i] + d[j]) / 2 for i in range(len(d)) for j in range(i, len(d))]
        expect("wilcoxon-ties", d, "hodges_lehmann", answer["hodges_lehmann"], float(np.median(walsh)))
        nonzero = [x for x in d if x != 0]
        if nonzero:
            ranks = stats.rankdata(np.abs(nonzero))
            plus = sum(r for r, x in zip(ranks, nonzero) if x > 0)
            minus = sum(r for r, x in zip(ranks, nonzero) if x < 0)
            expect("wilcoxon-ties", d, "rank_biserial", answer["rank_biserial"],
                   float((plus - minus) / (plus + minus)))

    # McNemar's exact power: sum over every (b, c, concordant) outcome of the
    # multinomial, each judged by SciPy's binomtest.
    cases = []
    for _ in range(25):
        n = int(rng.integers(1, 26))
        p10 = float(rng.uniform(0, 0.6))
        p01 = float(rng.uniform(0, 1 - p10)) * 0.5
        cases.append({"test": "mcnemar_power", "n": n, "p10": p10, "p01": p01})
    for case, answer in zip(cases, run_cases(binary, cases)):
        n, p10, p01 = case["n"], case["p10"], case["p01"]
        power = 0.0
        for b in range(n + 1):
            for c in range(n - b + 1):
                if b + c == 0 or stats.binomtest(b, b + c, 0.5).pvalue > 0.05:
                    continue
                power += stats.multinomial.pmf([b, c, n - b - c], n, [p10, p01, 1 - p10 - p01])
        expect("mcnemar-power", case, "power", answer["power"], float(power), rel=1e-8, abs_tol=1e-12)

    # Fisher's exact power: every pair of binomial outcomes, each judged by
    # SciPy's fisher_exact.
    cases = []
    for _ in range(20):
        cases.append({"test": "fisher_power", "n1": int(rng.integers(1, 16)),
                      "p1": float(rng.uniform(0, 1)), "n2": int(rng.integers(1, 16)),
                      "p2": float(rng.uniform(0, 1))})
    for case, answer in zip(cases, run_cases(binary, cases)):
        n1, p1, n2, p2 = case["n1"], case["p1"], case["n2"], case["p2"]
        power = 0.0
        for x1 in range(n1 + 1):
            for x2 in range(n2 + 1):
                if stats.fisher_exact([[x1, n1 - x1], [x2, n2 - x2]])[1] <= 0.05:
                    power += stats.binom.pmf(x1, n1, p1) * stats.binom.pmf(x2, n2, p2)
        expect("fisher-power", case, "power", answer["power"], float(power), rel=1e-8, abs_tol=1e-12)

    # Holm: from its definition, written out independently here.
    cases = [{"test": "holm", "p": [float(x) for x in rng.uniform(0, 0.2, size=int(rng.integers(1, 12)))]}
             for _ in range(100)]
    for case, answer in zip(cases, run_cases(binary, cases)):
        p = case["p"]
        m = len(p)
        order = sorted(range(m), key=lambda i: p[i])
        adjusted = [0.0] * m
        running = 0.0
        for rank, i in enumerate(order):
            running = max(running, min(1.0, (m - rank) * p[i]))
            adjusted[i] = running
        for i in range(m):
            expect("holm", case, f"adjusted[{i}]", answer["adjusted"][i], adjusted[i], rel=1e-14)

    # Walsh fraction (P(D + D' > 0) estimate), brute force.
    cases = [{"test": "walsh", "d": [float(x) for x in rng.integers(-4, 5, size=int(rng.integers(2, 20)))]}
             for _ in range(50)]
    for case, answer in zip(cases, run_cases(binary, cases)):
        d = case["d"]
        pairs = [(d[i] + d[j]) for i in range(len(d)) for j in range(i + 1, len(d))]
        fraction = (sum(s > 0 for s in pairs) + 0.5 * sum(s == 0 for s in pairs)) / len(pairs)
        expect("walsh", case, "fraction", answer["fraction"], fraction, rel=1e-14)

    # Noether's power against the simulated power of the exact signed-rank
    # test for normal shifts (true P(D + D' > 0) = Phi(sqrt(2) delta)). An
    # approximation: the tolerance is what it is held to, and the measured
    # gaps are printed.
    cases, simulated = [], []
    for n, delta in ((10, 0.8), (20, 0.5), (30, 0.3), (30, 0.5), (50, 0.3), (100, 0.2)):
        p_prime = float(stats.norm.cdf(math.sqrt(2) * delta))
        cases.append({"test": "noether", "n": n, "p_prime": p_prime})
        reps = 2000
        rejections = 0
        for _ in range(reps):
            d = rng.normal(delta, 1.0, size=n)
            method = "exact" if n <= 50 else "approx"
            rejections += stats.wilcoxon(d, method=method).pvalue <= 0.05
        simulated.append(rejections / reps)
    gaps = []
    for case, answer, sim in zip(cases, run_cases(binary, cases), simulated):
        gap = answer["power"] - sim
        gaps.append(f"n={case['n']} p'={case['p_prime']:.3f}: Noether {answer['power']:.3f}, simulated {sim:.3f}")
        expect("noether", case, "power vs simulation", answer["power"], sim, rel=0, abs_tol=0.08)
    print("noether vs simulation (2000 replicates each):\n  " + "\n  ".join(gaps))

    # Hodges-Lehmann interval: k from the exact null distribution of T+ by
    # enumerating all 2^n sign assignments, the order statistics of the
    # Walsh averages sorted here.
    cases = [{"test": "hl_interval", "d": [round(float(x), 3) for x in rng.normal(0.5, 2, size=int(rng.integers(1, 13)))]}
             for _ in range(60)]
    for case, answer in zip(cases, run_cases(binary, cases)):
        d = case["d"]
        n = len(d)
        counts = [0] * (n * (n + 1) // 2 + 1)
        for signs in itertools.product((0, 1), repeat=n):
            counts[sum(r for r, s in zip(range(1, n + 1), signs) if s)] += 1
        cdf = list(itertools.accumulate(c / 2 ** n for c in counts))
        k = next(t for t, value in enumerate(cdf) if value >= 0.025)
        k = max(k, 1)
        walsh = sorted((d[i] + d[j]) / 2 for i in range(n) for j in range(i, n))
        expect("hl_interval", case, "estimate", answer["estimate"], float(np.median(walsh)), rel=1e-12)
        expect("hl_interval", case, "low", answer["low"], walsh[k - 1], rel=1e-14)
        expect("hl_interval", case, "high", answer["high"], walsh[len(walsh) - k], rel=1e-14)
        expect("hl_interval", case, "coverage", answer["coverage"], 1 - 2 * cdf[k - 1], rel=1e-12)

    # Newcombe's paired interval (method 10), written out here from the
    # paper's formulas with SciPy's normal quantile.
    z = float(stats.norm.ppf(0.975))

    def wilson(k, n):
        p = k / n
        centre = (p + z * z / (2 * n)) / (1 + z * z / n)
        half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        return centre - half, centre + half

    cases = [{"test": "newcombe_paired", "table": [int(x) for x in rng.integers(0, 8, size=4)]}
             for _ in range(80)]
    for case, answer in zip(cases, run_cases(binary, cases)):
        a, b, c, dd = case["table"]
        n = a + b + c + dd
        if n == 0:
            expect("newcombe_paired", case, "difference", answer["difference"], None)
            continue
        p1, p2 = (a + b) / n, (a + c) / n
        l1, u1 = wilson(a + b, n)
        l2, u2 = wilson(a + c, n)
        margins = (a + b) * (c + dd) * (a + c) * (b + dd)
        phi = (a * dd - b * c) / math.sqrt(margins) if margins > 0 else 0.0
        delta = p1 - p2
        low = delta - math.sqrt(max(0.0, (p1 - l1) ** 2 - 2 * phi * (p1 - l1) * (u2 - p2) + (u2 - p2) ** 2))
        high = delta + math.sqrt(max(0.0, (p2 - l2) ** 2 - 2 * phi * (p2 - l2) * (u1 - p1) + (u1 - p1) ** 2))
        expect("newcombe_paired", case, "difference", answer["difference"], delta, rel=1e-12, abs_tol=1e-15)
        expect("newcombe_paired", case, "low", answer["low"], max(-1.0, low), rel=1e-9, abs_tol=1e-12)
        expect("newcombe_paired", case, "high", answer["high"], min(1.0, high), rel=1e-9, abs_tol=1e-12)

    print(f"{checked - len(failures)} passed, {len(failures)} failed")
    for failure in failures[:40]:
        print("FAIL", failure)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
