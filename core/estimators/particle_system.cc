#include "core/estimators/particle_system.h"

namespace totalgrad::estimators {

void GpDynamics::Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier,
                         RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                         RowMatrix* dvar_dz) const {
  gp::PredictOptions options;
  options.noise_variance_multiplier = noise_variance_multiplier;
  model_->Predict(z, options, mean, variance, dmean_dz, dvar_dz);
}

void FitcDynamics::Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier,
                           RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                           RowMatrix* dvar_dz) const {
  gp::PredictOptions options;
  options.noise_variance_multiplier = noise_variance_multiplier;
  model_->Predict(z, options, mean, variance, dmean_dz, dvar_dz);
}

}  // namespace totalgrad::estimators
