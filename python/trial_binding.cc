// Trials, scenes and simulations for Python: learner::RunTrial on a thread
// of its own, its episodes handed to Python one at a time as the JSON that
// `totalgrad trial --json` prints (io::EpisodeToJson), so the numbers are the
// CLI's bit for bit.
//
// The GIL is released while Python waits for an episode; the wait wakes every
// 100 ms to let Python handle signals, and Ctrl-C (KeyboardInterrupt) cancels
// the trial (TrialObserver::ShouldCancel, polled at least once per gradient
// step), waits for its thread to end, and is then raised.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "client/core_commands/scenes_format.h"
#include "client/core_commands/simulate_command.h"
#include "core/common/blas.h"
#include "core/learner/trial.h"
#include "core/tasks/scene_catalog.h"
#include "io/episode_json.h"
#include "python/bindings.h"
#include "results/plot_style.h"

namespace py = pybind11;

namespace totalgrad::python {
namespace {

using OptionPairs = std::vector<std::pair<std::string, std::string>>;

// Default options (the scene's horizon and threshold where not given) with
// `pairs` applied, then validated, as the CLI's flags; ValueError naming the
// first bad option (the CLI's messages, "did you mean" included).
learner::TrialOptions ParseTrialOptions(const OptionPairs& pairs) {
  absl::StatusOr<learner::TrialOptions> parsed = learner::TrialOptionsFromPairs(pairs);
  if (!parsed.ok()) throw py::value_error(std::string(parsed.status().message()));
  learner::TrialOptions options = *std::move(parsed);
  const absl::Status valid = options.Validate();
  if (!valid.ok()) throw py::value_error(std::string(valid.message()));
  return options;
}

// One trial on a thread of its own. Python calls NextEpisode until it returns
// None, then Summary. Destroying the object cancels a trial still running
// and waits for its thread.
class TrialRun final : public learner::TrialObserver {
 public:
  TrialRun(const OptionPairs& pairs, int threads) : options_(ParseTrialOptions(pairs)) {
    if (threads < 1) throw py::value_error("threads must be at least 1");
    run_.threads = threads;
    thread_ = std::thread([this] { Run(); });
  }
  ~TrialRun() override {
    cancel_ = true;
    if (thread_.joinable()) {
      py::gil_scoped_release release;
      thread_.join();
    }
  }
  TrialRun(const TrialRun&) = delete;
  TrialRun& operator=(const TrialRun&) = delete;

  // The next finished episode's JSON, or None once the trial has ended
  // (successfully: then Summary; with an error: raised here).
  std::optional<std::string> NextEpisode() {
    std::optional<py::error_already_set> interrupted;
    {
      py::gil_scoped_release release;
      std::unique_lock<std::mutex> lock(mutex_);
      while (episodes_.empty() && !finished_) {
        changed_.wait_for(lock, std::chrono::milliseconds(100));
        if (!episodes_.empty() || finished_ || interrupted) continue;
        lock.unlock();
        {
          py::gil_scoped_acquire acquire;
          if (PyErr_CheckSignals() != 0) {
            interrupted.emplace();  // takes the pending KeyboardInterrupt
            cancel_ = true;         // the trial stops at its next poll
          }
        }
        lock.lock();
      }
      if (interrupted) {
        changed_.wait(lock, [this] { return finished_; });
      } else if (!episodes_.empty()) {
        std::string next = std::move(episodes_.front());
        episodes_.pop_front();
        return next;
      }
    }
    if (thread_.joinable()) {
      py::gil_scoped_release release;
      thread_.join();
    }
    if (interrupted) throw *interrupted;
    if (!status_.ok()) {
      if (absl::IsInvalidArgument(status_)) throw py::value_error(status_.ToString());
      throw std::runtime_error("trial failed: " + status_.ToString());
    }
    return std::nullopt;
  }

  // After the last episode: success, final_eval_cost, threshold,
  // held_fraction and the options used (as `totalgrad trial --json`'s last
  // line, without "done" and "threads").
  std::string Summary() const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!finished_ || !status_.ok()) throw std::runtime_error("the trial has not completed");
    return io::TrialSummaryJson(summary_, options_).dump();
  }

  // TrialObserver (the trial's thread).
  void OnEpisode(const learner::EpisodeResult& result) override {
    std::string json = io::EpisodeToJson(result).dump();
    std::lock_guard<std::mutex> lock(mutex_);
    episodes_.push_back(std::move(json));
    changed_.notify_all();
  }
  bool ShouldCancel() override { return cancel_; }

 private:
  void Run() {
    SetBlasThreads(1);  // a trial is single-threaded by contract (determinism)
    absl::StatusOr<learner::TrialSummary> summary = learner::RunTrial(options_, this, run_);
    std::lock_guard<std::mutex> lock(mutex_);
    if (summary.ok()) {
      summary_ = *std::move(summary);
    } else {
      status_ = summary.status();
    }
    finished_ = true;
    changed_.notify_all();
  }

  const learner::TrialOptions options_;
  learner::RunOptions run_;
  std::atomic<bool> cancel_{false};
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::string> episodes_;  // guarded by mutex_
  bool finished_ = false;             // guarded by mutex_
  absl::Status status_;               // guarded by mutex_
  learner::TrialSummary summary_;     // guarded by mutex_
  std::thread thread_;                // last: starts after the members above exist
};

// `totalgrad simulate --json` for Python: the same parser and integrator.
std::string SimulateJson(const std::string& scene, const std::string& start,
                         const std::string& forces, const std::string& dt) {
  absl::StatusOr<cli::SimulateRequest> request =
      cli::ParseSimulateRequest(scene, start, forces, dt);
  if (!request.ok()) throw py::value_error(std::string(request.status().message()));
  cli::SimulateResult result;
  absl::Status run;
  {
    py::gil_scoped_release release;
    run = cli::RunSimulation(*request, &result);
  }
  if (!run.ok()) throw std::runtime_error(run.ToString());
  return cli::FormatSimulationJson(result);
}

}  // namespace

void AddTrialBindings(py::module_& module) {
  py::class_<TrialRun>(module, "_TrialRun")
      .def(py::init<const OptionPairs&, int>(), py::arg("options"), py::arg("threads") = 1)
      .def("next_episode", &TrialRun::NextEpisode)
      .def("summary", &TrialRun::Summary);
  module.def("_scenes_json", [] { return cli::ScenesToJson(tasks::SceneCatalog()).dump(); });
  module.def("_trial_options", [] { return learner::TrialOptionPairs(learner::TrialOptions()); },
             "every trial option as (key, default text), in the option table's order");
  module.def("_simulate_json", &SimulateJson, py::arg("scene"), py::arg("start"),
             py::arg("forces"), py::arg("dt"));
  module.def("_method_colour", &results::MethodColour, py::arg("method"),
             "the method's plot colour (results/plot_style.h)");
  module.def("_blas", [] {
    return py::make_tuple(BlasCoreName(), WantedBlasCore(std::getenv("TOTALGRAD_BLAS_CORE")));
  }, "(the OpenBLAS kernels loaded, the kernels the totalgrad binaries would choose or '')");
}

}  // namespace totalgrad::python
