#include "core/gp/training.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <sstream>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/common/check.h"
#include "core/common/finite.h"
#include "core/gp/lbfgs_minimize.h"
#include "core/gp/se_kernel.h"

namespace totalgrad::gp {
namespace {

constexpr double kLog2Pi = 1.8378770664093454836;  // log(2 pi)

// (N-1)-normalised standard deviation of each column; 0 when N < 2.
Vector ColumnStd(const RowMatrix& m) {
  Vector std_dev = Vector::Zero(m.cols());
  if (m.rows() < 2) return std_dev;
  for (Eigen::Index c = 0; c < m.cols(); ++c) {
    const double mean = m.col(c).mean();
    std_dev(c) = std::sqrt((m.col(c).array() - mean).square().sum() /
                           static_cast<double>(m.rows() - 1));
  }
  return std_dev;
}

// PILCO takes log(std) of the data in the initialisation and the penalty; a
// constant column would give log(0). Such columns carry no information for
// the kernel, so any finite reference works: 1, as in InitialHyperparameters.
Vector NonZeroStd(const Vector& std_dev) {
  return std_dev.unaryExpr([](double s) { return s > 0 && std::isfinite(s) ? s : 1.0; });
}


absl::Status ValidateTrainingArguments(const RowMatrix& inputs, const RowMatrix& targets,
                                       const TrainingOptions& options,
                                       const GpHyperparameters& hyp) {
  if (absl::Status s = ValidateGpData(inputs, targets, hyp); !s.ok()) return s;
  if (options.max_iterations < 0) {
    return absl::InvalidArgumentError("options.max_iterations must be >= 0");
  }
  if (options.penalty.enabled) {
    if (!(options.penalty.lengthscale_ratio > 1.0)) {
      return absl::InvalidArgumentError("options.penalty.lengthscale_ratio must be > 1");
    }
    if (!(options.penalty.signal_to_noise > 1.0)) {
      return absl::InvalidArgumentError("options.penalty.signal_to_noise must be > 1");
    }
    if (options.penalty.power < 1) {
      return absl::InvalidArgumentError("options.penalty.power must be >= 1");
    }
  }
  return absl::OkStatus();
}

}  // namespace

const OptionTable<PenaltyOptions>& PenaltyOptions::Table() {
  static const OptionTable<PenaltyOptions>* table = [] {
    auto* t = new OptionTable<PenaltyOptions>();
    t->Bool("gp_penalty", &PenaltyOptions::enabled)
        .Double("gp_penalty_lengthscale_ratio", &PenaltyOptions::lengthscale_ratio)
        .Double("gp_penalty_signal_to_noise", &PenaltyOptions::signal_to_noise)
        .Int("gp_penalty_power", &PenaltyOptions::power);
    return t;
  }();
  return *table;
}

absl::Status PenaltyOptions::Validate() const {
  if (!(lengthscale_ratio > 1) || !std::isfinite(lengthscale_ratio))
    return InvalidOption("gp_penalty_lengthscale_ratio", "must be finite and > 1");
  if (!(signal_to_noise > 1) || !std::isfinite(signal_to_noise))
    return InvalidOption("gp_penalty_signal_to_noise", "must be finite and > 1");
  if (power < 2 || power % 2 != 0) return InvalidOption("gp_penalty_power", "must be an even integer >= 2");
  return absl::OkStatus();
}

const OptionTable<TrainingOptions>& TrainingOptions::Table() {
  static const OptionTable<TrainingOptions>* table = [] {
    auto* t = new OptionTable<TrainingOptions>();
    t->Int("gp_iterations", &TrainingOptions::max_iterations)
        .Nest(&TrainingOptions::penalty, PenaltyOptions::Table());
    return t;
  }();
  return *table;
}

absl::Status TrainingOptions::Validate() const {
  if (max_iterations < 0) return InvalidOption("gp_iterations", "must be >= 0");
  return penalty.Validate();
}

std::string TrainingSummary::BriefReport() const {
  std::ostringstream os;
  os << "GP training: " << final_loss.size() << " outputs; loss [";
  for (size_t a = 0; a < final_loss.size(); ++a) os << (a ? ", " : "") << final_loss[a];
  os << "]; iterations [";
  for (size_t a = 0; a < iterations.size(); ++a) os << (a ? ", " : "") << iterations[a];
  os << "]; line-search failures " << line_search_failures << "; non-finite evaluations "
     << non_finite_evaluations;
  return os.str();
}

bool PenalisedNlml(const RowMatrix& inputs, const Vector& targets, const Vector& input_std,
                   const Vector& packed_log_hyp, const PenaltyOptions& penalty, double* value,
                   Vector* gradient) {
  TG_CHECK(value != nullptr);
  const Eigen::Index n = inputs.rows();
  const Eigen::Index e = inputs.cols();
  TG_CHECK_EQ(targets.size(), n);
  TG_CHECK_EQ(input_std.size(), e);
  TG_CHECK_EQ(packed_log_hyp.size(), e + 2);
  if (!packed_log_hyp.allFinite()) return false;

  const Vector inv_lengthscales = (-packed_log_hyp.head(e)).array().exp();
  const double sf2 = std::exp(2.0 * packed_log_hyp(e));
  const double sn2 = std::exp(2.0 * packed_log_hyp(e + 1));
  if (!inv_lengthscales.allFinite() || !std::isfinite(sf2) || !std::isfinite(sn2)) return false;

  // Distances are translation invariant. Centring first keeps the cancellation
  // in |a|^2 + |b|^2 - 2 a.b (kernel and length-scale gradient) at the scale of
  // the data spread instead of the data offset.
  const RowMatrix scaled =
      (inputs.rowwise() - inputs.colwise().mean()) * inv_lengthscales.asDiagonal();
  const Vector sq_norms = scaled.rowwise().squaredNorm();
  Matrix kse;  // noise-free kernel
  internal::SeCrossKernel(scaled, sq_norms, scaled, sq_norms, sf2, &kse);
  kse.diagonal().setConstant(sf2);
  // The BLAS may round entries (i, j) and (j, i) differently; the gradient
  // below relies on exact symmetry.
  kse.triangularView<Eigen::StrictlyUpper>() = kse.transpose();

  Matrix k = kse;
  k.diagonal().array() += sn2;
  const Eigen::LLT<Matrix> llt(k);
  if (!internal::CholeskyAccepted(llt, sf2 + sn2)) return false;
  const Vector alpha = llt.solve(targets);
  double nlml = 0.5 * targets.dot(alpha) +
                llt.matrixLLT().diagonal().array().log().sum() +
                0.5 * static_cast<double>(n) * kLog2Pi;

  Vector grad;
  if (gradient != nullptr) {
    grad.resize(e + 2);
    // dNLML/dtheta = 1/2 sum_ij W_ij dK_ij / dtheta with W = K^-1 - alpha alpha^T.
    Matrix w = llt.solve(Matrix::Identity(n, n));
    w.noalias() -= alpha * alpha.transpose();
    grad(e + 1) = sn2 * w.trace();  // dK/dlog sn = 2 sn^2 I
    // M = W .* Kse. dK/dlog sf = 2 Kse, and dK_ij/dlog l_m = Kse_ij (xs_im - xs_jm)^2
    // which, summed against the symmetric M, expands to
    //   1/2 sum_ij M_ij (xs_im - xs_jm)^2 = sum_i xs_im (xs_im r_i - (M xs)_im),
    // r = rowsum(M): one N x N x E product instead of E element-wise passes.
    w.array() *= kse.array();
    grad(e) = w.sum();
    const Vector row_sums = w.rowwise().sum();
    const Matrix m_xs = w * scaled;
    grad.head(e) = (scaled.array() * ((scaled.array().colwise() * row_sums.array()) -
                                      m_xs.array()))
                       .colwise()
                       .sum()
                       .transpose();
  }

  if (penalty.enabled) {
    // hypCurb (pilco-spec 4.4): sum_m ((log l_m - log std_m) / log ls)^p
    //                           + ((log sf - log sn) / log snr)^p.
    const int p = penalty.power;
    const double log_ls = std::log(penalty.lengthscale_ratio);
    const double log_snr = std::log(penalty.signal_to_noise);
    for (Eigen::Index m = 0; m < e; ++m) {
      const double u = (packed_log_hyp(m) - std::log(input_std(m))) / log_ls;
      nlml += std::pow(u, p);
      if (gradient != nullptr) grad(m) += p * std::pow(u, p - 1) / log_ls;
    }
    const double u = (packed_log_hyp(e) - packed_log_hyp(e + 1)) / log_snr;
    nlml += std::pow(u, p);
    if (gradient != nullptr) {
      const double d = p * std::pow(u, p - 1) / log_snr;
      grad(e) += d;
      grad(e + 1) -= d;
    }
  }

  if (!std::isfinite(nlml)) return false;
  if (gradient != nullptr) {
    if (!grad.allFinite()) return false;
    *gradient = std::move(grad);
  }
  *value = nlml;
  return true;
}

GpHyperparameters InitialHyperparameters(const RowMatrix& inputs, const RowMatrix& targets) {
  const Vector input_std = NonZeroStd(ColumnStd(inputs));
  const Vector target_std = NonZeroStd(ColumnStd(targets));
  GpHyperparameters hyp;
  hyp.log_lengthscales = input_std.array().log().transpose().replicate(targets.cols(), 1);
  hyp.log_signal_std = target_std.array().log();
  hyp.log_noise_std = (target_std.array() / 10.0).log();
  return hyp;
}

absl::StatusOr<TrainingSummary> TrainHyperparameters(const RowMatrix& inputs,
                                                     const RowMatrix& targets,
                                                     const TrainingOptions& options,
                                                     GpHyperparameters* hyperparameters) {
  TG_CHECK(hyperparameters != nullptr);
  if (absl::Status s = ValidateTrainingArguments(inputs, targets, options, *hyperparameters);
      !s.ok()) {
    return s;
  }
  const int num_outputs = static_cast<int>(targets.cols());
  const Vector input_std = NonZeroStd(ColumnStd(inputs));

  // Every start point is checked before anything is trained, so that a
  // FailedPrecondition leaves *hyperparameters untouched as documented.
  for (int a = 0; a < num_outputs; ++a) {
    double value = 0;
    Vector gradient;
    const Vector target = targets.col(a);
    if (!PenalisedNlml(inputs, target, input_std, hyperparameters->Packed(a), options.penalty,
                       &value, &gradient)) {
      return absl::FailedPreconditionError(absl::StrCat(
          "the penalised NLML of output ", a,
          " is not finite at the start hyperparameters (K not positive definite)"));
    }
  }

  TrainingSummary summary;
  GpHyperparameters trained = *hyperparameters;
  for (int a = 0; a < num_outputs; ++a) {
    const Vector target = targets.col(a);
    const internal::ObjectiveFunction loss = [&](const Vector& x, double* value,
                                                 Vector* gradient) {
      return PenalisedNlml(inputs, target, input_std, x, options.penalty, value, gradient);
    };
    internal::MinimizeResult result;
    // Cannot fail: every start point was evaluated above.
    TG_CHECK(internal::MinimizeLbfgs(loss, trained.Packed(a), options.max_iterations, &result));
    trained.SetPacked(a, result.x);
    summary.final_loss.push_back(result.value);
    summary.iterations.push_back(result.iterations);
    summary.line_search_failures += result.line_search_failures;
    summary.non_finite_evaluations += result.non_finite_evaluations;
  }
  *hyperparameters = trained;
  return summary;
}

}  // namespace totalgrad::gp
