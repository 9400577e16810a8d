#include "core/learner/trajectory.h"

#include <cstring>

#include "absl/strings/str_cat.h"
#include "core/common/binary_codec.h"

namespace totalgrad::learner {
namespace {

constexpr char kMagic[8] = {'T', 'G', 'T', 'R', 'A', 'J', '\0', '\0'};
// No trial comes near this many rollouts; a larger count is corruption.
constexpr uint64_t kMaxRollouts = 1000000;

absl::Status Invalid(const std::string& message) {
  return absl::InvalidArgumentError(absl::StrCat("episode trajectories: ", message));
}

void WriteTrajectory(binary::Writer& w, const StateTrajectory& t) {
  w.Mat(t.states);
  w.Mat(t.controls);
}

StateTrajectory ReadTrajectory(binary::Reader& r, const char* what) {
  StateTrajectory t;
  t.states = r.Mat(what);
  t.controls = r.Mat(what);
  return t;
}

// Empty, or T + 1 state rows for T control rows (T >= 0: an episode that
// ended before its first step keeps its start state and no control).
absl::Status CheckTrajectory(const StateTrajectory& t, const std::string& what) {
  if (t.empty()) return absl::OkStatus();
  if (t.states.rows() != t.controls.rows() + 1 || t.states.cols() < 1 ||
      (t.controls.rows() > 0 && t.controls.cols() < 1)) {
    return Invalid(absl::StrCat(what, ": states ", t.states.rows(), "x", t.states.cols(),
                                " do not fit controls ", t.controls.rows(), "x",
                                t.controls.cols(), " (one state row more than control rows)"));
  }
  return absl::OkStatus();
}

}  // namespace

StateTrajectory TrajectoryOfEpisode(const tasks::Episode& episode) {
  StateTrajectory t;
  t.states = episode.states;
  const Eigen::Index steps = episode.states.rows() - 1;
  const Eigen::Index controls = steps > 0 ? episode.forces.size() / steps : 0;
  t.controls = Eigen::Map<const RowMatrix>(episode.forces.data(), steps, controls);
  return t;
}

std::string EncodeEpisodeTrajectories(const EpisodeTrajectories& e) {
  binary::Writer w;
  w.Bytes(kMagic, sizeof(kMagic));
  w.U32(kTrajectoryFormatVersion);
  WriteTrajectory(w, e.real);
  w.Mat(e.predicted_mean);
  w.Mat(e.predicted_std);
  w.U64(e.verdict_rollouts.size());
  for (const StateTrajectory& rollout : e.verdict_rollouts) WriteTrajectory(w, rollout);
  const uint64_t checksum = binary::Fnv1a(w.out());
  w.U64(checksum);
  return std::move(w.out());
}

absl::StatusOr<EpisodeTrajectories> DecodeEpisodeTrajectories(std::string_view bytes) {
  if (bytes.size() < sizeof(kMagic) + 4 + 8 ||
      std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
    return Invalid("not totalgrad episode trajectories");
  }
  binary::Reader header(bytes.substr(sizeof(kMagic)));
  const uint32_t version = header.U32("format version");
  if (version != kTrajectoryFormatVersion) {
    return Invalid(absl::StrCat("format version ", version, "; this build reads version ",
                                kTrajectoryFormatVersion));
  }
  const std::string_view body = bytes.substr(0, bytes.size() - 8);
  binary::Reader tail(bytes.substr(bytes.size() - 8));
  if (tail.U64("checksum") != binary::Fnv1a(body)) {
    return Invalid("checksum mismatch (truncated or corrupt)");
  }
  binary::Reader r(body.substr(sizeof(kMagic) + 4));
  EpisodeTrajectories e;
  e.real = ReadTrajectory(r, "real");
  e.predicted_mean = r.Mat("predicted_mean");
  e.predicted_std = r.Mat("predicted_std");
  const uint64_t rollouts = r.U64("verdict_rollouts");
  if (r.ok() && rollouts > kMaxRollouts) r.Fail("verdict_rollouts", "too many");
  for (uint64_t i = 0; i < rollouts && r.ok(); ++i)
    e.verdict_rollouts.push_back(ReadTrajectory(r, "verdict_rollouts[]"));
  if (!r.ok()) return Invalid(r.error());
  if (r.left() != 0) return Invalid(absl::StrCat(r.left(), " bytes after the last field"));
  if (absl::Status s = CheckTrajectory(e.real, "real"); !s.ok()) return s;
  for (size_t i = 0; i < e.verdict_rollouts.size(); ++i) {
    if (absl::Status s = CheckTrajectory(e.verdict_rollouts[i], absl::StrCat("verdict rollout ", i));
        !s.ok())
      return s;
  }
  if (e.predicted_mean.rows() != e.predicted_std.rows() ||
      e.predicted_mean.cols() != e.predicted_std.cols()) {
    return Invalid(absl::StrCat("predicted_mean ", e.predicted_mean.rows(), "x",
                                e.predicted_mean.cols(), " and predicted_std ",
                                e.predicted_std.rows(), "x", e.predicted_std.cols(), " differ"));
  }
  return e;
}

}  // namespace totalgrad::learner
