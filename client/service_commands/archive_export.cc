#include "client/service_commands/archive_export.h"

#include <chrono>
#include <iostream>
#include <map>
#include <utility>
#include <vector>

#include "client/service_commands/streamed_reads.h"
#include "runtime/build_info.h"
#include "server/service/sweep_archive.h"
#include "server/service/sweep_archive_writer.h"

namespace totalgrad::cli {
namespace {

// The episode stream stays open while every job's log is fetched beside it.
constexpr absl::Duration kArchiveStreamTimeout = absl::Hours(6);

// Study rows by job (a sweep's study jobs are few; their rows are held).
struct StudyRowsOfJob {
  std::vector<v1::StudyCellRow> cells;
  std::vector<v1::StudyReferenceRow> references;
};

std::map<int64_t, StudyRowsOfJob> ByJob(v1::ListStudyRowsResponse* rows) {
  std::map<int64_t, StudyRowsOfJob> by_job;
  for (auto& cell : *rows->mutable_cells()) by_job[cell.job_id()].cells.push_back(std::move(cell));
  for (auto& reference : *rows->mutable_references()) {
    by_job[reference.job_id()].references.push_back(std::move(reference));
  }
  return by_job;
}

// Checkpoints kept in the archive, for the line on stderr.
struct CheckpointTally {
  int kept = 0;
  int64_t bytes = 0;
};

// Fills one job's attempts and, when asked, its final checkpoint. A
// completed trial whose worker kept no checkpoint (too large, or an import
// of an archive without them) is archived without one.
grpc::Status FetchJobDetails(Connection* c, bool with_checkpoints, service::ArchiveJobInput* input,
                             CheckpointTally* tally) {
  v1::JobRequest request;
  request.set_job_id(input->job.job_id());
  v1::GetJobLogResponse log;
  grpc::Status status = c->Call(&v1::ControlService::Stub::GetJobLog, request, &log);
  if (!status.ok()) return status;
  input->attempts.assign(log.attempts().begin(), log.attempts().end());
  if (!with_checkpoints || input->job.state() != v1::JOB_STATE_COMPLETED ||
      input->job.kind() != v1::JOB_KIND_TRIAL) {
    return grpc::Status::OK;
  }
  v1::GetJobArtifactsResponse artifacts;
  status = c->Call(&v1::ControlService::Stub::GetJobArtifacts, request, &artifacts);
  if (status.error_code() == grpc::StatusCode::NOT_FOUND) return grpc::Status::OK;
  if (!status.ok()) return status;
  tally->bytes += static_cast<int64_t>(artifacts.checkpoint().data().size());
  ++tally->kept;
  input->checkpoints[artifacts.attempt()] = artifacts.checkpoint();
  return grpc::Status::OK;
}

// Moves the rows of job `job_id` from the cursor (ordered by job id, like
// the jobs) into *episodes; rows of jobs not listed are passed over.
void TakeEpisodesOf(int64_t job_id, EpisodeRowCursor* rows, std::vector<v1::EpisodeRow>* episodes) {
  for (const v1::EpisodeRow* row = rows->Peek(); row != nullptr && row->job_id() <= job_id;
       row = rows->Peek()) {
    if (row->job_id() == job_id) episodes->push_back(*row);
    rows->Pop();
  }
}

}  // namespace

int ExportArchive(Connection* c, const std::string& sweep_name, std::ostream& out,
                  bool with_checkpoints, v1::SweepContents* counted) {
  const std::string what = "results export " + sweep_name;
  v1::SweepRequest sweep_request;
  sweep_request.set_name(sweep_name);
  v1::SweepInfo sweep;
  grpc::Status status = c->Call(&v1::ControlService::Stub::GetSweep, sweep_request, &sweep);
  if (!status.ok()) return ReportError(status, what);
  v1::ListStudyRowsResponse study;
  status = FetchStudyRows(c, sweep_name, /*all_attempts=*/true, &study);
  if (!status.ok()) return ReportError(status, what);
  std::map<int64_t, StudyRowsOfJob> study_rows = ByJob(&study);

  const int64_t now_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                             std::chrono::system_clock::now().time_since_epoch())
                             .count();
  service::SweepArchiveWriter writer(&out, sweep, BuildId(), now_ms);
  EpisodeRowCursor episodes(c, sweep_name, /*all_attempts=*/true, kArchiveStreamTimeout);
  CheckpointTally tally;
  v1::ListJobsRequest jobs;
  jobs.set_sweep_name(sweep_name);
  status = ForEachJobPage(c, jobs, [&](const v1::ListJobsResponse& page) {
    for (const v1::JobInfo& job : page.jobs()) {
      service::ArchiveJobInput input;
      input.job = job;
      if (grpc::Status got = FetchJobDetails(c, with_checkpoints, &input, &tally); !got.ok()) {
        return got;
      }
      TakeEpisodesOf(job.job_id(), &episodes, &input.episodes);
      if (auto rows = study_rows.find(job.job_id()); rows != study_rows.end()) {
        input.cells = std::move(rows->second.cells);
        input.references = std::move(rows->second.references);
      }
      writer.AddJob(input);
    }
    return grpc::Status::OK;
  });
  if (!status.ok()) return ReportError(status, what);
  status = episodes.Finish();
  if (!status.ok()) return ReportError(status, what);
  writer.Finish();
  if (with_checkpoints) {
    std::cerr << what << ": " << tally.kept << " checkpoints kept, " << (tally.bytes + 1023) / 1024
              << " KiB";
    if (tally.kept > 0) {
      std::cerr << " (" << (tally.bytes / tally.kept + 1023) / 1024
                << " KiB a trial; base64 adds a third)";
    }
    std::cerr << "\n";
  }
  if (counted != nullptr) *counted = writer.counted();
  return 0;
}

}  // namespace totalgrad::cli
