// `totalgrad sweep size NAME` and `totalgrad sweep prune NAME [--completed]
// [--dry-run]`: what a sweep's rows take in the coordinator's file and the
// removal of checkpoints nothing will read (PruneSweep). A checkpoint is a
// trial's state after an episode; from checkpoint format 4 it also holds the
// trial's trajectories (docs/diagnostics.md), so the completed trials' own
// checkpoints are removed only when asked (--completed).
#include <iostream>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "absl/strings/str_format.h"
#include "client/service_commands/connection.h"

namespace totalgrad::cli {
namespace {

std::string Megabytes(int64_t bytes) { return absl::StrFormat("%.1f MB", bytes / 1e6); }

std::string Checkpoints(const v1::CheckpointUse& use) {
  std::string text = absl::StrFormat("%d (%s", use.count(), Megabytes(use.bytes()));
  if (use.count() > 0) absl::StrAppendFormat(&text, ", %.0f KB each", use.bytes() / 1e3 / use.count());
  return text + ")";
}

void PrintUse(const std::string& sweep, const v1::PruneSweepResponse& use, Format format) {
  if (format != Format::kTable) {  // JSON (CSV has no shape for it: JSON too)
    const auto checkpoints = [](const v1::CheckpointUse& c) {
      return nlohmann::ordered_json{{"count", c.count()}, {"bytes", c.bytes()}};
    };
    nlohmann::ordered_json out;
    out["sweep"] = sweep;
    out["episodes"] = use.episodes();
    out["episode_details_bytes"] = use.episode_details_bytes();
    out["checkpoints_completed"] = checkpoints(use.completed());
    out["checkpoints_stale"] = checkpoints(use.stale());
    out["checkpoints_unfinished"] = checkpoints(use.unfinished());
    std::cout << out.dump(2) << "\n";
    return;
  }
  std::cout << "sweep " << sweep << ":\n"
            << "  episode rows                      " << use.episodes() << " (details text "
            << Megabytes(use.episode_details_bytes()) << ")\n"
            << "  checkpoints, completed trials     " << Checkpoints(use.completed())
            << ": final states with their trajectories\n"
            << "  checkpoints, superseded attempts  " << Checkpoints(use.stale())
            << ": read by nothing (sweep prune removes them)\n"
            << "  checkpoints, unfinished jobs      " << Checkpoints(use.unfinished())
            << ": where their next attempts resume (never pruned)\n";
}

v1::PruneScope Scope(bool completed) {
  return completed ? v1::PRUNE_SCOPE_COMPLETED : v1::PRUNE_SCOPE_STALE;
}

// `sweep prune`'s flags.
struct PruneFlags {
  std::string sweep;
  bool completed = false;  // also the completed trials' final states
  bool dry_run = false;
};

int Prune(Connection* c, const PruneFlags& flags) {
  const std::string& sweep = flags.sweep;
  const bool completed = flags.completed;
  const bool dry_run = flags.dry_run;
  const std::string what = "sweep prune " + sweep;
  v1::PruneSweepRequest request;
  request.set_name(sweep);
  request.set_scope(dry_run ? v1::PRUNE_SCOPE_NONE : Scope(completed));
  v1::PruneSweepResponse use;
  const grpc::Status status = c->Call(&v1::ControlService::Stub::PruneSweep, request, &use);
  if (!status.ok()) return ReportError(status, what);
  if (dry_run) {
    v1::CheckpointUse would = use.stale();
    if (completed) {
      would.set_count(would.count() + use.completed().count());
      would.set_bytes(would.bytes() + use.completed().bytes());
    }
    std::cout << "dry run: sweep prune " << sweep << (completed ? " --completed" : "")
              << " would remove " << would.count() << " checkpoints (" << Megabytes(would.bytes())
              << ")\n";
    return 0;
  }
  std::cout << "removed " << use.removed().count() << " checkpoints ("
            << Megabytes(use.removed().bytes()) << ") of sweep " << sweep
            << (completed ? ", the completed trials' final states (and trajectories) included"
                          : "")
            << "; the database file keeps its size and reuses the freed pages (VACUUM shrinks "
               "it)\n";
  return 0;
}

}  // namespace

void AddSweepDiskCommands(CLI::App* sweep_cmd, int* exit_code) {
  auto sweep = std::make_shared<std::string>();
  CLI::App* size = AddCommand(
      sweep_cmd, "size",
      "what a sweep's rows take in the coordinator's database: episode rows and trial "
      "checkpoints (final states with trajectories, superseded attempts', unfinished jobs')",
      exit_code, [sweep](Connection* c) {
        v1::PruneSweepRequest request;
        request.set_name(*sweep);
        request.set_scope(v1::PRUNE_SCOPE_NONE);
        v1::PruneSweepResponse use;
        const grpc::Status status = c->Call(&v1::ControlService::Stub::PruneSweep, request, &use);
        if (!status.ok()) return ReportError(status, "sweep size " + *sweep);
        PrintUse(*sweep, use, c->format());
        return 0;
      });
  size->add_option("NAME", *sweep, "sweep name")->required();

  auto prune_flags = std::make_shared<PruneFlags>();
  CLI::App* prune = AddCommand(
      sweep_cmd, "prune",
      "remove the checkpoints of a sweep's completed jobs that nothing reads (their superseded "
      "attempts'); --completed also removes the completed trials' final states, and with them "
      "their trajectories and `job artifacts` (export first: results export NAME --checkpoints)",
      exit_code,
      [prune_flags](Connection* c) { return Prune(c, *prune_flags); },
      /*with_format=*/false);
  prune->add_option("NAME", prune_flags->sweep, "sweep name")->required();
  prune->add_flag("--completed", prune_flags->completed,
                  "also the completed trials' own checkpoints (final states, trajectories)");
  prune->add_flag("--dry-run", prune_flags->dry_run, "say what would be removed, remove nothing");
}

}  // namespace totalgrad::cli
