// The record of one finished episode that every layer carries (issue 13):
// the numbers a trial reports per episode, written once with their field
// table (core/common/record.h). learner::EpisodeResult extends it with what
// only the trial has (timing, GP, policy, flags: the stored `details_json`);
// the worker's EpisodeOutcome and the store's Episode extend it with that
// details text. The table is the columns of the `episodes` table, the fields
// of the proto's EpisodeReport, the CSV columns of `totalgrad results export
// -f csv` and the first keys of an episode's JSON (`totalgrad trial --json`,
// sweep archives). Adding a field: docs/core.md, "Where to add what", "A new
// results column".
//
// Header only (the table too), so that the worker's runtime, which links no
// numerical code, shares it.
#ifndef TOTALGRAD_CORE_LEARNER_EPISODE_RECORD_H_
#define TOTALGRAD_CORE_LEARNER_EPISODE_RECORD_H_

#include <limits>
#include <vector>

#include "core/common/record.h"

namespace totalgrad::learner {

// NaN: no value (the evaluation and prediction of episode 0; a time a
// report did not carry).
struct EpisodeSummary {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  int episode = 0;                     // 0 = the random episode
  double real_cost = kNaN;             // cost of the episode whose data were added
  double eval_cost_mean = kNaN;        // over eval_rollouts episodes (NaN for episode 0)
  double eval_cost_std = kNaN;
  double predicted_cost = kNaN;        // the model's expected cost of the optimised policy
  double optimisation_seconds = kNaN;  // wall time of GP fit + policy optimisation
  double cpu_seconds = kNaN;           // CPU time of the whole episode
  // The rollout verdict's fraction of the final policy's rollouts that were
  // held (learner::ClassifyController; TrialOptions::verdict_*): set on a
  // trial's last episode when verdict_rollouts > 0, NaN on every other
  // episode and in rows stored before the field existed.
  double held_fraction = kNaN;
  // What the policy optimisation did (particle methods; NaN, or empty, for
  // PILCO, episode 0, a quantity the method lacks, and rows stored before
  // the fields existed): learner::OptimisationDiagnostics, whose header
  // gives the formulas. first/middle/last: gradient steps 1, S/2 and S.
  double gradient_norm_first = kNaN;
  double gradient_norm_middle = kNaN;
  double gradient_norm_last = kNaN;
  double gradient_norm_mean = kNaN;
  double gradient_snr_first = kNaN;
  double gradient_snr_middle = kNaN;
  double gradient_snr_last = kNaN;
  double gradient_snr_mean = kNaN;
  double step_norm_first = kNaN;
  double step_norm_middle = kNaN;
  double step_norm_last = kNaN;
  double step_norm_mean = kNaN;
  double ess_min = kNaN;           // BIW importance weights' ESS, min over the horizon
  double ess_median = kNaN;        // its median over the horizon
  double ess_low_fraction = kNaN;  // fraction of the horizon with ESS < P / 10
  std::vector<double> lr_share;    // per step t = 1..H, TP / GTP / GTP+sn
};

inline const record::FieldTable<EpisodeSummary>& EpisodeFields() {
  using E = EpisodeSummary;
  static const record::FieldTable<E>* const table = new record::FieldTable<E>{
      {"episode", &E::episode},
      {"real_cost", &E::real_cost},
      {"eval_cost_mean", &E::eval_cost_mean},
      {"eval_cost_std", &E::eval_cost_std},
      {"predicted_cost", &E::predicted_cost},
      {"optimisation_seconds", &E::optimisation_seconds},
      {"cpu_seconds", &E::cpu_seconds},
      {"held_fraction", &E::held_fraction},
      {"gradient_norm_first", &E::gradient_norm_first},
      {"gradient_norm_middle", &E::gradient_norm_middle},
      {"gradient_norm_last", &E::gradient_norm_last},
      {"gradient_norm_mean", &E::gradient_norm_mean},
      {"gradient_snr_first", &E::gradient_snr_first},
      {"gradient_snr_middle", &E::gradient_snr_middle},
      {"gradient_snr_last", &E::gradient_snr_last},
      {"gradient_snr_mean", &E::gradient_snr_mean},
      {"step_norm_first", &E::step_norm_first},
      {"step_norm_middle", &E::step_norm_middle},
      {"step_norm_last", &E::step_norm_last},
      {"step_norm_mean", &E::step_norm_mean},
      {"ess_min", &E::ess_min},
      {"ess_median", &E::ess_median},
      {"ess_low_fraction", &E::ess_low_fraction},
      // A list: JSON only, no CSV column.
      {"lr_share", &E::lr_share, false},
  };
  return *table;
}

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_EPISODE_RECORD_H_
