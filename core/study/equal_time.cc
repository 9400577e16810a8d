#include "core/study/equal_time.h"

#include <algorithm>
#include <cmath>

namespace totalgrad::study {
namespace {

bool Measured(const TimeErrorPoint& p) {
  return std::isfinite(p.seconds) && p.seconds > 0 && std::isfinite(p.error) && p.error > 0;
}

bool Usable(const CellResult& c) {
  return !c.omitted && c.replicates >= 1 && std::isfinite(c.time_min_s) && c.time_min_s > 0 &&
         std::isfinite(c.rel_rmse) && c.rel_rmse > 0;
}

}  // namespace

double InterpolateErrorAtTime(const std::vector<TimeErrorPoint>& points, double seconds) {
  double best = CellResult::kNaN;
  const auto keep = [&best](double e) {
    if (!std::isfinite(best) || e < best) best = e;
  };
  if (!(seconds > 0)) return best;
  const double log_t = std::log(seconds);
  for (size_t i = 0; i + 1 < points.size(); ++i) {
    const TimeErrorPoint& a = points[i];
    const TimeErrorPoint& b = points[i + 1];
    if (!Measured(a) || !Measured(b)) continue;
    const double lo = std::min(a.seconds, b.seconds), hi = std::max(a.seconds, b.seconds);
    if (seconds < lo || seconds > hi) continue;
    if (a.seconds == b.seconds) {  // both at T
      keep(std::min(a.error, b.error));
      continue;
    }
    const double la = std::log(a.seconds), lb = std::log(b.seconds);
    const double w = (log_t - la) / (lb - la);
    keep(std::exp((1.0 - w) * std::log(a.error) + w * std::log(b.error)));
  }
  // A curve of one measured point covers exactly its own time.
  for (const TimeErrorPoint& p : points) {
    if (Measured(p) && p.seconds == seconds) keep(p.error);
  }
  return best;
}

EqualTimeComparison CompareAtEqualTime(const StudyResult& result, const std::vector<double>& seconds) {
  EqualTimeComparison out;
  // Estimators in study order: the particle ones have curves, the others a point.
  std::vector<std::string> particle_estimators;
  for (const CellResult& c : result.cells) {
    if (c.particles <= 0) continue;
    if (std::find(particle_estimators.begin(), particle_estimators.end(), c.estimator) ==
        particle_estimators.end()) {
      particle_estimators.push_back(c.estimator);
    }
  }
  for (const ReferenceGradient& ref : result.references) {
    const int h = ref.horizon;
    std::vector<std::vector<TimeErrorPoint>> curves;
    for (const std::string& label : particle_estimators) {
      std::vector<const CellResult*> cells;
      for (const CellResult& c : result.cells) {
        if (c.estimator == label && c.horizon == h && c.particles > 0) cells.push_back(&c);
      }
      std::sort(cells.begin(), cells.end(),
                [](const CellResult* a, const CellResult* b) { return a->particles < b->particles; });
      std::vector<TimeErrorPoint> curve;
      for (const CellResult* c : cells) {
        curve.push_back(Usable(*c) ? TimeErrorPoint{c->time_min_s, c->rel_rmse} : TimeErrorPoint{});
      }
      curves.push_back(std::move(curve));
    }
    for (double t : seconds) {
      EqualTimeRow row;
      row.horizon = h;
      row.seconds = t;
      row.reference_agrees = ref.agree;
      row.reference_checked = !(ref.agreement_resolution > 1.0);
      row.floor = ref.floor > 0 ? ref.floor : CellResult::kNaN;
      row.estimators = particle_estimators;
      for (const auto& curve : curves) row.errors.push_back(InterpolateErrorAtTime(curve, t));
      row.ratios.assign(row.errors.size(), CellResult::kNaN);
      if (ref.agree && ref.norm > 0) {
        for (size_t e = 0; e < row.errors.size(); ++e) {
          if (std::isfinite(row.errors[e]) &&
              (!std::isfinite(row.winner_error) || row.errors[e] < row.winner_error)) {
            row.winner_error = row.errors[e];
            row.winner = row.estimators[e];
          }
        }
        if (!row.winner.empty()) {
          for (size_t e = 0; e < row.errors.size(); ++e) {
            if (std::isfinite(row.errors[e])) row.ratios[e] = row.errors[e] / row.winner_error;
          }
          row.winner_below_floor = std::isfinite(row.floor) && row.winner_error < row.floor;
        }
        // The lowest error another estimator measured within T (the first in
        // study order on ties); the winner's own smaller-P cells are its curve.
        for (const CellResult& c : result.cells) {
          if (c.particles <= 0 || c.horizon != h || !Usable(c) || c.time_min_s > t) continue;
          if (c.estimator == row.winner) continue;
          if (!std::isfinite(row.best_within_error) || c.rel_rmse < row.best_within_error) {
            row.best_within_error = c.rel_rmse;
            row.best_within_seconds = c.time_min_s;
            row.best_within_particles = c.particles;
            row.best_within = c.estimator;
          }
        }
        if (!row.best_within.empty() && !row.winner.empty() &&
            !(row.best_within_error < row.winner_error)) {
          row.best_within.clear();
          row.best_within_particles = 0;
          row.best_within_error = row.best_within_seconds = CellResult::kNaN;
        }
      }
      out.rows.push_back(std::move(row));
    }
    for (const CellResult& c : result.cells) {
      if (c.particles > 0 || c.horizon != h) continue;
      FixedCostPoint p;
      p.estimator = c.estimator;
      p.horizon = h;
      if (c.omitted) p.omission_reason = c.omission_reason;
      if (Usable(c)) {
        p.seconds = c.time_min_s;
        p.error = c.rel_rmse;
      }
      out.fixed_cost.push_back(p);
    }
  }
  return out;
}

}  // namespace totalgrad::study
