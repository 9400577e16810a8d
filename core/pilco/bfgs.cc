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

// A point on the search line: step x along r, value f, slope d = g.r.
// minimize.m keeps its points as triples (x1, f1, d1) ... (x4, f4, d4) that
// move together; here each triple is one Probe, so "the point 2 becomes
// point 1" is one assignment.
struct Probe {
  double x;
  double f;
  double d;
};

// Line search along r from `start` (slope d0 = g.r < 0) with initial step
// `first_step`. The arithmetic is minimize.m's, operation for operation.
LineSearchResult LineSearch(Evaluator& eval, const BfgsOptions& o, const Point& start,
                            const Vector& r, double d0, double first_step) {
  LineSearchResult res;
  res.best = start;
  const double f0 = start.f;
  int budget = o.max_evaluations_per_line_search;
  Probe p1{0, f0, d0}, p2{0, f0, d0}, p3{first_step, f0, d0};
  Vector g3 = start.g;
  bool have_p3 = false;
  auto consider = [&](double step, double f, const Vector& g) {
    if (f < res.best.f) {
      res.best.x = start.x + step * r;
      res.best.f = f;
      res.best.g = g;
    }
  };
  // Extrapolation.
  while (true) {
    have_p3 = false;
    while (!have_p3 && budget > 0) {
      --budget;
      double f;
      Vector g;
      if (eval(start.x + p3.x * r, &f, &g)) {
        have_p3 = true;
        p3.f = f;
        g3 = std::move(g);
      } else {
        p3.x = 0.5 * (p2.x + p3.x);  // back towards the last good point
      }
    }
    if (!have_p3) return res;  // nothing evaluable: failure, best = start or earlier
    p3.d = g3.dot(r);
    consider(p3.x, p3.f, g3);
    if (p3.d > o.sig * d0 || p3.f > f0 + p3.x * o.rho * d0 || budget == 0) break;
    // Still descending steeply: extrapolate by a cubic fit.
    p1 = p2;
    p2 = p3;
    const double a = 6.0 * (p1.f - p2.f) + 3.0 * (p2.d + p1.d) * (p2.x - p1.x);
    const double b = 3.0 * (p2.f - p1.f) - (2.0 * p1.d + p2.d) * (p2.x - p1.x);
    const double disc = b * b - a * p1.d * (p2.x - p1.x);
    double next = kInf;
    if (disc >= 0) next = p1.x - p1.d * (p2.x - p1.x) * (p2.x - p1.x) / (b + std::sqrt(disc));
    if (!std::isfinite(next) || next < 0 || next > p2.x * o.max_extrapolation) {
      next = p2.x * o.max_extrapolation;
    } else if (next < p2.x + o.interpolation_margin * (p2.x - p1.x)) {
      next = p2.x + o.interpolation_margin * (p2.x - p1.x);
    }
    p3.x = next;
  }
  // Interpolation (sectioning) until the Wolfe-Powell conditions hold.
  Probe p4 = p3;
  while ((std::abs(p3.d) > -o.sig * d0 || p3.f > f0 + p3.x * o.rho * d0) && budget > 0) {
    if (p3.d > 0 || p3.f > f0 + p3.x * o.rho * d0) {
      p4 = p3;
    } else {
      p2 = p3;
    }
    double next;
    if (p4.f > f0) {
      next = p2.x - (0.5 * p2.d * (p4.x - p2.x) * (p4.x - p2.x)) /
                        (p4.f - p2.f - p2.d * (p4.x - p2.x));
    } else {
      const double a = 6.0 * (p2.f - p4.f) / (p4.x - p2.x) + 3.0 * (p4.d + p2.d);
      const double b = 3.0 * (p4.f - p2.f) - (2.0 * p2.d + p4.d) * (p4.x - p2.x);
      next = p2.x + (std::sqrt(b * b - a * p2.d * (p4.x - p2.x) * (p4.x - p2.x)) - b) / a;
    }
    if (!std::isfinite(next)) next = 0.5 * (p2.x + p4.x);
    next = std::max(std::min(next, p4.x - o.interpolation_margin * (p4.x - p2.x)),
                    p2.x + o.interpolation_margin * (p4.x - p2.x));
    p3.x = next;
    --budget;
    double f;
    Vector g;
    if (eval(start.x + p3.x * r, &f, &g)) {
      p3.f = f;
      g3 = std::move(g);
      p3.d = g3.dot(r);
      consider(p3.x, p3.f, g3);
    } else {
      // Treat as "too far": a new upper bracket with an infinite value.
      p3.f = kInf;
      p3.d = kInf;
    }
  }
  if (std::abs(p3.d) <= -o.sig * d0 && p3.f <= f0 + p3.x * o.rho * d0 && std::isfinite(p3.f)) {
    res.success = true;
    res.step = p3.x;
    res.accepted.x = start.x + p3.x * r;
    res.accepted.f = p3.f;
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
