// `totalgrad results export` (episode rows as CSV or JSON lines, or the whole
// sweep as an archive) and `totalgrad results import` (an archive into this
// coordinator). The archive format is server/service/sweep_archive.h.
#include <chrono>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/format.h"
#include "server/common/build_info.h"
#include "server/service/sweep_archive.h"

namespace totalgrad::cli {
namespace {

constexpr size_t kImportChunkBytes = 1 << 20;

nlohmann::json NumberOrNull(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

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

int ExportRows(Connection* c, const std::string& sweep, bool all_attempts, bool csv,
               std::ostream& out, int64_t* rows) {
  if (csv) {
    out << "job_id,attempt,final_attempt,method,seed,variant,episode,real_cost,eval_cost_mean,"
           "eval_cost_std,predicted_cost,wall_seconds,cpu_seconds,reported_unix_ms,details_json\n";
  }
  const grpc::Status status = ForEachEpisodeRow(c, sweep, all_attempts, [&](const v1::EpisodeRow& r) {
    const auto& e = r.report();
    ++*rows;
    const double cpu = e.has_cpu_seconds() ? e.cpu_seconds() : std::nan("");
    if (csv) {
      out << r.job_id() << "," << r.attempt() << "," << (r.final_attempt() ? 1 : 0) << ","
          << CsvField(r.method()) << "," << CsvField(r.seed()) << "," << CsvField(r.variant())
          << "," << e.episode() << "," << FormatNumber(e.real_cost()) << ","
          << FormatNumber(e.eval_cost_mean()) << "," << FormatNumber(e.eval_cost_std()) << ","
          << FormatNumber(e.predicted_cost()) << "," << FormatNumber(e.optimisation_seconds())
          << "," << FormatNumber(cpu) << "," << r.reported_unix_ms() << ","
          << CsvField(e.details_json()) << "\n";
      return;
    }
    nlohmann::json object = {{"job_id", r.job_id()}, {"attempt", r.attempt()},
                             {"final_attempt", r.final_attempt()}, {"method", r.method()},
                             {"seed", SeedJson(r.seed())}, {"variant", r.variant()},
                             {"episode", e.episode()}, {"real_cost", NumberOrNull(e.real_cost())},
                             {"eval_cost_mean", NumberOrNull(e.eval_cost_mean())},
                             {"eval_cost_std", NumberOrNull(e.eval_cost_std())},
                             {"predicted_cost", NumberOrNull(e.predicted_cost())},
                             {"wall_seconds", NumberOrNull(e.optimisation_seconds())},
                             {"cpu_seconds", NumberOrNull(cpu)},
                             {"reported_unix_ms", r.reported_unix_ms()}};
    object["details"] = nlohmann::json::parse(e.details_json(), nullptr, false);
    if (object["details"].is_discarded()) object["details"] = e.details_json();
    out << object.dump() << "\n";
  });
  if (!status.ok()) return ReportError(status, "results export " + sweep);
  return 0;
}

int ExportArchive(Connection* c, const std::string& sweep_name, std::ostream& out) {
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

}  // namespace

void AddArchiveCommands(CLI::App* results, int* exit_code) {
  auto sweep = std::make_shared<std::string>();
  auto all_attempts = std::make_shared<bool>(false);
  auto output = std::make_shared<std::string>();
  auto format = std::make_shared<std::string>("csv");
  CLI::App* export_cmd = AddCommand(
      results, "export",
      "write a sweep's results: every episode row (-f csv, the default, or -f jsonl: one JSON "
      "object per row) or the whole sweep as an archive for `results import` (-f json: spec, "
      "jobs with their options, attempts with worker builds, episodes, study rows)",
      exit_code,
      [sweep, all_attempts, output, format](Connection* c) {
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
                             ? ExportArchive(c, *sweep, out)
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
                  << response.study_rows_imported() << " study rows); "
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
