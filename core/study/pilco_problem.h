// PILCO's moment-matching problem on a study's frozen problem: the one place
// that builds it, for the study's PILCO cells (study.h) and for Python's
// `Problem.gradients("PILCO")`, so both give the same objective and gradient.
#ifndef TOTALGRAD_CORE_STUDY_PILCO_PROBLEM_H_
#define TOTALGRAD_CORE_STUDY_PILCO_PROBLEM_H_

#include <string>

#include "absl/status/statusor.h"
#include "core/estimators/rollout.h"
#include "core/pilco/pilco.h"
#include "core/study/frozen_problem.h"

namespace totalgrad::study {

// PILCO's problem on `frozen`'s policy features (the raw state, or its one
// angle as (sin, cos)) at problem.horizon, with `problem`'s cost in closed
// form and start distribution, built as the trial builds it
// (learner::MakePilcoProblem); the model noise is in the predictions when
// the particles' transitions have it (noise multiplier > 0). When the
// multiplier is neither 0 nor 1, PILCO (which adds the noise variance once)
// differs from the particles: `noise_note` (may be null) says so, otherwise
// it is cleared. InvalidArgument when the cost has no closed form or the
// features cannot be built (several angles), naming why.
absl::StatusOr<pilco::PilcoProblem> MakeStudyPilcoProblem(const FrozenProblem& frozen,
                                                          const estimators::Problem& problem,
                                                          std::string* noise_note);

}  // namespace totalgrad::study

#endif  // TOTALGRAD_CORE_STUDY_PILCO_PROBLEM_H_
