// `totalgrad results export` (episode rows as CSV or JSON lines, or the whole
// sweep as an archive), `totalgrad results import` (an archive into this
// coordinator) and `totalgrad sweep delete` (archive, then delete). The
// archive format is server/service/sweep_archive.h.
#include <ctime>
#include <fstream>
#include <iostream>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "client/service_commands/archive_export.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/output_file.h"
#include "client/service_commands/format.h"
#include "client/service_commands/streamed_reads.h"
#include "core/learner/episode_record.h"
#include "io/record_format.h"
#include "runtime/record_proto.h"

namespace totalgrad::cli {
namespace {

constexpr size_t kImportChunkBytes = 1 << 20;

// One row per episode: the row's coordinates, its job's columns (state,
// verdict, final cost, options: streamed_reads.h, AppendEpisodeJobColumns),
// the episode's record (its CSV columns or JSON keys, io/record_format.h over
// learner::EpisodeFields()), when it was reported, and the details. The CSV
// header's option columns are the union over the sweep's jobs (a first pass
// over the job pages), in first-seen order.
int ExportRows(Connection* c, const std::string& sweep, bool all_attempts, bool csv,
               std::ostream& out, int64_t* rows) {
  const auto& table = learner::EpisodeFields();
  std::vector<std::string> option_keys;
  if (csv) {
    std::set<std::string> seen;
    v1::ListJobsRequest request;
    request.set_sweep_name(sweep);
    const grpc::Status listed = ForEachJobPage(c, request, [&](const v1::ListJobsResponse& page) {
      for (const v1::JobInfo& job : page.jobs()) {
        for (const std::string& name : EpisodeJobColumnNames(job)) {
          if (seen.insert(name).second) option_keys.push_back(name);
        }
      }
      return grpc::Status::OK;
    });
    if (!listed.ok()) return ReportError(listed, "results export " + sweep);
    std::vector<std::string> columns = {"job_id", "attempt", "final_attempt", "method", "seed",
                                        "variant"};
    if (option_keys.empty()) option_keys = {"job_state", "success", "final_eval_cost"};
    columns.insert(columns.end(), option_keys.begin(), option_keys.end());
    for (const std::string& column : io::RecordCsvColumns(table)) columns.push_back(column);
    columns.push_back("reported_unix_ms");
    columns.push_back("details_json");
    out << io::CsvLine(columns) << "\n";
  }
  const grpc::Status status = ForEachEpisodeRowWithJob(
      c, sweep, all_attempts, [&](const v1::EpisodeRow& r, const v1::JobInfo& job) {
        ++*rows;
        if (!csv) {
          out << EpisodeRowJson(r, &job).dump() << "\n";
          return;
        }
        const auto& e = r.report();
        learner::EpisodeSummary episode;
        record_proto::RecordFromProto(table, e, &episode);
        std::vector<std::string> cells = {std::to_string(r.job_id()), std::to_string(r.attempt()),
                                          r.final_attempt() ? "1" : "0", r.method(), r.seed(),
                                          r.variant()};
        // The job's columns as text: the JSON's typed values written back
        // (numbers in their shortest round-trip form, booleans 1/0, null empty).
        nlohmann::json job_columns = nlohmann::json::object();
        AppendEpisodeJobColumns(job, &job_columns);
        for (const std::string& key : option_keys) {
          const auto it = job_columns.find(key);
          if (it == job_columns.end() || it->is_null()) {
            cells.emplace_back();
          } else if (it->is_boolean()) {
            cells.push_back(it->get<bool>() ? "1" : "0");
          } else if (it->is_number_float()) {
            cells.push_back(io::RecordNumberText(it->get<double>()));
          } else if (it->is_string()) {
            cells.push_back(it->get<std::string>());
          } else {
            cells.push_back(it->dump());
          }
        }
        for (std::string& cell : io::RecordCsvCells(table, episode)) cells.push_back(std::move(cell));
        cells.push_back(std::to_string(r.reported_unix_ms()));
        cells.push_back(e.details_json());
        out << io::CsvLine(cells) << "\n";
      });
  if (!status.ok()) return ReportError(status, "results export " + sweep);
  return 0;
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

// `results export`'s flags.
struct ExportFlags {
  std::string sweep;
  std::string format = "csv";  // csv, jsonl or json (an archive)
  std::string output;          // empty: stdout
  bool all_attempts = false;
  bool checkpoints = false;
};

int RunExport(Connection* c, const ExportFlags& flags) {
  // A file appears under its name only complete (output_file.h);
  // stdout gets the rows as they arrive.
  std::unique_ptr<OutputFile> file;
  if (!flags.output.empty()) {
    absl::StatusOr<std::unique_ptr<OutputFile>> created =
        OutputFile::Create(flags.output, OutputFile::Existing::kReplace, 0666);
    if (!created.ok()) {
      std::cerr << "error: results export: " << created.status().message() << "\n";
      return 1;
    }
    file = *std::move(created);
  }
  std::ostream& out = file ? file->stream() : std::cout;
  int64_t rows = 0;
  const int code =
      flags.format == "json"
          ? ExportArchive(c, flags.sweep, out, flags.checkpoints, /*counted=*/nullptr)
          : ExportRows(c, flags.sweep, flags.all_attempts, flags.format == "csv", out, &rows);
  if (code != 0) return code;
  if (file) {
    if (const absl::Status written = file->Commit(); !written.ok()) {
      std::cerr << "error: results export: " << written.message() << "\n";
      return 1;
    }
  } else if (!out.flush()) {
    std::cerr << "error: results export: writing stdout failed\n";
    return 1;
  }
  if (!flags.output.empty()) {
    if (flags.format == "json") {
      std::cerr << "archive of sweep " << flags.sweep << " written to " << flags.output << "\n";
    } else {
      std::cerr << rows << " rows written to " << flags.output << "\n";
    }
  }
  return 0;
}

}  // namespace

grpc::Status ImportArchive(Connection* c, const std::string& archive,
                           v1::ImportSweepResponse* response) {
  std::ifstream in(archive, std::ios::binary);
  if (!in) return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "cannot read " + archive);
  grpc::ClientContext context;
  rpc::PrepareContext(&context, c->token(), absl::Minutes(30), /*wait_for_ready=*/false);
  auto writer = c->control()->ImportSweep(&context, response);
  std::string buffer(kImportChunkBytes, '\0');
  bool first = true;
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const std::streamsize got = in.gcount();
    if (got <= 0) break;
    v1::ImportSweepChunk chunk;
    chunk.set_data(buffer.data(), static_cast<size_t>(got));
    if (first) chunk.set_source_name(archive);
    first = false;
    if (!writer->Write(chunk)) break;  // the coordinator ended the call: Finish says why
  }
  writer->WritesDone();
  return writer->Finish();
}

std::string ImportSummary(const v1::ImportSweepResponse& response) {
  std::string summary = absl::StrCat(
      response.sweep_created() ? "created" : "into existing", " sweep ", response.sweep().name(),
      ": ", response.jobs_imported(), " jobs taken over (", response.episodes_imported(),
      " episodes, ", response.study_rows_imported(), " study rows, ",
      response.checkpoints_imported(), " checkpoints); ", response.jobs_already_complete(),
      " already complete here, ", response.jobs_not_completed(), " not completed in the archive, ",
      response.jobs_running_here(), " running here, ", response.jobs_unknown(),
      " not in this sweep");
  if (response.jobs_keeping_options() > 0) {
    absl::StrAppend(&summary, "; ", response.jobs_keeping_options(),
                    " keep the options their trials ran with (this build's defaults differ in ",
                    absl::StrJoin(response.options_kept(), ", "), ")");
  }
  return summary;
}

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
        const auto archive_not_written = [&](const absl::Status& error) {
          std::cerr << "error: sweep delete " << *name << ": the archive could not be written ("
                    << error.message() << "); nothing was deleted\n";
          return 1;
        };
        absl::StatusOr<std::unique_ptr<OutputFile>> file =
            OutputFile::Create(path, OutputFile::Existing::kRefuse, 0600);
        if (!file.ok()) return archive_not_written(file.status());
        v1::SweepContents counted;
        if (const int code =
                ExportArchive(c, *name, (*file)->stream(), /*with_checkpoints=*/true, &counted);
            code != 0)
          return code;
        if (const absl::Status written = (*file)->Commit(); !written.ok()) {
          return archive_not_written(written);
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
  auto flags = std::make_shared<ExportFlags>();
  CLI::App* export_cmd = AddCommand(
      results, "export",
      "write a sweep's results: every episode row (-f csv, the default, or -f jsonl: one JSON "
      "object per row) or the whole sweep as an archive for `results import` (-f json: spec, "
      "jobs with their options, attempts with worker builds, episodes, study rows)",
      exit_code, [flags](Connection* c) { return RunExport(c, *flags); },
      /*with_format=*/false);
  export_cmd->add_option("SWEEP", flags->sweep, "sweep name")->required();
  export_cmd->add_option("-f,--format", flags->format, "csv (default), jsonl or json (an archive)")
      ->check(CLI::IsMember({"csv", "jsonl", "json"}));
  export_cmd->add_flag("--all-attempts", flags->all_attempts,
                       "rows of every attempt, not only each job's counting one (csv, jsonl; an "
                       "archive always has all)");
  export_cmd->add_option("-o,--output", flags->output, "write to FILE instead of stdout");
  export_cmd->add_flag("--checkpoints", flags->checkpoints,
                       "json: keep each completed trial's final checkpoint (its final policy and "
                       "GP data) in the archive, so that an import can re-evaluate it (`job "
                       "artifacts`); sizes on stderr. `sweep delete` always keeps them");

  auto archive = std::make_shared<std::string>();
  CLI::App* import_cmd = AddCommand(
      results, "import",
      "take over the completed jobs of a sweep archive (`results export SWEEP -f json` of another "
      "coordinator): creates the sweep if this coordinator has none of that name; jobs completed "
      "here are kept; then resubmit the sweep file and only the missing jobs run. With --db "
      "DB it imports into that database file instead (created when missing; refused while a "
      "coordinator holds it), e.g. to read an archive with `results ... --db DB`",
      exit_code,
      [archive](Connection* c) {
        v1::ImportSweepResponse response;
        const grpc::Status status = ImportArchive(c, *archive, &response);
        if (!status.ok()) return ReportError(status, "results import " + *archive);
        std::cout << ImportSummary(response) << "\n";
        return 0;
      },
      /*with_format=*/false, /*offline=*/nullptr, /*db_writable=*/true);
  import_cmd->add_option("FILE", *archive, "archive written by results export -f json")
      ->required();
}

}  // namespace totalgrad::cli
