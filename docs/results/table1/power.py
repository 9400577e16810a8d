#!/usr/bin/python3
"""What n seeds per method can show (issue 16, docs/results/table1.md).

Exact power of the two-sided Fisher exact test at alpha = 0.05 for two
methods with true success rates p1 and p2 and n independent trials each:
the probability, summed over every outcome (x1, x2), of p < alpha. Paired
(McNemar) power needs the joint distribution of the pairs, which the paper
does not give; for methods whose successes are independent given the seed
the unpaired figure is the reference. Also the 95% Wilson interval's
half-width at n and p = 0.5 (the widest).

Usage: power.py [N...]   (default: 10 20 50 100)
"""
import math
import sys

from scipy.stats import binom, fisher_exact

PAPER = {"PILCO": 0.73, "RP": 0.15, "TP": 0.48, "GTP": 0.69}  # tip cost, k = 1
PAIRS = [("RP", "GTP"), ("RP", "PILCO"), ("TP", "GTP")]


def fisher_power(p1, p2, n, alpha=0.05):
    power = 0.0
    for x1 in range(n + 1):
        for x2 in range(n + 1):
            _, p = fisher_exact([[x1, n - x1], [x2, n - x2]], alternative="two-sided")
            if p < alpha:
                power += binom.pmf(x1, n, p1) * binom.pmf(x2, n, p2)
    return power


def wilson_half_width(n, p=0.5, z=1.959963984540054):
    return z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)


def main():
    sizes = [int(a) for a in sys.argv[1:]] or [10, 20, 50, 100]
    print("| n per method | " + " | ".join(f"{a} vs {b} ({PAPER[a]} vs {PAPER[b]})" for a, b in PAIRS)
          + " | Wilson 95% half-width at p = 0.5 |")
    print("|---" * (len(PAIRS) + 2) + "|")
    for n in sizes:
        cells = [f"{fisher_power(PAPER[a], PAPER[b], n):.2f}" for a, b in PAIRS]
        print(f"| {n} | " + " | ".join(cells) + f" | {wilson_half_width(n):.2f} |")


if __name__ == "__main__":
    main()
