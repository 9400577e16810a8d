#include "results/plot_style.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"

namespace totalgrad::results {

std::string MethodColour(const std::string& method) {
  // Distinct hues (Tableau 10 plus black for PILCO, the analytic reference),
  // readable on white and as thin lines.
  static constexpr std::array<std::pair<const char*, const char*>, 9> kKnown = {{
      {"PILCO", "#000000"}, {"RP", "#e15759"}, {"GR", "#9c755f"},
      {"LR", "#76b7b2"},    {"TP", "#4e79a7"}, {"GLR", "#b07aa1"},
      {"GTP", "#59a14f"},   {"GTP+sn", "#f28e2b"}, {"DEL", "#ff9da7"},
  }};
  for (const auto& [name, colour] : kKnown) {
    if (method == name) return colour;
  }
  static constexpr std::array<const char*, 5> kOthers = {"#edc948", "#17becf", "#bcbd22",
                                                         "#7f7f7f", "#8c564b"};
  uint32_t hash = 2166136261u;  // FNV-1a: the same on every machine
  for (unsigned char c : method) hash = (hash ^ c) * 16777619u;
  return kOthers[hash % kOthers.size()];
}

CurvePanel DescribePanel(const std::string& variant,
                         const std::vector<std::pair<std::string, std::string>>& options) {
  CurvePanel panel;
  panel.variant = variant;
  panel.threshold = std::nan("");
  std::string scene, cost, noise_k;
  for (const auto& [key, value] : options) {
    if (key == "scene") scene = value;
    else if (key == "cost") cost = value;
    else if (key == "noise_k") noise_k = value;
    else if (key == "threshold") {
      double threshold = 0;
      if (absl::SimpleAtod(value, &threshold)) panel.threshold = threshold;
    }
  }
  auto append = [&](const std::string& part) {
    if (part.empty()) return;
    if (!panel.title.empty()) panel.title += ", ";
    panel.title += part;
  };
  append(scene);
  append(cost.empty() ? "" : cost + " cost");
  append(noise_k.empty() ? "" : "k = " + noise_k);
  for (absl::string_view pair : absl::StrSplit(variant, ' ', absl::SkipEmpty())) {
    const std::string key(pair.substr(0, pair.find('=')));
    if (key != "scene" && key != "cost" && key != "noise_k") append(std::string(pair));
  }
  if (panel.title.empty()) panel.title = variant.empty() ? "all trials" : variant;
  return panel;
}

}  // namespace totalgrad::results
