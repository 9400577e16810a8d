// sweep / job / worker / results / admin subcommands. Each callback opens a
// connection, makes its calls with deadlines and retries, prints, and stores
// its exit code.
#include "client/service_commands/service_commands.h"

#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/streamed_reads.h"
#include "client/service_commands/format.h"
#include "server/service/convert.h"
#include "server/storage/service_records.h"
#include "server/sweep/sweep_proto.h"
#include "server/sweep/prepared_sweep.h"
#include "server/sweep/sweep_spec.h"

namespace totalgrad::cli {

void AddRunCommand(CLI::App* app, int* exit_code);  // run_command.cc
void AddJobArtifactCommands(CLI::App* job_cmd, int* exit_code);  // artifacts.cc
void AddCompareCommand(CLI::App* results, int* exit_code);  // compare.cc
void AddDiagnosticsCommand(CLI::App* results, int* exit_code);  // diagnostics_command.cc
void AddTable1Command(CLI::App* results, int* exit_code);   // table1_command.cc
void AddPowerCommand(CLI::App* results, int* exit_code);    // table1_command.cc

namespace {

// Sweep summaries: -f json|csv are the record's table
// (storage::SweepFields()); the text table is a view of some of its fields.
void PrintSweeps(const std::vector<const v1::SweepInfo*>& infos, Format format) {
  std::vector<storage::SweepRecord> sweeps;
  for (const auto* info : infos) sweeps.push_back(service::FromProto(*info));
  if (format != Format::kTable) {
    PrintRecords(storage::SweepFields(), sweeps, format, std::cout);
    return;
  }
  Listing listing;
  listing.columns = {"name", "state", "finished", "jobs", "queued", "running", "completed",
                     "failed", "cancelled", "episodes", "episodes_expected", "created", "spec_hash"};
  for (const storage::SweepRecord& s : sweeps) {
    listing.rows.push_back({s.name, std::string(storage::ToString(s.state)),
                            s.finished() ? "yes" : "no", std::to_string(s.jobs_total),
                            std::to_string(s.jobs_queued), std::to_string(s.jobs_running),
                            std::to_string(s.jobs_completed), std::to_string(s.jobs_failed),
                            std::to_string(s.jobs_cancelled), std::to_string(s.episodes_stored),
                            std::to_string(s.episodes_expected), FormatTime(s.created_ms),
                            s.spec_hash.substr(0, 12)});
  }
  Print(listing, format, std::cout);
}

// `sweep submit --dry-run` when no coordinator answers: the jobs and
// episodes the spec expands to, counted here.
int PrintLocalDryRun(sweep::SweepSpec spec) {
  const absl::StatusOr<sweep::PreparedSweep> prepared = sweep::PrepareSweep(std::move(spec));
  if (!prepared.ok()) {
    std::cerr << "error: " << prepared.status().message() << "\n";
    return kExitBadInput;
  }
  std::cout << "dry run (no coordinator answered; counted here, so whether it would grow a "
               "stored sweep is unknown): sweep "
            << prepared->spec.name << " would have " << prepared->jobs_total << " jobs ("
            << prepared->spec.studies.size() << " studies) and " << prepared->episodes_expected
            << " episodes (spec " << prepared->spec_hash.substr(0, 12) << ")\n";
  return 0;
}


// The estimated cost of what submitting `spec` would run, on stderr: of the
// whole sweep, or, when the coordinator holds a sweep of that name with
// another grid, of the jobs the submission would add (the union of the two
// grids less the stored one, as the coordinator grows it).
void PrintCostEstimate(Connection* connection, const sweep::SweepSpec& spec) {
  absl::StatusOr<sweep::SweepCostEstimate> cost = sweep::EstimateSweepCost(spec);
  if (!cost.ok()) return;  // the submission names the error
  if (connection != nullptr) {
    v1::SweepRequest request;
    request.set_name(spec.name);
    v1::SweepInfo stored;
    if (connection->Call(&v1::ControlService::Stub::GetSweep, request, &stored).ok()) {
      // As the coordinator grows a sweep: the union of the two canonical specs.
      absl::StatusOr<sweep::SweepSpec> old = sweep::SpecFromCanonicalJson(stored.canonical_spec());
      absl::StatusOr<sweep::PreparedSweep> submitted = sweep::PrepareSweep(spec);
      absl::StatusOr<sweep::SweepSpec> grown =
          !old.ok() ? old.status()
          : !submitted.ok() ? submitted.status()
                            : sweep::UnionOfSweeps(*old, submitted->spec);
      absl::StatusOr<sweep::SweepCostEstimate> before =
          old.ok() ? sweep::EstimateSweepCost(*old) : old.status();
      absl::StatusOr<sweep::SweepCostEstimate> after =
          grown.ok() ? sweep::EstimateSweepCost(*grown) : grown.status();
      if (before.ok() && after.ok()) {
        sweep::SweepCostEstimate added = *after;
        added.trials -= before->trials;
        added.studies -= before->studies;
        added.cpu_seconds -= before->cpu_seconds;
        if (added.trials == 0 && added.studies == 0) {
          std::cerr << "estimated cost: nothing new to run (sweep " << spec.name
                    << " is stored with these jobs)\n";
        } else {
          std::cerr << "estimated cost of the jobs this adds to sweep " << spec.name << ": "
                    << added.Text() << "\n";
        }
        return;
      }
      // A grid the stored one cannot grow into: the coordinator refuses it, naming why.
    }
  }
  std::cerr << "estimated cost: " << cost->Text() << "\n";
}

// `sweep submit FILE`: validates the file, prints the cost estimate, then
// submits it (or, with dry_run, asks the coordinator what it would store).
// `connection` null: no coordinator answered, which only a dry run survives
// (PrintLocalDryRun).
int SubmitSweepFile(Connection* connection, const std::string& file, bool wait, bool dry_run) {
  std::string source;
  absl::StatusOr<sweep::SweepSpec> spec = sweep::LoadSweepFile(file, &source);
  if (!spec.ok()) {
    std::cerr << "error: " << spec.status().message() << "\n";
    return 2;
  }
  // The cost before anything is stored: a mistake of 100x shows here.
  PrintCostEstimate(connection, *spec);
  if (connection == nullptr) return PrintLocalDryRun(*spec);
  v1::SubmitSweepRequest request;
  sweep::SweepSpecToProto(*spec, request.mutable_spec());
  request.set_source_name(file);
  request.set_source_text(source);
  request.set_dry_run(dry_run);
  v1::SubmitSweepResponse response;
  const grpc::Status status =
      connection->Call(&v1::ControlService::Stub::SubmitSweep, request, &response);
  if (!status.ok()) return ReportError(status, "sweep submit " + file);
  const v1::SweepInfo& info = response.sweep();
  if (dry_run) {
    std::cout << "dry run: sweep " << info.name() << " would have " << info.jobs_total()
              << " jobs (" << spec->studies.size() << " studies) and " << info.episodes_expected()
              << " episodes (spec " << info.spec_hash().substr(0, 12) << ")\n";
    return 0;
  }
  if (response.jobs_added() > 0) {
    std::cout << "grew sweep " << info.name() << " by " << response.jobs_added() << " jobs (now "
              << info.jobs_total() << " jobs, spec " << info.spec_hash().substr(0, 12) << ")";
    if (info.state() == v1::SWEEP_STATE_CANCELLED) {
      std::cout << "; the sweep is cancelled: `totalgrad sweep resume " << info.name()
                << "` runs them";
    }
    std::cout << "\n";
  } else {
    std::cout << (response.created() ? "submitted" : "already submitted (no change)")
              << ": sweep " << info.name() << ", " << info.jobs_total() << " jobs, spec "
              << info.spec_hash().substr(0, 12) << "\n";
  }
  if (!wait) return 0;
  return WaitForSweepUntilInterrupted(connection, info.name());
}

void AddSweepCommands(CLI::App* app, int* exit_code) {
  CLI::App* sweep_cmd = app->add_subcommand("sweep", "submit and control sweeps");
  sweep_cmd->require_subcommand(1);

  auto file = std::make_shared<std::string>();
  auto wait = std::make_shared<bool>(false);
  auto dry_run = std::make_shared<bool>(false);
  CLI::App* submit = AddCommand(
      sweep_cmd, "submit", "submit a sweep file (resubmitting the same file is a no-op)",
      exit_code,
      [file, wait, dry_run](Connection* connection) {
        return SubmitSweepFile(connection, *file, *wait, *dry_run);
      },
      /*with_format=*/true,
      // A dry run needs no coordinator: the jobs are then expanded here.
      [file, dry_run](const absl::Status& unreachable) -> std::optional<int> {
        if (!*dry_run) return std::nullopt;
        return SubmitSweepFile(nullptr, *file, /*wait=*/false, /*dry_run=*/true);
      });
  submit->add_option("FILE", *file, "sweep file (TOML)")->required();
  submit->add_flag("--wait", *wait, "show progress until the sweep finishes; exit 1 if it failed");
  submit->add_flag("--dry-run", *dry_run, "validate and count the jobs; store nothing");

  auto list_format = AddCommand(sweep_cmd, "list", "list sweeps", exit_code, [](Connection* c) {
    v1::ListSweepsResponse response;
    const grpc::Status status =
        c->Call(&v1::ControlService::Stub::ListSweeps, v1::ListSweepsRequest(), &response);
    if (!status.ok()) return ReportError(status, "sweep list");
    std::vector<const v1::SweepInfo*> sweeps;
    for (const auto& s : response.sweeps()) sweeps.push_back(&s);
    PrintSweeps(sweeps, c->format());
    return 0;
  });
  (void)list_format;

  auto status_name = std::make_shared<std::string>();
  auto status_wait = std::make_shared<bool>(false);
  CLI::App* status_cmd = AddCommand(
      sweep_cmd, "status", "show one sweep", exit_code,
      [status_name, status_wait](Connection* c) {
        if (*status_wait) {
          const int code = WaitForSweepUntilInterrupted(c, *status_name);
          if (code != 0 && code != 1) return code;
        }
        v1::SweepRequest request;
        request.set_name(*status_name);
        v1::SweepInfo info;
        const grpc::Status status = c->Call(&v1::ControlService::Stub::GetSweep, request, &info);
        if (!status.ok()) return ReportError(status, "sweep status " + *status_name);
        PrintSweeps({&info}, c->format());
        return info.finished() && info.jobs_completed() != info.jobs_total() ? 1 : 0;
      });
  status_cmd->add_option("SWEEP", *status_name, "sweep name")->required();
  status_cmd->add_flag("--wait", *status_wait, "show progress until the sweep finishes");

  struct Control {
    const char* name;
    const char* help;
    grpc::Status (v1::ControlService::Stub::*method)(grpc::ClientContext*, const v1::SweepRequest&,
                                                     v1::SweepInfo*);
  };
  for (const Control& control :
       {Control{"cancel", "cancel queued jobs and stop running trials (results are kept)",
                &v1::ControlService::Stub::CancelSweep},
        Control{"pause", "hand out no more jobs; running trials continue",
                &v1::ControlService::Stub::PauseSweep},
        Control{"resume", "hand out jobs again", &v1::ControlService::Stub::ResumeSweep}}) {
    auto name = std::make_shared<std::string>();
    CLI::App* command = AddCommand(
        sweep_cmd, control.name, control.help, exit_code, [name, control](Connection* c) {
          v1::SweepRequest request;
          request.set_name(*name);
          v1::SweepInfo info;
          const grpc::Status status = c->Call(control.method, request, &info);
          if (!status.ok()) return ReportError(status, absl::StrCat("sweep ", control.name, " ", *name));
          PrintSweeps({&info}, c->format());
          return 0;
        });
    command->add_option("SWEEP", *name, "sweep name")->required();
  }
  AddSweepDeleteCommand(sweep_cmd, exit_code);
  AddSweepDiskCommands(sweep_cmd, exit_code);  // size, prune (disk_commands.cc)
}

// `job list`: the jobs of `sweep_name` ("" all) in `states` (comma-separated
// names, "" all), page by page.
int ListJobs(Connection* c, const std::string& sweep_name, const std::string& states) {
  v1::ListJobsRequest request;
  request.set_sweep_name(sweep_name);
  if (!states.empty()) {
    for (absl::string_view state : absl::StrSplit(states, ',')) {
      const std::map<std::string, v1::JobState> names = {
          {"queued", v1::JOB_STATE_QUEUED}, {"running", v1::JOB_STATE_RUNNING},
          {"completed", v1::JOB_STATE_COMPLETED}, {"failed", v1::JOB_STATE_FAILED},
          {"cancelled", v1::JOB_STATE_CANCELLED}};
      auto it = names.find(std::string(state));
      if (it == names.end()) {
        std::cerr << "error: --state: '" << state
                  << "' is not one of queued, running, completed, failed, cancelled\n";
        return 2;
      }
      request.add_states(it->second);
    }
  }
  // -f json|csv: the job's table (storage::JobFields()), written page by
  // page as the pages arrive; the text table is a view of some of its
  // fields (its widths need every row first).
  RecordPrinter<storage::JobRecord> printer(storage::JobFields(), c->format(), std::cout);
  Listing listing;
  listing.columns = {"job",     "sweep",    "method", "seed",     "variant", "state",
                     "attempts", "failures", "lost",  "episodes", "worker",  "final_cost",
                     "success", "last_error"};
  const grpc::Status status =
      ForEachJobPage(c, request, [&](const v1::ListJobsResponse& page) {
        for (const v1::JobInfo& info : page.jobs()) {
          const storage::JobRecord j = service::FromProto(info);
          if (c->format() != Format::kTable) {
            printer.Add(j);
            continue;
          }
          const bool done = j.state == storage::JobState::kCompleted;
          listing.rows.push_back(
              {std::to_string(j.id), j.sweep_name, j.method, j.seed, j.variant,
               std::string(storage::ToString(j.state)), std::to_string(j.attempts),
               std::to_string(j.failures), std::to_string(j.lost_leases),
               absl::StrCat(j.episodes_stored, "/", j.episodes_expected), j.worker_id,
               done ? FormatFixed(j.final_eval_cost, 3) : "",
               done ? (j.success ? "yes" : "no") : "", j.last_error.substr(0, 60)});
        }
        return grpc::Status::OK;
      });
  if (!status.ok()) return ReportError(status, "job list");
  if (c->format() != Format::kTable) {
    printer.Finish();
    return 0;
  }
  Print(listing, c->format(), std::cout);
  return 0;
}

void AddJobCommands(CLI::App* app, int* exit_code) {
  CLI::App* job_cmd = app->add_subcommand("job", "inspect and retry jobs");
  job_cmd->require_subcommand(1);

  auto sweep_name = std::make_shared<std::string>();
  auto states = std::make_shared<std::string>();
  CLI::App* list = AddCommand(job_cmd, "list", "list jobs", exit_code, [sweep_name, states](Connection* c) {
    return ListJobs(c, *sweep_name, *states);
  });
  list->add_option("--sweep", *sweep_name, "only this sweep");
  list->add_option("--state", *states, "only these states, e.g. failed,running");

  auto retry_ids = std::make_shared<std::vector<int64_t>>();
  CLI::App* retry = AddCommand(job_cmd, "retry", "re-queue failed or cancelled jobs", exit_code,
                               [retry_ids](Connection* c) {
    int code = 0;
    for (int64_t id : *retry_ids) {
      v1::JobRequest request;
      request.set_job_id(id);
      v1::JobInfo job;
      const grpc::Status status = c->Call(&v1::ControlService::Stub::RetryJob, request, &job);
      if (!status.ok()) {
        code = ReportError(status, absl::StrCat("job retry ", id));
        continue;
      }
      std::cout << "job " << id << " re-queued (" << job.method() << " seed " << job.seed() << ")\n";
    }
    return code;
  }, /*with_format=*/false);
  retry->add_option("JOB", *retry_ids, "job ids")->required();

  auto superseded_id = std::make_shared<int64_t>(0);
  auto by_id = std::make_shared<int64_t>(0);
  CLI::App* supersede = AddCommand(
      job_cmd, "supersede",
      "replace a completed trial's result by a re-run of it from another sweep (same method, "
      "seed and options but the rollout verdict's): the re-run's completed attempt is copied "
      "in and counts from then on; the old attempts and an event keep the history",
      exit_code,
      [superseded_id, by_id](Connection* c) {
        v1::SupersedeJobRequest request;
        request.set_job_id(*superseded_id);
        request.set_by_job_id(*by_id);
        v1::JobInfo job;
        const grpc::Status status = c->Call(&v1::ControlService::Stub::SupersedeJob, request, &job);
        if (!status.ok()) return ReportError(status, absl::StrCat("job supersede ", *superseded_id));
        std::cout << "job " << job.job_id() << " (" << job.method() << " seed " << job.seed()
                  << ") now counts job " << *by_id << "'s result as its attempt " << job.attempts()
                  << ": final cost " << job.final_eval_cost() << "\n";
        return 0;
      },
      /*with_format=*/false);
  supersede->add_option("JOB", *superseded_id, "the completed trial to supersede")->required();
  supersede->add_option("--by", *by_id, "the completed re-run (a job of another sweep)")->required();

  AddJobArtifactCommands(job_cmd, exit_code);  // artifacts, trajectory (artifacts.cc)

  auto log_id = std::make_shared<int64_t>(0);
  CLI::App* logs = AddCommand(job_cmd, "logs", "a job's attempts, errors and events", exit_code,
                              [log_id](Connection* c) {
    v1::JobRequest request;
    request.set_job_id(*log_id);
    v1::GetJobLogResponse response;
    const grpc::Status status = c->Call(&v1::ControlService::Stub::GetJobLog, request, &response);
    if (!status.ok()) return ReportError(status, absl::StrCat("job logs ", *log_id));
    const v1::JobInfo& job = response.job();
    if (c->format() == Format::kTable) {
      std::cout << "job " << job.job_id() << " of sweep " << job.sweep_name() << ": "
                << job.method() << " seed " << job.seed() << " " << job.variant() << ", "
                << StateName(job.state()) << "\noptions:";
      for (const auto& o : job.options()) std::cout << " " << o.key() << "=" << o.value();
      std::cout << "\n\n";
    }
    Listing attempts;
    attempts.columns = {"attempt", "state", "worker", "host", "build", "started", "ended",
                        "episodes", "error"};
    attempts.numeric_columns = {"attempt", "episodes"};
    const char* names[] = {"?", "running", "completed", "failed", "lease_lost", "released", "cancelled"};
    for (const auto& a : response.attempts()) {
      attempts.rows.push_back({std::to_string(a.attempt()), names[std::clamp<int>(a.state(), 0, 6)],
                               a.worker_id(), a.worker_host(), a.worker_build(),
                               FormatTime(a.started_unix_ms()), FormatTime(a.ended_unix_ms()),
                               std::to_string(a.episodes_stored()), a.error()});
    }
    Print(attempts, c->format(), std::cout);
    if (c->format() == Format::kTable) {
      std::cout << "\nevents:\n";
      for (const auto& e : response.events()) {
        std::cout << "  " << FormatTime(e.unix_ms()) << "  attempt " << e.attempt() << "  "
                  << e.kind() << "  " << e.message() << "\n";
      }
    }
    return 0;
  });
  logs->add_option("JOB", *log_id, "job id")->required();
}

void AddWorkerCommands(CLI::App* app, int* exit_code) {
  CLI::App* worker_cmd = app->add_subcommand("worker", "inspect workers");
  worker_cmd->require_subcommand(1);
  AddCommand(worker_cmd, "list", "workers the coordinator has heard from", exit_code, [](Connection* c) {
    v1::ListWorkersResponse response;
    const grpc::Status status =
        c->Call(&v1::ControlService::Stub::ListWorkers, v1::ListWorkersRequest(), &response);
    if (!status.ok()) return ReportError(status, "worker list");
    Listing listing;
    listing.columns = {"worker", "state", "host", "slots", "running", "last_seen", "build"};
    listing.numeric_columns = {"slots", "running"};
    const char* names[] = {"?", "active", "draining", "gone"};
    for (const auto& w : response.workers()) {
      listing.rows.push_back({w.worker_id(), names[std::clamp<int>(w.state(), 0, 3)], w.host(),
                              std::to_string(w.slots()), std::to_string(w.running()),
                              FormatTime(w.last_seen_unix_ms()), w.build()});
    }
    Print(listing, c->format(), std::cout);
    return 0;
  });
  auto drain_id = std::make_shared<std::string>();
  CLI::App* drain = AddCommand(worker_cmd, "drain",
                               "stop giving a worker new jobs: its running trials get the worker's "
                               "--drain-timeout to finish (then they are released and resume from "
                               "their checkpoints elsewhere), and it exits; a new process with the "
                               "same id gets work again",
                               exit_code, [drain_id](Connection* c) {
    v1::DrainWorkerRequest request;
    request.set_worker_id(*drain_id);
    v1::WorkerInfo info;
    const grpc::Status status = c->Call(&v1::ControlService::Stub::DrainWorker, request, &info);
    if (!status.ok()) return ReportError(status, "worker drain " + *drain_id);
    std::cout << "worker " << info.worker_id() << " is draining (" << info.running()
              << " trials running)\n";
    return 0;
  }, /*with_format=*/false);
  drain->add_option("WORKER", *drain_id, "worker id")->required();
}

void AddResultsCommands(CLI::App* app, int* exit_code) {
  CLI::App* results = app->add_subcommand("results", "query results");
  results->require_subcommand(1);
  auto table_sweep = std::make_shared<std::string>();
  auto table_plot = std::make_shared<std::string>();
  CLI::App* table = AddCommand(results, "table",
                               "success rate per method and task variant, 95% Wilson interval, n",
                               exit_code, [table_sweep, table_plot](Connection* c) {
    return PrintResultsTable(c, *table_sweep, c->format(), *table_plot);
  });
  table->add_option("SWEEP", *table_sweep, "sweep name")->required();
  table->add_option("--plot", *table_plot,
                    "also draw the success rates with their Wilson intervals into FILE.svg, "
                    "FILE.pdf or FILE.png (gnuplot)");

  auto curves_sweep = std::make_shared<std::string>();
  auto plot = std::make_shared<std::string>();
  auto top = std::make_shared<int>(0);
  CLI::App* curves = AddCommand(results, "curves",
                                "median, quartiles, mean and standard error of the evaluation "
                                "cost per episode over completed trials",
                                exit_code, [curves_sweep, plot, top](Connection* c) {
    if (*top > 0 && plot->empty()) {
      std::cerr << "error: results curves: --top K draws the paper's Figure 3; give --plot FILE\n";
      return 2;
    }
    return PrintCurves(c, *curves_sweep, c->format(), *plot, /*print_table=*/true, *top);
  });
  curves->add_option("SWEEP", *curves_sweep, "sweep name")->required();
  curves->add_option("--plot", *plot, "also draw the curves into FILE.svg, FILE.pdf or FILE.png (gnuplot)");
  curves->add_option("--top", *top,
                     "draw the paper's Figure 3: per variant all runs (median and quartiles; mean "
                     "+- standard error) beside the K runs of lowest final cost")
      ->check(CLI::Range(1, 100000));

  AddArchiveCommands(results, exit_code);  // export, import (archive_commands.cc)
  AddCompareCommand(results, exit_code);
  AddDiagnosticsCommand(results, exit_code);
  AddTable1Command(results, exit_code);
  AddPowerCommand(results, exit_code);

  auto study_sweep = std::make_shared<std::string>();
  auto study_references = std::make_shared<bool>(false);
  auto study_all = std::make_shared<bool>(false);
  auto study_output = std::make_shared<std::string>();
  auto study_plot = std::make_shared<std::string>();
  CLI::App* study_cmd = AddCommand(
      results, "study",
      "the rows of the sweep's study jobs: one per study cell (the columns of a study's "
      "table.csv), or per reference gradient",
      exit_code, [study_sweep, study_references, study_all, study_output, study_plot](Connection* c) {
        std::ofstream file;
        if (!study_output->empty()) {
          file.open(*study_output);
          if (!file) {
            std::cerr << "error: results study: cannot write " << *study_output << "\n";
            return 1;
          }
        }
        return PrintStudyResults(c, *study_sweep, c->format(), *study_references, *study_all,
                                 study_output->empty() ? std::cout : file, *study_plot);
      });
  study_cmd->add_option("SWEEP", *study_sweep, "sweep name")->required();
  study_cmd->add_flag("--references", *study_references,
                      "the reference gradients (references.csv columns) instead of the cells");
  study_cmd->add_flag("--all-attempts", *study_all, "include failed and lost attempts");
  study_cmd->add_option("-o,--output", *study_output, "write to FILE instead of stdout");
  study_cmd->add_option("--plot", *study_plot,
                        "also draw each study's work-precision plot (points labelled with P) and "
                        "horizon sweep, PNG and PDF, into DIR/<study>/ (gnuplot)");
}

void AddAdminCommands(CLI::App* app, int* exit_code) {
  CLI::App* admin = app->add_subcommand("admin", "coordinator health and backups");
  admin->require_subcommand(1);
  AddCommand(admin, "health", "is the coordinator serving", exit_code, [](Connection* c) {
    v1::HealthResponse response;
    const grpc::Status status =
        c->Call(&v1::ControlService::Stub::Health, v1::HealthRequest(), &response);
    if (!status.ok()) return ReportError(status, "admin health");
    Listing listing;
    listing.columns = {"serving", "build", "database", "sweeps", "queued", "running", "workers"};
    listing.numeric_columns = {"sweeps", "queued", "running", "workers"};
    listing.rows.push_back({response.serving() ? "yes" : "no", response.build(),
                            response.database(), std::to_string(response.sweeps()),
                            std::to_string(response.jobs_queued()),
                            std::to_string(response.jobs_running()),
                            std::to_string(response.workers_active())});
    Print(listing, c->format(), std::cout);
    if (!response.serving()) {
      std::cerr << "not serving: "
                << (response.not_serving_reason().empty() ? "(no reason given)"
                                                          : response.not_serving_reason())
                << "\n";
    }
    return response.serving() ? 0 : 1;
  });
  auto backup_name = std::make_shared<std::string>();
  CLI::App* backup = AddCommand(admin, "backup", "consistent copy of the database (online backup)",
                                exit_code, [backup_name](Connection* c) {
    v1::BackupRequest request;
    request.set_file_name(*backup_name);
    v1::BackupResponse response;
    const grpc::Status status = c->Call(&v1::ControlService::Stub::Backup, request, &response);
    if (!status.ok()) return ReportError(status, "admin backup " + *backup_name);
    std::cout << "backup written on the coordinator: " << response.path() << " ("
              << response.bytes() << " bytes)\n";
    return 0;
  }, /*with_format=*/false);
  backup->add_option("NAME", *backup_name, "file name inside the coordinator's --backup-dir")
      ->required();
}

}  // namespace

void AddServiceCommands(CLI::App* app, int* exit_code) {
  AddSweepCommands(app, exit_code);
  AddJobCommands(app, exit_code);
  AddWorkerCommands(app, exit_code);
  AddResultsCommands(app, exit_code);
  AddAdminCommands(app, exit_code);
  AddRunCommand(app, exit_code);
  app->footer(
      "Exit codes of the service commands: 0 success; 1 failed (a refused operation, a waited "
      "sweep with failed jobs); 2 bad input (malformed file, unknown name, bad token); 3 the "
      "coordinator is unreachable (no answer); 4 the coordinator answered but cannot do it "
      "(its database is full, failing, deleted or locked by another process: see its log).");
}

}  // namespace totalgrad::cli
