#include "results/diagnostics.h"

#include <cmath>
#include <limits>
#include <numeric>

#include "results/stats.h"

namespace totalgrad::results {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The per-step LR share's two summaries (NaN when the episode has none).
double LrShareMean(const learner::EpisodeSummary& e) {
  if (e.lr_share.empty()) return kNaN;
  return std::accumulate(e.lr_share.begin(), e.lr_share.end(), 0.0) /
         static_cast<double>(e.lr_share.size());
}
double LrShareLast(const learner::EpisodeSummary& e) {
  return e.lr_share.empty() ? kNaN : e.lr_share.back();
}

// The record's scalar statistics: its double fields after the ones every
// trial has (costs, times, the rollout verdict).
bool IsStatistic(const std::string& name) {
  for (const char* not_one : {"real_cost", "eval_cost_mean", "eval_cost_std", "predicted_cost",
                              "optimisation_seconds", "cpu_seconds", "held_fraction"}) {
    if (name == not_one) return false;
  }
  return true;
}

}  // namespace

const std::vector<std::string>& DiagnosticStatistics() {
  static const std::vector<std::string>* const names = [] {
    auto* list = new std::vector<std::string>;
    for (const auto& field : learner::EpisodeFields()) {
      if (field.type() == record::FieldType::kDouble && IsStatistic(field.name))
        list->push_back(field.name);
    }
    list->push_back("lr_share_mean");
    list->push_back("lr_share_last");
    return list;
  }();
  return *names;
}

std::vector<DiagnosticPoint> DiagnosticCurves(const std::vector<EpisodeStatistics>& rows,
                                              const std::string& only) {
  std::vector<DiagnosticPoint> points;
  for (const std::string& statistic : DiagnosticStatistics()) {
    if (!only.empty() && statistic != only) continue;
    const record::Field<learner::EpisodeSummary>* field = nullptr;
    for (const auto& f : learner::EpisodeFields())
      if (statistic == f.name) field = &f;
    std::vector<EpisodeValue> values;
    values.reserve(rows.size());
    for (const EpisodeStatistics& row : rows) {
      double value = kNaN;
      if (field != nullptr) value = field->Get<double>(row.episode);
      else if (statistic == "lr_share_mean") value = LrShareMean(row.episode);
      else if (statistic == "lr_share_last") value = LrShareLast(row.episode);
      values.push_back({row.method, row.variant, row.episode.episode, value});
    }
    for (const CurvePoint& p : Curves(values)) {
      points.push_back({statistic, p.method, p.variant, p.episode, p.trials, p.q25, p.median, p.q75});
    }
  }
  return points;
}

const record::FieldTable<DiagnosticPoint>& DiagnosticPointFields() {
  static const record::FieldTable<DiagnosticPoint> table = {
      {"statistic", &DiagnosticPoint::statistic},
      {"method", &DiagnosticPoint::method},
      {"variant", &DiagnosticPoint::variant},
      {"episode", &DiagnosticPoint::episode},
      {"trials", &DiagnosticPoint::trials},
      {"q25", &DiagnosticPoint::q25},
      {"median", &DiagnosticPoint::median},
      {"q75", &DiagnosticPoint::q75},
  };
  return table;
}

}  // namespace totalgrad::results
