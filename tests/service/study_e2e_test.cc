// Study jobs end to end (issue 6): a sweep with a [[study]] runs through the
// real coordinator and worker binaries; the study rows stored in SQLite equal
// an in-process core study run of the same spec (same seed, same numbers;
// timing columns excepted). A study that fails on the worker is a job
// failure with its message, and `totalgrad run` / `totalgrad results study`
// handle study sweeps.
#include <signal.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "io/study_file.h"
#include "core/common/blas.h"
#include "core/study/study.h"
#include "tests/service/e2e_util.h"
#include "tests/service/service_testutil.h"

namespace totalgrad::testing {
namespace study_e2e_test {

using std::chrono::seconds;

// A study of a few seconds at most: tiny synthetic problem, three
// estimators (one Gaussian, PILCO without particles), two horizons; budgets
// so large no cell or reference is cut short by time (which would make the
// numbers depend on the machine's speed).
constexpr char kTinyStudy[] =
    R"({"problem": {"synthetic": {"data": 40, "horizon": 6, "basis_functions": 8, "seed": 3}},
        "estimators": ["RP", "LR", "TP", "PILCO"], "particles": [8, 16], "horizons": [3, 6],
        "replicates": 3, "seed": 11, "cell_budget_seconds": 600, "ess_replicates": 1,
        "reference": {"particles": 24, "replicates": 3, "budget_seconds": 600}})";

bool Same(double a, double b) { return (std::isnan(a) && std::isnan(b)) || a == b; }

class StudyEndToEndTest : public ServiceFixture {
 protected:
  v1::ListStudyRowsResponse StudyRows(const std::string& sweep, bool all_attempts = false) {
    v1::ListStudyRowsRequest request;
    request.set_sweep_name(sweep);
    request.set_all_attempts(all_attempts);
    v1::ListStudyRowsResponse response;
    const grpc::Status status = control_->ListStudyRows(Context(kUserToken).get(), request, &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return response;
  }
};

TEST_F(StudyEndToEndTest, StudyRowsInSqliteEqualALocalCoreRun) {
  StartCoordinator();
  auto worker = StartWorker("a");
  // A mixed sweep: one tiny trial and one study.
  v1::SweepSpec spec = MakeSpec("study-e2e", {1}, TinyProtocol());
  const std::string study_json = nlohmann::json::parse(kTinyStudy).dump();
  auto* entry = spec.add_studies();
  entry->set_name("tiny");
  entry->set_spec_json(study_json);
  entry->set_source("inline");
  v1::SubmitSweepResponse submitted;
  const grpc::Status status = Submit(spec, &submitted);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(submitted.sweep().jobs_total(), 2);
  ASSERT_TRUE(WaitFinished("study-e2e", seconds(120))) << worker->Log();
  const v1::SweepInfo sweep = Sweep("study-e2e");
  ASSERT_EQ(sweep.jobs_completed(), 2) << worker->Log();
  const std::vector<v1::JobInfo> jobs = Jobs("study-e2e");
  ASSERT_EQ(jobs.size(), 2u);
  EXPECT_EQ(jobs[0].kind(), v1::JOB_KIND_TRIAL);
  EXPECT_EQ(jobs[1].kind(), v1::JOB_KIND_STUDY);
  EXPECT_EQ(jobs[1].method(), "study");
  EXPECT_EQ(jobs[1].variant(), "tiny");
  EXPECT_EQ(jobs[1].seed(), "11");
  // The trial is unaffected by the study next to it.
  ExpectRowsEqualReference("study-e2e", TinyProtocol());

  // The same study in this process.
  absl::StatusOr<io::StudySpec> local_spec =
      io::ParseStudySpec(nlohmann::json::parse(study_json), "");
  ASSERT_TRUE(local_spec.ok()) << local_spec.status();
  auto problem = io::LoadStudyProblem(*local_spec);
  ASSERT_TRUE(problem.ok()) << problem.status();
  SetBlasThreads(1);
  absl::StatusOr<study::StudyResult> local = study::RunStudy(**problem, local_spec->options);
  ASSERT_TRUE(local.ok()) << local.status();

  const v1::ListStudyRowsResponse rows = StudyRows("study-e2e");
  ASSERT_EQ(rows.cells_size(), static_cast<int>(local->cells.size()));
  ASSERT_EQ(rows.references_size(), static_cast<int>(local->references.size()));
  for (int i = 0; i < rows.cells_size(); ++i) {
    const v1::StudyCellRow& s = rows.cells(i);
    const study::CellResult& l = local->cells[i];
    SCOPED_TRACE(absl::StrCat("cell ", i, ": ", l.estimator, " P=", l.particles, " H=", l.horizon));
    EXPECT_EQ(s.job_id(), jobs[1].job_id());
    EXPECT_EQ(s.attempt(), 1);
    EXPECT_EQ(s.study(), "tiny");
    EXPECT_EQ(s.index(), i);
    EXPECT_EQ(s.estimator(), l.estimator);
    EXPECT_EQ(s.method(), l.method);
    EXPECT_EQ(s.particles(), l.particles);
    EXPECT_EQ(s.horizon(), l.horizon);
    EXPECT_EQ(s.replicates(), l.replicates);
    EXPECT_EQ(s.nonfinite(), l.nonfinite);
    EXPECT_EQ(s.errors(), l.errors);
    EXPECT_EQ(s.budget_hit(), l.budget_hit);
    EXPECT_FALSE(l.budget_hit);  // else the comparison would depend on speed
    EXPECT_EQ(s.omitted(), l.omitted);
    EXPECT_EQ(s.omission_reason(), l.omission_reason);
    EXPECT_EQ(s.error(), l.error);
    EXPECT_EQ(s.reference_agrees(), l.reference_agrees);
    EXPECT_EQ(s.note(), study::CellNote(l));
    for (auto [stored, expected, name] :
         {std::tuple{s.rel_rmse(), l.rel_rmse, "rel_rmse"},
          std::tuple{s.rel_bias(), l.rel_bias, "rel_bias"},
          std::tuple{s.rel_bias_noise(), l.rel_bias_noise, "rel_bias_noise"},
          std::tuple{s.total_variance(), l.total_variance, "total_variance"},
          std::tuple{s.cos_mean(), l.cos_mean, "cos_mean"},
          std::tuple{s.objective_mean(), l.objective_mean, "objective_mean"},
          std::tuple{s.ess_mean(), l.ess_mean, "ess_mean"},
          std::tuple{s.ess_min(), l.ess_min, "ess_min"},
          std::tuple{s.k_lr_mean(), l.k_lr_mean, "k_lr_mean"}}) {
      EXPECT_TRUE(Same(stored, expected)) << name << ": stored " << stored << ", local " << expected;
    }
    ASSERT_EQ(s.k_lr_per_step_size(), static_cast<int>(l.k_lr_per_step.size()));
    for (int k = 0; k < s.k_lr_per_step_size(); ++k) {
      EXPECT_TRUE(Same(s.k_lr_per_step(k), l.k_lr_per_step[k])) << "k_lr_per_step " << k;
    }
    // Timings differ between runs; they must be there for every cell that ran.
    if (!l.omitted) {
      EXPECT_GT(s.time_min_s(), 0);
      EXPECT_GE(s.time_median_s(), s.time_min_s());
    }
  }
  for (int i = 0; i < rows.references_size(); ++i) {
    const v1::StudyReferenceRow& s = rows.references(i);
    const study::ReferenceGradient& l = local->references[i];
    SCOPED_TRACE(absl::StrCat("reference H=", l.horizon));
    EXPECT_EQ(s.horizon(), l.horizon);
    EXPECT_TRUE(Same(s.norm(), l.norm));
    EXPECT_TRUE(Same(s.relative_error(), l.relative_error));
    EXPECT_TRUE(Same(s.floor(), l.floor));
    EXPECT_TRUE(Same(s.objective(), l.objective));
    EXPECT_TRUE(Same(s.agreement_max_z(), l.agreement_max_z));
    EXPECT_TRUE(Same(s.agreement_mean_z2(), l.agreement_mean_z2));
    EXPECT_EQ(s.agree(), l.agree);
    EXPECT_EQ(s.note(), l.note);
    EXPECT_EQ(std::vector<std::string>(s.used().begin(), s.used().end()), l.used);
    EXPECT_EQ(std::vector<int>(s.replicates().begin(), s.replicates().end()), l.replicates);
    ASSERT_EQ(s.gradient_size(), l.gradient.size());
    ASSERT_EQ(s.standard_error_size(), l.standard_error.size());
    for (int k = 0; k < s.gradient_size(); ++k) {
      EXPECT_TRUE(Same(s.gradient(k), l.gradient(k))) << k;
      EXPECT_TRUE(Same(s.standard_error(k), l.standard_error(k))) << k;
    }
  }
  // The cells' floors are their horizon's reference floor.
  for (const auto& c : rows.cells()) {
    for (const auto& r : rows.references()) {
      if (r.horizon() == c.horizon()) {
        EXPECT_EQ(c.reference_floor(), r.floor());
      }
    }
  }
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(seconds(20)), 0) << worker->Log();
}

// A study the coordinator accepts but the worker cannot run (the inlined
// snapshot has no snapshot of the requested episode): a job failure carrying
// the message, stored; the worker carries on with the next job.
TEST_F(StudyEndToEndTest, AStudyThatFailsOnTheWorkerIsAStoredJobFailure) {
  StartCoordinator();
  auto worker = StartWorker("a");
  const std::string text =
      ReadFile(std::string(TOTALGRAD_SOURCE_DIR) + "/docs/error-vs-time/swingup_tp_seed1.json");
  nlohmann::json snapshot = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  ASSERT_TRUE(snapshot.is_object()) << text.size();
  ASSERT_TRUE(snapshot["snapshots"].is_array() && !snapshot["snapshots"].empty());
  const nlohmann::json first = snapshot["snapshots"][0];
  snapshot["snapshots"] = nlohmann::json::array();
  snapshot["snapshots"].push_back(first);
  const int present = first["episode"].get<int>();
  nlohmann::json study = nlohmann::json::parse(kTinyStudy);
  study["problem"] = {{"snapshot", snapshot}, {"episode", 99}};
  v1::SweepSpec spec;
  spec.set_name("study-fail");
  spec.set_max_attempts(2);
  auto* bad = spec.add_studies();
  bad->set_name("missing-episode");
  bad->set_spec_json(study.dump());
  auto* good = spec.add_studies();
  good->set_name("fine");
  good->set_spec_json(nlohmann::json::parse(kTinyStudy).dump());
  const grpc::Status status = Submit(spec);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_TRUE(WaitFinished("study-fail", seconds(120))) << worker->Log();
  const std::vector<v1::JobInfo> jobs = Jobs("study-fail");
  ASSERT_EQ(jobs.size(), 2u);
  EXPECT_EQ(jobs[0].state(), v1::JOB_STATE_FAILED);
  EXPECT_EQ(jobs[0].failures(), 2);
  EXPECT_NE(jobs[0].last_error().find("no snapshot of episode 99"), std::string::npos)
      << jobs[0].last_error();
  EXPECT_NE(jobs[0].last_error().find(absl::StrCat("it has ", present)), std::string::npos)
      << jobs[0].last_error();
  const v1::GetJobLogResponse log = JobLog(jobs[0].job_id());
  ASSERT_EQ(log.attempts_size(), 2);
  EXPECT_EQ(log.attempts(0).state(), v1::ATTEMPT_STATE_FAILED);
  EXPECT_NE(log.attempts(0).error().find("episode 99"), std::string::npos);
  // The worker did not crash: it ran the next study.
  EXPECT_EQ(jobs[1].state(), v1::JOB_STATE_COMPLETED);
  EXPECT_TRUE(worker->Running());
  EXPECT_GT(StudyRows("study-fail").cells_size(), 0);
  // A failed study stores no rows of its own.
  const v1::ListStudyRowsResponse all = StudyRows("study-fail", /*all_attempts=*/true);
  for (const auto& c : all.cells()) EXPECT_EQ(c.study(), "fine");
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(seconds(20)), 0) << worker->Log();
}

// The coordinator re-checks what it receives: a study naming a snapshot file
// (which it cannot read) is refused with the entry named, and nothing is stored.
TEST_F(StudyEndToEndTest, TheCoordinatorRefusesAStudyThatIsNotSelfContained) {
  StartCoordinator();
  v1::SweepSpec spec;
  spec.set_name("study-path");
  auto* entry = spec.add_studies();
  entry->set_name("path");
  entry->set_spec_json(R"({"problem": {"snapshot": "snap.json"}})");
  const grpc::Status status = Submit(spec);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("study[0] 'path': problem.snapshot"), std::string::npos)
      << status.error_message();
  v1::ListSweepsResponse sweeps;
  ASSERT_TRUE(control_->ListSweeps(Context(kUserToken).get(), {}, &sweeps).ok());
  EXPECT_EQ(sweeps.sweeps_size(), 0);
}

// `totalgrad run` on the shipped study sweep: everything starts, the study
// rows are printed, everything stops; `results study` exports them as CSV
// with table.csv's columns.
TEST_F(StudyEndToEndTest, RunAndResultsStudyWithTheShippedStudySweep) {
  const std::string path = std::string(TOTALGRAD_SOURCE_DIR) + "/deploy/sweeps/study-demo.toml";
  const std::string run_dir = dir_ + "/run";
  std::string out, err;
  ASSERT_EQ(RunCommand({TOTALGRAD_CLI_BIN, "run", path, "--workers", "2", "--dir", run_dir},
                       &out, &err),
            0)
      << out << err;
  EXPECT_NE(out.find("reference gradients"), std::string::npos) << out;
  EXPECT_NE(out.find("synthetic-h10"), std::string::npos) << out;
  EXPECT_NE(out.find("swingup-ep3"), std::string::npos) << out;
  EXPECT_NE(out.find("PILCO"), std::string::npos) << out;
  EXPECT_FALSE(std::filesystem::exists(run_dir + "/study-demo.db-wal"));
  // The database holds the rows: a coordinator on it answers `results study`.
  std::filesystem::copy_file(run_dir + "/study-demo.db", db_);
  StartCoordinator();
  ASSERT_EQ(RunCommand({TOTALGRAD_CLI_BIN, "results", "study", "study-demo", "-f", "csv",
                        "--coordinator", absl::StrCat("127.0.0.1:", port_), "--insecure",
                        "--token-file", dir_ + "/user.token"},
                       &out, &err),
            0)
      << err;
  EXPECT_EQ(out.rfind("study,job_id,attempt,index,estimator,method,particles,horizon,replicates,"
                      "nonfinite,errors,time_min_s,time_median_s,rel_rmse,rel_bias,"
                      "rel_bias_noise,total_variance,cos_mean,objective_mean,ess_mean,ess_min,"
                      "k_lr_mean,reference_agrees,reference_floor,budget_hit,omitted,note\n",
                      0),
            0u)
      << out;
  // synthetic: 3 particle methods x 2 P x 2 H + PILCO x 2 H; swing-up: 2 x 1 x 1 + 1.
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1 + 14 + 3) << out;
  ASSERT_EQ(RunCommand({TOTALGRAD_CLI_BIN, "results", "study", "study-demo", "--references", "-f",
                        "json", "--coordinator", absl::StrCat("127.0.0.1:", port_), "--insecure",
                        "--token-file", dir_ + "/user.token"},
                       &out, &err),
            0)
      << err;
  const nlohmann::json refs = nlohmann::json::parse(out, nullptr, false);
  ASSERT_TRUE(refs.is_array()) << out;
  EXPECT_EQ(refs.size(), 3u);  // H = 5, 10 and H = 5
  EXPECT_TRUE(refs[0]["norm"].is_number()) << out;
  // Issue 29: `results study --plot DIR` draws each study as `totalgrad
  // study` does, from the stored rows: PNG and PDF, points labelled with P.
  const std::string plots = dir_ + "/plots";
  ASSERT_EQ(RunCommand({TOTALGRAD_CLI_BIN, "results", "study", "study-demo", "--plot", plots,
                        "--coordinator", absl::StrCat("127.0.0.1:", port_), "--insecure",
                        "--token-file", dir_ + "/user.token"},
                       &out, &err),
            0)
      << err;
  for (const char* study : {"synthetic-h10", "swingup-ep3"}) {
    for (const char* file : {"work_precision.png", "work_precision.pdf", "horizon_sweep.png",
                             "horizon_sweep.pdf"}) {
      const std::string path = absl::StrCat(plots, "/", study, "/", file);
      ASSERT_TRUE(std::filesystem::exists(path)) << path << "\n" << err;
      EXPECT_GT(std::filesystem::file_size(path), 1000u) << path;
    }
  }
  // The synthetic study's data: RP at P = 10 and 30.
  const std::string wp = ReadFile(plots + "/synthetic-h10/wp_0.dat");
  EXPECT_NE(wp.find("\n10 "), std::string::npos) << wp;
  EXPECT_NE(wp.find("\n30 "), std::string::npos) << wp;
  EXPECT_NE(ReadFile(plots + "/synthetic-h10/work_precision.gp").find("with labels"),
            std::string::npos);
}

}  // namespace study_e2e_test
}  // namespace totalgrad::testing
