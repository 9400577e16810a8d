#include "core/tasks/plant.h"

#include "absl/strings/str_cat.h"
#include "core/common/check.h"

namespace totalgrad::tasks {

absl::Status Plant::Step(const Vector& x, const Vector& u, Vector* next,
                         ode::IntegrationReport* report) const {
  TG_CHECK(next != nullptr);
  if (x.size() != state_dim() || u.size() != control_dim()) {
    return absl::InvalidArgumentError(absl::StrCat("plant step: state of size ", x.size(), " and ",
                                                   u.size(), " controls; the plant has ",
                                                   state_dim(), " and ", control_dim()));
  }
  if (!x.allFinite()) return absl::InvalidArgumentError("plant step: non-finite state");
  if (!u.allFinite()) return absl::InvalidArgumentError("plant step: non-finite control");
  const ode::Rhs rhs = [this, &u](const Vector& z, Vector* dzdt) { Derivative(z, u, dzdt); };
  Vector z = x;
  const absl::Status status = ode::IntegrateAdaptive(rhs, dt_, integrator_, &z, report);
  if (!status.ok()) return absl::Status(status.code(), absl::StrCat("plant step: ", status.message()));
  *next = std::move(z);
  return absl::OkStatus();
}

}  // namespace totalgrad::tasks
