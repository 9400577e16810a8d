// One description per record (issue 13): every record with a field table
// (core/common/record.h) goes through every path that copies it, with every
// field set to a non-default value, and comes out equal, bit for bit:
//   core struct -> proto (the worker) -> store row (the coordinator, SQLite)
//   -> proto (ListStudyRows) -> core struct (the CLI) -> CSV and JSON
//   (`totalgrad results study`, `totalgrad study`'s table.csv, results.json).
// The values are set by walking the table, so a field added to a table is
// covered without touching this file; the comparison walks the table too,
// and a comparison that cannot see a dropped field is itself a failure here
// (RecordsTest.TheComparisonSeesEveryField). The table/proto/SQL agreement
// (names and types) and the migration of stored rows are checked as well,
// and so is the sweep archive: every record written and read back
// (RecordsArchive.*), and the archives of older versions still read.
#include <gtest/gtest.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <type_traits>

#include "absl/strings/str_cat.h"
#include "client/core_commands/study_format.h"
#include "core/learner/episode_record.h"
#include "core/learner/trial.h"
#include "core/learner/trial_options.h"
#include "core/study/study.h"
#include "io/episode_json.h"
#include "io/record_format.h"
#include "io/study_results.h"
#include "runtime/record_proto.h"
#include "server/service/convert.h"
#include "server/service/options_as_run.h"
#include "server/service/sweep_archive.h"
#include "server/storage/sqlite_db.h"
#include "server/storage/sqlite_records.h"
#include "server/storage/sqlite_schema.h"
#include "server/storage/sqlite_store.h"
#include "server/storage/service_records.h"
#include "tests/service/schema_downgrade.h"
#include "tests/service/service_testutil.h"
#include "worker/job_runner.h"
#include "totalgrad/v1/types.pb.h"

#include <google/protobuf/util/json_util.h>

namespace totalgrad::testing {
namespace {

using record::FieldTable;
using record::FieldType;

constexpr int64_t kNow = 1'700'000'000'000;

// Sets every (non-derived) field of *r to a value that no default has:
// integers 1000 + position, doubles (position + 1) / 7 (not exact in
// decimal, so a format that rounds shows), bools flipped, texts holding a
// comma and a quote (CSV quoting), lists of two or three such values.
template <typename R>
void SetEveryField(const FieldTable<R>& table, R* r) {
  for (size_t i = 0; i < table.size(); ++i) {
    const auto& field = table[i];
    const int n = static_cast<int>(i);
    const double x = (n + 1) / 7.0;
    const std::string text = absl::StrCat("value of ", field.name, ", \"quoted\"");
    switch (field.type()) {
      case FieldType::kInt: field.template Get<int>(*r) = 1000 + n; break;
      // Beyond 32 bits, so a path that narrows shows.
      case FieldType::kInt64: field.template Get<int64_t>(*r) = 5'000'000'000 + n; break;
      case FieldType::kEnum: {
        // The first of these names the enum has, that is not its default:
        // a table cannot list an enum's names, so the test knows a few.
        const std::string before = field.EnumToText(*r);
        bool set = false;
        for (const char* name : {"cancelled", "study", "lease_lost", "paused", "completed"}) {
          if (name != before && field.ParseEnum(name, r)) {
            set = true;
            break;
          }
        }
        EXPECT_TRUE(set) << field.name << ": no known non-default name; add one above";
        break;
      }
      case FieldType::kDerivedBool: break;
      case FieldType::kDouble: field.template Get<double>(*r) = x; break;
      case FieldType::kBool: field.template Get<bool>(*r) = !field.template Get<bool>(*r); break;
      case FieldType::kText: field.template Get<std::string>(*r) = text; break;
      case FieldType::kInts: field.template Get<std::vector<int>>(*r) = {n, -n - 1, 7}; break;
      case FieldType::kTexts:
        field.template Get<std::vector<std::string>>(*r) = {text, absl::StrCat(field.name, "-b")};
        break;
      case FieldType::kDoubles:
      case FieldType::kVector: record::SetDoubles(field, {x, -x / 3, 1e-300 * x}, r); break;
      case FieldType::kTextPairs:
        // Out of key order, and a key repeated: a path that sorts or
        // de-duplicates shows.
        field.template Get<record::TextPairs>(*r) = {
            {"zeta", text}, {"alpha", "1"}, {"zeta", "again"}};
        break;
      case FieldType::kDerivedText: break;
    }
  }
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

bool SameDoubles(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size()) return false;
  for (size_t k = 0; k < a.size(); ++k) {
    if (!SameBits(a[k], b[k])) return false;
  }
  return true;
}

// The names of the fields (derived ones included) whose values differ;
// doubles compare bit for bit.
template <typename R>
std::vector<std::string> DifferingFields(const FieldTable<R>& table, const R& a, const R& b) {
  std::vector<std::string> names;
  for (const auto& field : table) {
    bool same = true;
    switch (field.type()) {
      case FieldType::kInt: same = field.template Get<int>(a) == field.template Get<int>(b); break;
      case FieldType::kInt64:
        same = field.template Get<int64_t>(a) == field.template Get<int64_t>(b);
        break;
      case FieldType::kEnum: same = field.EnumToText(a) == field.EnumToText(b); break;
      case FieldType::kDerivedBool: same = field.DeriveBool(a) == field.DeriveBool(b); break;
      case FieldType::kDouble:
        same = SameBits(field.template Get<double>(a), field.template Get<double>(b));
        break;
      case FieldType::kBool: same = field.template Get<bool>(a) == field.template Get<bool>(b); break;
      case FieldType::kText:
        same = field.template Get<std::string>(a) == field.template Get<std::string>(b);
        break;
      case FieldType::kDerivedText: same = field.Derive(a) == field.Derive(b); break;
      case FieldType::kInts:
        same = field.template Get<std::vector<int>>(a) == field.template Get<std::vector<int>>(b);
        break;
      case FieldType::kTexts:
        same = field.template Get<std::vector<std::string>>(a) ==
               field.template Get<std::vector<std::string>>(b);
        break;
      case FieldType::kDoubles:
      case FieldType::kVector:
        same = SameDoubles(record::DoublesOf(field, a), record::DoublesOf(field, b));
        break;
      case FieldType::kTextPairs:
        same = field.template Get<record::TextPairs>(a) == field.template Get<record::TextPairs>(b);
        break;
    }
    if (!same) names.push_back(field.name);
  }
  return names;
}

template <typename R>
std::vector<std::string> Names(const FieldTable<R>& table) {
  std::vector<std::string> names;
  for (const auto& field : table) names.push_back(field.name);
  return names;
}

// Every CSV cell of a double field reads back to the same bits (the
// record's one number format is a round trip).
template <typename R>
void ExpectCsvNumbersRoundTrip(const FieldTable<R>& table, const R& r) {
  for (const auto& field : table) {
    if (!field.csv || field.type() != FieldType::kDouble) continue;
    const std::string text = io::RecordFieldText(field, r);
    double back = 0;
    const auto parsed = std::from_chars(text.data(), text.data() + text.size(), back);
    EXPECT_TRUE(parsed.ec == std::errc() && parsed.ptr == text.data() + text.size()) << text;
    EXPECT_TRUE(SameBits(back, field.template Get<double>(r))) << field.name << ": " << text;
  }
}

TEST(RecordTables, NamesAreUniqueAndEveryFieldHasItsProtoField) {
  for (const auto& names : {Names(study::CellFields()), Names(study::ReferenceFields()),
                            Names(learner::EpisodeFields())}) {
    EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size());
  }
  EXPECT_EQ(record_proto::RecordProtoMismatch(study::CellFields(),
                                              *v1::StudyCellRow::descriptor()),
            "");
  EXPECT_EQ(record_proto::RecordProtoMismatch(study::ReferenceFields(),
                                              *v1::StudyReferenceRow::descriptor()),
            "");
  EXPECT_EQ(record_proto::RecordProtoMismatch(learner::EpisodeFields(),
                                              *v1::EpisodeReport::descriptor()),
            "");
  EXPECT_EQ(record_proto::RecordProtoMismatch(results::CompletedTrialResultFields(),
                                              *v1::TrialResult::descriptor()),
            "");
  // The check has power: a field the message lacks, and one of another type.
  const FieldTable<study::CellResult> missing = {{"no_such_field", &study::CellResult::ess_min}};
  EXPECT_NE(record_proto::RecordProtoMismatch(missing, *v1::StudyCellRow::descriptor()), "");
  const FieldTable<study::CellResult> mistyped = {{"estimator", &study::CellResult::ess_min}};
  EXPECT_NE(record_proto::RecordProtoMismatch(mistyped, *v1::StudyCellRow::descriptor()), "");
}

TEST(RecordTables, EveryFieldIsSetToANonDefaultValue) {
  study::CellResult cell;
  SetEveryField(study::CellFields(), &cell);
  EXPECT_EQ(DifferingFields(study::CellFields(), study::CellResult{}, cell),
            Names(study::CellFields()));
  study::ReferenceGradient ref;
  SetEveryField(study::ReferenceFields(), &ref);
  EXPECT_EQ(DifferingFields(study::ReferenceFields(), study::ReferenceGradient{}, ref),
            Names(study::ReferenceFields()));
  learner::EpisodeSummary episode;
  SetEveryField(learner::EpisodeFields(), &episode);
  EXPECT_EQ(DifferingFields(learner::EpisodeFields(), learner::EpisodeSummary{}, episode),
            Names(learner::EpisodeFields()));
}

// The comparison used below reports a field whose value was lost on a path
// (put back to its default), and that field only (and the note, which is
// derived from the flags and texts it shows).
TEST(RecordTables, TheComparisonSeesEveryField) {
  study::CellResult full;
  SetEveryField(study::CellFields(), &full);
  for (const auto& field : study::CellFields()) {
    if (field.derived()) continue;
    study::CellResult dropped = full;
    study::CellResult defaults;
    // Copy the default of this one field over the full value.
    const FieldTable<study::CellResult> one = {field};
    nlohmann::ordered_json j = io::RecordToJson(one, defaults);
    ASSERT_TRUE(io::RecordFromJson(one, j, "", &dropped).ok());
    std::vector<std::string> differing = DifferingFields(study::CellFields(), full, dropped);
    differing.erase(std::remove(differing.begin(), differing.end(), "note"), differing.end());
    EXPECT_EQ(differing, std::vector<std::string>{field.name});
  }
}

// A job and a sweep summary (server/storage/service_records.h) through
// every path that copies them: the coordinator's proto (ToProto) and the
// CLI's way back (FromProto), then the CLI's and the dashboard's JSON and
// the CLI's CSV (io/record_format.h), every field set by walking the table.
template <typename R, typename Message>
void ExpectServiceRecordThroughEveryPath(const FieldTable<R>& table, const R& full) {
  ASSERT_EQ(record_proto::RecordProtoMismatch(table, *Message::descriptor()), "");
  ASSERT_EQ(DifferingFields(table, R{}, full), Names(table));
  Message message;
  service::ToProto(full, &message);
  const R back = service::FromProto(message);
  EXPECT_EQ(DifferingFields(table, full, back), std::vector<std::string>{}) << "proto";

  R from_json;
  TG_ASSERT_OK(io::RecordFromJson(table, io::RecordToJson(table, back), "job: ", &from_json));
  EXPECT_EQ(DifferingFields(table, full, from_json), std::vector<std::string>{}) << "JSON";

  // CSV: every csv field has its column, and its cell is the full record's
  // value, which is not the default's (a dropped field would be).
  const std::vector<std::string> columns = io::RecordCsvColumns(table);
  const std::vector<std::string> cells = io::RecordCsvCells(table, back);
  const std::vector<std::string> defaults = io::RecordCsvCells(table, R{});
  ASSERT_EQ(cells.size(), columns.size());
  EXPECT_EQ(cells, io::RecordCsvCells(table, full));
  for (size_t k = 0; k < cells.size(); ++k) {
    EXPECT_NE(cells[k], defaults[k]) << "CSV column " << columns[k];
  }
  ExpectCsvNumbersRoundTrip(table, back);
}

TEST(ServiceRecords, JobThroughEveryPath) {
  const auto& table = storage::JobFields();
  std::vector<std::string> names = Names(table);
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size());
  storage::JobRecord job;
  SetEveryField(table, &job);
  ExpectServiceRecordThroughEveryPath<storage::JobRecord, v1::JobInfo>(table, job);
  v1::JobInfo info;
  service::ToProto(job, &info);
  ASSERT_EQ(info.options_size(), 3);
  EXPECT_EQ(info.options(2).key(), "zeta");
  EXPECT_EQ(info.options(2).value(), "again");
  // The CSV/JSON names are the proto's: job_id, not the struct's `id`.
  EXPECT_EQ(io::RecordToJson(table, job)["job_id"], job.id);
  EXPECT_EQ(io::RecordToJson(table, job)["state"], "cancelled");
}

TEST(ServiceRecords, SweepSummaryThroughEveryPath) {
  const auto& table = storage::SweepFields();
  std::vector<std::string> names = Names(table);
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size());
  storage::SweepRecord sweep;
  SetEveryField(table, &sweep);
  ExpectServiceRecordThroughEveryPath<storage::SweepRecord, v1::SweepInfo>(table, sweep);
  // The derived `finished` is written (proto, JSON) from the counts.
  v1::SweepInfo info;
  service::ToProto(sweep, &info);
  EXPECT_FALSE(info.finished());
  EXPECT_EQ(info.created_unix_ms(), sweep.created_ms);
}

// An enumerator's text is checked on the way in: a name the enum lacks is an
// error in JSON; UNSPECIFIED (an older sender) leaves the default.
TEST(ServiceRecords, EnumeratorsAreReadByName) {
  storage::JobRecord job;
  const absl::Status bad = io::RecordFromJson(
      storage::JobFields(), nlohmann::ordered_json{{"state", "sleeping"}}, "job 3: ", &job);
  EXPECT_EQ(bad.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(bad.message(), "job 3: state: 'sleeping' is not one of its names");
  // An attempt's state is not a job's.
  EXPECT_EQ(io::RecordFromJson(storage::JobFields(),
                               nlohmann::ordered_json{{"state", "lease_lost"}}, "", &job)
                .code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(job.state, storage::JobState::kQueued);
  v1::JobInfo info;
  info.set_state(v1::JOB_STATE_UNSPECIFIED);
  info.set_kind(v1::JOB_KIND_STUDY);
  const storage::JobRecord back = service::FromProto(info);
  EXPECT_EQ(back.state, storage::JobState::kQueued);
  EXPECT_EQ(back.kind, storage::JobKind::kStudy);
  info.set_state(v1::JOB_STATE_FAILED);
  EXPECT_EQ(service::FromProto(info).state, storage::JobState::kFailed);
}

class RecordsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = MakeTempDir();
    path_ = dir_ + "/store.db";
    Open();
  }
  void TearDown() override {
    store_.reset();
    if (!HasFailure()) std::filesystem::remove_all(dir_);
  }
  void Open() {
    auto store = storage::SqliteStore::Open(path_);
    ASSERT_TRUE(store.ok()) << store.status();
    store_ = std::move(*store);
  }
  // A trial sweep of one job of 3 episodes, leased to "w1" as attempt 1.
  int64_t CreateTrialJob() {
    bool created = false;
    EXPECT_TRUE(store_->CreateSweep(MakeSweep("trials", 1, 3), kNow, &created).ok());
    auto jobs = store_->ListJobs({"trials", {}, 0, 1000});
    EXPECT_TRUE(jobs.ok());
    const int64_t job_id = jobs->back().id;
    TG_EXPECT_OK(store_->StartAttempt({job_id, 1}, MakeWorker("w1"), kNow, kNow + 90'000));
    return job_id;
  }
  // A sweep with one study job, leased to worker "w1" as attempt 1.
  int64_t CreateStudyJob() {
    storage::NewSweep sweep = MakeSweep("records", 1, 3);
    sweep.jobs.push_back(::totalgrad::testing::MakeStudyJob(R"({"problem":{"synthetic":{}}})"));
    bool created = false;
    EXPECT_TRUE(store_->CreateSweep(sweep, kNow, &created).ok());
    auto jobs = store_->ListJobs({"records", {}, 0, 1000});
    EXPECT_TRUE(jobs.ok());
    const int64_t job_id = jobs->back().id;
    TG_EXPECT_OK(store_->StartAttempt({job_id, 1}, MakeWorker("w1"), kNow, kNow + 90'000));
    return job_id;
  }

  std::string dir_, path_;
  std::unique_ptr<storage::SqliteStore> store_;
};

// The store reads a job and a sweep through views generated from their
// tables (sqlite_records.h MakeSqlView): a job's options come back in their
// order, and the store's own fields are read too.
TEST_F(RecordsTest, JobAndSweepReadThroughTheirTables) {
  const int64_t job_id = CreateTrialJob();
  store_.reset();
  Open();
  TG_ASSERT_OK_AND_ASSIGN(storage::JobRecord job, store_->GetJob(job_id));
  const OptionPairs expected = {{"method", "RP"}, {"seed", "1"}, {"noise_k", "1"}};
  EXPECT_EQ(job.options, expected);
  EXPECT_EQ(job.worker_id, "w1");
  EXPECT_EQ(job.state, storage::JobState::kRunning);
  EXPECT_EQ(job.episodes_expected, 3);
  EXPECT_EQ(job.max_attempts, 3);
  EXPECT_EQ(job.max_lost_leases, 20);
  EXPECT_GT(job.sweep_id, 0);
  EXPECT_EQ(job.sweep_name, "trials");
  TG_ASSERT_OK_AND_ASSIGN(storage::SweepRecord sweep, store_->GetSweep("trials"));
  EXPECT_EQ(sweep.id, job.sweep_id);
  EXPECT_EQ(sweep.jobs_running, 1);
  EXPECT_EQ(sweep.episodes_expected, 3);
  EXPECT_EQ(sweep.max_lost_leases, 20);
  EXPECT_EQ(sweep.created_ms, kNow);
}

// A field the store does not place, and a placement naming no field, stop
// the program with the field's name (the first store test would show it).
TEST(RecordSqlViewDeathTest, EveryFieldHasAnExpressionAndEveryExpressionAField) {
  EXPECT_DEATH(storage::internal::MakeSqlView<storage::SweepRecord>(
                   {&storage::SweepStoreOnlyFields()}, {}, {}),
               "record field 'id' has no SQL expression");
  EXPECT_DEATH(storage::internal::MakeSqlView<storage::SweepRecord>(
                   {&storage::SweepStoreOnlyFields()}, {{"id", "s.id"}, {"colour", "s.colour"}},
                   {}),
               "SQL expression 's.colour' names no field");
  const auto view = storage::internal::MakeSqlView<storage::SweepRecord>(
      {&storage::SweepStoreOnlyFields()}, {{"id", "s.id"}}, {});
  EXPECT_EQ(view.select_list, "s.id");
  EXPECT_EQ(view.fields.size(), 1u);
}

TEST_F(RecordsTest, StudyRowsThroughEveryPath) {
  study::CellResult cell;
  SetEveryField(study::CellFields(), &cell);
  study::ReferenceGradient ref;
  SetEveryField(study::ReferenceFields(), &ref);

  // The worker: core records -> rows.
  v1::StudyCellRow sent_cell;
  sent_cell.set_index(4);
  record_proto::RecordToProto(study::CellFields(), cell, &sent_cell);
  v1::StudyReferenceRow sent_ref;
  sent_ref.set_index(2);
  record_proto::RecordToProto(study::ReferenceFields(), ref, &sent_ref);
  EXPECT_EQ(sent_cell.note(), study::CellNote(cell));

  // The coordinator: rows -> the store -> rows.
  const int64_t job = CreateStudyJob();
  storage::StudyRows rows;
  rows.cells.push_back(service::FromProto(sent_cell));
  rows.references.push_back(service::FromProto(sent_ref));
  TG_ASSERT_OK_AND_ASSIGN(
      storage::ResultTotals stored,
      store_->StoreResults({job, 1}, "w1", {{}, rows}, kNow, std::nullopt));
  EXPECT_EQ(stored, (storage::ResultTotals{.study_cells = 1, .study_references = 1}));
  store_.reset();
  Open();  // from the file, not from a cache
  std::vector<storage::StudyCellRecord> cells;
  std::vector<storage::StudyReferenceRecord> refs;
  TG_ASSERT_OK(store_->ListStudyRows("records", true, &cells, &refs));
  ASSERT_EQ(cells.size(), 1u);
  ASSERT_EQ(refs.size(), 1u);
  v1::StudyCellRow listed_cell;
  service::ToProto(cells[0], &listed_cell);
  v1::StudyReferenceRow listed_ref;
  service::ToProto(refs[0], &listed_ref);
  EXPECT_EQ(listed_cell.index(), 4);
  EXPECT_EQ(listed_cell.job_id(), job);
  EXPECT_EQ(listed_cell.study(), "tiny");
  EXPECT_EQ(listed_ref.index(), 2);

  // The CLI: rows -> core records.
  study::CellResult back_cell;
  record_proto::RecordFromProto(study::CellFields(), listed_cell, &back_cell);
  study::ReferenceGradient back_ref;
  record_proto::RecordFromProto(study::ReferenceFields(), listed_ref, &back_ref);
  EXPECT_EQ(DifferingFields(study::CellFields(), cell, back_cell), std::vector<std::string>{});
  EXPECT_EQ(DifferingFields(study::ReferenceFields(), ref, back_ref), std::vector<std::string>{});

  // CSV: the same cells from the original and from the copy, numbers that
  // read back bit for bit; `totalgrad study`'s table.csv is that CSV.
  EXPECT_EQ(io::RecordCsvCells(study::CellFields(), back_cell),
            io::RecordCsvCells(study::CellFields(), cell));
  EXPECT_EQ(io::RecordCsvCells(study::ReferenceFields(), back_ref),
            io::RecordCsvCells(study::ReferenceFields(), ref));
  ExpectCsvNumbersRoundTrip(study::CellFields(), back_cell);
  ExpectCsvNumbersRoundTrip(study::ReferenceFields(), back_ref);
  study::StudyResult result;
  result.cells = {back_cell};
  result.references = {back_ref};
  EXPECT_EQ(cli::StudyTableCsv(result),
            io::CsvLine(io::RecordCsvColumns(study::CellFields())) + "\n" +
                io::CsvLine(io::RecordCsvCells(study::CellFields(), cell)) + "\n");
  EXPECT_EQ(cli::StudyReferenceCsv(result),
            io::CsvLine(io::RecordCsvColumns(study::ReferenceFields())) + "\n" +
                io::CsvLine(io::RecordCsvCells(study::ReferenceFields(), ref)) + "\n");

  // JSON: results.json written from the copy and read back is the original.
  const nlohmann::ordered_json doc = io::StudyResultToJson(result, io::StudySpec{});
  EXPECT_EQ(doc["cells"][0].dump(), io::RecordToJson(study::CellFields(), cell).dump());
  EXPECT_EQ(doc["references"][0].dump(), io::RecordToJson(study::ReferenceFields(), ref).dump());
  absl::StatusOr<study::StudyResult> read =
      io::StudyResultFromJson(nlohmann::json::parse(doc.dump()));
  TG_ASSERT_OK(read.status());
  ASSERT_EQ(read->cells.size(), 1u);
  ASSERT_EQ(read->references.size(), 1u);
  EXPECT_EQ(DifferingFields(study::CellFields(), cell, read->cells[0]), std::vector<std::string>{});
  EXPECT_EQ(DifferingFields(study::ReferenceFields(), ref, read->references[0]),
            std::vector<std::string>{});
}

// The episode: the trial's result -> the worker's report -> the store ->
// the export's row -> CSV, JSON lines, `trial --json` and a sweep archive
// (written and read back, and as version 1 wrote it).
TEST_F(RecordsTest, EpisodesThroughEveryPath) {
  learner::EpisodeResult result;
  SetEveryField<learner::EpisodeSummary>(learner::EpisodeFields(), &result);
  result.episode = 2;  // the store accepts episodes 0..2 of this trial; 0 is the default
  result.predicted_cost_mean_per_step = Vector{{0.5, 0.25}};
  result.predicted_cost_std_per_step = Vector{{0.125, 0.0625}};
  const learner::EpisodeSummary& record = result;

  // The worker: the record whole (learner_runner.cc) and by name (worker.cc).
  worker::EpisodeOutcome outcome;
  static_cast<learner::EpisodeSummary&>(outcome) = result;
  outcome.details_json = io::EpisodeDetailsJson(result);
  v1::EpisodeReport report;
  record_proto::RecordToProto<learner::EpisodeSummary>(learner::EpisodeFields(), outcome, &report);
  report.set_details_json(outcome.details_json);
  EXPECT_TRUE(report.has_cpu_seconds());

  // The coordinator and its store.
  const int64_t job = CreateTrialJob();
  const storage::Episode stored = service::FromProto(report);
  TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{stored}}, kNow, std::nullopt).status());
  store_.reset();
  Open();
  std::vector<storage::EpisodeRowRecord> exported;
  TG_ASSERT_OK(store_->ExportEpisodes("trials", true, 10,
                                      [&](std::vector<storage::EpisodeRowRecord> batch) {
                                        for (auto& row : batch) exported.push_back(std::move(row));
                                        return absl::OkStatus();
                                      }));
  ASSERT_EQ(exported.size(), 1u);
  v1::EpisodeRow row;
  service::ToProto(exported[0], &row);
  EXPECT_EQ(row.report().details_json(), outcome.details_json);

  // The CLI.
  learner::EpisodeSummary back;
  record_proto::RecordFromProto(learner::EpisodeFields(), row.report(), &back);
  EXPECT_EQ(DifferingFields(learner::EpisodeFields(), record, back), std::vector<std::string>{});
  EXPECT_EQ(io::RecordCsvCells(learner::EpisodeFields(), back),
            io::RecordCsvCells(learner::EpisodeFields(), record));
  ExpectCsvNumbersRoundTrip(learner::EpisodeFields(), back);
  // `trial --json`: the record's keys with the same values, then the details.
  const nlohmann::json line = io::EpisodeToJson(result);
  const nlohmann::ordered_json expected = io::RecordToJson(learner::EpisodeFields(), back);
  for (const auto& field : learner::EpisodeFields()) {
    EXPECT_EQ(line.at(field.name).dump(), expected.at(field.name).dump()) << field.name;
  }
  EXPECT_TRUE(line.contains("timing") && line.contains("flags"));
  EXPECT_EQ(line["predicted_cost_mean_per_step"], nlohmann::json::array({0.5, 0.25}));

  // A sweep archive of that row, written and read back.
  v1::SweepInfo sweep;
  sweep.set_name("trials");
  sweep.set_state(v1::SWEEP_STATE_RUNNING);
  service::ArchiveJobInput input;
  input.job.set_method("RP");
  input.job.set_seed("1");
  input.job.set_state(v1::JOB_STATE_COMPLETED);
  v1::AttemptInfo attempt;
  attempt.set_attempt(1);
  attempt.set_state(v1::ATTEMPT_STATE_COMPLETED);
  input.attempts.push_back(attempt);
  input.episodes.push_back(row);
  nlohmann::ordered_json doc = service::SweepArchiveToJson(sweep, {input}, "test", kNow);
  absl::StatusOr<service::ParsedSweepArchive> parsed = service::ParseSweepArchive(doc.dump());
  TG_ASSERT_OK(parsed.status());
  ASSERT_EQ(parsed->jobs.at(0).attempts.at(0).episodes.size(), 1u);
  const storage::Episode& archived = parsed->jobs[0].attempts[0].episodes[0].first;
  EXPECT_EQ(DifferingFields<learner::EpisodeSummary>(learner::EpisodeFields(), record, archived),
            std::vector<std::string>{});
  // Version 1 named optimisation_seconds wall_seconds; such archives still read.
  doc["version"] = 1;
  nlohmann::ordered_json& old = doc["jobs"][0]["attempt_log"][0]["episodes"][0];
  old["wall_seconds"] = old["optimisation_seconds"];
  old.erase("optimisation_seconds");
  parsed = service::ParseSweepArchive(doc.dump());
  TG_ASSERT_OK(parsed.status());
  // Version 1 is read as it was written: the fields it had; those added to
  // the record since (held_fraction, ...) read as their defaults.
  const std::vector<std::string> version1 = {"episode", "real_cost", "eval_cost_mean",
                                             "eval_cost_std", "predicted_cost",
                                             "optimisation_seconds", "cpu_seconds"};
  std::vector<std::string> later;
  for (const auto& field : learner::EpisodeFields())
    if (std::find(version1.begin(), version1.end(), field.name) == version1.end())
      later.push_back(field.name);
  EXPECT_EQ(DifferingFields<learner::EpisodeSummary>(
                learner::EpisodeFields(), record, parsed->jobs[0].attempts[0].episodes[0].first),
            later);
  // Its attempts are read through the attempt's record: a bad state or a
  // missing field is refused by its path in the archive.
  nlohmann::ordered_json bad_state = doc;
  bad_state["jobs"][0]["attempt_log"][0]["state"] = "finished";
  absl::StatusOr<service::ParsedSweepArchive> refused =
      service::ParseSweepArchive(bad_state.dump());
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(std::string(refused.status().message()).find("jobs[0].attempt_log[0].state"),
            std::string::npos)
      << refused.status();
  nlohmann::ordered_json no_build = doc;
  no_build["jobs"][0]["attempt_log"][0].erase("worker_build");
  refused = service::ParseSweepArchive(no_build.dump());
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(std::string(refused.status().message()).find("jobs[0].attempt_log[0].worker_build"),
            std::string::npos)
      << refused.status();
}

// An older worker's report has no cpu_seconds: it reads as NaN (no value),
// and NaN is sent as no value (fields with presence, `optional double`).
TEST(RecordProto, AnAbsentOptionalDoubleIsNaN) {
  v1::EpisodeReport report;
  report.set_episode(1);
  learner::EpisodeSummary e;
  e.cpu_seconds = 3;
  record_proto::RecordFromProto(learner::EpisodeFields(), report, &e);
  EXPECT_TRUE(std::isnan(e.cpu_seconds));
  EXPECT_EQ(e.optimisation_seconds, 0);  // no presence: the proto's 0
  v1::EpisodeReport sent;
  record_proto::RecordToProto(learner::EpisodeFields(), e, &sent);
  EXPECT_FALSE(sent.has_cpu_seconds());
  // Likewise a reference row from a worker built before agreement_resolution.
  study::ReferenceGradient ref;
  ref.agreement_resolution = 0.5;
  record_proto::RecordFromProto(study::ReferenceFields(), v1::StudyReferenceRow{}, &ref);
  EXPECT_TRUE(std::isnan(ref.agreement_resolution));
}

// Study rows in a sweep archive: written as their records' JSON and read
// back; a version-1 archive (protobuf's JSON mapping) still reads the same.
TEST(RecordsArchive, StudyRowsRoundTripInBothVersions) {
  study::CellResult cell;
  SetEveryField(study::CellFields(), &cell);
  study::ReferenceGradient ref;
  SetEveryField(study::ReferenceFields(), &ref);
  service::ArchiveJobInput input;
  input.job.set_kind(v1::JOB_KIND_STUDY);
  input.job.set_method("study");
  input.job.set_seed("1");
  input.job.set_state(v1::JOB_STATE_COMPLETED);
  v1::AttemptInfo attempt;
  attempt.set_attempt(1);
  attempt.set_state(v1::ATTEMPT_STATE_COMPLETED);
  input.attempts.push_back(attempt);
  v1::StudyCellRow cell_row;
  cell_row.set_attempt(1);
  cell_row.set_index(5);
  record_proto::RecordToProto(study::CellFields(), cell, &cell_row);
  input.cells.push_back(cell_row);
  v1::StudyReferenceRow ref_row;
  ref_row.set_attempt(1);
  ref_row.set_index(1);
  record_proto::RecordToProto(study::ReferenceFields(), ref, &ref_row);
  input.references.push_back(ref_row);
  v1::SweepInfo sweep;
  sweep.set_name("studies");
  sweep.set_state(v1::SWEEP_STATE_RUNNING);
  nlohmann::ordered_json doc = service::SweepArchiveToJson(sweep, {input}, "test", kNow);
  auto check = [&](const std::string& text) {
    absl::StatusOr<service::ParsedSweepArchive> parsed = service::ParseSweepArchive(text);
    TG_ASSERT_OK(parsed.status());
    const storage::StudyRows& rows = parsed->jobs.at(0).attempts.at(0).study;
    ASSERT_EQ(rows.cells.size(), 1u);
    ASSERT_EQ(rows.references.size(), 1u);
    EXPECT_EQ(rows.cells[0].index, 5);
    EXPECT_EQ(rows.references[0].index, 1);
    EXPECT_EQ(DifferingFields<study::CellResult>(study::CellFields(), cell, rows.cells[0]),
              std::vector<std::string>{});
    EXPECT_EQ(DifferingFields<study::ReferenceGradient>(study::ReferenceFields(), ref,
                                                        rows.references[0]),
              std::vector<std::string>{});
  };
  check(doc.dump());
  // As version 1 wrote them.
  auto proto_json = [](const google::protobuf::Message& m) {
    std::string text;
    google::protobuf::util::JsonPrintOptions options;
    options.preserve_proto_field_names = true;
    EXPECT_TRUE(google::protobuf::util::MessageToJsonString(m, &text, options).ok());
    return nlohmann::ordered_json::parse(text);
  };
  doc["version"] = 1;
  doc["jobs"][0]["attempt_log"][0]["study_cells"] = nlohmann::ordered_json::array({proto_json(cell_row)});
  doc["jobs"][0]["attempt_log"][0]["study_references"] =
      nlohmann::ordered_json::array({proto_json(ref_row)});
  check(doc.dump());
}

// Archive version 3: the sweep, a job and its attempts are written through
// their field tables (server/storage/service_records.h) and read back
// through them. Every field of each table, set to a non-default value by
// walking the table, is a key of the archive's object holding that value, so
// a field added to a table that the archive does not carry fails here; the
// parsed archive holds what the import takes, bit for bit.
TEST(RecordsArchive, EveryFieldOfTheSweepJobAndAttemptTablesIsCarried) {
  storage::SweepRecord sweep;
  SetEveryField(storage::SweepFields(), &sweep);
  ASSERT_EQ(DifferingFields(storage::SweepFields(), storage::SweepRecord{}, sweep),
            Names(storage::SweepFields()));
  storage::JobRecord job;
  SetEveryField(storage::JobFields(), &job);
  job.state = storage::JobState::kCompleted;  // so that its completed attempt is written
  job.options = {{"episodes", "3"}, {"learning_rate", "0.1"}};
  ASSERT_EQ(DifferingFields(storage::JobFields(), storage::JobRecord{}, job),
            Names(storage::JobFields()));
  storage::ImportedAttempt failed;
  SetEveryField(storage::ImportedAttemptFields(), &failed);
  ASSERT_EQ(DifferingFields(storage::ImportedAttemptFields(), storage::ImportedAttempt{}, failed),
            Names(storage::ImportedAttemptFields()));
  const std::vector<std::string> names = Names(storage::ImportedAttemptFields());
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size());
  storage::ImportedAttempt completed = failed;
  completed.attempt = failed.attempt + 1;
  completed.state = storage::AttemptState::kCompleted;

  v1::SweepInfo sweep_info;
  service::ToProto(sweep, &sweep_info);
  service::ArchiveJobInput input;
  service::ToProto(job, &input.job);
  ASSERT_EQ(record_proto::RecordProtoMismatch(storage::ImportedAttemptFields(),
                                              *v1::AttemptInfo::descriptor()),
            "");
  for (const storage::ImportedAttempt* attempt : {&failed, &completed}) {
    record_proto::RecordToProto(storage::ImportedAttemptFields(), *attempt,
                                &input.attempts.emplace_back());
  }
  // The completed attempt's checkpoint (results export --checkpoints), bytes
  // that are not text.
  v1::TrialCheckpoint& kept = input.checkpoints[completed.attempt];
  kept.set_episode(2);
  kept.set_format_version(2);
  kept.set_data(std::string("\0state\xff\x01", 8));
  const nlohmann::ordered_json doc = service::SweepArchiveToJson(sweep_info, {input}, "test", kNow);
  EXPECT_EQ(doc.at("version"), 4);

  // Written: every field's key, holding the record's value.
  auto expect_carried = [](const auto& table, const auto& full,
                           const nlohmann::ordered_json& object, const std::string& what) {
    for (const auto& field : table) {
      EXPECT_TRUE(object.contains(field.name)) << what << " lacks '" << field.name << "'";
    }
    std::decay_t<decltype(full)> back;
    TG_ASSERT_OK(io::RecordFromJson(table, object, what + ".", &back));
    EXPECT_EQ(DifferingFields(table, full, back), std::vector<std::string>{}) << what;
  };
  expect_carried(storage::SweepFields(), sweep, doc.at("sweep"), "sweep");
  const nlohmann::ordered_json& written = doc.at("jobs").at(0);
  expect_carried(storage::JobFields(), job, written, "jobs[0]");
  ASSERT_EQ(written.at("attempt_log").size(), 2u);
  expect_carried(storage::ImportedAttemptFields(), failed, written["attempt_log"][0],
                 "jobs[0].attempt_log[0]");
  expect_carried(storage::ImportedAttemptFields(), completed, written["attempt_log"][1],
                 "jobs[0].attempt_log[1]");
  EXPECT_EQ(written.at("options").dump(), R"([["episodes","3"],["learning_rate","0.1"]])");
  EXPECT_EQ(written.at("completed_attempt"), completed.attempt);

  // Read back: what the import takes.
  const absl::StatusOr<service::ParsedSweepArchive> parsed =
      service::ParseSweepArchive(doc.dump());
  TG_ASSERT_OK(parsed.status());
  EXPECT_EQ(parsed->name, sweep.name);
  EXPECT_EQ(parsed->canonical_spec, sweep.canonical_spec);
  EXPECT_EQ(parsed->spec_hash, sweep.spec_hash);
  EXPECT_EQ(parsed->state, sweep.state);
  ASSERT_EQ(parsed->jobs.size(), 1u);
  const storage::ImportedJob& read = parsed->jobs[0];
  EXPECT_EQ(read.record.kind, job.kind);
  EXPECT_EQ(read.record.method, job.method);
  EXPECT_EQ(read.record.seed, job.seed);
  EXPECT_EQ(read.record.variant, job.variant);
  EXPECT_EQ(read.record.state, job.state);
  EXPECT_EQ(read.record.failures, job.failures);
  EXPECT_EQ(read.record.lost_leases, job.lost_leases);
  EXPECT_EQ(read.record.last_error, job.last_error);
  EXPECT_EQ(read.record.success, job.success);
  EXPECT_TRUE(SameBits(read.record.final_eval_cost, job.final_eval_cost));
  EXPECT_EQ(read.completed_attempt, completed.attempt);
  ASSERT_EQ(read.attempts.size(), 2u);
  EXPECT_EQ(DifferingFields(storage::ImportedAttemptFields(), failed, read.attempts[0]),
            std::vector<std::string>{});
  EXPECT_EQ(DifferingFields(storage::ImportedAttemptFields(), completed, read.attempts[1]),
            std::vector<std::string>{});
  EXPECT_EQ(parsed->created_ms, sweep.created_ms);
  EXPECT_FALSE(read.attempts[0].checkpoint.has_value());
  ASSERT_TRUE(read.attempts[1].checkpoint.has_value());
  EXPECT_EQ(read.attempts[1].checkpoint->episode, 2);
  EXPECT_EQ(read.attempts[1].checkpoint->format_version, 2);
  EXPECT_EQ(read.attempts[1].checkpoint->data, kept.data());

  // Version 3 had no origin and no checkpoints; it wrote the sweep's
  // submission time, which its imports now keep too (0 where it lacks it).
  nlohmann::json v3 = nlohmann::json::parse(doc.dump());
  v3["version"] = 3;
  for (auto& attempt : v3["jobs"][0]["attempt_log"]) {
    attempt.erase("origin");
    attempt.erase("checkpoint");
  }
  const absl::StatusOr<service::ParsedSweepArchive> old = service::ParseSweepArchive(v3.dump());
  TG_ASSERT_OK(old.status());
  EXPECT_EQ(old->created_ms, doc["sweep"]["created_unix_ms"].get<int64_t>());
  EXPECT_GT(old->created_ms, 0);
  nlohmann::json v3_untimed = v3;
  v3_untimed["sweep"].erase("created_unix_ms");
  const absl::StatusOr<service::ParsedSweepArchive> untimed =
      service::ParseSweepArchive(v3_untimed.dump());
  TG_ASSERT_OK(untimed.status());
  EXPECT_EQ(untimed->created_ms, 0);
  EXPECT_EQ(old->jobs[0].attempts[1].origin, "");
  EXPECT_FALSE(old->jobs[0].attempts[1].checkpoint.has_value());
  // In version 4 the origin is required, and a checkpoint must be base64.
  nlohmann::json broken = nlohmann::json::parse(doc.dump());
  broken["jobs"][0]["attempt_log"][0].erase("origin");
  EXPECT_NE(service::ParseSweepArchive(broken.dump()).status().message().find(
                "jobs[0].attempt_log[0].origin"),
            std::string::npos);
  broken = nlohmann::json::parse(doc.dump());
  broken["jobs"][0]["attempt_log"][1]["checkpoint"]["data_base64"] = "not base64!";
  EXPECT_NE(service::ParseSweepArchive(broken.dump()).status().message().find(
                "jobs[0].attempt_log[1].checkpoint.data_base64"),
            std::string::npos);
}

// A version-4 archive of one sweep with two completed trials, one episode each.
nlohmann::ordered_json TwoTrialArchive() {
  v1::SweepInfo sweep;
  sweep.set_name("trials");
  sweep.set_state(v1::SWEEP_STATE_PAUSED);
  sweep.set_spec_hash("abc");
  sweep.set_canonical_spec("{}");
  sweep.set_jobs_total(2);
  sweep.set_jobs_completed(2);
  std::vector<service::ArchiveJobInput> jobs(2);
  for (int k = 0; k < 2; ++k) {
    service::ArchiveJobInput& input = jobs[static_cast<size_t>(k)];
    input.job.set_job_id(k + 1);
    input.job.set_method("RP");
    input.job.set_seed(std::to_string(k + 1));
    input.job.set_state(v1::JOB_STATE_COMPLETED);
    input.job.set_success(true);
    input.job.set_final_eval_cost(1.5 + k);
    v1::AttemptInfo& attempt = input.attempts.emplace_back();
    attempt.set_attempt(1);
    attempt.set_state(v1::ATTEMPT_STATE_COMPLETED);
    attempt.set_worker_id("w1");
    attempt.set_started_unix_ms(kNow);
    attempt.set_ended_unix_ms(kNow + 10);
    v1::EpisodeRow& row = input.episodes.emplace_back();
    row.set_attempt(1);
    row.set_reported_unix_ms(kNow + 5);
    row.mutable_report()->set_episode(0);
    row.mutable_report()->set_real_cost(2.25 + k);
    row.mutable_report()->set_details_json("{\"flags\": {}}");
  }
  return service::SweepArchiveToJson(sweep, jobs, "test", kNow);
}

// A malformed version-3 archive is refused by the path of the bad value and
// what is wrong with it (the tables' reader's words), be it a field the
// import takes or an informative one; an informative field's value is
// ignored.
TEST(RecordsArchive, AMalformedValueIsNamedByItsPath) {
  const nlohmann::ordered_json doc = TwoTrialArchive();
  const absl::StatusOr<service::ParsedSweepArchive> good = service::ParseSweepArchive(doc.dump());
  TG_ASSERT_OK(good.status());
  ASSERT_EQ(good->jobs.size(), 2u);
  EXPECT_EQ(good->state, storage::SweepState::kPaused);
  EXPECT_EQ(good->jobs[1].record.seed, "2");
  EXPECT_EQ(good->jobs[1].record.final_eval_cost, 2.5);
  ASSERT_EQ(good->jobs[1].attempts.at(0).episodes.size(), 1u);
  EXPECT_EQ(good->jobs[1].attempts[0].episodes[0].first.real_cost, 3.25);
  EXPECT_EQ(good->jobs[1].attempts[0].episodes[0].second, kNow + 5);

  auto error_after = [&](const std::function<void(nlohmann::ordered_json&)>& edit) {
    nlohmann::ordered_json broken = doc;
    edit(broken);
    const absl::StatusOr<service::ParsedSweepArchive> parsed =
        service::ParseSweepArchive(broken.dump());
    EXPECT_EQ(parsed.status().code(), absl::StatusCode::kInvalidArgument);
    return std::string(parsed.status().message());
  };
  using J = nlohmann::ordered_json;
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1]["failures"] = "two"; }),
            "archive: jobs[1].failures: not an integer");
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1]["state"] = "sleeping"; }),
            "archive: jobs[1].state: 'sleeping' is not one of its names");
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1]["seed"] = 2; }),
            "archive: jobs[1].seed: not a string");
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1]["success"] = 1; }),
            "archive: jobs[1].success: not true or false");
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1].erase("method"); }),
            "archive: jobs[1].method: missing");
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1].erase("completed_attempt"); }),
            "archive: jobs[1].completed_attempt: missing");
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1]["attempt_log"] = J::object(); }),
            "archive: jobs[1].attempt_log: not an array");
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1]["ordinal"] = 0.5; }),
            "archive: jobs[1].ordinal: not an integer");
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1] = "RP"; }), "archive: jobs[1]: not an object");
  EXPECT_EQ(error_after([](J& d) { d["sweep"].erase("spec_hash"); }),
            "archive: sweep.spec_hash: missing");
  EXPECT_EQ(error_after([](J& d) { d["sweep"]["state"] = "running fast"; }),
            "archive: sweep.state: 'running fast' is not one of its names");
  EXPECT_EQ(error_after([](J& d) { d["sweep"]["jobs_total"] = "2"; }),
            "archive: sweep.jobs_total: not an integer");
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1]["attempt_log"][0]["started_unix_ms"] = 1.5; }),
            "archive: jobs[1].attempt_log[0].started_unix_ms: not an integer");
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1]["attempt_log"][0].erase("worker_build"); }),
            "archive: jobs[1].attempt_log[0].worker_build: missing");
  EXPECT_EQ(error_after([](J& d) { d["jobs"][1]["attempt_log"][0]["state"] = "queued"; }),
            "archive: jobs[1].attempt_log[0].state: 'queued' is not one of its names");
  EXPECT_EQ(error_after([](J& d) {
              d["jobs"][1]["attempt_log"][0]["episodes"][0]["real_cost"] = "low";
            }),
            "archive: jobs[1].attempt_log[0].episodes[0].real_cost: not a number or null");
  EXPECT_EQ(error_after([](J& d) {
              d["jobs"][1]["attempt_log"][0]["episodes"][0].erase("reported_unix_ms");
            }),
            "archive: jobs[1].attempt_log[0].episodes[0].reported_unix_ms: missing");
  EXPECT_EQ(error_after([](J& d) {
              d["jobs"][1]["attempt_log"][0]["study_cells"] = J::array({J{{"estimator", "RP"}}});
            }),
            "archive: jobs[1].attempt_log[0].study_cells[0].index: missing");

  // Informative values (the counts, ids, the open attempt's worker) are
  // not taken: the import has its own.
  nlohmann::ordered_json other = doc;
  other["sweep"]["jobs_total"] = 99;
  other["sweep"]["finished"] = false;
  other["jobs"][1]["job_id"] = 12345;
  other["jobs"][1]["worker_id"] = "elsewhere";
  other["jobs"][1]["episodes_stored"] = 7;
  const absl::StatusOr<service::ParsedSweepArchive> same = service::ParseSweepArchive(other.dump());
  TG_ASSERT_OK(same.status());
  ASSERT_EQ(same->jobs.size(), 2u);
  EXPECT_EQ(same->jobs[1].attempts.size(), 1u);
  EXPECT_EQ(same->jobs[1].completed_attempt, 1);
}

// Issue 28: an import reads its archive as a stream. Each job is handed
// over as soon as it has been read (a 100,000-job archive parsed whole took
// the coordinator to 2.6-3.2 GB), whatever the order of the document's
// members; a job that does not read, or that the visitor refuses, stops the
// reading there.
TEST(RecordsArchive, JobsAreReadOneAtATimeInAnyMemberOrder) {
  const nlohmann::ordered_json doc = TwoTrialArchive();
  const std::string text = doc.dump();
  std::istringstream in(text);
  absl::StatusOr<service::SweepArchiveOpening> opening = service::ReadSweepArchiveOpening(in);
  TG_ASSERT_OK(opening.status());
  EXPECT_EQ(opening->version, service::kSweepArchiveVersion);
  EXPECT_EQ(opening->state, storage::SweepState::kPaused);
  in.clear();
  in.seekg(0);
  std::vector<std::streamoff> read_when_visited;
  std::vector<std::string> seeds;
  TG_ASSERT_OK(service::ForEachArchivedJob(in, opening->version, [&](storage::ImportedJob& job) {
    read_when_visited.push_back(in.rdbuf()->pubseekoff(0, std::ios::cur, std::ios::in));
    seeds.push_back(job.record.seed);
    return absl::OkStatus();
  }));
  EXPECT_EQ(seeds, (std::vector<std::string>{"1", "2"}));
  ASSERT_EQ(read_when_visited.size(), 2u);
  // The first job is handed over before the second is read.
  const size_t second_job = text.find("{\"job_id\"", text.find("{\"job_id\"") + 1);
  ASSERT_NE(second_job, std::string::npos);
  EXPECT_LE(read_when_visited[0], static_cast<std::streamoff>(second_job) + 1);
  EXPECT_GT(read_when_visited[1], read_when_visited[0]);

  // The jobs before the sweep (JSON does not order an object's members).
  nlohmann::ordered_json jobs_first;
  jobs_first["jobs"] = doc["jobs"];
  for (const auto& [key, value] : doc.items()) {
    if (key != "jobs") jobs_first[key] = value;
  }
  const absl::StatusOr<service::ParsedSweepArchive> reordered =
      service::ParseSweepArchive(jobs_first.dump());
  TG_ASSERT_OK(reordered.status());
  EXPECT_EQ(reordered->name, opening->name);
  ASSERT_EQ(reordered->jobs.size(), 2u);
  EXPECT_EQ(reordered->jobs[1].record.final_eval_cost, 2.5);

  // A refusal stops the reading: the second job is never handed over.
  std::istringstream again(text);
  int visited = 0;
  const absl::Status refused = service::ForEachArchivedJob(
      again, opening->version, [&](storage::ImportedJob&) {
        ++visited;
        return absl::ResourceExhaustedError("disk full");
      });
  EXPECT_EQ(refused.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_EQ(visited, 1);
  // So does a job that does not read, after the ones before it.
  nlohmann::ordered_json broken = doc;
  broken["jobs"][1]["state"] = "sleeping";
  const std::string broken_text = broken.dump();
  std::istringstream broken_in(broken_text);
  visited = 0;
  const absl::Status unreadable = service::ForEachArchivedJob(
      broken_in, opening->version, [&](storage::ImportedJob&) {
        ++visited;
        return absl::OkStatus();
      });
  EXPECT_EQ(unreadable.message(), "archive: jobs[1].state: 'sleeping' is not one of its names");
  EXPECT_EQ(visited, 1);
  // Text that is not one JSON document is refused when the opening is read.
  std::istringstream cut(text.substr(0, text.size() - 2));
  EXPECT_EQ(service::ReadSweepArchiveOpening(cut).status().message(),
            "archive: not a JSON document");
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Archives written before version 3 still read as they were written: the
// results of table 1 as first committed (version 1, kept in
// tests/service/testdata/; docs/results/table1/ holds their version-4
// export with PILCO's re-runs superseding seeds 10 and 11) and an
// archive written by the version-2 exporter (`results export -f json` of
// tests/service/cli_test.cc's tiny sweep, tests/service/testdata/).
TEST(RecordsArchive, ArchivesOfVersions1And2StillRead) {
  const std::string v1_text =
      ReadText(std::string(TOTALGRAD_SOURCE_DIR) +
               "/tests/service/testdata/table1-tip-k1.v1.archive.json");
  ASSERT_EQ(nlohmann::json::parse(v1_text).at("version"), 1);
  absl::StatusOr<service::ParsedSweepArchive> v1 = service::ParseSweepArchive(v1_text);
  TG_ASSERT_OK(v1.status());
  EXPECT_EQ(v1->name, "table1-tip-k1");
  EXPECT_EQ(v1->state, storage::SweepState::kRunning);
  ASSERT_EQ(v1->jobs.size(), 40u);
  const storage::ImportedJob& pilco = v1->jobs[0];
  EXPECT_EQ(pilco.record.method, "PILCO");
  EXPECT_EQ(pilco.record.seed, "10");  // an integer in the file
  EXPECT_EQ(pilco.record.state, storage::JobState::kCompleted);
  EXPECT_FALSE(pilco.record.success);
  EXPECT_EQ(pilco.record.final_eval_cost, 29.87976685061682);
  EXPECT_EQ(pilco.completed_attempt, 1);
  ASSERT_EQ(pilco.attempts.size(), 1u);
  EXPECT_EQ(pilco.attempts[0].worker_id, "t1-w1");
  EXPECT_EQ(pilco.attempts[0].started_ms, 1795502224958);
  ASSERT_EQ(pilco.attempts[0].episodes.size(), 16u);
  const auto& [last, reported] = pilco.attempts[0].episodes[15];
  EXPECT_EQ(last.episode, 15);
  EXPECT_EQ(last.eval_cost_mean, 29.87976685061682);
  EXPECT_EQ(last.optimisation_seconds, 38.444816686);  // "wall_seconds" in version 1
  EXPECT_EQ(last.cpu_seconds, 37.298129113000016);
  EXPECT_EQ(reported, 1795502464508);

  const std::string v2_text = ReadText(std::string(TOTALGRAD_SOURCE_DIR) +
                                       "/tests/service/testdata/sweep_archive_v2.json");
  ASSERT_EQ(nlohmann::json::parse(v2_text).at("version"), 2);
  absl::StatusOr<service::ParsedSweepArchive> v2 = service::ParseSweepArchive(v2_text);
  TG_ASSERT_OK(v2.status());
  EXPECT_EQ(v2->name, "cli");
  EXPECT_EQ(v2->state, storage::SweepState::kRunning);
  EXPECT_EQ(v2->spec_hash, "48f57d7b5c7bdc9f91d9ee2d8f1783f5c3e232db320b6ac9687c3a1ef3c2743f");
  ASSERT_EQ(v2->jobs.size(), 3u);
  const storage::ImportedJob& rp = v2->jobs[1];
  EXPECT_EQ(rp.record.kind, storage::JobKind::kTrial);
  EXPECT_EQ(rp.record.method, "RP");
  EXPECT_EQ(rp.record.seed, "2");  // an integer in the file
  EXPECT_EQ(rp.record.state, storage::JobState::kCompleted);
  EXPECT_TRUE(rp.record.success);
  EXPECT_EQ(rp.record.final_eval_cost, 9.995945407509343);
  EXPECT_EQ(rp.completed_attempt, 1);
  ASSERT_EQ(rp.attempts.size(), 1u);
  EXPECT_EQ(rp.attempts[0].state, storage::AttemptState::kCompleted);
  EXPECT_EQ(rp.attempts[0].worker_id, "fixture-worker");
  EXPECT_EQ(rp.attempts[0].ended_ms, 1795553015690);
  ASSERT_EQ(rp.attempts[0].episodes.size(), 3u);
  const auto& [episode, when] = rp.attempts[0].episodes[2];
  EXPECT_EQ(episode.episode, 2);
  EXPECT_EQ(episode.eval_cost_mean, 9.995945407509343);
  EXPECT_EQ(episode.optimisation_seconds, 0.006351128);
  EXPECT_EQ(episode.cpu_seconds, 0.0063668119999999995);
  EXPECT_EQ(when, 1795553015688);
  EXPECT_TRUE(nlohmann::json::parse(episode.details_json).is_object());
}

// Every field of the tables has its column in the database (a field added
// without its migration fails here before any write does).
TEST_F(RecordsTest, EveryFieldHasItsSqlColumn) {
  store_.reset();
  auto db = storage::internal::Db::Open(path_, false, 1000);
  ASSERT_TRUE(db.ok()) << db.status();
  auto columns_of = [&](const char* table) {
    std::set<std::string> columns;
    auto info = storage::internal::Statement::Prepare(*db, absl::StrCat("PRAGMA table_info(", table, ")"));
    EXPECT_TRUE(info.ok());
    while (info.ok()) {
      absl::StatusOr<bool> row = info->Step();
      if (!row.ok() || !*row) break;
      columns.insert(info->ColumnText(1));
    }
    return columns;
  };
  const std::set<std::string> cells = columns_of("study_cells");
  for (const std::string& c : storage::internal::RecordColumns(study::CellFields(), true)) {
    EXPECT_EQ(cells.count(c), 1u) << "study_cells has no column " << c;
  }
  const std::set<std::string> refs = columns_of("study_references");
  for (const std::string& c : storage::internal::RecordColumns(study::ReferenceFields(), true)) {
    EXPECT_EQ(refs.count(c), 1u) << "study_references has no column " << c;
  }
}

// A version-5 file (before study_references.agreement_resolution) is copied,
// then migrated; its rows read back unchanged, the new field as NaN (not
// computed), and new rows keep it.
TEST_F(RecordsTest, VersionFiveStudyRowsAreMigratedAfterABackup) {
  const int64_t job = CreateStudyJob();
  study::ReferenceGradient ref;
  SetEveryField(study::ReferenceFields(), &ref);
  storage::StudyRows rows;
  storage::StudyReference stored_ref;
  static_cast<study::ReferenceGradient&>(stored_ref) = ref;
  rows.references.push_back(stored_ref);
  TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{}, rows}, kNow, std::nullopt).status());
  store_.reset();
  {
    auto db = storage::internal::Db::Open(path_, false, 1000);
    ASSERT_TRUE(db.ok()) << db.status();
    TG_ASSERT_OK(::totalgrad::testing::DropColumnsAddedAfter(*db, 5));
    TG_ASSERT_OK(db->Exec("ALTER TABLE study_references DROP COLUMN agreement_resolution; "
                          "PRAGMA user_version=5"));
  }
  Open();
  EXPECT_TRUE(std::filesystem::exists(path_ + ".schema-v5-backup"));
  std::vector<storage::StudyCellRecord> cells;
  std::vector<storage::StudyReferenceRecord> refs;
  TG_ASSERT_OK(store_->ListStudyRows("records", true, &cells, &refs));
  ASSERT_EQ(refs.size(), 1u);
  EXPECT_TRUE(std::isnan(refs[0].reference.agreement_resolution));
  study::ReferenceGradient expected = ref;
  expected.agreement_resolution = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(DifferingFields<study::ReferenceGradient>(study::ReferenceFields(), expected,
                                                      refs[0].reference),
            std::vector<std::string>{});
}

// What an archived trial ran with, in this build's terms: every key of the
// trial option table, the archive's values where it has them, and where it
// lacks a key added since, the value the computation had before it existed.
TEST(OptionsAsRun, KeysAddedSinceTheArchiveTakeTheirEarlierValues) {
  storage::ImportedJob job;
  job.record.kind = storage::JobKind::kTrial;
  job.record.state = storage::JobState::kCompleted;
  job.record.method = "RP";
  job.record.seed = "10";
  job.record.options = {{"method", "RP"}, {"seed", "10"}, {"particles", "300"}};
  TG_ASSERT_OK(service::SetOptionsAsRun(&job));
  ASSERT_TRUE(job.options_as_run.has_value());
  const std::map<std::string, std::string> ran(job.options_as_run->begin(),
                                               job.options_as_run->end());
  EXPECT_EQ(ran.size(), learner::TrialOptionKeys().size());
  EXPECT_EQ(ran.at("particles"), "300");
  EXPECT_EQ(ran.at("gp_variance_tolerance"), "0");  // today's default is 0.01
  EXPECT_EQ(ran.at("verdict_rollouts"), "0");       // no verdict before it existed
  // A job that did not complete, or a study, keeps this sweep's options.
  storage::ImportedJob queued = job;
  queued.options_as_run.reset();
  queued.record.state = storage::JobState::kQueued;
  TG_ASSERT_OK(service::SetOptionsAsRun(&queued));
  EXPECT_FALSE(queued.options_as_run.has_value());
  // A key this build does not know: an archive of a newer build, refused by name.
  storage::ImportedJob newer = job;
  newer.options_as_run.reset();
  newer.record.options.emplace_back("warp_drive", "1");
  const absl::Status refused = service::SetOptionsAsRun(&newer);
  EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(std::string(refused.message()).find("job RP seed 10"), std::string::npos) << refused;
  EXPECT_NE(std::string(refused.message()).find("warp_drive"), std::string::npos) << refused;
}

}  // namespace
}  // namespace totalgrad::testing
