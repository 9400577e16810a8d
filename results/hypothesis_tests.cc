#include "results/hypothesis_tests.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>

namespace totalgrad::results {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Outcomes whose probability is within this relative distance of the
// observed one count as "as extreme" (R's fisher.test and SciPy's binomtest
// use the same 1e-7): they are equal but for rounding in lgamma.
constexpr double kRelativeTolerance = 1 + 1e-7;

double LogBinomialPmf(int k, int n, double p) {
  if (k < 0 || k > n) return -std::numeric_limits<double>::infinity();
  // 0 * log(0) is 0 here: p = 0 or 1 puts all mass on one outcome.
  const double log_p = k == 0 ? 0.0 : k * std::log(p);
  const double log_q = k == n ? 0.0 : (n - k) * std::log1p(-p);
  return LogChoose(n, k) + log_p + log_q;
}

// Binomial pmf over 0..n (all of it; for the power sums).
std::vector<double> BinomialPmf(int n, double p) {
  std::vector<double> pmf(n + 1);
  for (int k = 0; k <= n; ++k) pmf[k] = std::exp(LogBinomialPmf(k, n, p));
  return pmf;
}

// Two-sided p-value from a discrete null distribution given as log pmf over
// its support: the mass of the outcomes no more probable than `observed`.
// Summed from the smallest terms up, so small p-values keep their digits.
double TwoSidedFromLogPmf(const std::vector<double>& log_pmf, size_t observed) {
  const double threshold = log_pmf[observed] + std::log(kRelativeTolerance);
  std::vector<double> terms;
  for (double value : log_pmf) {
    if (value <= threshold) terms.push_back(std::exp(value));
  }
  std::sort(terms.begin(), terms.end());
  double p = 0;
  for (double t : terms) p += t;
  return std::min(1.0, p);
}

// For one margin configuration of a 2x2 table (row totals r1, r2 and first
// column total c1), every possible top-left cell x in [lo, hi] and its
// two-sided Fisher p-value. Sorting the pmf values once makes each p-value a
// binary search: O(m log m) for the m outcomes instead of O(m^2).
struct HypergeometricPValues {
  int lo = 0;
  std::vector<double> p;  // p[x - lo]
};

HypergeometricPValues FisherPValuesForMargins(int r1, int r2, int c1) {
  HypergeometricPValues out;
  out.lo = std::max(0, c1 - r2);
  const int hi = std::min(r1, c1);
  const double log_total = LogChoose(r1 + r2, c1);
  std::vector<double> log_pmf;
  for (int x = out.lo; x <= hi; ++x) {
    log_pmf.push_back(LogChoose(r1, x) + LogChoose(r2, c1 - x) - log_total);
  }
  std::vector<double> sorted = log_pmf;
  std::sort(sorted.begin(), sorted.end());
  std::vector<double> cumulative(sorted.size());  // sum of exp(sorted[0..i])
  double sum = 0;
  for (size_t i = 0; i < sorted.size(); ++i) {
    sum += std::exp(sorted[i]);
    cumulative[i] = sum;
  }
  out.p.resize(log_pmf.size());
  const double log_tolerance = std::log(kRelativeTolerance);
  for (size_t i = 0; i < log_pmf.size(); ++i) {
    const auto end = std::upper_bound(sorted.begin(), sorted.end(), log_pmf[i] + log_tolerance);
    const size_t count = end - sorted.begin();
    out.p[i] = count == 0 ? 0.0 : std::min(1.0, cumulative[count - 1]);
  }
  return out;
}

}  // namespace

std::vector<double> SignedRankNullDistribution(const std::vector<int>& doubled_ranks) {
  const int total = std::accumulate(doubled_ranks.begin(), doubled_ranks.end(), 0);
  std::vector<double> distribution(total + 1, 0.0);
  distribution[0] = 1.0;
  int reach = 0;
  for (int rank : doubled_ranks) {
    for (int s = reach; s >= 0; --s) {
      if (distribution[s] == 0) continue;
      distribution[s + rank] += distribution[s] * 0.5;
      distribution[s] *= 0.5;
    }
    reach += rank;
  }
  return distribution;
}

double LogChoose(int n, int k) {
  if (k < 0 || k > n || n < 0) return -std::numeric_limits<double>::infinity();
  return std::lgamma(n + 1.0) - std::lgamma(k + 1.0) - std::lgamma(n - k + 1.0);
}

double NormalCdf(double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); }

double NormalQuantile(double p) {
  if (!(p > 0 && p < 1)) return kNaN;
  // Bisection to bracket, then Newton on the CDF; erfc keeps full relative
  // precision in both tails.
  double low = -40, high = 40;
  for (int i = 0; i < 200 && high - low > 1e-15 * std::max(1.0, std::abs(low)); ++i) {
    const double middle = 0.5 * (low + high);
    (NormalCdf(middle) < p ? low : high) = middle;
  }
  double z = 0.5 * (low + high);
  for (int i = 0; i < 3; ++i) {
    const double density = std::exp(-0.5 * z * z) / std::sqrt(2 * std::numbers::pi);
    if (density <= 0) break;
    z -= (NormalCdf(z) - p) / density;
  }
  return z;
}

double BinomialTestTwoSided(int successes, int trials, double p) {
  if (trials <= 0) return 1.0;
  if (successes < 0 || successes > trials || !(p > 0 && p < 1)) return kNaN;
  std::vector<double> log_pmf(trials + 1);
  for (int k = 0; k <= trials; ++k) log_pmf[k] = LogBinomialPmf(k, trials, p);
  return TwoSidedFromLogPmf(log_pmf, successes);
}

double McNemarExactP(int first_only, int second_only) {
  if (first_only < 0 || second_only < 0) return kNaN;
  return BinomialTestTwoSided(first_only, first_only + second_only, 0.5);
}

double McNemarExactPower(int pairs, double p_first_only, double p_second_only, double alpha) {
  if (pairs < 0 || p_first_only < 0 || p_second_only < 0 || p_first_only + p_second_only > 1 + 1e-12)
    return kNaN;
  if (pairs > kMaxExactPowerN) return kNaN;
  const double discordant = std::min(1.0, p_first_only + p_second_only);
  if (pairs == 0 || discordant == 0) return 0.0;  // no discordant pair can occur: never rejects
  const double share = p_first_only / discordant;  // P(first only | discordant)
  const std::vector<double> discordant_pmf = BinomialPmf(pairs, discordant);
  double power = 0;
  for (int d = 1; d <= pairs; ++d) {
    if (discordant_pmf[d] == 0) continue;
    // Under the null, b ~ Binomial(d, 1/2) is symmetric, so McNemarExactP(b,
    // d - b) = min(1, 2 P(B <= min(b, d - b))), 1 at the centre: one
    // cumulative sum per d gives every p-value.
    const std::vector<double> null_pmf = BinomialPmf(d, 0.5);
    const std::vector<double> split = BinomialPmf(d, share);
    double tail = 0;
    double reject = 0;
    for (int b = 0; 2 * b < d; ++b) {
      tail += null_pmf[b];
      if (2 * tail > alpha) break;
      reject += split[b] + split[d - b];
    }
    power += discordant_pmf[d] * reject;
  }
  return std::min(1.0, power);
}

double FisherExactP(int a, int b, int c, int d) {
  if (a < 0 || b < 0 || c < 0 || d < 0) return kNaN;
  const HypergeometricPValues values = FisherPValuesForMargins(a + b, c + d, a + c);
  return values.p[a - values.lo];
}

double OddsRatio(int a, int b, int c, int d) {
  const double numerator = static_cast<double>(a) * d;
  const double denominator = static_cast<double>(b) * c;
  if (denominator == 0) return numerator == 0 ? kNaN : std::numeric_limits<double>::infinity();
  return numerator / denominator;
}

double FisherExactPower(int n_first, double p_first, int n_second, double p_second,
                        double alpha) {
  if (n_first < 0 || n_second < 0 || p_first < 0 || p_first > 1 || p_second < 0 || p_second > 1)
    return kNaN;
  if (n_first + n_second > kMaxExactPowerN) return kNaN;
  if (n_first == 0 || n_second == 0) return 0.0;
  const std::vector<double> first = BinomialPmf(n_first, p_first);
  const std::vector<double> second = BinomialPmf(n_second, p_second);
  double power = 0;
  // Tables with the same total of successes share their p-values.
  for (int total = 0; total <= n_first + n_second; ++total) {
    const HypergeometricPValues values = FisherPValuesForMargins(n_first, n_second, total);
    for (size_t i = 0; i < values.p.size(); ++i) {
      if (values.p[i] > alpha) continue;
      const int x = values.lo + static_cast<int>(i);
      power += first[x] * second[total - x];
    }
  }
  return std::min(1.0, power);
}

WilcoxonResult WilcoxonSignedRank(const std::vector<double>& differences) {
  WilcoxonResult result;
  std::vector<double> nonzero;
  std::vector<double> finite;
  for (double d : differences) {
    if (std::isnan(d)) continue;
    finite.push_back(d);
    if (d == 0) {
      ++result.zeros;
    } else {
      nonzero.push_back(d);
    }
  }
  // Hodges-Lehmann: median of the Walsh averages, zeros included.
  if (finite.empty()) {
    result.hodges_lehmann = kNaN;
  } else {
    std::vector<double> walsh;
    walsh.reserve(finite.size() * (finite.size() + 1) / 2);
    for (size_t i = 0; i < finite.size(); ++i) {
      for (size_t j = i; j < finite.size(); ++j) walsh.push_back(0.5 * (finite[i] + finite[j]));
    }
    const size_t middle = walsh.size() / 2;
    std::nth_element(walsh.begin(), walsh.begin() + middle, walsh.end());
    double median = walsh[middle];
    if (walsh.size() % 2 == 0) {
      median = 0.5 * (median + *std::max_element(walsh.begin(), walsh.begin() + middle));
    }
    result.hodges_lehmann = median;
  }
  const int n = static_cast<int>(nonzero.size());
  result.n = n;
  if (n == 0) return result;  // p = 1: nothing to test

  // Midranks of |d|, held doubled so they are integers.
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](int i, int j) { return std::abs(nonzero[i]) < std::abs(nonzero[j]); });
  std::vector<int> doubled_rank(n);
  double tie_term = 0;  // sum over tie groups of t^3 - t
  for (int start = 0; start < n;) {
    int end = start;
    while (end + 1 < n && std::abs(nonzero[order[end + 1]]) == std::abs(nonzero[order[start]])) {
      ++end;
    }
    const int t = end - start + 1;
    if (t > 1) {
      result.ties = true;
      tie_term += static_cast<double>(t) * t * t - t;
    }
    // Ranks start+1 .. end+1; their mean doubled is start + end + 2.
    for (int k = start; k <= end; ++k) doubled_rank[order[k]] = start + end + 2;
    start = end + 1;
  }
  int doubled_plus = 0;
  for (int i = 0; i < n; ++i) {
    if (nonzero[i] > 0) doubled_plus += doubled_rank[i];
  }
  const int doubled_total = n * (n + 1);
  result.w_plus = doubled_plus / 2.0;
  result.w_minus = (doubled_total - doubled_plus) / 2.0;
  result.rank_biserial = (result.w_plus - result.w_minus) / (result.w_plus + result.w_minus);

  if (n <= kWilcoxonExactMaxN) {
    result.exact = true;
    const std::vector<double> distribution = SignedRankNullDistribution(doubled_rank);
    // Symmetric about doubled_total / 2: the centre itself gives p = 1.
    if (2 * doubled_plus == doubled_total) {
      result.p = 1.0;
      return result;
    }
    double lower = 0, upper = 0;  // P(2W+ <= observed), P(2W+ >= observed)
    for (int s = 0; s <= doubled_plus; ++s) lower += distribution[s];
    for (int s = doubled_plus; s <= doubled_total; ++s) upper += distribution[s];
    result.p = std::min(1.0, 2 * std::min(lower, upper));
    return result;
  }
  const double mean = n * (n + 1) / 4.0;
  const double variance = (n * (n + 1.0) * (2.0 * n + 1) - 0.5 * tie_term) / 24.0;
  const double statistic = std::min(result.w_plus, result.w_minus);
  if (variance <= 0) {
    result.p = 1.0;
    return result;
  }
  const double z = (statistic - mean) / std::sqrt(variance);
  result.p = std::min(1.0, 2 * NormalCdf(-std::abs(z)));
  return result;
}

double WalshPositiveFraction(const std::vector<double>& differences) {
  std::vector<double> finite;
  for (double d : differences) {
    if (!std::isnan(d)) finite.push_back(d);
  }
  if (finite.size() < 2) return 0.5;
  double positive = 0;
  double pairs = 0;
  for (size_t i = 0; i < finite.size(); ++i) {
    for (size_t j = i + 1; j < finite.size(); ++j) {
      const double sum = finite[i] + finite[j];
      positive += sum > 0 ? 1.0 : (sum == 0 ? 0.5 : 0.0);
      pairs += 1;
    }
  }
  return positive / pairs;
}

double WilcoxonPowerNoether(int n, double p_prime, double alpha) {
  if (n <= 0) return 0.0;
  if (!(p_prime >= 0 && p_prime <= 1) || !(alpha > 0 && alpha < 1)) return kNaN;
  const double z_alpha = NormalQuantile(1 - alpha / 2);
  return NormalCdf(std::sqrt(3.0 * n) * std::abs(p_prime - 0.5) - z_alpha);
}

std::vector<double> HolmAdjust(const std::vector<double>& p_values) {
  std::vector<size_t> order;
  for (size_t i = 0; i < p_values.size(); ++i) {
    if (!std::isnan(p_values[i])) order.push_back(i);
  }
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t i, size_t j) { return p_values[i] < p_values[j]; });
  std::vector<double> adjusted(p_values.size(), kNaN);
  const double m = static_cast<double>(order.size());
  double running_max = 0;
  for (size_t rank = 0; rank < order.size(); ++rank) {
    const double scaled = std::min(1.0, (m - rank) * p_values[order[rank]]);
    running_max = std::max(running_max, scaled);
    adjusted[order[rank]] = running_max;
  }
  return adjusted;
}

}  // namespace totalgrad::results
