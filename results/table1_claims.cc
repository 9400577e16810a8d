#include "results/table1_claims.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <tuple>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "results/paired_intervals.h"
#include "results/stats.h"

namespace totalgrad::results {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

size_t MethodColumn(const std::string& method) {
  const std::vector<std::string>& methods = Table1Methods();
  return static_cast<size_t>(std::find(methods.begin(), methods.end(), method) - methods.begin());
}

const std::vector<CompletedTrial>& TrialsOf(const Table1& table, size_t row,
                                         const std::string& method) {
  return table.cell_trials[row * Table1Methods().size() + MethodColumn(method)];
}

// Seeds order numerically where they are numbers ("9" before "10").
bool SeedLess(const std::string& a, const std::string& b) {
  int64_t x = 0, y = 0;
  if (absl::SimpleAtoi(a, &x) && absl::SimpleAtoi(b, &y)) return x < y;
  return a < b;
}

bool Held(const CompletedTrial& trial) { return trial.held_fraction >= 0.5; }

}  // namespace

const std::vector<double>& DefaultSensitivityThresholds() {
  static const std::vector<double>* thresholds = new std::vector<double>{13, 14, 15, 16, 17};
  return *thresholds;
}

std::vector<ThresholdRate> ThresholdSensitivity(const Table1& table,
                                                const std::vector<double>& thresholds) {
  std::vector<ThresholdRate> rates;
  for (size_t index = 0; index < table.cells.size(); ++index) {
    const Table1Cell& cell = table.cells[index];
    std::vector<CompletedTrial> trials = table.cell_trials[index];
    if (trials.empty()) continue;
    std::sort(trials.begin(), trials.end(),
              [](const CompletedTrial& a, const CompletedTrial& b) { return SeedLess(a.seed, b.seed); });
    for (double threshold : thresholds) {
      ThresholdRate rate;
      rate.cost = cell.cost;
      rate.noise_k = cell.noise_k;
      rate.method = cell.method;
      rate.threshold = threshold;
      std::vector<std::string> changed;
      for (const CompletedTrial& trial : trials) {
        if (!std::isfinite(trial.final_eval_cost)) continue;
        const bool succeeds = trial.final_eval_cost < threshold;
        rate.success.Add(succeeds);
        if (succeeds != trial.success) {
          changed.push_back(absl::StrFormat("seed %s: %.2f %s", trial.seed, trial.final_eval_cost,
                                            succeeds ? "fails -> succeeds" : "succeeds -> fails"));
        }
      }
      rate.changed = static_cast<int>(changed.size());
      rate.changed_trials = absl::StrJoin(changed, "; ");
      rates.push_back(std::move(rate));
    }
  }
  return rates;
}

const record::FieldTable<ThresholdRate>& ThresholdRateFields() {
  static const record::FieldTable<ThresholdRate> table = [] {
    record::FieldTable<ThresholdRate> fields = {{"cost", &ThresholdRate::cost},
                                                {"noise_k", &ThresholdRate::noise_k},
                                                {"method", &ThresholdRate::method},
                                                {"threshold", &ThresholdRate::threshold}};
    AppendWilsonRateFields<&ThresholdRate::success>(kSuccessRateNames, &fields);
    fields.insert(fields.end(), {{"changed", &ThresholdRate::changed},
                                 {"changed_trials", &ThresholdRate::changed_trials}});
    return fields;
  }();
  return table;
}

const std::vector<PlannedComparison>& Table1PlannedComparisons() {
  // Rows index Table1Rows(): 2 is (tip, k = 0.01), 3 is (tip, k = 1).
  static const std::vector<PlannedComparison>* planned = new std::vector<PlannedComparison>{
      {2, "GTP", "PILCO", "GTP matches PILCO"},
      {2, "TP", "GTP", "TP against the Gaussian-shaped GTP"},
      {2, "GTP+sn", "GTP", "injected model noise repairs GTP at low noise"},
      {2, "LR", "RP", "LR does worse than RP at low noise"},
      {3, "GTP", "PILCO", "GTP matches PILCO"},
      {3, "TP", "GTP", "TP against the Gaussian-shaped GTP"},
  };
  return *planned;
}

namespace {

// Pairs `method`'s and `other`'s trials of one row by seed and fills every
// field but the Holm adjustments.
ClaimComparison Compare(const Table1& table, const PlannedComparison& planned) {
  const Table1Row& row = Table1Rows()[planned.row];
  ClaimComparison comparison;
  comparison.cost = row.cost;
  comparison.noise_k = row.noise_k;
  comparison.method = planned.method;
  comparison.other = planned.other;
  comparison.claim = planned.claim;
  std::map<std::string, const CompletedTrial*> other_by_seed;
  for (const CompletedTrial& trial : TrialsOf(table, planned.row, planned.other)) {
    other_by_seed[trial.seed] = &trial;
  }
  PairedOutcomes success, verdict;
  std::vector<double> cost_differences;
  for (const CompletedTrial& mine : TrialsOf(table, planned.row, planned.method)) {
    const auto partner = other_by_seed.find(mine.seed);
    if (partner == other_by_seed.end()) continue;
    const CompletedTrial& theirs = *partner->second;
    success.Add(mine.success, theirs.success);
    if (!std::isnan(mine.held_fraction) && !std::isnan(theirs.held_fraction)) {
      verdict.Add(Held(mine), Held(theirs));
    }
    if (std::isfinite(mine.final_eval_cost) && std::isfinite(theirs.final_eval_cost)) {
      cost_differences.push_back(mine.final_eval_cost - theirs.final_eval_cost);
    }
  }
  comparison.success = ComparePairedSuccess(success);
  comparison.verdict = ComparePairedSuccess(verdict);

  comparison.cost_pairs = static_cast<int>(cost_differences.size());
  const ShiftInterval shift = HodgesLehmannInterval(cost_differences);
  comparison.cost_shift = shift.estimate;
  comparison.cost_shift95_low = shift.low;
  comparison.cost_shift95_high = shift.high;
  comparison.wilcoxon_p = WilcoxonSignedRank(cost_differences).p;
  comparison.wilcoxon_power =
      comparison.cost_pairs == 0
          ? kNaN
          : WilcoxonPowerNoether(comparison.cost_pairs, WalshPositiveFraction(cost_differences));
  return comparison;
}

// Holm over the comparisons of one row that have pairs, one test at a time:
// `test` gives a comparison's pairs, its p-value and where its adjusted
// p-value goes (NaN for a comparison without pairs).
template <typename Test>
void AdjustWithinRows(std::vector<ClaimComparison>* comparisons, Test test) {
  const std::vector<PlannedComparison>& planned = Table1PlannedComparisons();
  for (size_t row = 0; row < Table1Rows().size(); ++row) {
    std::vector<double*> adjusted_of;
    std::vector<double> p_values;
    for (size_t i = 0; i < planned.size(); ++i) {
      if (planned[i].row != row) continue;
      const auto [pairs, p, holm] = test((*comparisons)[i]);
      if (pairs == 0) {
        *holm = kNaN;
        continue;
      }
      adjusted_of.push_back(holm);
      p_values.push_back(p);
    }
    const std::vector<double> adjusted = HolmAdjust(p_values);
    for (size_t k = 0; k < adjusted_of.size(); ++k) *adjusted_of[k] = adjusted[k];
  }
}

}  // namespace

std::vector<ClaimComparison> CompareClaims(const Table1& table) {
  std::vector<ClaimComparison> comparisons;
  for (const PlannedComparison& planned : Table1PlannedComparisons()) {
    comparisons.push_back(Compare(table, planned));
  }
  for (PairedSuccess ClaimComparison::*paired : {&ClaimComparison::success,
                                                 &ClaimComparison::verdict}) {
    AdjustWithinRows(&comparisons, [paired](ClaimComparison& c) {
      PairedSuccess& s = c.*paired;
      return std::tuple{s.pairs, s.mcnemar_p, &s.mcnemar_p_holm};
    });
  }
  AdjustWithinRows(&comparisons, [](ClaimComparison& c) {
    return std::tuple{c.cost_pairs, c.wilcoxon_p, &c.wilcoxon_p_holm};
  });
  return comparisons;
}

const record::FieldTable<ClaimComparison>& ClaimComparisonFields() {
  using C = ClaimComparison;
  static const record::FieldTable<C> table = [] {
    record::FieldTable<C> fields = {{"cost", &C::cost},     {"noise_k", &C::noise_k},
                                    {"method", &C::method}, {"other", &C::other},
                                    {"claim", &C::claim}};
    AppendPairedSuccessFields<&C::success>(kPairedSuccessNames, &fields);
    AppendPairedSuccessFields<&C::verdict>(kPairedVerdictNames, &fields);
    fields.insert(fields.end(), {{"cost_pairs", &C::cost_pairs},
                                 {"cost_shift", &C::cost_shift},
                                 {"cost_shift95_low", &C::cost_shift95_low},
                                 {"cost_shift95_high", &C::cost_shift95_high},
                                 {"wilcoxon_p", &C::wilcoxon_p},
                                 {"wilcoxon_p_holm", &C::wilcoxon_p_holm},
                                 {"wilcoxon_power", &C::wilcoxon_power}});
    return fields;
  }();
  return table;
}

std::vector<PowerEntry> PairedPowerTable(int pairs, double alpha) {
  int min_discordant = 0;
  while (min_discordant <= pairs && !(McNemarExactP(min_discordant, 0) < alpha)) {
    ++min_discordant;
  }
  std::vector<PowerEntry> entries;
  for (double other_only : {0.0, 0.1}) {
    for (int tenths = 1; tenths <= 10; ++tenths) {
      const double method_only = tenths / 10.0;
      if (method_only + other_only > 1 + 1e-12) continue;
      PowerEntry entry;
      entry.pairs = pairs;
      entry.method_only_rate = method_only;
      entry.other_only_rate = other_only;
      entry.difference = method_only - other_only;
      entry.power = McNemarExactPower(pairs, method_only, other_only, alpha);
      entry.power_holm2 = McNemarExactPower(pairs, method_only, other_only, alpha / 2);
      entry.power_holm4 = McNemarExactPower(pairs, method_only, other_only, alpha / 4);
      entry.min_one_sided_discordant = min_discordant > pairs ? -1 : min_discordant;
      entries.push_back(entry);
    }
  }
  return entries;
}

const record::FieldTable<PowerEntry>& PowerEntryFields() {
  static const record::FieldTable<PowerEntry> table = {
      {"pairs", &PowerEntry::pairs},
      {"method_only_rate", &PowerEntry::method_only_rate},
      {"other_only_rate", &PowerEntry::other_only_rate},
      {"difference", &PowerEntry::difference},
      {"power", &PowerEntry::power},
      {"power_holm2", &PowerEntry::power_holm2},
      {"power_holm4", &PowerEntry::power_holm4},
      {"min_one_sided_discordant", &PowerEntry::min_one_sided_discordant},
  };
  return table;
}

}  // namespace totalgrad::results
