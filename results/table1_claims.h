// What Table 1's verdicts rest on, from the grid's trials (results/table1.h):
//   * threshold sensitivity: each cell's success rate when the threshold on
//     the final evaluation cost is moved (the paper's is 15), and which
//     trials' verdicts change;
//   * the paired comparisons the paper's claims call for, by seed within a
//     row: intervals on the paired differences first (success rate,
//     rollout verdict, final cost), then p-values Holm-corrected within the
//     row, each test its own family;
//   * the power table: what a comparison of n paired seeds can settle.
//
// Pure functions of their arguments; thread-safe.
#ifndef TOTALGRAD_RESULTS_TABLE1_CLAIMS_H_
#define TOTALGRAD_RESULTS_TABLE1_CLAIMS_H_

#include <string>
#include <vector>

#include "core/common/record.h"
#include "results/hypothesis_tests.h"
#include "results/paired_success.h"
#include "results/table1.h"

namespace totalgrad::results {

// The thresholds `results table1 --view sensitivity` uses unless told.
const std::vector<double>& DefaultSensitivityThresholds();

// One cell of the grid at one threshold. A trial succeeds at threshold t
// when its final cost is below t (the rule of the trial itself); trials
// without a finite final cost are left out of `success.trials`.
struct ThresholdRate {
  std::string cost;
  double noise_k = 0;
  std::string method;
  double threshold = 0;
  WilsonRate success;  // of the trials with a finite final cost
  // Trials whose verdict at this threshold differs from their stored one,
  // as "seed 14: 15.53 fails -> succeeds", joined by "; " in seed order.
  int changed = 0;
  std::string changed_trials;
};

// One entry per cell with at least one trial (grid order), times each
// threshold in the given order.
std::vector<ThresholdRate> ThresholdSensitivity(const Table1& table,
                                                const std::vector<double>& thresholds);

const record::FieldTable<ThresholdRate>& ThresholdRateFields();

// A comparison the paper's claims call for: `method` against `other` in row
// `row` of Table1Rows(), and the claim it tests.
struct PlannedComparison {
  size_t row = 0;
  std::string method;
  std::string other;
  std::string claim;
};

// Both tip rows: GTP vs PILCO (GTP matches PILCO), TP vs GTP (the
// Gaussian-shaped TP); tip, k = 0.01: GTP+sn vs GTP (injected model noise
// repairs the LR part at low noise), LR vs RP (LR does worse at low noise).
const std::vector<PlannedComparison>& Table1PlannedComparisons();

// One planned comparison, paired by seed; differences are method minus
// other (a positive success difference: `method` succeeded more often; a
// negative cost shift: `method` reached lower final costs). Holm's
// adjustment runs over the row's comparisons that have pairs, each test (the
// threshold's McNemar, the rollout verdict's McNemar, the costs' Wilcoxon)
// a family of its own.
struct ClaimComparison {
  std::string cost;
  double noise_k = 0;
  std::string method;
  std::string other;
  std::string claim;
  // Success by the threshold (each trial's stored verdict), over the seeds
  // with a completed trial of both methods (success.pairs).
  PairedSuccess success;
  // The rollout verdict (held in at least half of the rollouts), over the
  // pairs where both trials were classified.
  PairedSuccess verdict;

  // Final costs, over the pairs where both are finite: the Hodges-Lehmann
  // shift with the signed-rank test's interval (paired_intervals.h).
  int cost_pairs = 0;
  double cost_shift = 0;  // NaN without cost pairs
  double cost_shift95_low = 0;
  double cost_shift95_high = 0;
  double wilcoxon_p = 1;
  double wilcoxon_p_holm = 1;
  double wilcoxon_power = 0;  // Noether's approximation at the observed effect
};

// Every planned comparison, in Table1PlannedComparisons() order.
std::vector<ClaimComparison> CompareClaims(const Table1& table);

const record::FieldTable<ClaimComparison>& ClaimComparisonFields();

// What n paired seeds can settle for a success-rate difference: the exact
// power of McNemar's test when a seed succeeds with `method` only with
// probability method_only_rate and with `other` only with other_only_rate
// (the true difference is their difference), at level alpha and at Holm's
// strictest step alpha / m for the families of two and four comparisons
// (the tip rows' sizes).
struct PowerEntry {
  int pairs = 0;
  double method_only_rate = 0;
  double other_only_rate = 0;
  double difference = 0;
  double power = 0;          // at alpha
  double power_holm2 = 0;    // at alpha / 2
  double power_holm4 = 0;    // at alpha / 4
  // The fewest discordant pairs all one way that reach p < alpha (McNemar).
  int min_one_sided_discordant = 0;
};

// For `pairs` seeds, differences 0.1 .. 1.0 by 0.1 with no discordance the
// other way (the best case), then the same differences with
// other_only_rate = 0.1 where they fit (method_only_rate <= 0.9).
std::vector<PowerEntry> PairedPowerTable(int pairs, double alpha = kDefaultAlpha);

const record::FieldTable<PowerEntry>& PowerEntryFields();

}  // namespace totalgrad::results

#endif  // TOTALGRAD_RESULTS_TABLE1_CLAIMS_H_
