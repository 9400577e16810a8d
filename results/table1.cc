#include "results/table1.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <utility>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "results/stats.h"

namespace totalgrad::results {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Parmas et al. 2018, Table 1, in Table1Rows() x Table1Methods() order
// (PILCO RP GR LR TP GTP GLR GTP+sn). The paper ran GTP+sn at k = 0.01 only.
constexpr double kPaperRates[4][8] = {
    {0.88, 0.69, 0.63, 0.57, 0.82, 0.65, 0.42, 0.88},  // angle, k = 0.01
    {0.79, 0.74, 0.89, 0.96, 0.99, 0.90, 0.93, kNaN},  // angle, k = 1
    {0.92, 0.44, 0.47, 0.36, 0.54, 0.60, 0.45, 0.80},  // tip, k = 0.01
    {0.73, 0.15, 0.68, 0.28, 0.48, 0.69, 0.35, kNaN},  // tip, k = 1
};

const std::string* FindOption(const record::TextPairs& options, const std::string& key) {
  for (const auto& [name, value] : options) {
    if (name == key) return &value;
  }
  return nullptr;
}

// Where a trial goes: its cell's index, or why it has none.
struct Placement {
  std::optional<size_t> cell;
  std::string reason;  // when !cell: "of method DEL (not a Table 1 method)"
};

Placement Place(const CompletedTrial& trial) {
  const std::vector<std::string>& methods = Table1Methods();
  const auto method = std::find(methods.begin(), methods.end(), trial.method);
  if (method == methods.end()) {
    return {std::nullopt, absl::StrCat("of method ", trial.method, " (not a Table 1 method)")};
  }
  const std::string* cost = FindOption(trial.options, "cost");
  if (cost == nullptr) return {std::nullopt, "without the option 'cost'"};
  const std::string* noise_text = FindOption(trial.options, "noise_k");
  if (noise_text == nullptr) return {std::nullopt, "without the option 'noise_k'"};
  double noise_k = 0;
  if (!absl::SimpleAtod(*noise_text, &noise_k)) {
    return {std::nullopt, absl::StrCat("with noise_k '", *noise_text, "' (not a number)")};
  }
  const std::vector<Table1Row>& rows = Table1Rows();
  bool cost_known = false;
  for (size_t r = 0; r < rows.size(); ++r) {
    if (rows[r].cost != *cost) continue;
    cost_known = true;
    if (rows[r].noise_k == noise_k) {
      return {r * methods.size() + static_cast<size_t>(method - methods.begin()), ""};
    }
  }
  if (!cost_known) {
    return {std::nullopt, absl::StrCat("with cost '", *cost, "' (Table 1 has angle and tip)")};
  }
  return {std::nullopt,
          absl::StrCat("with noise_k ", *noise_text, " (Table 1 has 0.01 and 1)")};
}

// Keeps strings in first-appearance order, once each.
void AddOnce(std::vector<std::string>* list, const std::string& value) {
  if (std::find(list->begin(), list->end(), value) == list->end()) list->push_back(value);
}

std::string Plural(int count, const char* one, const char* many) {
  return absl::StrCat(count, " ", count == 1 ? one : many);
}

}  // namespace

const std::vector<std::string>& Table1Methods() {
  static const std::vector<std::string>* methods = new std::vector<std::string>{
      "PILCO", "RP", "GR", "LR", "TP", "GTP", "GLR", "GTP+sn"};
  return *methods;
}

std::string Table1Row::Label() const { return absl::StrCat(cost, ", k = ", noise_k); }

const std::vector<Table1Row>& Table1Rows() {
  static const std::vector<Table1Row>* rows = new std::vector<Table1Row>{
      {"angle", 0.01}, {"angle", 1}, {"tip", 0.01}, {"tip", 1}};
  return *rows;
}

double PaperSuccessRate(size_t row, const std::string& method) {
  const std::vector<std::string>& methods = Table1Methods();
  const auto column = std::find(methods.begin(), methods.end(), method);
  if (row >= Table1Rows().size() || column == methods.end()) return kNaN;
  return kPaperRates[row][column - methods.begin()];
}

const record::TextPairs& PaperProtocol() {
  static const record::TextPairs* protocol = new record::TextPairs{
      {"scene", "cartpole-swingup"}, {"episodes", "15"},      {"policy_steps", "600"},
      {"particles", "300"},          {"eval_rollouts", "30"}, {"threshold", "15"}};
  return *protocol;
}

std::vector<std::string> ProtocolDifferences(const record::TextPairs& options) {
  std::vector<std::string> differences;
  for (const auto& [key, paper] : PaperProtocol()) {
    const std::string* value = FindOption(options, key);
    if (value == nullptr) {
      differences.push_back(absl::StrCat(key, " missing (paper ", paper, ")"));
      continue;
    }
    double ours = 0, theirs = 0;
    const bool numbers = key != "scene" && absl::SimpleAtod(*value, &ours) &&
                         absl::SimpleAtod(paper, &theirs);
    const bool same = numbers ? ours == theirs : *value == paper;
    if (!same) differences.push_back(absl::StrCat(key, " = ", *value, " (paper ", paper, ")"));
  }
  return differences;
}

std::string PaperInInterval(const Table1Cell& cell) {
  if (cell.success.trials == 0 || std::isnan(cell.paper_success_rate)) return "";
  const bool inside = cell.paper_success_rate >= cell.success.low &&
                      cell.paper_success_rate <= cell.success.high;
  return inside ? "yes" : "no";
}

const record::FieldTable<Table1Cell>& Table1CellFields() {
  static const record::FieldTable<Table1Cell> table = [] {
    record::FieldTable<Table1Cell> fields = {{"cost", &Table1Cell::cost},
                                             {"noise_k", &Table1Cell::noise_k},
                                             {"method", &Table1Cell::method}};
    AppendWilsonRateFields<&Table1Cell::success>(kSuccessRateNames, &fields);
    AppendWilsonRateFields<&Table1Cell::held>(kHeldRateNames, &fields);
    fields.insert(fields.end(),
                  {{"paper_success_rate", &Table1Cell::paper_success_rate},
                   {"paper_in_interval", &PaperInInterval},
                   {"off_protocol_trials", &Table1Cell::off_protocol_trials},
                   {"protocol_differences", &Table1Cell::protocol_differences},
                   {"sweeps", &Table1Cell::sweeps}});
    return fields;
  }();
  return table;
}

absl::StatusOr<Table1> ComputeTable1(const std::vector<CompletedTrial>& trials) {
  const std::vector<Table1Row>& rows = Table1Rows();
  const std::vector<std::string>& methods = Table1Methods();
  Table1 table;
  table.cells.resize(rows.size() * methods.size());
  table.cell_trials.resize(table.cells.size());
  for (size_t r = 0; r < rows.size(); ++r) {
    for (size_t m = 0; m < methods.size(); ++m) {
      Table1Cell& cell = table.cells[r * methods.size() + m];
      cell.cost = rows[r].cost;
      cell.noise_k = rows[r].noise_k;
      cell.method = methods[m];
      cell.paper_success_rate = PaperSuccessRate(r, methods[m]);
    }
  }

  std::vector<std::vector<const CompletedTrial*>> members(table.cells.size());
  std::map<std::pair<size_t, std::string>, const CompletedTrial*> by_seed;  // (cell, seed)
  std::vector<std::pair<std::string, int>> outside;  // reason, trials
  for (const CompletedTrial& trial : trials) {
    const Placement placement = Place(trial);
    if (!placement.cell) {
      auto reason = std::find_if(outside.begin(), outside.end(),
                                 [&](const auto& entry) { return entry.first == placement.reason; });
      if (reason == outside.end()) {
        outside.emplace_back(placement.reason, 1);
      } else {
        ++reason->second;
      }
      ++table.trials_outside;
      continue;
    }
    const size_t index = *placement.cell;
    const auto [seen, inserted] = by_seed.emplace(std::pair{index, trial.seed}, &trial);
    if (!inserted) {
      const CompletedTrial& first = *seen->second;
      const std::string what = absl::StrCat("seed ", trial.seed, " of ", trial.method, " in (",
                                            rows[index / methods.size()].Label(), ")");
      if (first.sweep != trial.sweep) {
        return absl::InvalidArgumentError(absl::StrCat(
            what, " is in sweep ", first.sweep, " (job ", first.job_id, ") and in sweep ",
            trial.sweep, " (job ", trial.job_id,
            "): pooling them would count the seed twice; name only one of the two sweeps"));
      }
      return absl::InvalidArgumentError(absl::StrCat(
          what, " is twice in sweep ", trial.sweep, " (job ", first.job_id, ", variant '",
          first.variant, "', and job ", trial.job_id, ", variant '", trial.variant,
          "'): pooling them would count the seed twice"));
    }
    members[index].push_back(&trial);
  }
  for (const auto& [reason, count] : outside) {
    table.outside.push_back(absl::StrCat(Plural(count, "trial", "trials"), " ", reason));
  }

  for (size_t index = 0; index < table.cells.size(); ++index) {
    if (members[index].empty()) continue;
    Table1Cell& cell = table.cells[index];
    std::vector<CompletedTrial> cell_rows;
    std::vector<std::string> differences;
    for (const CompletedTrial* trial : members[index]) {
      CompletedTrial row = *trial;
      row.variant = "";  // one cell: the grid's place, whatever the sweep called it
      cell_rows.push_back(std::move(row));
      table.cell_trials[index].push_back(*trial);
      AddOnce(&cell.sweeps, trial->sweep);
      const std::vector<std::string> off = ProtocolDifferences(trial->options);
      if (!off.empty()) ++cell.off_protocol_trials;
      for (const std::string& difference : off) AddOnce(&differences, difference);
    }
    cell.protocol_differences = absl::StrJoin(differences, "; ");
    // The statistics are SuccessTable's, as in `results table`: one
    // (method, variant) here, so one cell.
    const TableCell counted = SuccessTable(cell_rows).front();
    cell.success = counted.success;
    cell.held = counted.held;
  }
  return table;
}

}  // namespace totalgrad::results
