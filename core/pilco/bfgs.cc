#include "core/pilco/bfgs.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "absl/strings/str_format.h"

namespace totalgrad::pilco {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Point {
  Vector x;
  double f = kInf;
  Vector g;
};

class Evaluator {
 public:
  Evaluator(const Objective& objective, BfgsSummary* summary)
      : objective_(objective), summary_(summary) {}
  // False if the objective failed or returned non-finite numbers.
  bool operator()(const Vector& x, double* f, Vector* g) {
    ++summary_->evaluations;
    const bool ok = objective_(x, f, g) && std::isfinite(*f) && g->size() == x.size() &&
                    g->allFinite();
    if (!ok) ++summary_->failed_evaluations;
    return ok;
  }

 private:
  const Objective& objective_;
  BfgsSummary* summary_;
};

struct LineSearchResult {
  bool success = false;
  double step = 0;  // accepted step along r (success only)
  Point accepted;   // success only
  Point best;       // lowest value seen, the start included
};

// Line search along r from `start` (slope d0 = g.r < 0) with initial step x3.
LineSearchResult LineSearch(Evaluator& eval, const BfgsOptions& o, const Point& start,
                            const Vector& r, double d0, double x3) {
  LineSearchResult res;
  res.best = start;
  const double f0 = start.f;
  int budget = o.max_evaluations_per_line_search;
  double x1 = 0, f1 = f0, d1 = d0;
  double x2 = 0, f2 = f0, d2 = d0;
  double f3 = f0, d3 = d0;
  Vector g3 = start.g;
  bool have_x3 = false;
  auto consider = [&](double step, double f, const Vector& g) {
    if (f < res.best.f) {
      res.best.x = start.x + step * r;
      res.best.f = f;
      res.best.g = g;
    }
  };
  // Extrapolation.
  while (true) {
    have_x3 = false;
    while (!have_x3 && budget > 0) {
      --budget;
      double f;
      Vector g;
      if (eval(start.x + x3 * r, &f, &g)) {
        have_x3 = true;
        f3 = f;
        g3 = std::move(g);
      } else {
        x3 = 0.5 * (x2 + x3);  // back towards the last good point
      }
    }
    if (!have_x3) return res;  // nothing evaluable: failure, best = start or earlier
    d3 = g3.dot(r);
    consider(x3, f3, g3);
    if (d3 > o.sig * d0 || f3 > f0 + x3 * o.rho * d0 || budget == 0) break;
    // Still descending steeply: extrapolate by a cubic fit.
    x1 = x2;
    f1 = f2;
    d1 = d2;
    x2 = x3;
    f2 = f3;
    d2 = d3;
    const double a = 6.0 * (f1 - f2) + 3.0 * (d2 + d1) * (x2 - x1);
    const double b = 3.0 * (f2 - f1) - (2.0 * d1 + d2) * (x2 - x1);
    const double disc = b * b - a * d1 * (x2 - x1);
    double next = kInf;
    if (disc >= 0) next = x1 - d1 * (x2 - x1) * (x2 - x1) / (b + std::sqrt(disc));
    if (!std::isfinite(next) || next < 0 || next > x2 * o.max_extrapolation) {
      next = x2 * o.max_extrapolation;
    } else if (next < x2 + o.interpolation_margin * (x2 - x1)) {
      next = x2 + o.interpolation_margin * (x2 - x1);
    }
    x3 = next;
  }
  // Interpolation (sectioning) until the Wolfe-Powell conditions hold.
  double x4 = x3, f4 = f3, d4 = d3;
  while ((std::abs(d3) > -o.sig * d0 || f3 > f0 + x3 * o.rho * d0) && budget > 0) {
    if (d3 > 0 || f3 > f0 + x3 * o.rho * d0) {
      x4 = x3;
      f4 = f3;
      d4 = d3;
    } else {
      x2 = x3;
      f2 = f3;
      d2 = d3;
    }
    double next;
    if (f4 > f0) {
      next = x2 - (0.5 * d2 * (x4 - x2) * (x4 - x2)) / (f4 - f2 - d2 * (x4 - x2));
    } else {
      const double a = 6.0 * (f2 - f4) / (x4 - x2) + 3.0 * (d4 + d2);
      const double b = 3.0 * (f4 - f2) - (2.0 * d2 + d4) * (x4 - x2);
      next = x2 + (std::sqrt(b * b - a * d2 * (x4 - x2) * (x4 - x2)) - b) / a;
    }
    if (!std::isfinite(next)) next = 0.5 * (x2 + x4);
    next = std::max(std::min(next, x4 - o.interpolation_margin * (x4 - x2)),
                    x2 + o.interpolation_margin * (x4 - x2));
    x3 = next;
    --budget;
    double f;
    Vector g;
    if (eval(start.x + x3 * r, &f, &g)) {
      f3 = f;
      g3 = std::move(g);
      d3 = g3.dot(r);
      consider(x3, f3, g3);
    } else {
      // Treat as "too far": a new upper bracket with an infinite value.
      f3 = kInf;
      d3 = kInf;
    }
  }
  if (std::abs(d3) <= -o.sig * d0 && f3 <= f0 + x3 * o.rho * d0 && std::isfinite(f3)) {
    res.success = true;
    res.step = x3;
    res.accepted.x = start.x + x3 * r;
    res.accepted.f = f3;
    res.accepted.g = g3;
  }
  return res;
}

double ClipStep(double step, double direction_norm, const BfgsOptions& o) {
  if (!(direction_norm > 0)) return step;
  return std::clamp(step, o.min_step_length / direction_norm, o.max_step_length / direction_norm);
}

}  // namespace

std::string BfgsSummary::BriefReport() const {
  const char* why = "max line searches";
  switch (termination) {
    case Termination::kMaxLineSearches: break;
    case Termination::kTwoFailedLineSearches: why = "two failed line searches in a row"; break;
    case Termination::kZeroGradient: why = "zero gradient"; break;
    case Termination::kCancelled: why = "cancelled"; break;
    case Termination::kInitialEvaluationFailed: why = "initial evaluation failed"; break;
  }
  return absl::StrFormat(
      "BFGS: %d line searches, %d evaluations (%d failed), %d failed line searches, f %.6g -> "
      "%.6g, stopped: %s",
      line_searches, evaluations, failed_evaluations, failed_line_searches, initial_value,
      final_value, why);
}

BfgsSummary MinimizeBfgs(const Objective& objective, const BfgsOptions& options, Vector* x) {
  BfgsSummary summary;
  Evaluator eval(objective, &summary);
  const int n = static_cast<int>(x->size());
  Point cur;
  cur.x = *x;
  if (!eval(cur.x, &cur.f, &cur.g)) {
    summary.termination = BfgsSummary::Termination::kInitialEvaluationFailed;
    summary.initial_value = summary.final_value = kInf;
    return summary;
  }
  summary.initial_value = cur.f;
  summary.history.push_back(cur.f);
  Matrix h = Matrix::Identity(n, n);
  Vector r = -cur.g;
  double d0 = cur.g.dot(r);
  double step = 1.0 / (1.0 - d0);
  bool last_failed = false;
  summary.termination = BfgsSummary::Termination::kMaxLineSearches;
  while (summary.line_searches < options.max_line_searches) {
    if (options.should_stop && options.should_stop()) {
      summary.termination = BfgsSummary::Termination::kCancelled;
      break;
    }
    if (cur.g.squaredNorm() == 0.0) {
      summary.termination = BfgsSummary::Termination::kZeroGradient;
      break;
    }
    ++summary.line_searches;
    step = ClipStep(step, r.norm(), options);
    LineSearchResult ls = LineSearch(eval, options, cur, r, d0, step);
    if (ls.success) {
      const Vector t = ls.accepted.x - cur.x;
      const Vector y = ls.accepted.g - cur.g;
      const double ty = t.dot(y);
      if (ty > 0) {
        const Vector hy = h * y;
        h += ((ty + y.dot(hy)) / (ty * ty)) * (t * t.transpose()) -
             (hy * t.transpose() + t * hy.transpose()) / ty;
      }
      cur = std::move(ls.accepted);
      step = ls.step;
      last_failed = false;
    } else {
      ++summary.failed_line_searches;
      cur = std::move(ls.best);
      if (last_failed) {
        summary.history.push_back(cur.f);
        summary.termination = BfgsSummary::Termination::kTwoFailedLineSearches;
        break;
      }
      last_failed = true;
    }
    summary.history.push_back(cur.f);
    r = -(h * cur.g);
    d0 = cur.g.dot(r);
    if (!(d0 < 0)) {  // H lost positive definiteness (round-off): restart
      h.setIdentity();
      r = -cur.g;
      d0 = cur.g.dot(r);
    }
    if (!ls.success) step = 1.0 / (1.0 - d0);
  }
  *x = cur.x;
  summary.final_value = cur.f;
  return summary;
}

}  // namespace totalgrad::pilco
