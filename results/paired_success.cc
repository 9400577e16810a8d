#include "results/paired_success.h"

namespace totalgrad::results {

PairedSuccess ComparePairedSuccess(const PairedOutcomes& outcomes, double alpha) {
  PairedSuccess s;
  s.pairs = outcomes.pairs();
  s.both = outcomes.both;
  s.method_only = outcomes.first_only;
  s.other_only = outcomes.second_only;
  s.neither = outcomes.neither;
  const RateDifferenceInterval interval = NewcombePairedInterval(outcomes);
  s.difference = interval.difference;
  s.difference95_low = interval.low;
  s.difference95_high = interval.high;
  s.mcnemar_p = McNemarExactP(s.method_only, s.other_only);
  s.mcnemar_p_holm = s.mcnemar_p;
  if (s.pairs > 0) {
    s.mcnemar_power = McNemarExactPower(s.pairs, static_cast<double>(s.method_only) / s.pairs,
                                        static_cast<double>(s.other_only) / s.pairs, alpha);
  }
  return s;
}

}  // namespace totalgrad::results
