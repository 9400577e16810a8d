// Confidence intervals on paired differences, for comparisons where each
// seed gives one trial of each of two methods (results/table1_claims.h):
// the difference in success rates from the 2x2 table of paired outcomes,
// and the shift in final costs from the paired cost differences. Intervals
// come first in a report, p-values second: an interval says how large a
// difference the data allow, which a p-value alone does not.
//
// Pure functions of their arguments; thread-safe.
#ifndef TOTALGRAD_RESULTS_PAIRED_INTERVALS_H_
#define TOTALGRAD_RESULTS_PAIRED_INTERVALS_H_

#include <vector>

namespace totalgrad::results {

// The 2x2 table of paired binary outcomes (first method, second method).
struct PairedOutcomes {
  int both = 0;         // both succeeded
  int first_only = 0;   // only the first succeeded
  int second_only = 0;  // only the second succeeded
  int neither = 0;
  int pairs() const { return both + first_only + second_only + neither; }
  // Counts one pair by whether each succeeded.
  void Add(bool first, bool second) {
    ++(first ? (second ? both : first_only) : (second ? second_only : neither));
  }
};

struct RateDifferenceInterval {
  int pairs = 0;
  double difference = 0;  // first rate - second rate = (first_only - second_only) / pairs
  double low = 0;         // 95% (or the requested level)
  double high = 0;
};

// Newcombe's hybrid score interval for the difference of two paired
// proportions (Newcombe 1998, Stat Med 17:2635, method 10): the Wilson
// intervals (l1, u1) of the first rate p1 = (both + first_only) / n and
// (l2, u2) of p2 = (both + second_only) / n, combined with the phi
// coefficient of the 2x2 table,
//   phi = (both * neither - first_only * second_only)
//         / sqrt((both + first_only)(second_only + neither)
//                (both + second_only)(first_only + neither)),
// taken as 0 when a margin is empty; with d = p1 - p2,
//   low  = d - sqrt((p1 - l1)^2 - 2 phi (p1 - l1)(u2 - p2) + (u2 - p2)^2),
//   high = d + sqrt((p2 - l2)^2 - 2 phi (p2 - l2)(u1 - p1) + (u1 - p1)^2).
// Always within [-1, 1]. `z` is the normal quantile of the level (1.96 for
// 95%). With no pairs every field but `pairs` is NaN.
RateDifferenceInterval NewcombePairedInterval(const PairedOutcomes& outcomes,
                                              double z = 1.959963984540054);

struct ShiftInterval {
  int n = 0;              // finite differences used
  double estimate = 0;    // Hodges-Lehmann: median of the Walsh averages
  double low = 0;
  double high = 0;
  // 1 - 2 P(T+ <= k - 1) for the rank k used (the signed-rank statistic's
  // distribution is discrete, so the level is met or exceeded, not hit).
  double coverage = 0;
};

// The Hodges-Lehmann shift of paired differences d_i (first minus second)
// with the confidence interval that inverts the Wilcoxon signed-rank test
// (Hollander & Wolfe, Nonparametric Statistical Methods, 3.2; R's
// wilcox.test(conf.int = TRUE, exact = TRUE)): with the M = n(n+1)/2 Walsh
// averages (d_i + d_j)/2, i <= j, sorted as W_(1) <= ... <= W_(M), and k the
// smallest integer with P(T+ <= k) >= (1 - level)/2 under the null
// distribution of the signed-rank statistic T+ with ranks 1..n (k = 1 when
// that is 0), the interval is [W_(k), W_(M + 1 - k)]. For n <= 50 the null
// distribution is exact; above, k = floor(M/2 - z sqrt(n(n+1)(2n+1)/24)),
// at least 1. Ties and zero differences keep their Walsh averages (the
// estimate equals WilcoxonResult::hodges_lehmann); the coverage is then
// approximate. NaN differences are dropped. With no finite difference
// every field but `n` is NaN; with one, the interval is that difference.
ShiftInterval HodgesLehmannInterval(const std::vector<double>& differences, double level = 0.95);

}  // namespace totalgrad::results

#endif  // TOTALGRAD_RESULTS_PAIRED_INTERVALS_H_
