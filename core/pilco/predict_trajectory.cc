// PredictTrajectory (propagation.h): the horizon of moment-matched steps,
// the expected cost of each, and dJ/dtheta by one reverse sweep.
#include <cmath>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"
#include "core/common/status_context.h"
#include "core/pilco/propagation.h"

namespace totalgrad::pilco {

absl::Status PredictTrajectory(const Propagator& propagator, const gaussian::GaussianCost& cost,
                               const Vector& params, const Vector& mu0, const Matrix& S0,
                               int horizon, Trajectory* trajectory, Vector* gradient) {
  const int d = propagator.state_dim();
  TG_CHECK(cost.state_dim() == d);
  if (mu0.size() != d || S0.rows() != d || S0.cols() != d) {
    return absl::InvalidArgumentError(absl::StrCat("mu0 / S0 must have dimension ", d));
  }
  if (horizon < 1) return absl::InvalidArgumentError("horizon must be >= 1");
  if (params.size() != propagator.num_parameters()) {
    return absl::InvalidArgumentError(absl::StrCat("policy has ", params.size(),
                                                   " parameters; expected ",
                                                   propagator.num_parameters()));
  }
  if (!params.allFinite()) return absl::InvalidArgumentError("policy parameters not finite");
  const bool with_gradient = gradient != nullptr;
  Trajectory& tr = *trajectory;
  tr.means.assign(horizon + 1, Vector());
  tr.covs.assign(horizon + 1, Matrix());
  tr.means[0] = mu0;
  tr.covs[0] = S0;
  tr.cost_mean.resize(horizon);
  tr.cost_std.resize(horizon);
  std::vector<StepCache> caches(with_gradient ? horizon : 0);
  std::vector<Vector> cost_dm(with_gradient ? horizon : 0);
  std::vector<Matrix> cost_ds(with_gradient ? horizon : 0);
  for (int t = 0; t < horizon; ++t) {
    if (absl::Status st =
            propagator.Step(params, tr.means[t], tr.covs[t], &tr.means[t + 1], &tr.covs[t + 1],
                            with_gradient ? &caches[t] : nullptr);
        !st.ok()) {
      return WithContext(st, absl::StrCat("step ", t + 1));
    }
    gaussian::CostMoments cm;
    if (absl::Status st = cost.Evaluate(tr.means[t + 1], tr.covs[t + 1], with_gradient, &cm);
        !st.ok()) {
      return WithContext(st, absl::StrCat("step ", t + 1));
    }
    tr.cost_mean(t) = cm.mean;
    tr.cost_std(t) = std::sqrt(cm.var);
    if (with_gradient) {
      cost_dm[t] = cm.dmean_dm;
      cost_ds[t] = cm.dmean_dS;
    }
  }
  tr.total_cost = tr.cost_mean.sum();
  if (!with_gradient) return absl::OkStatus();
  gradient->setZero(propagator.num_parameters());
  Vector mb = Vector::Zero(d);
  Matrix sb = Matrix::Zero(d, d);
  for (int t = horizon - 1; t >= 0; --t) {
    mb += cost_dm[t];
    sb += cost_ds[t];
    Vector mb_prev;
    Matrix sb_prev;
    if (absl::Status st =
            propagator.StepBackward(params, caches[t], mb, sb, &mb_prev, &sb_prev, gradient);
        !st.ok()) {
      return WithContext(st, absl::StrCat("step ", t + 1));
    }
    mb = std::move(mb_prev);
    sb = std::move(sb_prev);
  }
  if (!gradient->allFinite()) return absl::InternalError("dJ/dtheta not finite");
  return absl::OkStatus();
}

}  // namespace totalgrad::pilco
