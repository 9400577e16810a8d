// Evaluates the comparison statistics on cases read from stdin, one JSON
// object per line, and writes one JSON answer per line: the bridge through
// which stats_scipy_test.py checks them against SciPy and brute force.
//
//   {"test": "binom", "k": 3, "n": 10, "p": 0.5}          -> {"p": ...}
//   {"test": "fisher", "table": [a, b, c, d]}             -> {"p": ..., "odds_ratio": ...}
//   {"test": "wilcoxon", "d": [...]}                      -> {"p", "w_plus", "w_minus", "n",
//                                                             "exact", "hodges_lehmann", ...}
//   {"test": "mcnemar_power", "n": 20, "p10": .3, "p01": .1}  -> {"power": ...}
//   {"test": "fisher_power", "n1", "p1", "n2", "p2"}      -> {"power": ...}
//   {"test": "noether", "n": 30, "p_prime": 0.7}          -> {"power": ...}
//   {"test": "walsh", "d": [...]}                         -> {"fraction": ...}
//   {"test": "holm", "p": [...]}                          -> {"adjusted": [...]}
//   {"test": "hl_interval", "d": [...]}                   -> {"estimate", "low", "high",
//                                                             "coverage"}
//   {"test": "newcombe_paired", "table": [both, first_only, second_only, neither]}
//                                                         -> {"difference", "low", "high"}
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "results/hypothesis_tests.h"
#include "results/paired_intervals.h"

namespace {

using nlohmann::json;
using namespace totalgrad::results;

json Number(double value) { return std::isnan(value) ? json(nullptr) : json(value); }

json Evaluate(const json& c) {
  const std::string test = c.at("test");
  if (test == "binom") {
    return {{"p", Number(BinomialTestTwoSided(c.at("k"), c.at("n"), c.at("p")))}};
  }
  if (test == "fisher") {
    const auto& t = c.at("table");
    const double odds = OddsRatio(t[0], t[1], t[2], t[3]);
    return {{"p", Number(FisherExactP(t[0], t[1], t[2], t[3]))},
            {"odds_ratio", std::isinf(odds) ? json("inf") : Number(odds)}};
  }
  if (test == "wilcoxon") {
    const WilcoxonResult r = WilcoxonSignedRank(c.at("d").get<std::vector<double>>());
    return {{"p", r.p}, {"w_plus", r.w_plus}, {"w_minus", r.w_minus}, {"n", r.n},
            {"zeros", r.zeros}, {"exact", r.exact}, {"ties", r.ties},
            {"hodges_lehmann", Number(r.hodges_lehmann)}, {"rank_biserial", r.rank_biserial}};
  }
  if (test == "mcnemar_power") {
    return {{"power", Number(McNemarExactPower(c.at("n"), c.at("p10"), c.at("p01")))}};
  }
  if (test == "fisher_power") {
    return {{"power",
             Number(FisherExactPower(c.at("n1"), c.at("p1"), c.at("n2"), c.at("p2")))}};
  }
  if (test == "noether") {
    return {{"power", Number(WilcoxonPowerNoether(c.at("n"), c.at("p_prime")))}};
  }
  if (test == "walsh") {
    return {{"fraction", WalshPositiveFraction(c.at("d").get<std::vector<double>>())}};
  }
  if (test == "hl_interval") {
    const ShiftInterval r = HodgesLehmannInterval(c.at("d").get<std::vector<double>>());
    return {{"estimate", Number(r.estimate)}, {"low", Number(r.low)}, {"high", Number(r.high)},
            {"coverage", Number(r.coverage)}};
  }
  if (test == "newcombe_paired") {
    const auto& t = c.at("table");
    const RateDifferenceInterval r = NewcombePairedInterval({t[0], t[1], t[2], t[3]});
    return {{"difference", Number(r.difference)}, {"low", Number(r.low)}, {"high", Number(r.high)}};
  }
  if (test == "holm") {
    json adjusted = json::array();
    for (double p : HolmAdjust(c.at("p").get<std::vector<double>>())) adjusted.push_back(Number(p));
    return {{"adjusted", adjusted}};
  }
  return {{"error", "unknown test '" + test + "'"}};
}

}  // namespace

int main() {
  std::string line;
  while (std::getline(std::cin, line)) {
    if (line.empty()) continue;
    const json request = json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (request.is_discarded() || !request.is_object()) {
      std::cout << json{{"error", "not a JSON object: " + line}}.dump() << "\n";
      continue;
    }
    try {
      std::cout << Evaluate(request).dump() << "\n";
    } catch (const json::exception& e) {  // a malformed case: say so, go on
      std::cout << json{{"error", e.what()}}.dump() << "\n";
    }
  }
  return 0;
}
