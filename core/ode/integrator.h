// Integration of ordinary differential equations dx/dt = f(x) over one
// control period, used for the *real* plant (never inside policy
// optimisation, which runs on the learned GP model).
//
// IntegrateAdaptive: embedded Dormand-Prince 5(4) (Boost.Odeint's
// runge_kutta_dopri5 with its error controller). It either meets the
// tolerances with finite states, or returns a non-OK status naming what went
// wrong (step budget exhausted, step size underflow, non-finite state). It
// never returns a state it could not vouch for.
//
// IntegrateRk4: classical fixed-step RK4, the reference for convergence tests.
//
// Thread safety: free functions, no shared state.
#ifndef TOTALGRAD_CORE_ODE_INTEGRATOR_H_
#define TOTALGRAD_CORE_ODE_INTEGRATOR_H_

#include <functional>

#include "absl/status/status.h"
#include "core/common/option_table.h"
#include "core/common/types.h"

namespace totalgrad::ode {

// Right-hand side: writes f(x) into *dxdt (same size as x, already sized).
using Rhs = std::function<void(const Vector& x, Vector* dxdt)>;

struct IntegratorOptions {
  double relative_tolerance = 1e-10;
  double absolute_tolerance = 1e-10;
  double initial_step = 1e-3;  // seconds
  double min_step = 1e-14;     // below this the integration is declared stiff/failed
  int max_steps = 200000;      // accepted + rejected steps per call

  // Trial option keys integrator_relative_tolerance, integrator_absolute_tolerance,
  // integrator_initial_step, integrator_min_step, integrator_max_steps.
  static const OptionTable<IntegratorOptions>& Table();
  // InvalidArgument naming the field: negative or non-finite tolerances, both
  // tolerances 0, initial_step <= 0, min_step < 0, max_steps < 1.
  absl::Status Validate() const;
  bool operator==(const IntegratorOptions&) const = default;
};

struct IntegrationReport {
  int accepted_steps = 0;
  int rejected_steps = 0;
  // Smallest accepted step the error controller chose (seconds). The last
  // step, shortened to land exactly on `duration`, counts only when it is the
  // only step. 0 if no step was accepted.
  double smallest_step = 0.0;
};

// Integrates from t = 0 to t = duration (> 0) starting at *state, and on
// success overwrites *state with x(duration). On failure *state is left
// unchanged and the status says why (InvalidArgument for a non-finite start
// or duration <= 0, ResourceExhausted for the step budget, Internal for a
// non-finite intermediate state or step-size underflow). `report` may be null;
// it is filled on failure too. Invalid options (options.Validate()) are
// InvalidArgument. A non-finite f(x) at the start state is
// Internal. The result is taken at exactly t = duration (the last step is
// shortened to land there).
absl::Status IntegrateAdaptive(const Rhs& rhs, double duration, const IntegratorOptions& options,
                               Vector* state, IntegrationReport* report);

// Classical RK4 with `substeps` equal steps over [0, duration]. No checks.
void IntegrateRk4(const Rhs& rhs, double duration, int substeps, Vector* state);

}  // namespace totalgrad::ode

#endif  // TOTALGRAD_CORE_ODE_INTEGRATOR_H_
