// The estimator statistics of a sweep's trials summarised per method, task
// variant and episode (issue 27 item 4): for every statistic the median and
// quartiles over trials of the episode's value, as results::Curves does for
// the evaluation cost. One computation for `totalgrad results diagnostics`
// and the dashboard's per-method statistic curves (/api/diagnostics).
//
// The statistics are the scalar optimisation diagnostics of the episode
// record (learner::EpisodeFields(): gradient_norm_*, gradient_snr_*,
// step_norm_*, ess_*; docs/diagnostics.md gives their formulas) and two
// summaries of the per-step LR share: lr_share_mean (its mean over the
// horizon) and lr_share_last (at t = H). A value a method does not have
// (NaN: PILCO, episode 0, LR shares of methods without total propagation,
// rows stored before the fields existed) is left out, so a statistic no
// trial has gives no point.
#ifndef TOTALGRAD_RESULTS_DIAGNOSTICS_H_
#define TOTALGRAD_RESULTS_DIAGNOSTICS_H_

#include <string>
#include <vector>

#include "core/common/record.h"
#include "core/learner/episode_record.h"
#include "results/stats.h"

namespace totalgrad::results {

// One stored episode of a completed trial.
struct EpisodeStatistics {
  std::string method;
  std::string variant;
  learner::EpisodeSummary episode;
};

struct DiagnosticPoint {
  std::string statistic;
  CurvePoint curve;  // of the statistic's values (trials: those with a value)
};

// The statistics' names, in the order of the points.
const std::vector<std::string>& DiagnosticStatistics();

// Points ordered by statistic (DiagnosticStatistics()' order), then method
// and variant (first appearance), then episode. `only` non-empty: that
// statistic alone (it must be one of DiagnosticStatistics()).
std::vector<DiagnosticPoint> DiagnosticCurves(const std::vector<EpisodeStatistics>& rows,
                                              const std::string& only = "");

// statistic, then CurvePointFields()' (method, variant, episode, trials,
// q25, median, q75, mean, standard_error): the CSV columns and JSON keys of
// `results diagnostics` and /api/diagnostics.
const record::FieldTable<DiagnosticPoint>& DiagnosticPointFields();

}  // namespace totalgrad::results

#endif  // TOTALGRAD_RESULTS_DIAGNOSTICS_H_
