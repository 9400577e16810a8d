#include "client/service_commands/streamed_reads.h"

#include <cmath>
#include <utility>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "core/learner/episode_record.h"
#include "core/learner/trial_options.h"
#include "io/record_format.h"
#include "runtime/record_proto.h"
#include "runtime/rpc_client.h"

namespace totalgrad::cli {
namespace {

// Jobs asked for per page; the coordinator ends a page earlier at about
// 1 MiB (server/service/message_budget.h).
constexpr int kJobsPerPage = 1000;
// A listing's stream: the whole sweep's rows, read as fast as they come.
constexpr absl::Duration kListingStreamTimeout = absl::Minutes(30);

// Reads a server stream of batches into *whole: `merge` moves one batch in.
// A coordinator without the stream (UNIMPLEMENTED, before issue 28) is asked
// with `fallback` (its unary call) instead.
template <typename Request, typename Response, typename Merge, typename Fallback>
grpc::Status ReadBatches(
    Connection* connection,
    std::unique_ptr<grpc::ClientReader<Response>> (v1::ControlService::Stub::*stream)(
        grpc::ClientContext*, const Request&),
    const Request& request, Response* whole, Merge merge, Fallback fallback) {
  grpc::ClientContext context;
  rpc::PrepareContext(&context, connection->token(), kListingStreamTimeout,
                      /*wait_for_ready=*/false);
  auto reader = (connection->control()->*stream)(&context, request);
  Response batch;
  bool first = true;
  while (reader->Read(&batch)) {
    merge(first, &batch, whole);
    first = false;
  }
  grpc::Status status = reader->Finish();
  if (status.error_code() == grpc::StatusCode::UNIMPLEMENTED) {
    whole->Clear();
    return fallback();
  }
  return status;
}

// The seed as a JSON number when it is one (seeds are integers below 2^53).
nlohmann::json SeedJson(const std::string& seed) {
  int64_t value;
  return absl::SimpleAtoi(seed, &value) ? nlohmann::json(value) : nlohmann::json(seed);
}

// An option's canonical text as JSON, typed by its field in the trial's
// option table (TrialOptions::Table()): numbers (1 included, as 1.0) and
// integers as numbers, booleans as booleans, names and unknown keys as text.
nlohmann::json TypedOption(const std::string& key, const std::string& text) {
  const auto* field = learner::TrialOptions::Table().Find(key);
  const OptionType type = field == nullptr ? OptionType::kText : field->type;
  if (type == OptionType::kBool && (text == "true" || text == "false")) return text == "true";
  int64_t integer;
  if (type == OptionType::kInteger && absl::SimpleAtoi(text, &integer)) return integer;
  double number;
  if (type == OptionType::kNumber && absl::SimpleAtod(text, &number) && std::isfinite(number)) {
    return number;
  }
  return text;
}

bool IsRowCoordinate(const std::string& key) { return key == "method" || key == "seed"; }

}  // namespace

std::vector<std::string> EpisodeJobColumnNames(const v1::JobInfo& job) {
  std::vector<std::string> names = {"job_state", "success", "final_eval_cost"};
  for (const v1::TrialOption& option : job.options()) {
    if (!IsRowCoordinate(option.key())) names.push_back(option.key());
  }
  return names;
}

void AppendEpisodeJobColumns(const v1::JobInfo& job, nlohmann::json* row) {
  (*row)["job_state"] = StateName(job.state());
  // Only a completed trial has a verdict (study jobs have none).
  const bool has_result = job.state() == v1::JOB_STATE_COMPLETED && job.kind() != v1::JOB_KIND_STUDY;
  (*row)["success"] = has_result ? nlohmann::json(job.success()) : nlohmann::json(nullptr);
  (*row)["final_eval_cost"] = has_result && std::isfinite(job.final_eval_cost())
                                  ? nlohmann::json(job.final_eval_cost())
                                  : nlohmann::json(nullptr);
  for (const v1::TrialOption& option : job.options()) {
    if (!IsRowCoordinate(option.key())) (*row)[option.key()] = TypedOption(option.key(), option.value());
  }
}

nlohmann::json EpisodeRowJson(const v1::EpisodeRow& row, const v1::JobInfo* job) {
  const auto& table = learner::EpisodeFields();
  learner::EpisodeSummary episode;
  record_proto::RecordFromProto(table, row.report(), &episode);
  nlohmann::json object = {{"job_id", row.job_id()}, {"attempt", row.attempt()},
                           {"final_attempt", row.final_attempt()}, {"method", row.method()},
                           {"seed", SeedJson(row.seed())}, {"variant", row.variant()}};
  if (job != nullptr) AppendEpisodeJobColumns(*job, &object);
  io::AppendRecordJson(table, episode, &object);
  object["reported_unix_ms"] = row.reported_unix_ms();
  object["details"] = nlohmann::json::parse(row.report().details_json(), nullptr, false);
  if (object["details"].is_discarded()) object["details"] = row.report().details_json();
  return object;
}

grpc::Status ForEachJobPage(Connection* connection, v1::ListJobsRequest request,
                            const std::function<grpc::Status(const v1::ListJobsResponse&)>& page) {
  request.set_page_size(kJobsPerPage);
  request.set_after_job_id(0);
  while (true) {
    v1::ListJobsResponse response;
    grpc::Status status = connection->Call(&v1::ControlService::Stub::ListJobs, request, &response);
    if (!status.ok()) return status;
    status = page(response);
    if (!status.ok()) return status;
    if (response.next_after_job_id() == 0) return grpc::Status::OK;
    request.set_after_job_id(response.next_after_job_id());
  }
}

grpc::Status ForEachEpisodeRowWithJob(
    Connection* connection, const std::string& sweep, bool all_attempts,
    const std::function<void(const v1::EpisodeRow&, const v1::JobInfo&)>& sink) {
  EpisodeRowCursor rows(connection, sweep, all_attempts, kListingStreamTimeout);
  const auto no_job = [](const v1::EpisodeRow& row) {
    return grpc::Status(grpc::StatusCode::INTERNAL,
                        absl::StrCat("episode row of job ", row.job_id(), " attempt ",
                                     row.attempt(), " whose job is not listed"));
  };
  v1::ListJobsRequest request;
  request.set_sweep_name(sweep);
  grpc::Status status = ForEachJobPage(connection, request, [&](const v1::ListJobsResponse& page) {
    for (const v1::JobInfo& job : page.jobs()) {
      for (const v1::EpisodeRow* row = rows.Peek(); row != nullptr && row->job_id() <= job.job_id();
           row = rows.Peek()) {
        if (row->job_id() < job.job_id()) return no_job(*row);
        sink(*row, job);
        rows.Pop();
      }
    }
    return grpc::Status::OK;
  });
  if (status.ok() && rows.Peek() != nullptr) status = no_job(*rows.Peek());
  const grpc::Status stream = rows.Finish();
  return status.ok() ? stream : status;
}

grpc::Status ForEachEpisodeRow(Connection* connection, const std::string& sweep,
                               bool all_attempts,
                               const std::function<void(const v1::EpisodeRow&)>& sink) {
  EpisodeRowCursor rows(connection, sweep, all_attempts, kListingStreamTimeout);
  for (const v1::EpisodeRow* row = rows.Peek(); row != nullptr; row = rows.Peek()) {
    sink(*row);
    rows.Pop();
  }
  return rows.Finish();
}

EpisodeRowCursor::EpisodeRowCursor(Connection* connection, const std::string& sweep,
                                   bool all_attempts, absl::Duration timeout) {
  v1::ExportEpisodesRequest request;
  request.set_sweep_name(sweep);
  request.set_all_attempts(all_attempts);
  rpc::PrepareContext(&context_, connection->token(), timeout, /*wait_for_ready=*/false);
  reader_ = connection->control()->ExportEpisodes(&context_, request);
}

EpisodeRowCursor::~EpisodeRowCursor() {
  if (finished_) return;
  context_.TryCancel();
  Finish();
}

const v1::EpisodeRow* EpisodeRowCursor::Peek() {
  while (next_ >= batch_.rows_size()) {
    if (ended_ || !reader_->Read(&batch_)) {
      ended_ = true;
      return nullptr;
    }
    next_ = 0;
  }
  return &batch_.rows(next_);
}

grpc::Status EpisodeRowCursor::Finish() {
  finished_ = true;
  while (!ended_ && reader_->Read(&batch_)) {
  }
  ended_ = true;
  return reader_->Finish();
}

grpc::Status FetchTrialResults(Connection* connection, const std::string& sweep,
                               v1::ListTrialResultsResponse* response) {
  v1::SweepRequest request;
  request.set_name(sweep);
  return ReadBatches(
      connection, &v1::ControlService::Stub::ExportTrialResults, request, response,
      [](bool first, v1::ListTrialResultsResponse* batch, v1::ListTrialResultsResponse* whole) {
        if (first) *whole->mutable_sweep() = batch->sweep();
        for (auto& row : *batch->mutable_results()) *whole->add_results() = std::move(row);
      },
      [&] {
        return connection->Call(&v1::ControlService::Stub::ListTrialResults, request, response);
      });
}

grpc::Status FetchStudyRows(Connection* connection, const std::string& sweep, bool all_attempts,
                            v1::ListStudyRowsResponse* response) {
  v1::ListStudyRowsRequest request;
  request.set_sweep_name(sweep);
  request.set_all_attempts(all_attempts);
  return ReadBatches(
      connection, &v1::ControlService::Stub::ExportStudyRows, request, response,
      [](bool first, v1::ListStudyRowsResponse* batch, v1::ListStudyRowsResponse* whole) {
        if (first) *whole->mutable_sweep() = batch->sweep();
        for (auto& row : *batch->mutable_cells()) *whole->add_cells() = std::move(row);
        for (auto& row : *batch->mutable_references()) *whole->add_references() = std::move(row);
      },
      [&] {
        return connection->Call(&v1::ControlService::Stub::ListStudyRows, request, response);
      });
}

}  // namespace totalgrad::cli
