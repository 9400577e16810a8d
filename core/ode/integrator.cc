#include "core/ode/integrator.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <boost/numeric/odeint.hpp>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"

namespace totalgrad::ode {
namespace {

namespace odeint = boost::numeric::odeint;

// odeint works on std::vector<double> with its default range_algebra; the
// caller's Rhs works on Eigen vectors. The adapter copies through two
// preallocated buffers (4 doubles for the cart-pole, so the copies are noise
// next to the trigonometry in the right-hand side).
using OdeState = std::vector<double>;

class RhsAdapter {
 public:
  RhsAdapter(const Rhs& rhs, Eigen::Index n) : rhs_(rhs), x_(n), dxdt_(n) {}

  void operator()(const OdeState& x, OdeState& dxdt, double /*t*/) {
    x_ = Eigen::Map<const Vector>(x.data(), x_.size());
    dxdt_.setZero();
    rhs_(x_, &dxdt_);
    Eigen::Map<Vector>(dxdt.data(), dxdt_.size()) = dxdt_;
  }

 private:
  const Rhs& rhs_;
  Vector x_;
  Vector dxdt_;
};

bool AllFinite(const OdeState& v) {
  return std::all_of(v.begin(), v.end(), [](double e) { return std::isfinite(e); });
}

}  // namespace

const OptionTable<IntegratorOptions>& IntegratorOptions::Table() {
  static const OptionTable<IntegratorOptions>* table = [] {
    auto* t = new OptionTable<IntegratorOptions>();
    t->Double("integrator_relative_tolerance", &IntegratorOptions::relative_tolerance)
        .Double("integrator_absolute_tolerance", &IntegratorOptions::absolute_tolerance)
        .Double("integrator_initial_step", &IntegratorOptions::initial_step)
        .Double("integrator_min_step", &IntegratorOptions::min_step)
        .Int("integrator_max_steps", &IntegratorOptions::max_steps);
    return t;
  }();
  return *table;
}

absl::Status IntegratorOptions::Validate() const {
  const IntegratorOptions& o = *this;
  if (!(o.relative_tolerance >= 0) || !std::isfinite(o.relative_tolerance)) {
    return absl::InvalidArgumentError(
        absl::StrCat("integrator: relative_tolerance must be finite and >= 0, got ",
                     o.relative_tolerance));
  }
  if (!(o.absolute_tolerance >= 0) || !std::isfinite(o.absolute_tolerance)) {
    return absl::InvalidArgumentError(
        absl::StrCat("integrator: absolute_tolerance must be finite and >= 0, got ",
                     o.absolute_tolerance));
  }
  if (o.relative_tolerance == 0 && o.absolute_tolerance == 0) {
    return absl::InvalidArgumentError(
        "integrator: relative_tolerance and absolute_tolerance are both 0");
  }
  if (!(o.initial_step > 0) || !std::isfinite(o.initial_step)) {
    return absl::InvalidArgumentError(
        absl::StrCat("integrator: initial_step must be finite and > 0, got ", o.initial_step));
  }
  if (!(o.min_step >= 0) || !std::isfinite(o.min_step)) {
    return absl::InvalidArgumentError(
        absl::StrCat("integrator: min_step must be finite and >= 0, got ", o.min_step));
  }
  if (o.max_steps < 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("integrator: max_steps must be >= 1, got ", o.max_steps));
  }
  return absl::OkStatus();
}

absl::Status IntegrateAdaptive(const Rhs& rhs, double duration, const IntegratorOptions& options,
                               Vector* state, IntegrationReport* report) {
  TG_CHECK(state != nullptr);
  IntegrationReport local_report;
  IntegrationReport& rep = report != nullptr ? *report : local_report;
  rep = IntegrationReport{};

  if (!(duration > 0) || !std::isfinite(duration)) {
    return absl::InvalidArgumentError(
        absl::StrCat("integrator: duration must be finite and > 0, got ", duration));
  }
  if (absl::Status st = options.Validate(); !st.ok()) return st;
  if (!state->allFinite()) {
    return absl::InvalidArgumentError("integrator: start state is not finite");
  }

  const Eigen::Index n = state->size();
  OdeState x(state->data(), state->data() + n);
  OdeState dxdt(n), x_new(n), dxdt_new(n);
  RhsAdapter system(rhs, n);
  system(x, dxdt, 0.0);
  if (!AllFinite(dxdt)) {
    return absl::InternalError("integrator: non-finite derivative at the start state");
  }

  auto stepper = odeint::make_controlled(options.absolute_tolerance, options.relative_tolerance,
                                         odeint::runge_kutta_dopri5<OdeState>());

  double t = 0.0;
  double dt = std::min(options.initial_step, duration);
  bool chosen_step_seen = false;
  while (true) {
    if (rep.accepted_steps + rep.rejected_steps >= options.max_steps) {
      return absl::ResourceExhaustedError(absl::StrCat(
          "integrator: step budget of ", options.max_steps, " exhausted at t = ", t, " of ",
          duration, " (", rep.accepted_steps, " accepted, ", rep.rejected_steps,
          " rejected steps)"));
    }
    // Land exactly on `duration`: the step that would reach or pass it is
    // shortened to the remaining time, and on acceptance t is set to
    // `duration` itself rather than to the rounded sum t + dt.
    const double remaining = duration - t;
    if (remaining <= 0) break;  // t + dt rounded up onto `duration`
    const bool landing = dt >= remaining;
    const double attempted = landing ? remaining : dt;
    double step = attempted;
    double t_try = t;
    const odeint::controlled_step_result result =
        stepper.try_step(system, x, dxdt, t_try, x_new, dxdt_new, step);
    if (result == odeint::success) {
      // odeint's error norm ignores NaN entries (max with NaN keeps the old
      // value), so an accepted step is not yet a finite one: check it here.
      if (!AllFinite(x_new) || !AllFinite(dxdt_new)) {
        ++rep.rejected_steps;
        return absl::InternalError(
            absl::StrCat("integrator: non-finite state or derivative after a step of ", attempted,
                         " s at t = ", t));
      }
      ++rep.accepted_steps;
      // The smallest step the controller chose; a landing step is only as
      // long as the time that happened to be left, so it counts only when it
      // is the sole step.
      if (!landing) {
        rep.smallest_step = chosen_step_seen ? std::min(rep.smallest_step, attempted) : attempted;
        chosen_step_seen = true;
      } else if (!chosen_step_seen) {
        rep.smallest_step = attempted;
      }
      x.swap(x_new);
      dxdt.swap(dxdt_new);
      if (landing) break;
      t = t_try;
      dt = step;  // the controller's proposal for the next step
    } else {
      ++rep.rejected_steps;
      dt = step;  // shrunk by the controller
      if (!(dt >= options.min_step) || !std::isfinite(dt)) {
        return absl::InternalError(absl::StrCat("integrator: step size ", dt,
                                                " fell below min_step ", options.min_step,
                                                " at t = ", t, " (stiff or singular problem)"));
      }
    }
  }
  *state = Eigen::Map<const Vector>(x.data(), n);
  return absl::OkStatus();
}

void IntegrateRk4(const Rhs& rhs, double duration, int substeps, Vector* state) {
  TG_CHECK(state != nullptr);
  TG_CHECK(substeps >= 1);
  const double h = duration / substeps;
  const Eigen::Index n = state->size();
  Vector& x = *state;
  Vector k1(n), k2(n), k3(n), k4(n), tmp(n);
  for (int i = 0; i < substeps; ++i) {
    rhs(x, &k1);
    tmp = x + (0.5 * h) * k1;
    rhs(tmp, &k2);
    tmp = x + (0.5 * h) * k2;
    rhs(tmp, &k3);
    tmp = x + h * k3;
    rhs(tmp, &k4);
    x += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  }
}

}  // namespace totalgrad::ode
