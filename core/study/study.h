// Gradient studies: error against run time for every estimator on one frozen
// problem (issue 6; docs/error-vs-time.md; the protocol follows the
// work-precision methodology in shared/docs/estimators-notes.md).
//
// For each estimator x particle count P x horizon H (a "cell") the study runs
// R independent single-threaded estimates, with common random numbers
// across estimators (replicate r of a cell (P, H) uses the same substream for
// every estimator), and reports against a reference gradient g* of the plain
// particle objective J = E[sum_t c(x_t)]:
//
//   time_min_s      minimum over the R runs of the wall time of one Estimate
//                   (min of repeated runs; the first run's allocations and
//                   cold caches do not count); time_median_s as well
//   rel_rmse        sqrt(mean_r |g_r - g*|^2) / |g*|
//   rel_bias        |mean_r g_r - g*| / |g*|; rel_bias_noise =
//                   sqrt(total_variance / R) / |g*| is what an unbiased
//                   estimator's rel_bias would be from noise alone
//   total_variance  sum over coordinates of the sample variance over r
//   cos_mean        mean_r cos(g_r, g*)
//   ess_mean/min    for methods whose LR part uses batch importance weights:
//                   Kish ESS / P of each source particle's weights over the
//                   samples, averaged over sources and steps (min: the step
//                   with the smallest average), on the same particles as the
//                   first ess_replicates replicates
//   k_lr_mean       TP-type methods: the mean weight on LR, per step and
//                   overall (GradientEstimate::k_lr)
//
// The reference g* at each H pools (inverse variance per coordinate) the
// means of `reference.replicates` estimates at `reference.particles` from
// each reference estimator (default RP and LR with plain weights and the
// leave-one-out baseline: two different unbiased estimators). Their
// agreement is tested coordinate-wise; its standard error is reported, and
// 1.96 |SE| / |g*| is the floor no estimator's rel_rmse can be resolved
// below. An estimator whose estimates are not finite (RP overflowing at long
// horizons) is left out of the reference and the fact recorded.
//
// PILCO's deterministic moment-matching gradient (estimator "PILCO") runs on
// the same GP and policy with the problem's features (the raw state, angle
// index -1, or its one angle as (sin, cos); with several angles the cell is
// omitted, naming why), the model noise
// included in the predictions when the problem's noise multiplier is > 0
// (the particles' transitions include it), and the same cost in closed form.
// Like GR, GLR, GTP and DEL it estimates another objective; its error
// against g* shows that bias. It has no particle count (particles = 0).
//
// Nothing is dropped silently: failed estimates, non-finite estimates,
// cells cut short by the time budget and cells that could not run are
// counted or listed in the result.
//
// Thread safety: RunStudy uses one thread; the caller should limit the BLAS
// to one thread (SetBlasThreads(1)) for honest timings.
#ifndef TOTALGRAD_CORE_STUDY_STUDY_H_
#define TOTALGRAD_CORE_STUDY_STUDY_H_

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/types.h"
#include "core/estimators/estimator.h"
#include "core/estimators/rollout.h"
#include "core/study/frozen_problem.h"
#include "core/study/study_records.h"

namespace totalgrad::study {

// One estimator configuration: a method (a particle estimator, or PILCO's
// moment matching) with its options, shown under `label`.
struct EstimatorSpec {
  std::string label;
  estimators::Method method = estimators::Method::kRp;
  estimators::EstimatorOptions options;
};

// Every method of estimators::MethodNames() (the particle methods, then
// PILCO), default options, label = name: new estimators appear here without
// any change to the study.
std::vector<EstimatorSpec> DefaultEstimators();
// RP, and LR with plain weights and the leave-one-out baseline, labelled
// "LR(plain,loo)".
std::vector<EstimatorSpec> DefaultReferenceEstimators();

struct ReferenceOptions {
  std::vector<EstimatorSpec> estimators = DefaultReferenceEstimators();
  int particles = 1000;
  int replicates = 40;             // per estimator, >= 2
  double agreement_max_z = 4.5;    // |z| bound per coordinate for "agree"
  // and the bound on the mean z^2 (1 for agreeing estimators with exact SEs;
  // heavy-tailed gradients and R ~ 20 make the estimated SEs small by chance)
  double agreement_mean_z2 = 3.0;
  double budget_seconds = 120.0;   // per estimator and horizon; >= 2 replicates always
};

struct StudyOptions {
  std::vector<EstimatorSpec> estimators = DefaultEstimators();
  std::vector<int> particles = {10, 30, 100, 300, 1000, 3000};
  std::vector<int> horizons = {10, 30, 60, 100};
  int replicates = 20;             // estimates per cell, >= 2
  ReferenceOptions reference;
  uint64_t seed = 1;
  // A cell stops replicating (keeping at least 2 estimates) once its
  // estimates have taken this long; the cell records how many it ran.
  double cell_budget_seconds = 20.0;
  int ess_replicates = 2;          // forward passes per cell for the ESS (0: none)
  int ess_max_particles = 3000;    // no ESS above (O(P^2 H) per pass)

  // OK, or InvalidArgument naming the first bad field (empty lists,
  // non-positive entries, replicates < 2, an unknown estimator method or
  // option).
  absl::Status Validate() const;
};

struct StudyResult {
  std::string source;                        // FrozenProblem::source
  std::string scene;                         // FrozenProblem::scene
  int num_parameters = 0;
  std::vector<ReferenceGradient> references; // one per horizon, in options order
  std::vector<CellResult> cells;             // estimator-major, then P, then H
  double seconds = 0;
};

// Error statistics of R estimates against g* (|g*| > 0), as defined above.
struct ErrorMetrics {
  double rel_rmse = 0, rel_bias = 0, rel_bias_noise = 0, total_variance = 0, cos_mean = 0;
};
ErrorMetrics ComputeErrorMetrics(const std::vector<Vector>& estimates, const Vector& reference);

// Kish effective sample size (sum w)^2 / sum w^2 of non-negative weights; 0
// when all are 0.
double KishEss(const Eigen::Ref<const Eigen::RowVectorXd>& weights);
// Mean over source particles i of KishEss(row i of the BIW weights c_ij) / P
// for one recorded step (estimators::BiwLogWeights); in (0, 1], 1/P when
// the weights are one-hot.
double MeanBiwEss(const estimators::StepRecord& step);

// Per-coordinate inverse-variance pooling of independent means (each with
// its standard errors). Coordinates where every SE is 0 take the plain mean.
void PoolMeans(const std::vector<Vector>& means, const std::vector<Vector>& standard_errors,
               Vector* pooled, Vector* pooled_se);

// Progress lines ("reference H=30: RP 40 x P=1000 ..."), may be null.
using StudyProgress = std::function<void(const std::string& line)>;

// Polled before each horizon's reference and each cell; true stops the
// study (a service worker whose job was cancelled or drained). May be null.
using StudyShouldStop = std::function<bool()>;

// Runs the study. Errors: the options' InvalidArgument; InvalidArgument for
// an incomplete problem; Cancelled when should_stop returned true (the
// partial result is dropped). Numerical trouble is never an error: it is
// counted in the cells and references.
absl::StatusOr<StudyResult> RunStudy(const FrozenProblem& problem, const StudyOptions& options,
                                     const StudyProgress& progress = nullptr,
                                     const StudyShouldStop& should_stop = nullptr);

}  // namespace totalgrad::study

#endif  // TOTALGRAD_CORE_STUDY_STUDY_H_
