#include "client/core_commands/study_summary.h"

#include <cmath>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"

namespace totalgrad::cli {
namespace {

using OrderedJson = nlohmann::ordered_json;

std::string SecondsText(double s) {
  // 3 significant digits: the requested times print exactly (10 ms, 1 s).
  if (s < 1.0) return absl::StrFormat("%.3g ms", s * 1e3);
  return absl::StrFormat("%.3g s", s);
}

std::string Sig(double v, int digits) {
  return std::isfinite(v) ? absl::StrFormat("%.*g", digits, v) : std::string("n/a");
}

OrderedJson JsonNumber(double v) { return std::isfinite(v) ? OrderedJson(v) : OrderedJson(nullptr); }

// "RP 0.045 (P = 1000, 44 ms)": the lowest error measured within the row's
// time when it beats the winner (or there is none); "-" otherwise.
std::string BestWithin(const study::EqualTimeRow& row) {
  if (row.best_within.empty()) return "-";
  return absl::StrCat(row.best_within, " ", Sig(row.best_within_error, 3), " (P = ",
                      row.best_within_particles, ", ", SecondsText(row.best_within_seconds), ")");
}

}  // namespace

std::string StudySummaryMarkdown(const std::vector<LabelledStudy>& studies,
                                 const std::vector<double>& seconds) {
  std::ostringstream os;
  for (const LabelledStudy& s : studies) {
    const study::EqualTimeComparison cmp = study::CompareAtEqualTime(s.result, seconds);
    os << "### " << s.label << "\n\n";
    os << "Problem: " << s.result.source;
    if (!s.result.scene.empty()) os << "; scene " << s.result.scene;
    os << ".\n\n";
    if (cmp.rows.empty()) {
      os << "(no horizons)\n\n";
      continue;
    }
    const std::vector<std::string>& labels = cmp.rows.front().estimators;
    os << "| H | time per gradient | lowest error | " << absl::StrJoin(labels, " | ")
       << " | lower error measured in less time |\n";
    os << "|---|---|---|";
    for (size_t e = 0; e < labels.size(); ++e) os << "---|";
    os << "---|\n";
    bool any_below_floor = false;
    bool any_useless = false;  // a relative error >= 1: no better than a zero gradient
    bool any_unchecked = false;  // the references' agreement check had no power
    for (const study::EqualTimeRow& row : cmp.rows) {
      os << "| " << row.horizon << " | " << SecondsText(row.seconds) << " | ";
      if (!row.reference_agrees) {
        os << "no winner: the reference estimators disagree |";
        for (size_t e = 0; e < labels.size(); ++e) os << " - |";
        os << " - |\n";
        continue;
      }
      if (row.winner.empty()) {
        any_unchecked = any_unchecked || !row.reference_checked;
        os << "n/a (no estimator measured at this time)" << (row.reference_checked ? "" : "†")
           << " |";
        for (size_t e = 0; e < labels.size(); ++e) os << " n/a |";
        os << " " << BestWithin(row) << " |\n";
        continue;
      }
      any_below_floor = any_below_floor || row.winner_below_floor;
      any_unchecked = any_unchecked || !row.reference_checked;
      const bool useless = row.winner_error >= 1.0;
      any_useless = any_useless || useless;
      os << row.winner << " " << Sig(row.winner_error, 3) << (row.winner_below_floor ? "*" : "")
         << (row.reference_checked ? "" : "†")
         << (useless ? " (≥ 1)" : "") << " |";
      for (size_t e = 0; e < labels.size(); ++e) {
        os << " " << (labels[e] == row.winner ? std::string("1") : Sig(row.ratios[e], 2)) << " |";
      }
      os << " " << BestWithin(row) << " |\n";
    }
    os << "\n";
    if (any_below_floor) {
      os << "\\* below the reference gradient's noise floor (1.96 |SE| / |g\\*|): the error, and the "
            "ratios to it, are not resolved there.\n\n";
    }
    bool any_best_within = false;
    for (const study::EqualTimeRow& row : cmp.rows) any_best_within |= !row.best_within.empty();
    if (any_best_within) {
      os << "Last column: a cell measured in less than the row's time with a lower error than the "
            "winner's (or than anything, where no curve reaches that time): its estimator's "
            "largest P was faster than the time, so it is n/a there, but it did better.\n\n";
    }
    if (any_unchecked) {
      os << "†: the reference estimators' agreement check had no power at this horizon (a "
            "difference between them as large as |g\\*| would pass): g\\* rests on the more "
            "precise one alone.\n\n";
    }
    if (any_useless) {
      os << "(≥ 1): the lowest relative error is 1 or more: no estimator does better than a zero "
            "gradient there.\n\n";
    }
    if (!cmp.fixed_cost.empty()) {
      std::vector<std::string> points;
      std::string reason;  // the first omission's
      for (const study::FixedCostPoint& p : cmp.fixed_cost) {
        if (!p.omission_reason.empty() && reason.empty()) reason = p.omission_reason;
        points.push_back(std::isfinite(p.error)
                             ? absl::StrCat("H = ", p.horizon, ": ", Sig(p.error, 3), " in ",
                                            SecondsText(p.seconds))
                             : absl::StrCat("H = ", p.horizon, ": ",
                                            p.omission_reason.empty() ? "not measured" : "omitted"));
      }
      os << "Fixed-cost estimators (one deterministic gradient, not interpolated): "
         << cmp.fixed_cost.front().estimator << " " << absl::StrJoin(points, "; ") << ".";
      if (!reason.empty()) os << " Omitted: " << reason << ".";
      os << "\n\n";
    }
  }
  return os.str();
}

OrderedJson StudySummaryJson(const std::vector<LabelledStudy>& studies,
                             const std::vector<double>& seconds) {
  OrderedJson out = OrderedJson::array();
  for (const LabelledStudy& s : studies) {
    const study::EqualTimeComparison cmp = study::CompareAtEqualTime(s.result, seconds);
    OrderedJson rows = OrderedJson::array();
    for (const study::EqualTimeRow& row : cmp.rows) {
      OrderedJson errors = OrderedJson::object(), ratios = OrderedJson::object();
      for (size_t e = 0; e < row.estimators.size(); ++e) {
        errors[row.estimators[e]] = JsonNumber(row.errors[e]);
        ratios[row.estimators[e]] = JsonNumber(row.ratios[e]);
      }
      rows.push_back({{"horizon", row.horizon},
                      {"seconds", row.seconds},
                      {"reference_agrees", row.reference_agrees},
                      {"reference_checked", row.reference_checked},
                      {"floor", JsonNumber(row.floor)},
                      {"winner", row.winner.empty() ? OrderedJson(nullptr) : OrderedJson(row.winner)},
                      {"winner_error", JsonNumber(row.winner_error)},
                      {"winner_below_floor", row.winner_below_floor},
                      {"errors", errors},
                      {"ratios", ratios},
                      {"best_within", row.best_within.empty()
                                          ? OrderedJson(nullptr)
                                          : OrderedJson({{"estimator", row.best_within},
                                                         {"particles", row.best_within_particles},
                                                         {"error", row.best_within_error},
                                                         {"seconds", row.best_within_seconds}})}});
    }
    OrderedJson fixed = OrderedJson::array();
    for (const study::FixedCostPoint& p : cmp.fixed_cost) {
      fixed.push_back({{"estimator", p.estimator},
                       {"horizon", p.horizon},
                       {"seconds", JsonNumber(p.seconds)},
                       {"error", JsonNumber(p.error)},
                       {"omission_reason", p.omission_reason.empty()
                                               ? OrderedJson(nullptr)
                                               : OrderedJson(p.omission_reason)}});
    }
    out.push_back({{"label", s.label},
                   {"scene", s.result.scene},
                   {"source", s.result.source},
                   {"rows", rows},
                   {"fixed_cost", fixed}});
  }
  return out;
}

}  // namespace totalgrad::cli
