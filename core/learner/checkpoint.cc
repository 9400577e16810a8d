#include "core/learner/checkpoint.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "core/common/binary_codec.h"
#include "core/common/check.h"
#include "core/common/record.h"
#include "core/common/rng.h"
#include "core/learner/trajectory.h"
#include "core/tasks/scene.h"

namespace totalgrad::learner {
namespace {

constexpr char kMagic[8] = {'T', 'G', 'C', 'K', 'P', 'T', '\0', '\0'};
using binary::Fnv1a;
using binary::Reader;
using binary::Writer;


void WriteHyperparameters(Writer& w, const gp::GpHyperparameters& h) {
  w.Mat(h.log_lengthscales);
  w.Vec(h.log_signal_std);
  w.Vec(h.log_noise_std);
}

gp::GpHyperparameters ReadHyperparameters(Reader& r) {
  gp::GpHyperparameters h;
  h.log_lengthscales = r.Mat("hyperparameters.log_lengthscales");
  h.log_signal_std = r.Vec("hyperparameters.log_signal_std");
  h.log_noise_std = r.Vec("hyperparameters.log_noise_std");
  return h;
}

// The episode record's fields that version 1 did not write in fixed
// positions: versions 2 and 3 write every other field of EpisodeFields() by
// name, so a field added to the record is checkpointed with no change here
// (version 2: (name, double); version 3: (name, type, value), a type
// kNamedDouble or kNamedDoubles).
constexpr uint8_t kNamedDouble = 0;
constexpr uint8_t kNamedDoubles = 1;

std::vector<const record::Field<EpisodeSummary>*> NamedEpisodeFields() {
  static const std::vector<std::string> kVersion1 = {
      "episode", "real_cost", "eval_cost_mean", "eval_cost_std", "predicted_cost",
      "optimisation_seconds", "cpu_seconds"};
  std::vector<const record::Field<EpisodeSummary>*> named;
  for (const record::Field<EpisodeSummary>& field : EpisodeFields()) {
    if (std::find(kVersion1.begin(), kVersion1.end(), field.name) != kVersion1.end()) continue;
    // Doubles and lists of doubles; a field of another type needs a writer here first.
    TG_CHECK(field.type() == record::FieldType::kDouble ||
             field.type() == record::FieldType::kDoubles);
    named.push_back(&field);
  }
  return named;
}

void WriteEpisode(Writer& w, const EpisodeResult& e) {
  w.I64(e.episode);
  w.F64(e.real_cost);
  w.F64(e.eval_cost_mean);
  w.F64(e.eval_cost_std);
  w.F64(e.predicted_cost);
  w.F64(e.optimisation_seconds);
  WriteHyperparameters(w, e.hyperparameters);
  w.Vec(e.policy_parameters);
  w.I64(e.flags.non_finite_gradients);
  w.I64(e.flags.gp_line_search_failures);
  w.I64(e.flags.gp_non_finite_evaluations);
  w.U8(e.flags.zero_gradient ? 1 : 0);
  w.U8(e.flags.gp_jitter ? 1 : 0);
  w.Vec(e.predicted_cost_mean_per_step);
  w.Vec(e.predicted_cost_std_per_step);
  const EpisodeTiming& t = e.timing;
  for (double v : {e.cpu_seconds, t.model_cpu, t.model_wall, t.policy_cpu, t.policy_wall,
                   t.prediction_cpu, t.prediction_wall, t.real_episode_cpu, t.real_episode_wall,
                   t.evaluation_cpu, t.evaluation_wall})
    w.F64(v);
  w.I64(t.policy_steps);
  // The record's fields that version 1 does not list, by name and type.
  const std::vector<const record::Field<EpisodeSummary>*> named = NamedEpisodeFields();
  w.U64(named.size());
  for (const record::Field<EpisodeSummary>* field : named) {
    w.Str(field->name);
    if (field->type() == record::FieldType::kDouble) {
      w.U8(kNamedDouble);
      w.F64(field->Get<double>(e));
    } else {
      w.U8(kNamedDoubles);
      const std::vector<double>& values = field->Get<std::vector<double>>(e);
      w.Vec(Eigen::Map<const Vector>(values.data(), static_cast<Eigen::Index>(values.size())));
    }
  }
  // Version 4: the episode's trajectories, as their own format's bytes
  // (empty: none).
  w.Str(e.trajectories.empty() ? std::string() : EncodeEpisodeTrajectories(e.trajectories));
}

EpisodeResult ReadEpisode(Reader& r, uint32_t version) {
  EpisodeResult e;
  e.episode = static_cast<int>(r.I64("episodes[].episode"));
  e.real_cost = r.F64("episodes[].real_cost");
  e.eval_cost_mean = r.F64("episodes[].eval_cost_mean");
  e.eval_cost_std = r.F64("episodes[].eval_cost_std");
  e.predicted_cost = r.F64("episodes[].predicted_cost");
  e.optimisation_seconds = r.F64("episodes[].optimisation_seconds");
  e.hyperparameters = ReadHyperparameters(r);
  e.policy_parameters = r.Vec("episodes[].policy_parameters");
  e.flags.non_finite_gradients = static_cast<int>(r.I64("episodes[].flags"));
  e.flags.gp_line_search_failures = static_cast<int>(r.I64("episodes[].flags"));
  e.flags.gp_non_finite_evaluations = static_cast<int>(r.I64("episodes[].flags"));
  e.flags.zero_gradient = r.U8("episodes[].flags") != 0;
  e.flags.gp_jitter = r.U8("episodes[].flags") != 0;
  e.predicted_cost_mean_per_step = r.Vec("episodes[].predicted_cost_mean_per_step");
  e.predicted_cost_std_per_step = r.Vec("episodes[].predicted_cost_std_per_step");
  EpisodeTiming& t = e.timing;
  for (double* v : {&e.cpu_seconds, &t.model_cpu, &t.model_wall, &t.policy_cpu, &t.policy_wall,
                    &t.prediction_cpu, &t.prediction_wall, &t.real_episode_cpu,
                    &t.real_episode_wall, &t.evaluation_cpu, &t.evaluation_wall})
    *v = r.F64("episodes[].timing");
  t.policy_steps = static_cast<int>(r.I64("episodes[].timing.policy_steps"));
  if (version < 2) return e;  // the fields added since read as their defaults
  const uint64_t named = r.U64("episodes[].fields");
  if (r.ok() && named > 10000) r.Fail("episodes[].fields", "too many");
  for (uint64_t i = 0; i < named && r.ok(); ++i) {
    const std::string name = r.Str("episodes[].fields[].name");
    // Version 2 wrote doubles only, untyped.
    const uint8_t type = version >= 3 ? r.U8("episodes[].fields[].type") : kNamedDouble;
    double value = 0;
    Vector values;
    if (type == kNamedDouble) value = r.F64("episodes[].fields[].value");
    else if (type == kNamedDoubles) values = r.Vec("episodes[].fields[].values");
    else if (r.ok()) r.Fail("episodes[].fields[].type", absl::StrCat("unknown type ", type));
    const record::Field<EpisodeSummary>* field = nullptr;
    for (const record::Field<EpisodeSummary>* f : NamedEpisodeFields())
      if (name == f->name) field = f;
    const bool is_list = field != nullptr && field->type() == record::FieldType::kDoubles;
    if (!r.ok()) break;
    if (field == nullptr) {
      r.Fail("episodes[].fields", absl::StrCat("unknown episode field '", name, "'"));
    } else if (is_list != (type == kNamedDoubles)) {
      r.Fail("episodes[].fields", absl::StrCat("episode field '", name, "' has the wrong type"));
    } else if (is_list) {
      field->Get<std::vector<double>>(e).assign(values.data(), values.data() + values.size());
    } else {
      field->Get<double>(e) = value;
    }
  }
  if (version < 4 || !r.ok()) return e;  // no trajectories before version 4
  const std::string trajectories = r.Str("episodes[].trajectories");
  if (r.ok() && !trajectories.empty()) {
    absl::StatusOr<EpisodeTrajectories> decoded = DecodeEpisodeTrajectories(trajectories);
    if (decoded.ok()) e.trajectories = *std::move(decoded);
    else r.Fail("episodes[].trajectories", std::string(decoded.status().message()));
  }
  return e;
}

absl::Status Invalid(const std::string& message) {
  return absl::InvalidArgumentError(absl::StrCat("trial checkpoint: ", message));
}

}  // namespace

std::string EncodeCheckpoint(const TrialCheckpoint& c) {
  Writer w;
  w.Bytes(kMagic, sizeof(kMagic));
  w.U32(kCheckpointFormatVersion);
  w.I64(c.episode);
  w.U64(c.options.size());
  for (const auto& [key, value] : c.options) {
    w.Str(key);
    w.Str(value);
  }
  w.U64(c.episodes.size());
  for (const EpisodeResult& e : c.episodes) WriteEpisode(w, e);
  w.Mat(c.states);
  w.Vec(c.forces);
  w.Mat(c.next_states);
  w.Vec(c.policy_parameters);
  w.U8(c.hyperparameters.has_value() ? 1 : 0);
  if (c.hyperparameters) WriteHyperparameters(w, *c.hyperparameters);
  w.Mat(c.inducing_inputs);
  w.U8(c.optimizer.has_value() ? 1 : 0);
  if (c.optimizer) {
    w.Vec(c.optimizer->v);
    w.Vec(c.optimizer->m);
    w.U8(c.optimizer->first ? 1 : 0);
  }
  const uint64_t checksum = Fnv1a(w.out());
  w.U64(checksum);
  return std::move(w.out());
}

absl::StatusOr<TrialCheckpoint> DecodeCheckpoint(std::string_view bytes) {
  if (bytes.size() < sizeof(kMagic) + 4 + 8 ||
      std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
    return Invalid("not a totalgrad trial checkpoint");
  }
  Reader header(bytes.substr(sizeof(kMagic)));
  const uint32_t version = header.U32("format version");
  if (version < kOldestCheckpointFormatVersion || version > kCheckpointFormatVersion) {
    return Invalid(absl::StrCat("format version ", version, "; this build reads versions ",
                                kOldestCheckpointFormatVersion, " to ", kCheckpointFormatVersion));
  }
  const std::string_view body = bytes.substr(0, bytes.size() - 8);
  Reader tail(bytes.substr(bytes.size() - 8));
  if (tail.U64("checksum") != Fnv1a(body)) {
    return Invalid("checksum mismatch (truncated or corrupt)");
  }
  Reader r(body.substr(sizeof(kMagic) + 4));
  TrialCheckpoint c;
  c.episode = static_cast<int>(r.I64("episode"));
  const uint64_t options = r.U64("options");
  if (r.ok() && options > 10000) r.Fail("options", "too many");
  for (uint64_t i = 0; i < options && r.ok(); ++i) {
    std::string key = r.Str("options[].key");
    std::string value = r.Str("options[].value");
    c.options.emplace_back(std::move(key), std::move(value));
  }
  const uint64_t episodes = r.U64("episodes");
  if (r.ok() && episodes > 1000000) r.Fail("episodes", "too many");
  for (uint64_t i = 0; i < episodes && r.ok(); ++i) c.episodes.push_back(ReadEpisode(r, version));
  c.states = r.Mat("states");
  c.forces = r.Vec("forces");
  c.next_states = r.Mat("next_states");
  c.policy_parameters = r.Vec("policy_parameters");
  if (r.U8("hyperparameters") != 0) c.hyperparameters = ReadHyperparameters(r);
  c.inducing_inputs = r.Mat("inducing_inputs");
  if (r.U8("optimizer") != 0) {
    RmspropLike::State state;
    state.v = r.Vec("optimizer.v");
    state.m = r.Vec("optimizer.m");
    state.first = r.U8("optimizer.first") != 0;
    c.optimizer = std::move(state);
  }
  if (!r.ok()) return Invalid(r.error());
  if (r.left() != 0) return Invalid(absl::StrCat(r.left(), " bytes after the last field"));
  if (c.episode < 0 || c.episodes.size() != static_cast<size_t>(c.episode) + 1) {
    return Invalid(absl::StrCat("episode ", c.episode, " but ", c.episodes.size(),
                                " episode results"));
  }
  for (size_t i = 0; i < c.episodes.size(); ++i) {
    if (c.episodes[i].episode != static_cast<int>(i)) {
      return Invalid(absl::StrCat("episode result ", i, " is numbered ", c.episodes[i].episode));
    }
  }
  // forces: N F entries (F controls per transition).
  const Eigen::Index n = c.states.rows();
  if (c.next_states.rows() != n || c.states.cols() < 1 || c.next_states.cols() != c.states.cols() ||
      (n == 0 ? c.forces.size() != 0 : c.forces.size() < n || c.forces.size() % n != 0)) {
    return Invalid(absl::StrCat("data of inconsistent sizes: states ", c.states.rows(), "x",
                                c.states.cols(), ", forces ", c.forces.size(), ", next_states ",
                                c.next_states.rows(), "x", c.next_states.cols()));
  }
  return c;
}

absl::Status CheckResumable(const TrialCheckpoint& checkpoint, const TrialOptions& options) {
  // Compared as options, not as texts: a checkpoint written before an option
  // existed lists no pair for it, and resumes a trial that keeps the value
  // it was computed with (TrialOptionsFromStoredPairs).
  absl::StatusOr<TrialOptions> theirs = TrialOptionsFromStoredPairs(checkpoint.options);
  if (!theirs.ok()) return Invalid(absl::StrCat("its options do not parse: ", theirs.status().message()));
  const auto pairs = TrialOptionPairs(options);
  const auto there = TrialOptionPairs(*theirs);
  for (size_t i = 0; i < pairs.size(); ++i) {
    if (there[i] != pairs[i]) {
      return Invalid(absl::StrCat("it belongs to another trial: option ", pairs[i].first, " is '",
                                  pairs[i].second, "' here, the checkpoint has ", there[i].first,
                                  "=", there[i].second));
    }
  }
  // The data must be the scene's: D columns, F controls per transition
  // (forces N F). DecodeCheckpoint only knows they are mutually consistent.
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options.scene);
  if (!scene.ok()) return scene.status();
  const Eigen::Index n = checkpoint.states.rows();
  // (No data at all, a checkpoint before any episode, fits every scene.)
  if ((n > 0 && checkpoint.states.cols() != scene->state_dim()) ||
      checkpoint.forces.size() != n * scene->control_dim()) {
    return Invalid(absl::StrCat("its data do not fit scene '", scene->name, "' (", scene->state_dim(),
                                " states, ", scene->control_dim(), " controls): states ", n, "x",
                                checkpoint.states.cols(), ", forces ", checkpoint.forces.size()));
  }
  if (checkpoint.episode > options.episodes) {
    return Invalid(absl::StrCat("episode ", checkpoint.episode, " is beyond the trial's ",
                                options.episodes, " episodes"));
  }
  return absl::OkStatus();
}

}  // namespace totalgrad::learner
