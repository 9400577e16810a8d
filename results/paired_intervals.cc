#include "results/paired_intervals.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "results/hypothesis_tests.h"
#include "results/stats.h"

namespace totalgrad::results {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// P(T+ <= t) for t = 0 .. n(n+1)/2 under the null hypothesis, ranks 1..n
// (hypothesis_tests.h's distribution, whose entries are doubled sums).
std::vector<double> SignedRankCdf(int n) {
  std::vector<int> doubled_ranks(n);
  for (int rank = 1; rank <= n; ++rank) doubled_ranks[rank - 1] = 2 * rank;
  const std::vector<double> doubled = SignedRankNullDistribution(doubled_ranks);
  std::vector<double> cdf(n * (n + 1) / 2 + 1, 0.0);
  double running = 0;
  for (size_t t = 0; t < cdf.size(); ++t) {
    running += doubled[2 * t];  // odd doubled sums have probability 0
    cdf[t] = running;
  }
  return cdf;
}

}  // namespace

RateDifferenceInterval NewcombePairedInterval(const PairedOutcomes& outcomes, double z) {
  RateDifferenceInterval interval;
  interval.pairs = outcomes.pairs();
  if (interval.pairs == 0) {
    interval.difference = interval.low = interval.high = kNaN;
    return interval;
  }
  const double n = interval.pairs;
  const double a = outcomes.both, b = outcomes.first_only, c = outcomes.second_only,
               d = outcomes.neither;
  const double p1 = (a + b) / n, p2 = (a + c) / n;
  const auto [l1, u1] = WilsonInterval(outcomes.both + outcomes.first_only, interval.pairs, z);
  const auto [l2, u2] = WilsonInterval(outcomes.both + outcomes.second_only, interval.pairs, z);
  const double margins = (a + b) * (c + d) * (a + c) * (b + d);
  const double phi = margins > 0 ? (a * d - b * c) / std::sqrt(margins) : 0.0;
  // p1 - p2, as one correctly rounded quotient of the exact count difference.
  interval.difference = (b - c) / n;
  const double below = (p1 - l1) * (p1 - l1) - 2 * phi * (p1 - l1) * (u2 - p2) +
                       (u2 - p2) * (u2 - p2);
  const double above = (p2 - l2) * (p2 - l2) - 2 * phi * (p2 - l2) * (u1 - p1) +
                       (u1 - p1) * (u1 - p1);
  interval.low = std::max(-1.0, interval.difference - std::sqrt(std::max(below, 0.0)));
  interval.high = std::min(1.0, interval.difference + std::sqrt(std::max(above, 0.0)));
  return interval;
}

ShiftInterval HodgesLehmannInterval(const std::vector<double>& differences, double level) {
  ShiftInterval interval;
  std::vector<double> finite;
  for (double value : differences) {
    if (!std::isnan(value)) finite.push_back(value);
  }
  const int n = static_cast<int>(finite.size());
  interval.n = n;
  if (n == 0) {
    interval.estimate = interval.low = interval.high = interval.coverage = kNaN;
    return interval;
  }
  std::vector<double> walsh;
  walsh.reserve(finite.size() * (finite.size() + 1) / 2);
  for (int i = 0; i < n; ++i) {
    for (int j = i; j < n; ++j) walsh.push_back(0.5 * (finite[i] + finite[j]));
  }
  std::sort(walsh.begin(), walsh.end());
  const int count = static_cast<int>(walsh.size());
  interval.estimate = count % 2 == 1
                          ? walsh[count / 2]
                          : 0.5 * (walsh[count / 2 - 1] + walsh[count / 2]);

  const double tail = (1 - level) / 2;
  int k = 0;
  if (n <= kWilcoxonExactMaxN) {
    const std::vector<double> cdf = SignedRankCdf(n);
    while (cdf[k] < tail) ++k;
    k = std::max(k, 1);
    interval.coverage = 1 - 2 * cdf[k - 1];
  } else {
    const double spread = std::sqrt(n * (n + 1.0) * (2.0 * n + 1) / 24.0);
    k = std::max(1, static_cast<int>(std::floor(count / 2.0 - NormalQuantile(1 - tail) * spread)));
    // The normal approximation of P(T+ <= k - 1), with continuity.
    interval.coverage = 1 - 2 * NormalCdf((k - 1 + 0.5 - count / 2.0) / spread);
  }
  interval.low = walsh[k - 1];
  interval.high = walsh[count - k];
  return interval;
}

}  // namespace totalgrad::results
