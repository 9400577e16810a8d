// Job kinds as data (server/storage/job_kinds.h): each kind's result tables,
// its completion rule and its refusals, then the store's one completion path
// over a real SQLite file. The tables each kind must check are written out
// here, not read from the descriptor, so a table dropped from a kind (or a
// completion that skipped one) fails these tests.
#include "server/storage/job_kinds.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "server/storage/sqlite_store.h"
#include "tests/service/service_testutil.h"
#include "tests/service/store_fixture.h"

namespace totalgrad::storage {
namespace job_kinds_test {

using ::totalgrad::testing::MakeEpisode;
using ::totalgrad::testing::MakeStudyJob;
using ::totalgrad::testing::MakeSweep;
using ::totalgrad::testing::MakeWorker;

constexpr int64_t kNow = 1'000'000;

std::vector<std::string> TableNames(const JobKindInfo& kind) {
  std::vector<std::string> names;
  for (const ResultTable* table : kind.tables) names.emplace_back(table->name);
  return names;
}

bool Contains(const absl::Status& status, const std::string& text) {
  return status.message().find(text) != absl::string_view::npos;
}

TEST(JobKindsTest, EveryKindHasOneRowAndEveryTableOneOwner) {
  ASSERT_EQ(JobKinds().size(), 2u);
  for (JobKind kind : {JobKind::kTrial, JobKind::kStudy}) {
    const JobKindInfo& info = KindInfo(kind);
    EXPECT_EQ(info.kind, kind);
    EXPECT_EQ(ParseJobKind(info.name), kind);
    EXPECT_EQ(ToString(kind), info.name);
    EXPECT_FALSE(info.tables.empty()) << info.name;
  }
  EXPECT_EQ(ParseJobKind("sweep"), std::nullopt);
  ASSERT_EQ(ResultTables().size(), 3u);
  for (const ResultTable& table : ResultTables()) {
    int owners = 0;
    for (const JobKindInfo& kind : JobKinds()) owners += Owns(kind, table) ? 1 : 0;
    EXPECT_EQ(owners, 1) << table.name;
    EXPECT_TRUE(Owns(OwnerOf(table), table)) << table.name;
  }
}

TEST(JobKindsTest, TrialOwnsEpisodesCompletesWithItsOwnCountAndHasAVerdict) {
  const JobKindInfo& trial = KindInfo(JobKind::kTrial);
  EXPECT_EQ(trial.name, "trial");
  EXPECT_EQ(TableNames(trial), (std::vector<std::string>{"episodes"}));
  EXPECT_EQ(trial.tables[0]->index_column, "episode");
  EXPECT_EQ(trial.rule, CompletionRule::kJobExpected);
  EXPECT_TRUE(trial.checkpoints);
  EXPECT_TRUE(trial.reports_verdict);

  const LeaseKey key{4, 1};
  absl::StatusOr<ResultTotals> required = RequiredRows(trial, key, 3, {.episodes = 3});
  ASSERT_TRUE(required.ok()) << required.status();
  EXPECT_EQ(*required, (ResultTotals{.episodes = 3}));
  // The job's count decides, never the worker's: fewer or more are refused.
  for (int reported : {0, 2, 4}) {
    const absl::Status wrong = RequiredRows(trial, key, 3, {.episodes = reported}).status();
    EXPECT_EQ(wrong.code(), absl::StatusCode::kInvalidArgument) << reported;
    EXPECT_TRUE(Contains(wrong, absl::StrCat("reports ", reported,
                                             " episodes; the job expects 3 (episodes 0..2)")))
        << wrong;
  }
  // A study total in a trial's completion names the kind and the table.
  const absl::Status foreign =
      RequiredRows(trial, key, 3, {.episodes = 3, .study_references = 1}).status();
  EXPECT_EQ(foreign.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(Contains(foreign, "job 4 is a trial job; table study_references belongs to study "
                                "jobs"))
      << foreign;
}

TEST(JobKindsTest, StudyOwnsCellsAndReferencesCompletesWithTheWorkersTotals) {
  const JobKindInfo& study = KindInfo(JobKind::kStudy);
  EXPECT_EQ(study.name, "study");
  EXPECT_EQ(TableNames(study), (std::vector<std::string>{"study_cells", "study_references"}));
  for (const ResultTable* table : study.tables) EXPECT_EQ(table->index_column, "idx");
  EXPECT_EQ(study.rule, CompletionRule::kReported);
  EXPECT_FALSE(study.checkpoints);
  EXPECT_FALSE(study.reports_verdict);

  const LeaseKey key{9, 2};
  absl::StatusOr<ResultTotals> required =
      RequiredRows(study, key, 0, {.study_cells = 1200, .study_references = 3});
  ASSERT_TRUE(required.ok()) << required.status();
  EXPECT_EQ(*required, (ResultTotals{.study_cells = 1200, .study_references = 3}));
  // Each table needs at least one row and at most kMaxRowsPerTable, named.
  struct Case {
    ResultTotals reported;
    std::string named;
  };
  for (const Case& c : {Case{{.study_cells = 0, .study_references = 1}, "0 study_cells rows"},
                        Case{{.study_cells = 3, .study_references = 0}, "0 study_references rows"},
                        Case{{.study_cells = kMaxRowsPerTable + 1, .study_references = 1},
                             absl::StrCat(kMaxRowsPerTable + 1, " study_cells rows")}}) {
    const absl::Status wrong = RequiredRows(study, key, 0, c.reported).status();
    EXPECT_EQ(wrong.code(), absl::StatusCode::kInvalidArgument) << c.named;
    EXPECT_TRUE(Contains(wrong, c.named)) << wrong;
  }
  const absl::Status foreign =
      RequiredRows(study, key, 0, {.episodes = 1, .study_cells = 3, .study_references = 1})
          .status();
  EXPECT_EQ(foreign.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(Contains(foreign, "job 9 is a study job; table episodes belongs to trial jobs"))
      << foreign;
}

TEST(JobKindsTest, RowsOfAnotherKindsTableAreRefusedNamingKindAndTable) {
  JobResults episodes;
  episodes.episodes = {MakeEpisode(0)};
  JobResults cells;
  cells.study.cells.resize(1);
  JobResults references;
  references.study.references.resize(1);
  const JobKindInfo& trial = KindInfo(JobKind::kTrial);
  const JobKindInfo& study = KindInfo(JobKind::kStudy);
  EXPECT_TRUE(CheckOwnedTables(trial, 1, episodes).ok());
  EXPECT_TRUE(CheckOwnedTables(study, 1, cells).ok());
  EXPECT_TRUE(CheckOwnedTables(study, 1, references).ok());
  struct Case {
    const JobKindInfo* kind;
    const JobResults* rows;
    std::string named;
  };
  for (const Case& c :
       {Case{&study, &episodes, "job 1 is a study job; table episodes belongs to trial jobs"},
        Case{&trial, &cells, "job 1 is a trial job; table study_cells belongs to study jobs"},
        Case{&trial, &references,
             "job 1 is a trial job; table study_references belongs to study jobs"}}) {
    const absl::Status refused = CheckOwnedTables(*c.kind, 1, *c.rows);
    EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument) << c.named;
    EXPECT_TRUE(Contains(refused, c.named)) << refused;
  }
  const absl::Status missing = MissingRowsError(*trial.tables[0], {4, 1}, {1, 2}, 4);
  EXPECT_EQ(missing.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(missing.message(), "cannot complete job 4 attempt 1: episodes 1,2 of 0..3 are not stored");
}

// The store's one completion path: for every table of every kind, an attempt
// holding every row but one of that table cannot complete, and the error
// names that table's row. The (kind, table) pairs are listed here, so a
// completion check that skipped a table fails.
class JobKindsStoreTest : public ::totalgrad::testing::FreshStoreTest {
 protected:
  // A sweep with one trial (3 episodes) and one study job, both leased to "w1".
  void CreateAndLeaseBoth(const std::string& name) {
    NewSweep sweep = MakeSweep(name, 1, 3);
    sweep.jobs.push_back(MakeStudyJob());
    bool created = false;
    ASSERT_TRUE(store_->CreateSweep(sweep, kNow, &created).ok());
    auto jobs = store_->ListJobs({name, {}, 0, 1000});
    ASSERT_TRUE(jobs.ok());
    trial_ = jobs->front().id;
    study_ = jobs->back().id;
    TG_ASSERT_OK(store_->StartAttempt({trial_, 1}, MakeWorker("w1"), kNow, kNow + 90'000));
    TG_ASSERT_OK(store_->StartAttempt({study_, 1}, MakeWorker("w1"), kNow, kNow + 90'000));
  }
  AttemptEnd Completion(int64_t job, ResultTotals totals) {
    AttemptEnd end;
    end.key = {job, 1};
    end.worker_id = "w1";
    end.attempt_state = AttemptState::kCompleted;
    end.job_state = JobState::kCompleted;
    end.totals = totals;
    end.success = true;
    end.final_eval_cost = 1;
    end.now_ms = kNow;
    return end;
  }

  int64_t trial_ = 0;
  int64_t study_ = 0;
};

TEST_F(JobKindsStoreTest, EveryTableOfEveryKindIsCheckedAtCompletion) {
  // Full results: 3 episodes for the trial; 2 cells and 2 references for the study.
  JobResults trial_rows;
  for (int e = 0; e < 3; ++e) trial_rows.episodes.push_back(MakeEpisode(e));
  JobResults study_rows;
  study_rows.study.cells.resize(2);
  study_rows.study.references.resize(2);
  for (int i = 0; i < 2; ++i) {
    study_rows.study.cells[i].index = i;
    study_rows.study.cells[i].estimator = study_rows.study.cells[i].method = "RP";
    study_rows.study.references[i].index = i;
  }
  const ResultTotals trial_totals{.episodes = 3};
  const ResultTotals study_totals{.study_cells = 2, .study_references = 2};
  struct Case {
    std::string table;  // the table missing its row 1
    bool study;
    std::string named;
  };
  int sweep = 0;
  for (const Case& c : {Case{"episodes", false, "episodes 1 of 0..2 are not stored"},
                        Case{"study_cells", true, "study_cells rows 1 of 0..1 are not stored"},
                        Case{"study_references", true,
                             "study_references rows 1 of 0..1 are not stored"}}) {
    SCOPED_TRACE(c.table);
    CreateAndLeaseBoth(absl::StrCat("s", ++sweep));
    const int64_t job = c.study ? study_ : trial_;
    JobResults rows = c.study ? study_rows : trial_rows;
    if (c.table == "episodes") rows.episodes.erase(rows.episodes.begin() + 1);
    if (c.table == "study_cells") rows.study.cells.erase(rows.study.cells.begin() + 1);
    if (c.table == "study_references") {
      rows.study.references.erase(rows.study.references.begin() + 1);
    }
    TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", rows, kNow, std::nullopt).status());
    const ResultTotals totals = c.study ? study_totals : trial_totals;
    const absl::StatusOr<EndOutcome> refused = store_->EndAttempt(Completion(job, totals));
    EXPECT_EQ(refused.status().code(), absl::StatusCode::kFailedPrecondition) << refused.status();
    EXPECT_TRUE(Contains(refused.status(), c.named)) << refused.status();
    TG_ASSERT_OK_AND_ASSIGN(JobRecord still, store_->GetJob(job));
    EXPECT_EQ(still.state, JobState::kRunning);
    // The missing row arrives with the completion: it completes.
    AttemptEnd end = Completion(job, totals);
    end.results = c.study ? study_rows : trial_rows;
    TG_ASSERT_OK_AND_ASSIGN(EndOutcome outcome, store_->EndAttempt(end));
    EXPECT_EQ(outcome, EndOutcome::kApplied);
    TG_ASSERT_OK_AND_ASSIGN(JobRecord done, store_->GetJob(job));
    EXPECT_EQ(done.state, JobState::kCompleted);
  }
}

TEST_F(JobKindsStoreTest, RowsAndTotalsOfAnotherKindAreRefusedAndNothingChanges) {
  CreateAndLeaseBoth("s");
  JobResults episodes;
  episodes.episodes = {MakeEpisode(0)};
  JobResults cells;
  cells.study.cells.resize(1);
  const absl::Status to_study =
      store_->StoreResults({study_, 1}, "w1", episodes, kNow, std::nullopt).status();
  EXPECT_EQ(to_study.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(Contains(to_study, "is a study job; table episodes belongs to trial jobs"))
      << to_study;
  const absl::Status to_trial =
      store_->StoreResults({trial_, 1}, "w1", cells, kNow, std::nullopt).status();
  EXPECT_EQ(to_trial.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(Contains(to_trial, "is a trial job; table study_cells belongs to study jobs"))
      << to_trial;
  // A bundle with a valid part and a foreign part stores neither.
  JobResults mixed = episodes;
  mixed.study = cells.study;
  EXPECT_EQ(store_->StoreResults({trial_, 1}, "w1", mixed, kNow, std::nullopt).status().code(),
            absl::StatusCode::kInvalidArgument);
  TG_ASSERT_OK_AND_ASSIGN(ResultTotals stored,
                          store_->StoreResults({trial_, 1}, "w1", {}, kNow, std::nullopt));
  EXPECT_EQ(stored, ResultTotals{});
  // A trial-style completion of the study and a study-style one of the trial.
  const absl::Status study_as_trial =
      store_->EndAttempt(Completion(study_, {.episodes = 3})).status();
  EXPECT_EQ(study_as_trial.code(), absl::StatusCode::kInvalidArgument) << study_as_trial;
  const absl::Status trial_as_study =
      store_->EndAttempt(Completion(trial_, {.study_cells = 1, .study_references = 1})).status();
  EXPECT_EQ(trial_as_study.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(Contains(trial_as_study, "is a trial job; table study_cells belongs to study jobs"))
      << trial_as_study;
  // Checkpoints follow the kind too.
  const absl::Status checkpoint =
      store_->StoreCheckpoint({study_, 1}, "w1", {0, 1, "x"}, kNow);
  EXPECT_EQ(checkpoint.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(Contains(checkpoint, "study jobs keep no checkpoints")) << checkpoint;
  for (int64_t job : {trial_, study_}) {
    TG_ASSERT_OK_AND_ASSIGN(JobRecord record, store_->GetJob(job));
    EXPECT_EQ(record.state, JobState::kRunning);
    EXPECT_EQ(record.episodes_stored, 0);
  }
}

// Issue 28.5: an import checks a completed study job as EndAttempt does:
// each of its tables holds rows 0..n-1 with n >= 1. A study completed with
// cell 1 of 0..2 missing, or without references, is refused naming the job
// and the rows, and nothing of the archive is stored; whole, it is taken over.
TEST_F(JobKindsStoreTest, ImportOfACompletedStudyChecksEveryTableAsCompleteDoes) {
  NewSweep sweep = MakeSweep("moved", 0, 1);
  sweep.jobs.push_back(MakeStudyJob());
  auto archived = [] {
    ImportedJob job;
    job.record.kind = JobKind::kStudy;
    job.record.method = "study";
    job.record.seed = "7";
    job.record.variant = "tiny";
    job.record.state = JobState::kCompleted;
    job.completed_attempt = 2;
    ImportedAttempt& attempt = job.attempts.emplace_back();
    attempt.attempt = 2;
    attempt.state = AttemptState::kCompleted;
    for (int i : {0, 1, 2}) {
      StudyCell& cell = attempt.study.cells.emplace_back();
      cell.index = i;
      cell.estimator = cell.method = "RP";
    }
    attempt.study.references.emplace_back().index = 0;
    return job;
  };
  ImportedJob gap = archived();
  gap.attempts[0].study.cells.erase(gap.attempts[0].study.cells.begin() + 1);
  auto refused = store_->ImportJobs(sweep, "moved", {gap}, "a.json", kNow);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument) << refused.status();
  EXPECT_TRUE(Contains(refused.status(), "archive: job study seed 7 tiny is completed by "
                                         "attempt 2, which lacks study_cells rows 1 of 0..1"))
      << refused.status();
  EXPECT_EQ(store_->GetSweep("moved").status().code(), absl::StatusCode::kNotFound);

  ImportedJob no_references = archived();
  no_references.attempts[0].study.references.clear();
  refused = store_->ImportJobs(sweep, "moved", {no_references}, "a.json", kNow);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument) << refused.status();
  EXPECT_TRUE(Contains(refused.status(), "reports 0 study_references rows")) << refused.status();
  EXPECT_EQ(store_->GetSweep("moved").status().code(), absl::StatusCode::kNotFound);

  TG_ASSERT_OK_AND_ASSIGN(ImportResult result,
                          store_->ImportJobs(sweep, "moved", {archived()}, "a.json", kNow));
  EXPECT_EQ(result.jobs_imported, 1);
  EXPECT_EQ(result.study_rows_imported, 4);
}

}  // namespace job_kinds_test
}  // namespace totalgrad::storage
