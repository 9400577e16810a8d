#include "results/stats.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <tuple>

namespace totalgrad::results {

std::pair<double, double> WilsonInterval(int successes, int trials, double z) {
  if (trials <= 0) return {0.0, 1.0};
  const double n = trials;
  const double p = successes / n;
  const double z2 = z * z;
  const double centre = (p + z2 / (2 * n)) / (1 + z2 / n);
  const double half = z / (1 + z2 / n) * std::sqrt(p * (1 - p) / n + z2 / (4 * n * n));
  return {std::max(0.0, centre - half), std::min(1.0, centre + half)};
}

void WilsonRate::Add(bool succeeded) {
  ++trials;
  if (succeeded) ++successes;
  rate = static_cast<double>(successes) / trials;
  std::tie(low, high) = WilsonInterval(successes, trials);
}

double Quantile(std::vector<double> values, double q) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(values.begin(), values.end());
  const double position = q * (values.size() - 1);
  const size_t below = static_cast<size_t>(std::floor(position));
  const size_t above = std::min(below + 1, values.size() - 1);
  const double fraction = position - below;
  return values[below] + fraction * (values[above] - values[below]);
}

SampleSummary Summarize(const std::vector<double>& values) {
  SampleSummary summary;
  summary.trials = static_cast<int>(values.size());
  if (values.empty()) return summary;
  summary.q25 = Quantile(values, 0.25);
  summary.median = Quantile(values, 0.5);
  summary.q75 = Quantile(values, 0.75);
  const double n = static_cast<double>(values.size());
  double sum = 0;
  for (double v : values) sum += v;
  summary.mean = sum / n;
  if (values.size() >= 2) {
    double squares = 0;
    for (double v : values) squares += (v - summary.mean) * (v - summary.mean);
    summary.standard_error = std::sqrt(squares / (n - 1) / n);
  }
  return summary;
}

namespace {

// First-appearance order of keys.
class Order {
 public:
  int Of(const std::string& key) {
    auto [it, inserted] = index_.emplace(key, static_cast<int>(index_.size()));
    return it->second;
  }

 private:
  std::map<std::string, int> index_;
};

}  // namespace

std::vector<TableCell> SuccessTable(const std::vector<CompletedTrial>& rows) {
  Order methods, variants;
  std::map<std::pair<int, int>, std::pair<TableCell, std::vector<double>>> cells;
  for (const CompletedTrial& row : rows) {
    auto& [cell, costs] = cells[{methods.Of(row.method), variants.Of(row.variant)}];
    cell.method = row.method;
    cell.variant = row.variant;
    cell.success.Add(row.success);
    if (!std::isnan(row.final_eval_cost)) costs.push_back(row.final_eval_cost);
    if (!std::isnan(row.held_fraction)) cell.held.Add(row.held_fraction >= 0.5);
  }
  std::vector<TableCell> table;
  for (auto& [order, entry] : cells) {
    TableCell cell = entry.first;
    cell.median_final_cost = Quantile(entry.second, 0.5);
    table.push_back(cell);
  }
  return table;
}

const record::FieldTable<TableCell>& TableCellFields() {
  static const record::FieldTable<TableCell> table = [] {
    record::FieldTable<TableCell> fields = {{"method", &TableCell::method},
                                            {"variant", &TableCell::variant}};
    AppendWilsonRateFields<&TableCell::success>(kSuccessRateNames, &fields);
    fields.push_back({"median_final_cost", &TableCell::median_final_cost});
    AppendWilsonRateFields<&TableCell::held>(kHeldRateNames, &fields);
    return fields;
  }();
  return table;
}

std::vector<CurvePoint> Curves(const std::vector<EpisodeValue>& values) {
  Order methods, variants;
  std::map<std::tuple<int, int, int>, std::pair<CurvePoint, std::vector<double>>> points;
  for (const EpisodeValue& v : values) {
    if (std::isnan(v.value)) continue;
    auto& [point, samples] = points[{methods.Of(v.method), variants.Of(v.variant), v.episode}];
    point.method = v.method;
    point.variant = v.variant;
    point.episode = v.episode;
    samples.push_back(v.value);
  }
  std::vector<CurvePoint> curves;
  for (auto& [key, entry] : points) {
    CurvePoint point = entry.first;
    point.values = Summarize(entry.second);
    curves.push_back(point);
  }
  return curves;
}

const record::FieldTable<CurvePoint>& CurvePointFields() {
  static const record::FieldTable<CurvePoint> table = [] {
    record::FieldTable<CurvePoint> fields = {{"method", &CurvePoint::method},
                                             {"variant", &CurvePoint::variant},
                                             {"episode", &CurvePoint::episode}};
    AppendSampleSummaryFields<&CurvePoint::values>(&fields);
    return fields;
  }();
  return table;
}

std::vector<EpisodeValue> BestRuns(const std::vector<EpisodeValue>& values, int k) {
  // Each run's final value: the value of its last episode with one.
  std::map<int64_t, std::pair<int, double>> final_of;  // trial -> (episode, value)
  for (const EpisodeValue& v : values) {
    if (std::isnan(v.value)) continue;
    auto [it, inserted] = final_of.emplace(v.trial, std::pair{v.episode, v.value});
    if (!inserted && v.episode >= it->second.first) it->second = {v.episode, v.value};
  }
  // Runs per (method, variant), best first.
  std::map<std::pair<std::string, std::string>, std::vector<std::pair<double, int64_t>>> runs;
  std::map<int64_t, bool> seen;
  for (const EpisodeValue& v : values) {
    const auto final = final_of.find(v.trial);
    if (final == final_of.end() || seen[v.trial]) continue;
    seen[v.trial] = true;
    runs[{v.method, v.variant}].push_back({final->second.second, v.trial});
  }
  std::map<int64_t, bool> kept;
  for (auto& [key, list] : runs) {
    std::sort(list.begin(), list.end());
    for (size_t i = 0; i < list.size() && i < static_cast<size_t>(std::max(k, 0)); ++i) {
      kept[list[i].second] = true;
    }
  }
  std::vector<EpisodeValue> best;
  for (const EpisodeValue& v : values) {
    if (kept.count(v.trial) > 0) best.push_back(v);
  }
  return best;
}

}  // namespace totalgrad::results
