// Sweep specifications: what a sweep file says, its canonical form and hash,
// and its expansion into jobs.
//
// A sweep is a grid (methods x seeds x task variants x any other trial option)
// plus protocol overrides. Options are the trial runner's own (key, text)
// pairs (learner::SetTrialOption), so any option a method takes can be swept
// without the service knowing it, and an unknown method or key is refused by
// the runner's own validation.
//
// Sweep file (TOML; docs/service.md has the full reference):
//
//   name = "table1"                 # [A-Za-z0-9._-], 1..64 characters
//   description = "free text"       # optional
//   max_attempts = 3                # optional: application failures per job
//   max_lost_leases = 20            # optional: lost leases/releases per job
//   max_concurrent = 0              # optional: running jobs at once, 0 = no limit
//   [grid]                          # axes in file order, first varies slowest
//   method = ["RP", "PILCO"]
//   seed = { first = 0, count = 100 }   # or a list: [1, 2, 3]
//   noise_k = [0.01, 1.0]
//   [protocol]                      # applied to every job before the grid
//   episodes = 15
//   [[study]]                       # optional, repeatable: one study job each
//   name = "swingup-h30"            # [A-Za-z0-9._-], 1..64, unique in the sweep
//   file = "study.json"             # a study file, relative to the sweep file
//   # or: spec = '''{"problem": ...}'''  (the study file's JSON inline)
//   scene = "pendubot"              # optional: a synthetic study's scene; a
//                                   # snapshot study must already be on it
//
// A sweep has a [grid], [[study]] entries or both; study jobs come after the
// grid's trial jobs. A study's snapshot file is read when the sweep file is
// parsed and inlined (only the snapshot the study uses), so the spec that
// travels to the coordinator and workers is self-contained.
//
// Files: sweep_toml.cc reads sweep files; sweep_spec.cc the rest.
//
// Threading: free functions, no shared state.
#ifndef TOTALGRAD_SERVER_SWEEP_SWEEP_SPEC_H_
#define TOTALGRAD_SERVER_SWEEP_SWEEP_SPEC_H_

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/common/option_pairs.h"
#include "runtime/job_kind.h"

namespace totalgrad::sweep {


struct GridAxis {
  std::string key;
  std::vector<std::string> values;
};

// One [[study]] entry: a gradient study run as one job.
struct StudyEntry {
  std::string name;
  // The self-contained study file (snapshot inlined) as JSON text; canonical
  // (sorted keys, no whitespace) after CanonicalizeSpec.
  std::string spec_json;
  // File name or "inline"; informational (not hashed).
  std::string source;
};

struct SweepSpec {
  std::string name;
  std::string description;
  std::vector<GridAxis> grid;
  OptionPairs protocol;
  int max_attempts = 0;     // 0: kDefaultMaxAttempts
  int max_lost_leases = 0;  // 0: kDefaultMaxLostLeases
  int max_concurrent = 0;   // 0: no limit
  std::vector<StudyEntry> studies;
};

// Learned episodes per trial the service runs (it stores one row per
// episode and counts them in 32 bits; a trial of even 1000 episodes fits a
// GP on far more data than is practical).
inline constexpr int kMaxTrialEpisodes = 10000;
// Seeds are below 2^53: results reach readers as JSON and pandas numbers
// (doubles), which hold every smaller integer exactly.
inline constexpr uint64_t kMaxExactSeed = uint64_t{1} << 53;
inline constexpr int kDefaultMaxAttempts = 3;
inline constexpr int kDefaultMaxLostLeases = 20;
inline constexpr int kMaxJobsPerSweep = 100000;
inline constexpr size_t kMaxSourceBytes = 1 << 20;
// A study's self-contained spec (with its inlined snapshot).
inline constexpr size_t kMaxStudySpecBytes = 2 << 20;
inline constexpr int kMaxStudiesPerSweep = 1000;

// A trial or a study job (runtime/job_kind.h, the one definition).
using ::totalgrad::JobKind;

// One job of an expanded sweep.
struct ExpandedJob {
  JobKind kind = JobKind::kTrial;
  // Study jobs: the canonical study spec; method is "study", seed the
  // study's seed, variant the entry's name, options empty, episodes 0.
  std::string payload;
  std::string method;
  std::string seed;
  // "key=value ..." for the grid axes other than method and seed.
  std::string variant;
  // Every trial option as (key, canonical text): enough to re-run the trial.
  OptionPairs options;
  // Episodes the trial reports (the random one + the learned ones).
  int episodes_expected = 0;
};

// Parses a sweep file. InvalidArgument "FILE:LINE:COLUMN: FIELD: what is
// wrong" for a TOML syntax error, an unknown or mistyped field, or a value
// the trial runner refuses for its key. Nothing is validated across fields
// here beyond each value on its own; ValidateSpec/ExpandJobs do the rest.
absl::StatusOr<SweepSpec> ParseSweepToml(absl::string_view text, const std::string& file_name);
// Reads and parses the file at `path` (NotFound / InvalidArgument).
absl::StatusOr<SweepSpec> LoadSweepFile(const std::string& path, std::string* source_text);

// Checks the whole spec and rewrites every value in the runner's canonical
// text (e.g. "1.0" -> "1") and sorts [protocol] by key (each key sets its
// own option, so their order means nothing), so equal sweeps have equal
// canonical forms. The grid keeps its order (it is the job order).
// InvalidArgument naming the field: bad name, no method axis, empty axis,
// duplicate values or keys, a key in both grid and protocol, bad limits, a
// value the runner refuses or that exceeds a limit of the service, too many
// jobs.
absl::Status CanonicalizeSpec(SweepSpec* spec);

// Deterministic JSON of a canonicalized spec, and its SHA-256 in hex.
std::string CanonicalJson(const SweepSpec& spec);
std::string SpecHash(const SweepSpec& spec);
// The inverse of CanonicalJson (for `results import`: a sweep moved between
// coordinators is re-created from its canonical form).
// CanonicalJson(*SpecFromCanonicalJson(CanonicalJson(s))) == CanonicalJson(s).
// InvalidArgument naming the field that is missing or mistyped.
absl::StatusOr<SweepSpec> SpecFromCanonicalJson(const std::string& text);
// The hash builds before issue 12 gave the same spec: [protocol] in the
// order of `protocol_order` (the submitted order) instead of sorted. Equal to
// SpecHash when that order is already sorted. The coordinator accepts a
// resubmission of a sweep stored under this hash as the same sweep.
std::string LegacySpecHash(const SweepSpec& canonical,
                           const std::vector<std::string>& protocol_order);

// A sweep or study name: 1 to 64 characters from A-Z a-z 0-9 . _ -.
bool ValidSweepName(const std::string& name);

// Checks one study entry's self-contained spec (what the coordinator
// receives): a JSON object the study parser accepts, its snapshot inlined
// (a path is refused: the coordinator and workers cannot read the user's
// files). Returns the canonical JSON text. InvalidArgument naming the field.
absl::StatusOr<std::string> CanonicalStudySpec(const std::string& spec_json);

// A stored sweep and a resubmission of it with more values (issue 15: sweeps
// that grow). The union keeps the stored grid's axes in their order, each
// axis's stored values in their order followed by the submitted values it
// lacks, and the stored studies followed by new ones; the description is the
// submitted one. FailedPrecondition naming what differs otherwise: the grid's
// axes (added, removed or reordered: every job's identity would change), a
// protocol key or value, a limit, or a study of the same name with another
// spec. Both specs must be canonical. A job's identity is (kind, method,
// seed, variant), so the stored jobs are among the union's.
absl::StatusOr<SweepSpec> UnionOfSweeps(const SweepSpec& stored, const SweepSpec& submitted);

// Expands a canonicalized spec into its jobs, in grid order, then one job
// per study entry, handing each to `visit` as it is made and keeping none:
// the memory of expanding a sweep of 100,000 jobs is one job's (issue 28:
// a coordinator stores a submission while it expands it). Stops at the first
// error: `visit`'s, or InvalidArgument naming the grid point if the runner's
// whole-options validation refuses one (the jobs before it were visited).
absl::Status ForEachExpandedJob(const SweepSpec& spec,
                                const std::function<absl::Status(ExpandedJob&&)>& visit);
// The same, collected (errors as ForEachExpandedJob's).
absl::StatusOr<std::vector<ExpandedJob>> ExpandJobs(const SweepSpec& spec);

// The estimated CPU cost of a sweep's trial jobs (core/learner/cost_model.h),
// on the cost model's reference machine.
struct SweepCostEstimate {
  int trials = 0;
  int studies = 0;          // study jobs are not estimated
  double cpu_seconds = 0;   // all trials
  std::string reference_machine;
  // "about 12.3 CPU hours for 40 trials (reference machine: ...)" plus a note
  // on study jobs when there are any.
  std::string Text() const;
};
// InvalidArgument as ExpandJobs (the spec is canonicalized on a copy first).
absl::StatusOr<SweepCostEstimate> EstimateSweepCost(const SweepSpec& spec);

// Applies option pairs to default trial options (the scene's horizon and
// threshold where not given: learner::TrialOptionsFromPairs) and returns the full
// canonical list (what a worker is given). InvalidArgument naming the key.
absl::StatusOr<OptionPairs> ResolveOptions(const OptionPairs& pairs);

// The service's own limits on trial options, beyond what the runner checks:
// InvalidArgument naming the option, its value and the limit
// (episodes <= kMaxTrialEpisodes, seed < kMaxExactSeed).
absl::Status CheckServiceLimits(const std::string& key, const std::string& value);

}  // namespace totalgrad::sweep

#endif  // TOTALGRAD_SERVER_SWEEP_SWEEP_SPEC_H_
