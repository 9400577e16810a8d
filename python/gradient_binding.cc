// Gradients for Python: a frozen problem (a trial snapshot's model and
// policy, or a synthetic problem on a scene: the "problem" of a study file,
// io/study_file.h) and any particle estimator's gradient estimates on it, as
// numpy arrays; the whole error-vs-time study as one call.
//
// Estimates use the study's random streams (study::internal::RunReplicates:
// replicate r of a cell (P, H) on substream StreamIndex(0, H, P, r) of the
// seed), so `Problem.gradients(method, P, R, seed)` gives the estimates a
// study's cell at (P, H) averages, bit for bit, and every method sees the
// same random numbers (common random numbers).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "client/core_commands/study_format.h"
#include "core/common/blas.h"
#include "core/estimators/estimator.h"
#include "core/estimators/method.h"
#include "core/pilco/gp_moments.h"
#include "core/pilco/pilco.h"
#include "core/study/frozen_problem.h"
#include "core/study/pilco_problem.h"
#include "core/study/replicates.h"
#include "core/study/study.h"
#include "io/study_file.h"
#include "python/bindings.h"

namespace py = pybind11;

namespace totalgrad::python {
namespace {

using OptionPairs = std::vector<std::pair<std::string, std::string>>;

io::StudySpec ParseSpec(const std::string& study_json, const std::string& base_dir) {
  const nlohmann::json doc = nlohmann::json::parse(study_json, nullptr, false);
  if (doc.is_discarded()) throw py::value_error("the study document is not valid JSON");
  absl::StatusOr<io::StudySpec> spec = io::ParseStudySpec(doc, base_dir);
  if (!spec.ok()) throw py::value_error(std::string(spec.status().message()));
  return *std::move(spec);
}

std::unique_ptr<study::FrozenProblem> LoadProblem(const io::StudySpec& spec) {
  absl::StatusOr<std::unique_ptr<study::FrozenProblem>> problem;
  {
    py::gil_scoped_release release;
    problem = io::LoadStudyProblem(spec);
  }
  if (!problem.ok()) {
    if (absl::IsInvalidArgument(problem.status()) || absl::IsNotFound(problem.status())) {
      throw py::value_error(std::string(problem.status().message()));
    }
    throw std::runtime_error(problem.status().ToString());
  }
  return *std::move(problem);
}

py::array_t<double> ToNumpy(const std::vector<Vector>& rows, Eigen::Index columns) {
  py::array_t<double> out({static_cast<py::ssize_t>(rows.size()),
                           static_cast<py::ssize_t>(columns)});
  auto view = out.mutable_unchecked<2>();
  for (size_t r = 0; r < rows.size(); ++r) {
    for (Eigen::Index c = 0; c < columns; ++c) view(r, c) = rows[r](c);
  }
  return out;
}

class PyProblem {
 public:
  // The "problem" of a study document (JSON text); relative snapshot paths
  // from base_dir.
  PyProblem(const std::string& study_json, const std::string& base_dir)
      : problem_(LoadProblem(ParseSpec(study_json, base_dir))) {}

  // R estimates of `method` with P particles at horizon H (0: the
  // problem's): {"gradients": R x n, "objectives": R, "seconds": R,
  // "nonfinite": count}. PILCO is deterministic and has no particles: its
  // moment-matched gradient as the study's PILCO cell computes it, R timed
  // runs with R equal rows. ValueError for an unknown method or option;
  // RuntimeError naming the estimator's error.
  py::dict Gradients(const std::string& method_name, int particles, int replicates,
                     uint64_t seed, int horizon, const OptionPairs& option_pairs) {
    if (particles < 1) throw py::value_error("particles must be at least 1");
    if (replicates < 1) throw py::value_error("replicates must be at least 1");
    if (horizon < 0) throw py::value_error("horizon must be positive (0: the problem's)");
    const absl::StatusOr<estimators::Method> method = estimators::ParseMethod(method_name);
    if (!method.ok()) throw py::value_error(std::string(method.status().message()));
    if (*method == estimators::Method::kPilco) {
      if (!option_pairs.empty()) throw py::value_error("PILCO takes no estimator options");
      return PilcoGradients(replicates, horizon);
    }
    estimators::EstimatorOptions options;
    for (const auto& [key, value] : option_pairs) {
      if (absl::Status st = estimators::EstimatorOptions::Table().Set(key, value, &options);
          !st.ok()) {
        throw py::value_error(std::string(st.message()));
      }
    }
    absl::StatusOr<std::unique_ptr<estimators::Estimator>> estimator =
        estimators::MakeEstimator(*method, options);
    if (!estimator.ok()) throw py::value_error(std::string(estimator.status().message()));
    estimators::Problem problem = problem_->problem;
    if (horizon > 0) problem.horizon = horizon;
    study::internal::Replicates runs;
    {
      py::gil_scoped_release release;
      SetBlasThreads(1);
      runs = study::internal::RunReplicates(estimator->get(), problem, particles, replicates,
                                            std::numeric_limits<double>::infinity(), seed,
                                            /*kind=*/0);
    }
    if (runs.errors > 0) throw std::runtime_error(method_name + ": " + runs.first_error);
    const Eigen::Index n = runs.estimates.empty() ? 0 : runs.estimates.front().size();
    py::dict out;
    out["gradients"] = ToNumpy(runs.estimates, n);
    out["objectives"] = py::array_t<double>(static_cast<py::ssize_t>(runs.objectives.size()),
                                            runs.objectives.data());
    out["seconds"] = py::array_t<double>(static_cast<py::ssize_t>(runs.seconds.size()),
                                         runs.seconds.data());
    out["nonfinite"] = runs.nonfinite;
    return out;
  }

  // PILCO's moment matching on the problem (study::MakeStudyPilcoProblem):
  // the study's PILCO cell's objective and gradient, timed `replicates` times.
  py::dict PilcoGradients(int replicates, int horizon) {
    if (problem_->model == nullptr) {
      throw py::value_error("PILCO needs the problem's GP model (a snapshot or a synthetic problem)");
    }
    estimators::Problem problem = problem_->problem;
    if (horizon > 0) problem.horizon = horizon;
    absl::StatusOr<pilco::PilcoProblem> built = study::MakeStudyPilcoProblem(*problem_, problem, nullptr);
    if (!built.ok()) throw py::value_error("PILCO: " + std::string(built.status().message()));
    std::vector<Vector> gradients;
    std::vector<double> objectives, seconds;
    {
      py::gil_scoped_release release;
      SetBlasThreads(1);
      if (!pilco_gp_) {
        pilco_gp_ = std::make_unique<pilco::GaussianInputGp>(
            pilco::GaussianInputGpFromModel(*problem_->model));
      }
      for (int r = 0; r < replicates; ++r) {
        Vector g;
        const auto start = std::chrono::steady_clock::now();
        absl::StatusOr<pilco::Trajectory> trajectory =
            pilco::Propagate(*pilco_gp_, *built, problem_->policy->parameters(), &g);
        seconds.push_back(
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        if (!trajectory.ok()) {
          throw std::runtime_error("PILCO: " + std::string(trajectory.status().message()));
        }
        gradients.push_back(std::move(g));
        objectives.push_back(trajectory->total_cost);
      }
    }
    py::dict out;
    out["gradients"] = ToNumpy(gradients, gradients.front().size());
    out["objectives"] = py::array_t<double>(static_cast<py::ssize_t>(objectives.size()),
                                            objectives.data());
    out["seconds"] = py::array_t<double>(static_cast<py::ssize_t>(seconds.size()), seconds.data());
    int nonfinite = 0;
    for (const Vector& g : gradients) nonfinite += g.allFinite() ? 0 : 1;
    out["nonfinite"] = nonfinite;
    return out;
  }

  std::string source() const { return problem_->source; }
  std::string scene() const { return problem_->scene; }
  int horizon() const { return problem_->problem.horizon; }

 private:
  std::unique_ptr<study::FrozenProblem> problem_;
  std::unique_ptr<pilco::GaussianInputGp> pilco_gp_;  // built on first use by PILCO
};

// `totalgrad study FILE --format json` for a study document (JSON text).
std::string RunStudyJson(const std::string& study_json, const std::string& base_dir) {
  const io::StudySpec spec = ParseSpec(study_json, base_dir);
  const std::unique_ptr<study::FrozenProblem> problem = LoadProblem(spec);
  absl::StatusOr<study::StudyResult> result;
  {
    py::gil_scoped_release release;
    SetBlasThreads(1);  // timings are of single-threaded runs, as the CLI's
    result = study::RunStudy(*problem, spec.options, nullptr);
  }
  if (!result.ok()) throw std::runtime_error(result.status().ToString());
  return cli::StudyToJson(*result, spec).dump();
}

}  // namespace

void AddGradientBindings(py::module_& module) {
  py::class_<PyProblem>(module, "_Problem")
      .def(py::init<const std::string&, const std::string&>(), py::arg("study_json"),
           py::arg("base_dir"))
      .def("gradients", &PyProblem::Gradients, py::arg("method"), py::arg("particles"),
           py::arg("replicates"), py::arg("seed"), py::arg("horizon"), py::arg("options"))
      .def_property_readonly("source", &PyProblem::source)
      .def_property_readonly("scene", &PyProblem::scene)
      .def_property_readonly("horizon", &PyProblem::horizon);
  module.def("_study_json", &RunStudyJson, py::arg("study_json"), py::arg("base_dir"));
}

}  // namespace totalgrad::python
