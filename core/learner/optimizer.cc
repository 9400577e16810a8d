#include "core/learner/optimizer.h"

#include "core/common/check.h"

namespace totalgrad::learner {

const EnumNames<Normalisation>& NormalisationNames() {
  static const EnumNames<Normalisation>* names = new EnumNames<Normalisation>{
      {Normalisation::kParticleStd, "particle_std"},
      {Normalisation::kMeanStd, "mean_std"},
      {Normalisation::kRmsprop, "rmsprop"}};
  return *names;
}

const OptionTable<OptimizerOptions>& OptimizerOptions::Table() {
  static const OptionTable<OptimizerOptions>* table = [] {
    auto* t = new OptionTable<OptimizerOptions>();
    t->Double("learning_rate", &OptimizerOptions::learning_rate)
        .Double("momentum", &OptimizerOptions::momentum)
        .Double("decay", &OptimizerOptions::decay)
        .Double("epsilon", &OptimizerOptions::epsilon)
        .Enum("normalisation", &OptimizerOptions::normalisation, NormalisationNames());
    return t;
  }();
  return *table;
}

absl::Status OptimizerOptions::Validate() const {
  if (!(learning_rate > 0)) return InvalidOption("learning_rate", "must be > 0");
  if (!(momentum >= 0 && momentum < 1)) return InvalidOption("momentum", "must be in [0, 1)");
  if (!(decay >= 0 && decay < 1)) return InvalidOption("decay", "must be in [0, 1)");
  if (!(epsilon >= 0)) return InvalidOption("epsilon", "must be >= 0");
  if (!IsNamedEnum(NormalisationNames(), normalisation))
    return InvalidOption("normalisation", "is not a known value");
  return absl::OkStatus();
}

RmspropLike::RmspropLike(const OptimizerOptions& options, int num_parameters)
    : options_(options), v_(Vector::Zero(num_parameters)), m_(Vector::Zero(num_parameters)) {}

void RmspropLike::Reset() {
  v_.setZero();
  m_.setZero();
  first_ = true;
}

void RmspropLike::set_state(const State& state) {
  TG_CHECK_EQ(state.v.size(), v_.size());
  TG_CHECK_EQ(state.m.size(), m_.size());
  v_ = state.v;
  m_ = state.m;
  first_ = state.first;
}

void RmspropLike::Step(const Vector& gradient, const Vector& per_particle_variance,
                       int num_particles, Vector* parameters) {
  TG_CHECK_EQ(gradient.size(), v_.size());
  TG_CHECK_EQ(parameters->size(), v_.size());
  Vector s2;
  switch (options_.normalisation) {
    case Normalisation::kParticleStd:
      s2 = per_particle_variance;
      break;
    case Normalisation::kMeanStd:
      s2 = per_particle_variance / static_cast<double>(num_particles);
      break;
    case Normalisation::kRmsprop:
      s2 = gradient.array().square();
      break;
  }
  if (first_) {
    v_ = s2;
    first_ = false;
  } else {
    v_ = options_.decay * v_ + (1.0 - options_.decay) * s2;
  }
  m_ = options_.momentum * m_ + (gradient.array() / (v_.array().sqrt() + options_.epsilon)).matrix();
  *parameters -= options_.learning_rate * m_;
}

}  // namespace totalgrad::learner
