// Statistics for the results views: Wilson score intervals for success
// rates, quantiles, and the grouping behind `results table` (a sweep's
// success table) and `results curves` (the paper's Figure 2). Pure
// functions of their arguments; thread-safe.
#ifndef TOTALGRAD_RESULTS_STATS_H_
#define TOTALGRAD_RESULTS_STATS_H_

#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "core/common/record.h"
#include "results/completed_trial.h"

namespace totalgrad::results {

// 95% Wilson score interval for `successes` out of `trials` (z = 1.959964).
// Returns {0, 1} for trials == 0. Always within [0, 1].
std::pair<double, double> WilsonInterval(int successes, int trials, double z = 1.959963984540054);

// Quantile q in [0, 1] of `values` by linear interpolation between order
// statistics (Hyndman & Fan type 7, as R and NumPy default). NaN if empty.
double Quantile(std::vector<double> values, double q);

// Successes among trials, their rate and its 95% Wilson interval: the one
// success statistic of the success table, the Table-1 grid and the threshold
// sensitivity. With no trial the rate and both bounds are NaN (not the
// interval {0, 1}: no trial is no evidence, and a reader sees a blank).
struct WilsonRate {
  int trials = 0;
  int successes = 0;
  double rate = std::numeric_limits<double>::quiet_NaN();
  double low = std::numeric_limits<double>::quiet_NaN();
  double high = std::numeric_limits<double>::quiet_NaN();

  // Counts one more trial and keeps rate, low and high those of the counts.
  void Add(bool succeeded);
};

// The names a WilsonRate's five values have in every results record (CSV
// column, JSON key, proto field), in the order trials, successes, rate,
// low, high: one name per statistic wherever it is shown.
struct WilsonRateNames {
  const char* trials;
  const char* successes;
  const char* rate;
  const char* low;
  const char* high;
};
// Success by the final-cost threshold: trials, successes, success_rate,
// wilson95_low, wilson95_high.
inline constexpr WilsonRateNames kSuccessRateNames = {"trials", "successes", "success_rate",
                                                      "wilson95_low", "wilson95_high"};
// The rollout verdict: classified, held, held_rate, held_wilson95_low,
// held_wilson95_high.
inline constexpr WilsonRateNames kHeldRateNames = {"classified", "held", "held_rate",
                                                   "held_wilson95_low", "held_wilson95_high"};

// Appends to `table` the five fields of the WilsonRate at member kRate of
// the table's record, under `names`.
template <auto... kRate>
void AppendWilsonRateFields(const WilsonRateNames& names,
                            record::FieldTable<typename record::PathOf<kRate...>::Record>*
                                table) {
  table->insert(table->end(), {{names.trials, record::Nested<kRate..., &WilsonRate::trials>()},
                               {names.successes, record::Nested<kRate..., &WilsonRate::successes>()},
                               {names.rate, record::Nested<kRate..., &WilsonRate::rate>()},
                               {names.low, record::Nested<kRate..., &WilsonRate::low>()},
                               {names.high, record::Nested<kRate..., &WilsonRate::high>()}});
}

struct TableCell {
  std::string method;
  std::string variant;
  WilsonRate success;  // the trials' own verdicts (final cost below the threshold)
  double median_final_cost = 0;  // over the trials with a cost; NaN when none has one
  // The rollout verdict over the trials that have one (held.trials of
  // success.trials): trials whose final policy held in at least half of
  // its rollouts.
  WilsonRate held;
};

// One cell per (method, variant), methods in first-appearance order, then
// variants in first-appearance order.
std::vector<TableCell> SuccessTable(const std::vector<CompletedTrial>& trials);

// A TableCell's fields under the one name each statistic has wherever it is
// shown (`results table -f csv|json`, the dashboard's /api/sweep): method,
// variant, trials, successes, success_rate, wilson95_low, wilson95_high,
// median_final_cost, classified, held, held_rate, held_wilson95_low,
// held_wilson95_high. Written through io/record_format.h.
const record::FieldTable<TableCell>& TableCellFields();

struct EpisodeValue {
  std::string method;
  std::string variant;
  int episode = 0;
  double value = 0;  // evaluation cost mean (NaN values are skipped)
  int64_t trial = 0; // the trial (its job id): which values are one run, for BestRuns
};

// A sample of per-trial values at one point of a curve: how many, their
// quartiles (Quantile), their mean and its standard error. Every number is
// NaN for an empty sample; the standard error also for a single value.
struct SampleSummary {
  int trials = 0;
  double q25 = std::numeric_limits<double>::quiet_NaN();
  double median = std::numeric_limits<double>::quiet_NaN();
  double q75 = std::numeric_limits<double>::quiet_NaN();
  double mean = std::numeric_limits<double>::quiet_NaN();
  // The sample standard deviation over sqrt(trials).
  double standard_error = std::numeric_limits<double>::quiet_NaN();
};

// The summary of `values` (none of them NaN).
SampleSummary Summarize(const std::vector<double>& values);

// Appends to `table` the fields of the SampleSummary at member kSummary of
// the table's record: trials, q25, median, q75, mean, standard_error (the
// names of `results curves`, `results diagnostics` and the dashboard's
// curves).
template <auto... kSummary>
void AppendSampleSummaryFields(
    record::FieldTable<typename record::PathOf<kSummary...>::Record>* table) {
  using S = SampleSummary;
  table->insert(table->end(), {{"trials", record::Nested<kSummary..., &S::trials>()},
                               {"q25", record::Nested<kSummary..., &S::q25>()},
                               {"median", record::Nested<kSummary..., &S::median>()},
                               {"q75", record::Nested<kSummary..., &S::q75>()},
                               {"mean", record::Nested<kSummary..., &S::mean>()},
                               {"standard_error", record::Nested<kSummary..., &S::standard_error>()}});
}

struct CurvePoint {
  std::string method;
  std::string variant;
  int episode = 0;
  SampleSummary values;  // over the trials with a value at this episode
};

// One point per (method, variant, episode) with a value, methods in
// first-appearance order, then variants, then episodes.
std::vector<CurvePoint> Curves(const std::vector<EpisodeValue>& values);

// method, variant, episode, then the SampleSummary's fields.
const record::FieldTable<CurvePoint>& CurvePointFields();

// The values of the k best runs of each (method, variant): the paper's
// Figure 3 "top runs" panel. A run (EpisodeValue::trial) is ranked by its
// final value, the value of its last episode that has one; lower is better;
// ties by trial id. Values keep their order; runs without a value are
// dropped. k >= 1.
std::vector<EpisodeValue> BestRuns(const std::vector<EpisodeValue>& values, int k);

}  // namespace totalgrad::results

#endif  // TOTALGRAD_RESULTS_STATS_H_
