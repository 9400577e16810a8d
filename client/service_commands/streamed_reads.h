// The CLI's reads of what grows with a sweep, none as one message (issue 28):
// jobs page by page (ListJobs pages end at page_size jobs or about 1 MiB),
// episode rows from the ExportEpisodes stream, trial results and study rows
// from their streams (ExportTrialResults, ExportStudyRows), falling back to
// the unary ListTrialResults / ListStudyRows of a coordinator older than
// those streams (it answers UNIMPLEMENTED).
#ifndef TOTALGRAD_CLIENT_SERVICE_COMMANDS_STREAMED_READS_H_
#define TOTALGRAD_CLIENT_SERVICE_COMMANDS_STREAMED_READS_H_

#include <grpcpp/client_context.h>
#include <grpcpp/support/sync_stream.h>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/time/time.h"
#include "client/service_commands/connection.h"
#include "totalgrad/v1/control_service.grpc.pb.h"

namespace totalgrad::cli {

// Calls `page` with each page of the jobs `request` selects (its
// after_job_id and page_size are set here), in job id order, until the last
// page or the first non-OK status, which it returns.
grpc::Status ForEachJobPage(Connection* connection, v1::ListJobsRequest request,
                            const std::function<grpc::Status(const v1::ListJobsResponse&)>& page);

// Every episode row of the sweep, in order, to `sink` (constant memory).
grpc::Status ForEachEpisodeRow(Connection* connection, const std::string& sweep,
                               bool all_attempts,
                               const std::function<void(const v1::EpisodeRow&)>& sink);

// Every episode row of the sweep with its job, in order: the job pages
// (ListJobs) walked beside the rows, both in job id order, so memory is one
// page of jobs and one batch of rows. INTERNAL naming the row when a row's
// job is not listed.
grpc::Status ForEachEpisodeRowWithJob(
    Connection* connection, const std::string& sweep, bool all_attempts,
    const std::function<void(const v1::EpisodeRow&, const v1::JobInfo&)>& sink);

// The job's columns of an episode row, after its coordinates: the job's
// state ("completed", ...), its verdict and final evaluation cost (the
// counting attempt's; null while it has none), then every option of the job
// but method and seed (already columns) by its key, typed by the option
// table (learner::TrialOptions::Table(), OptionType): numbers as JSON
// numbers (noise_k 1 as 1.0), integers as integers, bools as booleans, names
// as text.
// EpisodeJobColumnNames is the same keys in order (for a CSV header).
void AppendEpisodeJobColumns(const v1::JobInfo& job, nlohmann::json* row);
std::vector<std::string> EpisodeJobColumnNames(const v1::JobInfo& job);

// One episode row as `results export -f jsonl` writes it and the Python
// module reads it: job_id, attempt, final_attempt, method, seed (a number
// when it is one), variant, with `job` its job's columns
// (AppendEpisodeJobColumns), the episode's record (learner::EpisodeFields(),
// io/record_format.h), reported_unix_ms and the parsed details.
nlohmann::json EpisodeRowJson(const v1::EpisodeRow& row, const v1::JobInfo* job = nullptr);

// The ExportEpisodes stream read one row at a time, for a reader that walks
// it beside another sequence in job id order (the archive's jobs).
class EpisodeRowCursor {
 public:
  EpisodeRowCursor(Connection* connection, const std::string& sweep, bool all_attempts,
                   absl::Duration timeout);
  ~EpisodeRowCursor();  // cancels the stream if it was not finished
  EpisodeRowCursor(const EpisodeRowCursor&) = delete;
  EpisodeRowCursor& operator=(const EpisodeRowCursor&) = delete;

  // The next row, or nullptr at the end of the stream (or after an error:
  // Finish returns it). Valid until Pop.
  const v1::EpisodeRow* Peek();
  void Pop() { ++next_; }
  // Reads what is left and returns the stream's status.
  grpc::Status Finish();

 private:
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::ExportEpisodesResponse>> reader_;
  v1::ExportEpisodesResponse batch_;
  int next_ = 0;
  bool ended_ = false;
  bool finished_ = false;
};

// Every completed trial's result with the sweep (ExportTrialResults, else
// ListTrialResults), into *response as ListTrialResults returns it.
grpc::Status FetchTrialResults(Connection* connection, const std::string& sweep,
                               v1::ListTrialResultsResponse* response);

// The sweep's study rows (ExportStudyRows, else ListStudyRows), into
// *response as ListStudyRows returns them.
grpc::Status FetchStudyRows(Connection* connection, const std::string& sweep, bool all_attempts,
                            v1::ListStudyRowsResponse* response);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_SERVICE_COMMANDS_STREAMED_READS_H_
