#include "core/study/pilco_problem.h"

#include "absl/strings/str_cat.h"
#include "core/learner/problem_builder.h"

namespace totalgrad::study {

absl::StatusOr<pilco::PilcoProblem> MakeStudyPilcoProblem(const FrozenProblem& frozen,
                                                          const estimators::Problem& problem,
                                                          std::string* noise_note) {
  if (noise_note != nullptr) noise_note->clear();
  absl::StatusOr<pilco::PilcoProblem> built = learner::MakePilcoProblem(
      *problem.cost, problem.mu0, problem.initial_std, problem.horizon, frozen.angle_indices,
      frozen.policy->num_basis(), frozen.policy->max_control());
  if (!built.ok()) return built.status();
  // The particles' transitions include the model noise whenever its
  // multiplier is > 0; PILCO's predictions then include it too.
  built->propagation.prediction_includes_noise = problem.noise_variance_multiplier > 0;
  if (noise_note != nullptr && problem.noise_variance_multiplier != 0 &&
      problem.noise_variance_multiplier != 1) {
    *noise_note = absl::StrCat("PILCO adds the noise variance once; the particles use it x",
                               problem.noise_variance_multiplier);
  }
  return built;
}

}  // namespace totalgrad::study
