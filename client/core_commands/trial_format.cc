#include "client/core_commands/trial_format.h"

#include <cmath>

namespace totalgrad::cli {
std::string FlagsText(const learner::EpisodeFlags& flags) {
  std::string text;
  auto add = [&text](const std::string& s) { text += (text.empty() ? "" : ",") + s; };
  if (flags.non_finite_gradients > 0) add("nonfinite_grad=" + std::to_string(flags.non_finite_gradients));
  if (flags.gp_line_search_failures > 0) add("gp_ls_fail=" + std::to_string(flags.gp_line_search_failures));
  if (flags.gp_non_finite_evaluations > 0) add("gp_nonfinite=" + std::to_string(flags.gp_non_finite_evaluations));
  if (flags.zero_gradient) add("zero_grad");
  if (flags.gp_jitter) add("gp_jitter");
  return text.empty() ? "-" : text;
}

}  // namespace totalgrad::cli
