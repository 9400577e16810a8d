// Two methods' success compared trial by trial, paired by seed: the one
// computation behind `results compare`, the dashboard's comparison table and
// the Table-1 claims (both by the threshold and by the rollout verdict), so
// that each shows the same numbers under the same names. Pure functions.
#ifndef TOTALGRAD_RESULTS_PAIRED_SUCCESS_H_
#define TOTALGRAD_RESULTS_PAIRED_SUCCESS_H_

#include <limits>

#include "core/common/record.h"
#include "results/hypothesis_tests.h"
#include "results/paired_intervals.h"

namespace totalgrad::results {

// `method` against `other` on the pairs where both have an outcome.
// Differences are method minus other: a positive difference, `method`
// succeeded more often.
struct PairedSuccess {
  int pairs = 0;
  int both = 0;         // both succeeded
  int method_only = 0;  // discordant: only `method` succeeded
  int other_only = 0;   // discordant: only `other` succeeded
  int neither = 0;
  // (method_only - other_only) / pairs with Newcombe's 95% interval
  // (NewcombePairedInterval); NaN without pairs.
  double difference = std::numeric_limits<double>::quiet_NaN();
  double difference95_low = std::numeric_limits<double>::quiet_NaN();
  double difference95_high = std::numeric_limits<double>::quiet_NaN();
  // McNemar's exact test; the Holm adjustment is the caller's, over the
  // family it forms (until then equal to mcnemar_p).
  double mcnemar_p = 1;
  double mcnemar_p_holm = 1;
  // Of the unadjusted test at level alpha with this many pairs, if the true
  // discordant rates were the observed ones; NaN without pairs.
  double mcnemar_power = std::numeric_limits<double>::quiet_NaN();
};

// Every field of the comparison of the 2x2 table `outcomes` (first =
// `method`, second = `other`).
PairedSuccess ComparePairedSuccess(const PairedOutcomes& outcomes, double alpha = kDefaultAlpha);

// The names of a PairedSuccess's fields in a results record, in the order
// of the struct.
struct PairedSuccessNames {
  const char* pairs;
  const char* both;
  const char* method_only;
  const char* other_only;
  const char* neither;
  const char* difference;
  const char* difference95_low;
  const char* difference95_high;
  const char* mcnemar_p;
  const char* mcnemar_p_holm;
  const char* mcnemar_power;
};
// By the trials' own verdicts (final cost below the threshold).
inline constexpr PairedSuccessNames kPairedSuccessNames = {
    "pairs",          "both_succeeded",           "method_only",
    "other_only",     "neither",                  "success_difference",
    "success_difference95_low", "success_difference95_high", "mcnemar_p",
    "mcnemar_p_holm", "mcnemar_power"};
// By the rollout verdict (held in at least half of the verdict rollouts).
inline constexpr PairedSuccessNames kPairedVerdictNames = {
    "verdict_pairs",          "verdict_both_held",          "verdict_method_only",
    "verdict_other_only",     "verdict_neither",            "verdict_difference",
    "verdict_difference95_low", "verdict_difference95_high", "verdict_mcnemar_p",
    "verdict_mcnemar_p_holm", "verdict_mcnemar_power"};

// Appends to `table` the fields of the PairedSuccess at member kMember of
// the table's record, under `names`.
template <auto... kMember>
void AppendPairedSuccessFields(
    const PairedSuccessNames& names,
    record::FieldTable<typename record::PathOf<kMember...>::Record>* table) {
  using S = PairedSuccess;
  table->insert(table->end(),
                {{names.pairs, record::Nested<kMember..., &S::pairs>()},
                 {names.both, record::Nested<kMember..., &S::both>()},
                 {names.method_only, record::Nested<kMember..., &S::method_only>()},
                 {names.other_only, record::Nested<kMember..., &S::other_only>()},
                 {names.neither, record::Nested<kMember..., &S::neither>()},
                 {names.difference, record::Nested<kMember..., &S::difference>()},
                 {names.difference95_low, record::Nested<kMember..., &S::difference95_low>()},
                 {names.difference95_high, record::Nested<kMember..., &S::difference95_high>()},
                 {names.mcnemar_p, record::Nested<kMember..., &S::mcnemar_p>()},
                 {names.mcnemar_p_holm, record::Nested<kMember..., &S::mcnemar_p_holm>()},
                 {names.mcnemar_power, record::Nested<kMember..., &S::mcnemar_power>()}});
}

}  // namespace totalgrad::results

#endif  // TOTALGRAD_RESULTS_PAIRED_SUCCESS_H_
