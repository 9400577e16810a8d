// The statistics behind `totalgrad results compare` and the dashboard's
// comparison view: exact tests for small samples, their effect sizes, the
// power of each test at the sample size it was given, and Holm's correction.
// Pure functions of their arguments; thread-safe.
//
// Conventions (the same as R and SciPy unless said otherwise):
//   * Two-sided tests throughout. An exact two-sided p-value is the total
//     probability, under the null hypothesis, of the outcomes that are no
//     more probable than the observed one (pmf(x) <= pmf(observed) * (1 +
//     1e-7), R's tolerance for outcomes equal up to rounding). p is in
//     [0, 1]; 1 when there is nothing to test (no discordant pairs, no
//     non-zero difference).
//   * Power is the probability that the unadjusted two-sided test at level
//     `alpha` rejects when the truth equals what was observed (the effect
//     estimated from the data, at the same sample size). It says whether a
//     non-significant result could have been significant with this n: a
//     power of 0.3 means a real effect of the observed size would be missed
//     7 times in 10. It is a function of the data, not a new finding.
#ifndef TOTALGRAD_RESULTS_HYPOTHESIS_TESTS_H_
#define TOTALGRAD_RESULTS_HYPOTHESIS_TESTS_H_

#include <vector>

namespace totalgrad::results {

// Significance level used when none is given.
inline constexpr double kDefaultAlpha = 0.05;

// log(n choose k) for 0 <= k <= n (lgamma; relative error ~1e-15 for the
// n of this product). -inf outside that range.
double LogChoose(int n, int k);

// Exact two-sided binomial test of `successes` in `trials` against success
// probability `p` in (0, 1) (SciPy's binomtest(...).pvalue). 1 for trials == 0.
double BinomialTestTwoSided(int successes, int trials, double p = 0.5);

// McNemar's exact test for paired binary outcomes. `first_only` counts the
// pairs where only the first method succeeded, `second_only` those where
// only the second did (the discordant pairs); concordant pairs carry no
// information about the difference. The p-value is the exact binomial test
// of first_only in first_only + second_only at 1/2.
double McNemarExactP(int first_only, int second_only);

// Exact power of McNemar's test at level alpha with `pairs` pairs when the
// probabilities of the two kinds of discordant pair are `p_first_only` and
// `p_second_only` (p_first_only + p_second_only <= 1). Sums over the
// multinomial outcomes.
double McNemarExactPower(int pairs, double p_first_only, double p_second_only,
                         double alpha = kDefaultAlpha);

// Fisher's exact test of the 2x2 table
//            success  failure
//   first       a        b
//   second      c        d
// two-sided (SciPy's fisher_exact, R's fisher.test). 1 when a margin is 0.
double FisherExactP(int a, int b, int c, int d);

// Sample odds ratio a*d / (b*c): +inf when b*c == 0 < a*d, NaN when both
// are 0 (SciPy's fisher_exact statistic).
double OddsRatio(int a, int b, int c, int d);

// Exact power of Fisher's test at level alpha for two independent groups of
// `n_first` and `n_second` trials whose success probabilities are
// `p_first` and `p_second`. O(N^2 log N) for N = n_first + n_second.
double FisherExactPower(int n_first, double p_first, int n_second, double p_second,
                        double alpha = kDefaultAlpha);

// Largest n (= n_first + n_second, differences, pairs) for which the power
// functions above compute exactly; larger inputs return NaN rather than
// take minutes.
inline constexpr int kMaxExactPowerN = 4000;

// Wilcoxon's signed-rank test of paired differences d_i = first_i - second_i.
struct WilcoxonResult {
  int n = 0;             // non-zero differences (zeros are dropped, SciPy's "wilcox")
  int zeros = 0;         // dropped zero differences
  double w_plus = 0;     // sum of the (mid)ranks of |d_i| over positive d_i
  double w_minus = 0;    // the same over negative d_i; w_plus + w_minus = n(n+1)/2
  bool exact = false;    // p from the exact null distribution (else normal approximation)
  bool ties = false;     // some |d_i| were equal (midranks used)
  double p = 1;          // two-sided
  // Matched-pairs rank-biserial correlation (w_plus - w_minus) / (w_plus +
  // w_minus), in [-1, 1]: -1 when every difference is negative (the first
  // is always lower). 0 when n == 0.
  double rank_biserial = 0;
  // Hodges-Lehmann estimate of the shift: the median of the Walsh averages
  // (d_i + d_j) / 2, i <= j, over all differences (zeros included). NaN if
  // there are none.
  double hodges_lehmann = 0;
};

// Exact null distribution (all 2^n sign assignments equally likely, ranks
// as observed, midranks for ties: the exact conditional test) for n <=
// kWilcoxonExactMaxN, else the normal approximation with the tie-corrected
// variance and no continuity correction (SciPy's wilcoxon(method="approx")).
// With no ties the exact p equals SciPy's wilcoxon(method="exact"). NaN
// differences are ignored (counted neither in n nor in zeros).
inline constexpr int kWilcoxonExactMaxN = 50;
WilcoxonResult WilcoxonSignedRank(const std::vector<double>& differences);

// The exact null distribution of the signed-rank statistic for the given
// ranks held doubled (so midranks are integers): entry s is P(2 W+ = s) when
// each rank enters W+ with probability 1/2. The values are k / 2^n with
// 2^n <= 2^50, so every addition is exact.
std::vector<double> SignedRankNullDistribution(const std::vector<int>& doubled_ranks);

// Power of the two-sided signed-rank test at level alpha for n pairs when
// P(D + D' > 0) = p_prime for two independent differences (Noether 1987,
// JASA 82:645: Phi(sqrt(3n) |p_prime - 1/2| - z_{1-alpha/2})). A
// large-sample approximation: tests/results/stats_scipy_test.py measures it
// against simulated power.
double WilcoxonPowerNoether(int n, double p_prime, double alpha = kDefaultAlpha);

// The estimate of p_prime from observed differences: the fraction of Walsh
// averages (d_i + d_j) / 2, i < j, that are positive, ties (= 0) counting
// one half. 0.5 for fewer than two differences.
double WalshPositiveFraction(const std::vector<double>& differences);

// Holm's step-down adjustment of a family of p-values (Holm 1979): sorted
// ascending, p_(i) becomes max_{j <= i} min(1, (m - j + 1) p_(j)). Returned
// in the input order. NaN entries are left NaN and do not count in m.
std::vector<double> HolmAdjust(const std::vector<double>& p_values);

// Standard normal distribution function and its inverse (p in (0, 1)).
double NormalCdf(double z);
double NormalQuantile(double p);

}  // namespace totalgrad::results

#endif  // TOTALGRAD_RESULTS_HYPOTHESIS_TESTS_H_
