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
    for (CurvePoint& curve : Curves(values)) points.push_back({statistic, std::move(curve)});
  }
  return points;
}

const record::FieldTable<DiagnosticPoint>& DiagnosticPointFields() {
  using P = DiagnosticPoint;
  static const record::FieldTable<P> table = [] {
    record::FieldTable<P> fields = {
        {"statistic", &P::statistic},
        {"method", record::Nested<&P::curve, &CurvePoint::method>()},
        {"variant", record::Nested<&P::curve, &CurvePoint::variant>()},
        {"episode", record::Nested<&P::curve, &CurvePoint::episode>()}};
    AppendSampleSummaryFields<&P::curve, &CurvePoint::values>(&fields);
    return fields;
  }();
  return table;
}

}  // namespace totalgrad::results
