#include "results/comparison.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace totalgrad::results {
namespace {

void AddOnce(std::vector<std::string>* list, const std::string& value) {
  if (std::find(list->begin(), list->end(), value) == list->end()) list->push_back(value);
}

// The outcome of one trial, by seed, for one (method, variant).
using BySeed = std::map<std::string, const CompletedTrial*>;

Comparison Compare(const std::string& variant, const std::string& method,
                   const std::string& other, const BySeed& first, const BySeed& second,
                   double alpha) {
  Comparison c;
  c.variant = variant;
  c.method = method;
  c.other = other;
  PairedOutcomes outcomes;
  std::vector<double> cost_differences;
  for (const auto& [seed, trial] : first) {
    auto partner = second.find(seed);
    if (partner == second.end()) continue;
    outcomes.Add(trial->success, partner->second->success);
    const double difference = trial->final_eval_cost - partner->second->final_eval_cost;
    if (!std::isnan(difference)) cost_differences.push_back(difference);
  }
  c.success = ComparePairedSuccess(outcomes, alpha);

  c.cost_pairs = static_cast<int>(cost_differences.size());
  c.wilcoxon = WilcoxonSignedRank(cost_differences);
  c.wilcoxon_power = c.cost_pairs == 0 ? std::nan("")
                                       : WilcoxonPowerNoether(
                                             c.cost_pairs, WalshPositiveFraction(cost_differences),
                                             alpha);

  for (const auto& [seed, trial] : first) {
    ++c.method_trials;
    if (trial->success) ++c.method_successes;
  }
  for (const auto& [seed, trial] : second) {
    ++c.other_trials;
    if (trial->success) ++c.other_successes;
  }
  const double method_rate = static_cast<double>(c.method_successes) / c.method_trials;
  const double other_rate = static_cast<double>(c.other_successes) / c.other_trials;
  c.rate_difference = method_rate - other_rate;
  const int a = c.method_successes, b = c.method_trials - c.method_successes;
  const int cc = c.other_successes, d = c.other_trials - c.other_successes;
  c.odds_ratio = OddsRatio(a, b, cc, d);
  c.fisher_p = FisherExactP(a, b, cc, d);
  c.fisher_power = FisherExactPower(c.method_trials, method_rate, c.other_trials, other_rate, alpha);
  return c;
}

}  // namespace

absl::StatusOr<ComparisonReport> CompareMethods(const std::vector<CompletedTrial>& trials,
                                                const ComparisonOptions& options) {
  if (!(options.alpha > 0 && options.alpha < 1)) {
    return absl::InvalidArgumentError(
        absl::StrCat("alpha must be in (0, 1), got ", options.alpha));
  }
  ComparisonReport report;
  std::map<std::pair<std::string, std::string>, BySeed> groups;  // (variant, method) -> seeds
  for (const CompletedTrial& trial : trials) {
    AddOnce(&report.methods, trial.method);
    AddOnce(&report.variants, trial.variant);
    BySeed& seeds = groups[{trial.variant, trial.method}];
    if (!seeds.emplace(trial.seed, &trial).second) ++report.duplicate_trials;
  }
  if (!options.baseline.empty() &&
      std::find(report.methods.begin(), report.methods.end(), options.baseline) ==
          report.methods.end()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "--baseline: '", options.baseline, "' has no completed trial in this sweep (methods: ",
        report.methods.empty() ? "none yet" : absl::StrJoin(report.methods, ", "), ")"));
  }
  for (const std::string& variant : report.variants) {
    const size_t first_of_variant = report.comparisons.size();
    auto group = [&](const std::string& method) -> const BySeed* {
      auto it = groups.find({variant, method});
      return it == groups.end() ? nullptr : &it->second;
    };
    if (!options.baseline.empty()) {
      const BySeed* baseline = group(options.baseline);
      if (baseline == nullptr) continue;
      for (const std::string& method : report.methods) {
        const BySeed* mine = group(method);
        if (method == options.baseline || mine == nullptr) continue;
        report.comparisons.push_back(
            Compare(variant, method, options.baseline, *mine, *baseline, options.alpha));
      }
    } else {
      for (size_t i = 0; i < report.methods.size(); ++i) {
        for (size_t j = i + 1; j < report.methods.size(); ++j) {
          const BySeed* first = group(report.methods[i]);
          const BySeed* second = group(report.methods[j]);
          if (first == nullptr || second == nullptr) continue;
          report.comparisons.push_back(Compare(variant, report.methods[i], report.methods[j],
                                               *first, *second, options.alpha));
        }
      }
    }
    // Holm over this variant's comparisons, one family per test.
    std::vector<double> mcnemar, wilcoxon, fisher;
    for (size_t k = first_of_variant; k < report.comparisons.size(); ++k) {
      mcnemar.push_back(report.comparisons[k].success.mcnemar_p);
      wilcoxon.push_back(report.comparisons[k].wilcoxon.p);
      fisher.push_back(report.comparisons[k].fisher_p);
    }
    mcnemar = HolmAdjust(mcnemar);
    wilcoxon = HolmAdjust(wilcoxon);
    fisher = HolmAdjust(fisher);
    for (size_t k = first_of_variant; k < report.comparisons.size(); ++k) {
      Comparison& c = report.comparisons[k];
      c.success.mcnemar_p_holm = mcnemar[k - first_of_variant];
      c.wilcoxon_p_holm = wilcoxon[k - first_of_variant];
      c.fisher_p_holm = fisher[k - first_of_variant];
    }
  }
  return report;
}

namespace {
std::string Verdict(double p_holm, double direction, const Comparison& c, double alpha) {
  if (std::isnan(p_holm) || !(p_holm < alpha) || direction == 0) return "no evidence";
  return (direction > 0 ? c.method : c.other) + " better";
}
}  // namespace

std::string SuccessVerdict(const Comparison& c, double alpha) {
  return Verdict(c.success.mcnemar_p_holm, c.success.difference, c, alpha);
}

// A negative rank-biserial correlation means the method's costs are lower.
std::string CostVerdict(const Comparison& c, double alpha) {
  return Verdict(c.wilcoxon_p_holm, -c.wilcoxon.rank_biserial, c, alpha);
}

}  // namespace totalgrad::results
