// `totalgrad results export` (episode rows as CSV or JSON lines, or the whole
// sweep as an archive), `totalgrad results import` (an archive into this
// coordinator) and `totalgrad sweep delete` (archive, then delete). The
// archive format is server/service/sweep_archive.h.
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/format.h"
#include "core/learner/episode_record.h"
#include "io/record_format.h"
#include "server/common/record_proto.h"
#include "server/common/build_info.h"
#include "server/service/sweep_archive.h"

namespace totalgrad::cli {
namespace {

constexpr size_t kImportChunkBytes = 1 << 20;

// The seed as a JSON number when it is one (seeds are integers below 2^53).
nlohmann::json SeedJson(const std::string& seed) {
  int64_t value;
  return absl::SimpleAtoi(seed, &value) ? nlohmann::json(value) : nlohmann::json(seed);
}

// Streams every episode row of the sweep to `sink` (constant memory).
grpc::Status ForEachEpisodeRow(Connection* c, const std::string& sweep, bool all_attempts,
                               const std::function<void(const v1::EpisodeRow&)>& sink) {
  v1::ExportEpisodesRequest request;
  request.set_sweep_name(sweep);
  request.set_all_attempts(all_attempts);
  grpc::ClientContext context;
  rpc::PrepareContext(&context, c->token(), absl::Minutes(30), /*wait_for_ready=*/false);
  auto reader = c->control()->ExportEpisodes(&context, request);
  v1::ExportEpisodesResponse batch;
  while (reader->Read(&batch))
    for (const auto& row : batch.rows()) sink(row);
  return reader->Finish();
}

// One row per episode: the row's coordinates, the episode's record (its CSV
// columns or JSON keys, io/record_format.h over learner::EpisodeFields()),
// when it was reported, and the details.
int ExportRows(Connection* c, const std::string& sweep, bool all_attempts, bool csv,
               std::ostream& out, int64_t* rows) {
  const auto& table = learner::EpisodeFields();
  if (csv) {
    std::vector<std::string> columns = {"job_id", "attempt", "final_attempt", "method", "seed",
                                        "variant"};
    for (const std::string& column : io::RecordCsvColumns(table)) columns.push_back(column);
    columns.push_back("reported_unix_ms");
    columns.push_back("details_json");
    out << io::CsvLine(columns) << "\n";
  }
  const grpc::Status status = ForEachEpisodeRow(c, sweep, all_attempts, [&](const v1::EpisodeRow& r) {
    const auto& e = r.report();
    ++*rows;
    learner::EpisodeSummary episode;
    record_proto::RecordFromProto(table, e, &episode);
    if (csv) {
      std::vector<std::string> cells = {std::to_string(r.job_id()), std::to_string(r.attempt()),
                                        r.final_attempt() ? "1" : "0", r.method(), r.seed(),
                                        r.variant()};
      for (std::string& cell : io::RecordCsvCells(table, episode)) cells.push_back(std::move(cell));
      cells.push_back(std::to_string(r.reported_unix_ms()));
      cells.push_back(e.details_json());
      out << io::CsvLine(cells) << "\n";
      return;
    }
    nlohmann::json object = {{"job_id", r.job_id()}, {"attempt", r.attempt()},
                             {"final_attempt", r.final_attempt()}, {"method", r.method()},
                             {"seed", SeedJson(r.seed())}, {"variant", r.variant()}};
    io::AppendRecordJson(table, episode, &object);
    object["reported_unix_ms"] = r.reported_unix_ms();
    object["details"] = nlohmann::json::parse(e.details_json(), nullptr, false);
    if (object["details"].is_discarded()) object["details"] = e.details_json();
    out << object.dump() << "\n";
  });
  if (!status.ok()) return ReportError(status, "results export " + sweep);
  return 0;
}

// `with_checkpoints`: each completed trial's final checkpoint (its final
// policy and GP data, what `job artifacts` writes) goes into the archive
// with the attempt it belongs to; the sizes are reported on stderr.
int ExportArchive(Connection* c, const std::string& sweep_name, std::ostream& out,
                  bool with_checkpoints) {
  v1::SweepRequest sweep_request;
  sweep_request.set_name(sweep_name);
  v1::SweepInfo sweep;
  grpc::Status status = c->Call(&v1::ControlService::Stub::GetSweep, sweep_request, &sweep);
  if (!status.ok()) return ReportError(status, "results export " + sweep_name);
  std::vector<service::ArchiveJobInput> jobs;
  std::map<int64_t, size_t> index_of;
  int64_t after = 0;
  for (;;) {
    v1::ListJobsRequest request;
    request.set_sweep_name(sweep_name);
    request.set_page_size(10000);
    request.set_after_job_id(after);
    v1::ListJobsResponse page;
    status = c->Call(&v1::ControlService::Stub::ListJobs, request, &page);
    if (!status.ok()) return ReportError(status, "results export " + sweep_name);
    if (page.jobs_size() == 0) break;
    for (const v1::JobInfo& job : page.jobs()) {
      index_of[job.job_id()] = jobs.size();
      service::ArchiveJobInput input;
      input.job = job;
      jobs.push_back(std::move(input));
      after = job.job_id();
    }
  }
  for (service::ArchiveJobInput& input : jobs) {
    v1::JobRequest request;
    request.set_job_id(input.job.job_id());
    v1::GetJobLogResponse log;
    status = c->Call(&v1::ControlService::Stub::GetJobLog, request, &log);
    if (!status.ok()) return ReportError(status, "results export " + sweep_name);
    input.attempts.assign(log.attempts().begin(), log.attempts().end());
  }
  if (with_checkpoints) {
    int kept = 0;
    int64_t bytes = 0;
    for (service::ArchiveJobInput& input : jobs) {
      if (input.job.state() != v1::JOB_STATE_COMPLETED || input.job.kind() != v1::JOB_KIND_TRIAL)
        continue;
      v1::JobRequest request;
      request.set_job_id(input.job.job_id());
      v1::GetJobArtifactsResponse artifacts;
      status = c->Call(&v1::ControlService::Stub::GetJobArtifacts, request, &artifacts);
      // A completed trial whose worker kept no checkpoint (too large, or an
      // import of an archive without them) is archived without one.
      if (status.error_code() == grpc::StatusCode::NOT_FOUND) continue;
      if (!status.ok()) return ReportError(status, "results export " + sweep_name);
      bytes += static_cast<int64_t>(artifacts.checkpoint().data().size());
      ++kept;
      input.checkpoints[artifacts.attempt()] = artifacts.checkpoint();
    }
    std::cerr << "results export " << sweep_name << ": " << kept << " checkpoints kept, "
              << (bytes + 1023) / 1024 << " KiB";
    if (kept > 0) std::cerr << " (" << (bytes / kept + 1023) / 1024 << " KiB a trial; base64 adds a third)";
    std::cerr << "\n";
  }
  status = ForEachEpisodeRow(c, sweep_name, /*all_attempts=*/true, [&](const v1::EpisodeRow& row) {
    auto it = index_of.find(row.job_id());
    if (it != index_of.end()) jobs[it->second].episodes.push_back(row);
  });
  if (!status.ok()) return ReportError(status, "results export " + sweep_name);
  v1::ListStudyRowsRequest study_request;
  study_request.set_sweep_name(sweep_name);
  study_request.set_all_attempts(true);
  v1::ListStudyRowsResponse study;
  status = c->Call(&v1::ControlService::Stub::ListStudyRows, study_request, &study);
  if (!status.ok()) return ReportError(status, "results export " + sweep_name);
  for (const auto& cell : study.cells()) {
    auto it = index_of.find(cell.job_id());
    if (it != index_of.end()) jobs[it->second].cells.push_back(cell);
  }
  for (const auto& reference : study.references()) {
    auto it = index_of.find(reference.job_id());
    if (it != index_of.end()) jobs[it->second].references.push_back(reference);
  }
  const int64_t now_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                             std::chrono::system_clock::now().time_since_epoch())
                             .count();
  out << service::SweepArchiveToJson(sweep, jobs, BuildId(), now_ms).dump(1) << "\n";
  return 0;
}

// What an archive holds, counted as the coordinator counts a sweep
// (storage::SweepContents): the guard of DeleteSweep.
v1::SweepContents CountArchive(const nlohmann::json& archive) {
  v1::SweepContents counts;
  for (const auto& job : archive.at("jobs")) {
    counts.set_jobs(counts.jobs() + 1);
    for (const auto& attempt : job.at("attempt_log")) {
      counts.set_attempts(counts.attempts() + 1);
      if (attempt.contains("episodes")) {
        counts.set_episodes(counts.episodes() + static_cast<int64_t>(attempt["episodes"].size()));
      }
      for (const char* rows : {"study_cells", "study_references"}) {
        if (attempt.contains(rows)) {
          counts.set_study_rows(counts.study_rows() + static_cast<int64_t>(attempt[rows].size()));
        }
      }
    }
  }
  return counts;
}

// Writes `text` to `path` durably: a new file (never over an existing one),
// written, fsync'ed, then renamed into place. The error names the path and
// the system's reason (e.g. "No space left on device").
absl::Status WriteNewFileDurably(const std::string& path, const std::string& text) {
  if (std::filesystem::exists(path)) {
    return absl::AlreadyExistsError(absl::StrCat(path, " already exists; not overwriting it"));
  }
  const std::string temporary = path + ".partial";
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) {
    return absl::UnavailableError(absl::StrCat("cannot create ", temporary, ": ",
                                               std::strerror(errno)));
  }
  size_t written = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string reason = std::strerror(errno);
      ::close(fd);
      std::filesystem::remove(temporary);
      return absl::UnavailableError(absl::StrCat("writing ", temporary, ": ", reason));
    }
    written += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    const std::string reason = std::strerror(errno);
    std::filesystem::remove(temporary);
    return absl::UnavailableError(absl::StrCat("syncing ", temporary, ": ", reason));
  }
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error) {
    std::filesystem::remove(temporary);
    return absl::UnavailableError(
        absl::StrCat("renaming ", temporary, " to ", path, ": ", error.message()));
  }
  return absl::OkStatus();
}

// "NAME.deleted-YYYYMMDDTHHMMSSZ.archive.json" in the current directory.
std::string DefaultDeleteArchivePath(const std::string& sweep) {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &utc);
  return absl::StrCat(sweep, ".deleted-", stamp, ".archive.json");
}

}  // namespace

void AddSweepDeleteCommand(CLI::App* sweep_cmd, int* exit_code) {
  auto name = std::make_shared<std::string>();
  auto archive_path = std::make_shared<std::string>();
  CLI::App* command = AddCommand(
      sweep_cmd, "delete",
      "archive a sweep to a file (as results export -f json writes it), then delete the sweep "
      "and everything stored for it; `results import FILE` brings it back. Refused while a trial "
      "of the sweep runs (cancel it first)",
      exit_code,
      [name, archive_path](Connection* c) {
        const std::string path =
            archive_path->empty() ? DefaultDeleteArchivePath(*name) : *archive_path;
        std::ostringstream archive_text;
        if (const int code = ExportArchive(c, *name, archive_text, /*with_checkpoints=*/true);
            code != 0)
          return code;
        const nlohmann::json archive = nlohmann::json::parse(archive_text.str());
        const v1::SweepContents counted = CountArchive(archive);
        if (const absl::Status written = WriteNewFileDurably(path, archive_text.str());
            !written.ok()) {
          std::cerr << "error: sweep delete " << *name << ": the archive could not be written ("
                    << written.message() << "); nothing was deleted\n";
          return 1;
        }
        v1::DeleteSweepRequest request;
        request.set_name(*name);
        *request.mutable_expected() = counted;
        v1::DeleteSweepResponse response;
        const grpc::Status status =
            c->Call(&v1::ControlService::Stub::DeleteSweep, request, &response);
        if (!status.ok()) {
          const int code = ReportError(status, "sweep delete " + *name);
          std::cerr << "the sweep was not deleted; its archive stays in " << path << "\n";
          return code;
        }
        const v1::SweepContents& deleted = response.deleted();
        std::cout << "deleted sweep " << *name << " (" << deleted.jobs() << " jobs, "
                  << deleted.attempts() << " attempts, " << deleted.episodes() << " episodes, "
                  << deleted.study_rows() << " study rows)\narchived to " << path
                  << "\nrestore with: totalgrad results import " << path << "\n";
        return 0;
      },
      /*with_format=*/false);
  command->add_option("SWEEP", *name, "sweep name")->required();
  command->add_option("--archive", *archive_path,
                      "write the archive to FILE (default: SWEEP.deleted-<UTC time>.archive.json "
                      "in the current directory; an existing file is never overwritten)");
}

void AddArchiveCommands(CLI::App* results, int* exit_code) {
  auto sweep = std::make_shared<std::string>();
  auto all_attempts = std::make_shared<bool>(false);
  auto output = std::make_shared<std::string>();
  auto format = std::make_shared<std::string>("csv");
  auto checkpoints = std::make_shared<bool>(false);
  CLI::App* export_cmd = AddCommand(
      results, "export",
      "write a sweep's results: every episode row (-f csv, the default, or -f jsonl: one JSON "
      "object per row) or the whole sweep as an archive for `results import` (-f json: spec, "
      "jobs with their options, attempts with worker builds, episodes, study rows)",
      exit_code,
      [sweep, all_attempts, output, format, checkpoints](Connection* c) {
        std::ofstream file;
        if (!output->empty()) {
          file.open(*output);
          if (!file) {
            std::cerr << "error: results export: cannot write " << *output << "\n";
            return 1;
          }
        }
        std::ostream& out = output->empty() ? std::cout : file;
        int64_t rows = 0;
        const int code = *format == "json"
                             ? ExportArchive(c, *sweep, out, *checkpoints)
                             : ExportRows(c, *sweep, *all_attempts, *format == "csv", out, &rows);
        if (code != 0) return code;
        out.flush();
        if (!out) {
          std::cerr << "error: results export: writing " << (output->empty() ? "stdout" : *output)
                    << " failed\n";
          return 1;
        }
        if (!output->empty()) {
          if (*format == "json") std::cerr << "archive of sweep " << *sweep << " written to " << *output << "\n";
          else std::cerr << rows << " rows written to " << *output << "\n";
        }
        return 0;
      },
      /*with_format=*/false);
  export_cmd->add_option("SWEEP", *sweep, "sweep name")->required();
  export_cmd->add_option("-f,--format", *format, "csv (default), jsonl or json (an archive)")
      ->check(CLI::IsMember({"csv", "jsonl", "json"}));
  export_cmd->add_flag("--all-attempts", *all_attempts,
                       "rows of every attempt, not only each job's counting one (csv, jsonl; an "
                       "archive always has all)");
  export_cmd->add_option("-o,--output", *output, "write to FILE instead of stdout");
  export_cmd->add_flag("--checkpoints", *checkpoints,
                       "json: keep each completed trial's final checkpoint (its final policy and "
                       "GP data) in the archive, so that an import can re-evaluate it (`job "
                       "artifacts`); sizes on stderr. `sweep delete` always keeps them");

  auto archive = std::make_shared<std::string>();
  CLI::App* import_cmd = AddCommand(
      results, "import",
      "take over the completed jobs of a sweep archive (`results export SWEEP -f json` of another "
      "coordinator): creates the sweep if this coordinator has none of that name; jobs completed "
      "here are kept; then resubmit the sweep file and only the missing jobs run",
      exit_code,
      [archive](Connection* c) {
        std::ifstream in(*archive, std::ios::binary);
        if (!in) {
          std::cerr << "error: results import: cannot read " << *archive << "\n";
          return 2;
        }
        grpc::ClientContext context;
        rpc::PrepareContext(&context, c->token(), absl::Minutes(30), /*wait_for_ready=*/false);
        v1::ImportSweepResponse response;
        auto writer = c->control()->ImportSweep(&context, &response);
        std::string buffer(kImportChunkBytes, '\0');
        bool first = true;
        while (in) {
          in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
          const std::streamsize got = in.gcount();
          if (got <= 0) break;
          v1::ImportSweepChunk chunk;
          chunk.set_data(buffer.data(), static_cast<size_t>(got));
          if (first) chunk.set_source_name(*archive);
          first = false;
          if (!writer->Write(chunk)) break;  // the coordinator ended the call: Finish says why
        }
        writer->WritesDone();
        const grpc::Status status = writer->Finish();
        if (!status.ok()) return ReportError(status, "results import " + *archive);
        std::cout << (response.sweep_created() ? "created" : "into existing") << " sweep "
                  << response.sweep().name() << ": " << response.jobs_imported()
                  << " jobs taken over (" << response.episodes_imported() << " episodes, "
                  << response.study_rows_imported() << " study rows, "
                  << response.checkpoints_imported() << " checkpoints); "
                  << response.jobs_already_complete() << " already complete here, "
                  << response.jobs_not_completed() << " not completed in the archive, "
                  << response.jobs_running_here() << " running here, " << response.jobs_unknown()
                  << " not in this sweep\n";
        return 0;
      },
      /*with_format=*/false);
  import_cmd->add_option("FILE", *archive, "archive written by results export -f json")
      ->required();
}

}  // namespace totalgrad::cli
