// Internal to core/study: the reference gradient g* at one horizon (study.h
// describes the protocol: pooled means of the reference estimators, their
// agreement test and the noise floor).
#ifndef TOTALGRAD_CORE_STUDY_REFERENCE_H_
#define TOTALGRAD_CORE_STUDY_REFERENCE_H_

#include "core/estimators/rollout.h"
#include "core/study/study.h"

namespace totalgrad::study::internal {

// g* for `problem` (its horizon) from options.reference, with a note on
// every estimator left out, cut short or in disagreement. Never fails: a
// reference without finite estimates has agree = false and says why.
ReferenceGradient ComputeReference(const estimators::Problem& problem, const StudyOptions& options,
                                   const StudyProgress& progress);

}  // namespace totalgrad::study::internal

#endif  // TOTALGRAD_CORE_STUDY_REFERENCE_H_
