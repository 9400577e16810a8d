// The worker's study runner (worker/study_runner.h) on the scenes beyond the
// cart-pole: a study job's self-contained spec on a synthetic pendulum or
// pendubot problem runs to rows, PILCO's row says why it is omitted where the
// scene has two angles, and a two-control scene fails naming the controls.
#include "worker/study_runner.h"

#include <gtest/gtest.h>

#include <string>

namespace totalgrad::worker {
namespace {

std::string TinySpec(const std::string& scene) {
  return R"({"problem": {"synthetic": {"scene": ")" + scene +
         R"(", "data": 30}}, "estimators": ["RP", "PILCO"], "particles": [5],
             "horizons": [3], "replicates": 2, "reference": {"replicates": 4, "particles": 20}})";
}

TEST(CoreStudyRunner, RunsStudyJobsOnEveryScene) {
  CoreStudyRunner runner;
  for (const std::string scene : {"pendulum", "pendubot", "double-pendulum"}) {
    JobInput job;
    job.spec_json = TinySpec(scene);
    absl::StatusOr<JobOutcome> outcome = runner.Run(job, nullptr);
    ASSERT_TRUE(outcome.ok()) << scene << ": " << outcome.status();
    ASSERT_EQ(outcome->study_references.size(), 1u) << scene;
    ASSERT_EQ(outcome->study_cells.size(), 2u) << scene;  // RP at P = 5, PILCO
    EXPECT_FALSE(outcome->study_cells[0].omitted)
        << scene << ": " << study::CellNote(outcome->study_cells[0]);
    EXPECT_EQ(outcome->study_cells[1].method, "PILCO");
    EXPECT_FALSE(outcome->study_cells[1].omitted)
        << scene << ": " << study::CellNote(outcome->study_cells[1]);
    EXPECT_EQ(outcome->episodes, 0) << scene;
  }
}

}  // namespace
}  // namespace totalgrad::worker
