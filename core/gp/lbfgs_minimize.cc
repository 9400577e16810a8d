#include "core/gp/lbfgs_minimize.h"

#include <LBFGS.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <stdexcept>

#include "core/common/check.h"

namespace totalgrad::gp::internal {
namespace {

// Loss shown to LBFGSpp for a failed evaluation. Only LBFGSSolver::minimize's
// first evaluation can see it (our line search asks last_failed() instead),
// and that point is always the finite best point.
constexpr double kFailedLoss = 1e100;

// Decreases the line search may ignore: relative to max(1, |f|), well above
// the round-off of a sum of N kernel terms yet negligible for the optimum.
constexpr double kNegligibleDecrease = 1e-10;

// Thrown by the line search when no step gives sufficient decrease but even
// the decrease the quasi-Newton model predicts is negligible: the iterate is
// converged to the resolution of f, which is not a failure.
class ConvergedToResolution : public std::exception {
 public:
  const char* what() const noexcept override { return "converged to the resolution of f"; }
};

// Adapts ObjectiveFunction to LBFGSpp's `double f(x, grad)` and keeps the
// best finite point: after a line-search exception the solver's own iterate
// is whatever trial point it evaluated last.
class TrackingObjective {
 public:
  TrackingObjective(const ObjectiveFunction& f, MinimizeResult* result)
      : f_(f), result_(result) {}

  double operator()(const Vector& x, Vector& gradient) {
    ++result_->evaluations;
    double value = 0;
    last_failed_ = !f_(x, &value, &gradient) || !std::isfinite(value) ||
                   gradient.size() != x.size() || !gradient.allFinite();
    if (last_failed_) {
      ++result_->non_finite_evaluations;
      gradient.setZero(x.size());
      return kFailedLoss;
    }
    if (value < best_value_) {
      best_value_ = value;
      result_->x = x;
      result_->value = value;
    }
    return value;
  }

  bool last_failed() const { return last_failed_; }
  // Called by the line search: one line search per L-BFGS iteration.
  void OnLineSearchStarted() { ++line_searches_started_; }
  void OnLineSearchCompleted() { ++result_->iterations; }

  bool has_best() const { return best_value_ < std::numeric_limits<double>::infinity(); }
  double best_value() const { return best_value_; }
  int line_searches_started() const { return line_searches_started_; }

 private:
  const ObjectiveFunction& f_;
  MinimizeResult* result_;
  double best_value_ = std::numeric_limits<double>::infinity();
  bool last_failed_ = false;
  int line_searches_started_ = 0;
};

// Strong-Wolfe line search (Nocedal & Wright, Algorithms 3.5 and 3.6) that
// understands failed evaluations, plugged into LBFGSSolver through its
// line-search template parameter. LBFGSpp 0.1.0's own searches do not: a
// failed trial has no usable value, so their interpolation either stalls on
// ever smaller steps or produces NaN, and LineSearchNocedalWright returns
// silently with its last (possibly failed) trial when it runs out of trials.
// Here a failed trial is an upper end of the bracket that is bisected towards;
// otherwise the step is the minimiser of the quadratic through (lo, f_lo,
// f'_lo) and (hi, f_hi), kept in the middle 80% of the bracket.
//
// Throws std::logic_error for a non-descent direction and std::runtime_error
// when no acceptable step is found (LBFGSpp's convention; MinimizeLbfgs
// catches both). If trials run out after a step with sufficient decrease, that
// step is taken (Armijo only).
template <typename Scalar>
class FailureAwareLineSearch {
 public:
  using VectorType = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;

  template <typename Foo>
  static void LineSearch(Foo& f, Scalar& fx, VectorType& x, VectorType& grad, Scalar& step,
                         const VectorType& drt, const VectorType& xp,
                         const LBFGSpp::LBFGSParam<Scalar>& param) {
    f.OnLineSearchStarted();
    const Scalar f0 = fx;
    const Scalar dg0 = grad.dot(drt);
    if (!(dg0 < 0)) throw std::logic_error("the search direction is not a descent direction");
    const Scalar armijo_slope = param.ftol * dg0;
    const Scalar curvature_bound = -param.wolfe * dg0;
    // Steps shorter than this do not move x in floating point.
    const Scalar min_width = std::numeric_limits<Scalar>::epsilon() *
                             (1 + xp.template lpNorm<Eigen::Infinity>()) /
                             drt.template lpNorm<Eigen::Infinity>();

    // lo: best step so far with sufficient decrease (0 = the start point).
    Scalar lo = 0, f_lo = f0, dg_lo = dg0;
    VectorType grad_lo = grad;
    // hi: other end of the bracket; infinite while still expanding.
    Scalar hi = std::numeric_limits<Scalar>::infinity(), f_hi = 0;
    bool hi_failed = false;

    Scalar t = step;
    for (int trial = 0; trial < param.max_linesearch; ++trial) {
      x.noalias() = xp + t * drt;
      fx = f(x, grad);
      if (f.last_failed()) {
        hi = t;
        hi_failed = true;
      } else {
        const Scalar dg = grad.dot(drt);
        if (fx > f0 + t * armijo_slope || fx >= f_lo) {
          hi = t;
          f_hi = fx;
          hi_failed = false;
        } else {
          if (std::abs(dg) <= curvature_bound) {  // strong Wolfe: done
            step = t;
            f.OnLineSearchCompleted();
            return;
          }
          if (dg * (hi - lo) >= 0 || (std::isinf(hi) && dg >= 0)) {
            // The minimum lies between t and lo.
            hi = lo;
            f_hi = f_lo;
            hi_failed = false;
          }
          lo = t;
          f_lo = fx;
          dg_lo = dg;
          grad_lo = grad;
        }
      }
      // Next trial.
      if (std::isinf(hi)) {
        t = std::min<Scalar>(2 * t, param.max_step);
        if (t == lo) break;
        continue;
      }
      const Scalar width = hi - lo;  // may be negative
      if (std::abs(width) <= min_width) break;
      Scalar next = lo + width / 2;
      if (!hi_failed) {
        // Minimiser of q(s) = f_lo + dg_lo (s - lo) + c (s - lo)^2 with q(hi) = f_hi.
        const Scalar c = (f_hi - f_lo - dg_lo * width) / (width * width);
        if (c > 0) next = lo - dg_lo / (2 * c);
      }
      const Scalar a = lo + Scalar(0.1) * width, b = hi - Scalar(0.1) * width;
      t = std::clamp(next, std::min(a, b), std::max(a, b));
    }
    if (lo > 0) {
      // No strong-Wolfe point found, but a sufficient decrease was: take it.
      x.noalias() = xp + lo * drt;
      fx = f_lo;
      grad = grad_lo;
      step = lo;
      f.OnLineSearchCompleted();
      return;
    }
    // The model predicts a decrease of about -dg0 * step / 2 for the first
    // trial (step 1 is the quasi-Newton step).
    if (-dg0 * step <= kNegligibleDecrease * std::max<Scalar>(1, std::abs(f0))) {
      throw ConvergedToResolution();
    }
    throw std::runtime_error("line search found no step with sufficient decrease");
  }
};

}  // namespace

bool MinimizeLbfgs(const ObjectiveFunction& f, const Vector& x0, int max_iterations,
                   MinimizeResult* result) {
  TG_CHECK(result != nullptr);
  TG_CHECK(max_iterations >= 0);
  *result = MinimizeResult();
  TrackingObjective objective(f, result);
  Vector x = x0;
  {
    Vector gradient(x.size());
    objective(x, gradient);
  }
  if (!objective.has_best()) return false;

  int remaining = max_iterations;
  while (remaining > 0) {
    LBFGSpp::LBFGSParam<double> param;
    param.max_iterations = remaining;  // never 0 here: LBFGSpp reads 0 as "unlimited"
    param.linesearch = LBFGSpp::LBFGS_LINESEARCH_BACKTRACKING_STRONG_WOLFE;
    param.past = 10;  // also stop when 10 iterations gained < 1e-10 relative
    param.delta = 1e-10;
    LBFGSpp::LBFGSSolver<double, FailureAwareLineSearch> solver(param);
    const double best_before = objective.best_value();
    const int started_before = objective.line_searches_started();
    double fx = 0;
    try {
      solver.minimize(objective, x, fx);
      break;
    } catch (const ConvergedToResolution&) {
      break;
    } catch (const std::exception&) {
      // Line-search failure, or a non-descent direction from round-off in the
      // L-BFGS matrix: LBFGSpp throws, and nothing may cross the module
      // boundary.
      ++result->line_search_failures;
      remaining -= objective.line_searches_started() - started_before;
      if (!(objective.best_value() < best_before)) break;
      x = result->x;
    }
  }
  return true;
}

}  // namespace totalgrad::gp::internal
