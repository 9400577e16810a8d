// The paper's Table 1 (Parmas, Rasmussen, Peters and Doya 2018, "PIPPS",
// Table 1: success rates of eight policy-search methods on the cart-pole
// swing-up) from completed trials of any number of sweeps: one grid, one
// computation, for `totalgrad results table1` and the dashboard's
// /api/table1.
//
// The grid: rows are the task (trial options `cost` and `noise_k`),
//   (angle, k = 0.01), (angle, k = 1), (tip, k = 0.01), (tip, k = 1);
// columns are the methods PILCO, RP, GR, LR, TP, GTP, GLR, GTP+sn. A trial's
// cell is found from its job's options and its method, whatever sweep it is
// in; the trials of one cell from several sweeps are pooled. Each cell has
// our success rate with its 95% Wilson interval and n, the rollout verdict's
// rate (trials whose held_fraction >= 0.5 among those with one), the
// paper's number, whether that number lies inside our interval, and which
// options of its trials differ from the paper's protocol.
//
// Pure functions of their arguments; thread-safe.
#ifndef TOTALGRAD_RESULTS_TABLE1_H_
#define TOTALGRAD_RESULTS_TABLE1_H_

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/record.h"
#include "results/completed_trial.h"
#include "results/stats.h"

namespace totalgrad::results {

// The grid's columns, in the paper's order.
const std::vector<std::string>& Table1Methods();

// A row of the grid: the task's cost and observation noise multiplier.
struct Table1Row {
  std::string cost;  // the trial option "cost": "angle" or "tip"
  double noise_k = 0;  // the trial option "noise_k"
  // "angle, k = 0.01"
  std::string Label() const;
};

// (angle, 0.01), (angle, 1), (tip, 0.01), (tip, 1): the paper's order.
const std::vector<Table1Row>& Table1Rows();

// The paper's success rate in row `row` (an index into Table1Rows()) for
// `method`. NaN where the paper gives none (GTP+sn at k = 1) and for a row
// or method that is not in the grid.
double PaperSuccessRate(size_t row, const std::string& method);

// The paper's protocol, as (trial option, value): scene cartpole-swingup,
// episodes 15, policy_steps 600, particles 300, eval_rollouts 30,
// threshold 15.
const record::TextPairs& PaperProtocol();

// How a job's options (its (key, canonical text) pairs, as stored) differ
// from PaperProtocol(), one entry per differing option in the protocol's
// order: "particles = 50 (paper 300)", or "episodes missing (paper 15)" when
// the options lack the key. Numbers are compared as numbers ("15" equals
// "15.0"), the scene as text. Empty: the trial ran the paper's protocol.
std::vector<std::string> ProtocolDifferences(const record::TextPairs& options);

// One cell of the grid. With no trial, every rate and bound is NaN.
struct Table1Cell {
  std::string cost;
  double noise_k = 0;
  std::string method;
  WilsonRate success;
  // The rollout verdict, over the held.trials trials that have one.
  WilsonRate held;
  // The paper's number (PaperSuccessRate); NaN where it has none.
  double paper_success_rate = std::numeric_limits<double>::quiet_NaN();
  // Trials of this cell that did not run the paper's protocol, and the
  // distinct ProtocolDifferences of those trials joined by "; " in
  // first-appearance order ("" when every trial ran the protocol).
  int off_protocol_trials = 0;
  std::string protocol_differences;
  // The sweeps whose trials are pooled here, in first-appearance order.
  std::vector<std::string> sweeps;
};

// "yes" when the paper's number lies inside [success.low, success.high]
// (ends included), "no" when outside, "" when the cell has no trial or the
// paper no number.
std::string PaperInInterval(const Table1Cell& cell);

// The cell's fields under their names in `results table1 -f csv|json` and
// /api/table1: cost, noise_k, method, then the statistics named as in
// TableCellFields() (trials ... held_wilson95_high), paper_success_rate,
// paper_in_interval (derived: PaperInInterval), off_protocol_trials,
// protocol_differences, sweeps.
const record::FieldTable<Table1Cell>& Table1CellFields();

struct Table1 {
  // Every cell of the grid, row-major: cells[r * Table1Methods().size() + m]
  // is row Table1Rows()[r], method Table1Methods()[m].
  std::vector<Table1Cell> cells;
  // The trials of each cell, indexed as `cells`, in input order (each seed
  // once: ComputeTable1 refuses a seed twice in a cell).
  std::vector<std::vector<CompletedTrial>> cell_trials;
  // Trials that have no cell, counted per reason in first-appearance order:
  // "12 trials of method DEL (not a Table 1 method)", "3 trials with cost
  // 'saturating' (Table 1 has angle and tip)", "2 trials with noise_k 0.1
  // (Table 1 has 0.01 and 1)", "1 trial without the option 'noise_k'".
  std::vector<std::string> outside;
  int trials_outside = 0;
};

// Lays out `trials` in the grid. A trial's row is the one whose cost equals
// its option "cost" and whose noise_k equals its option "noise_k" read as a
// double; its column is its method.
//
// InvalidArgument, naming both, when two trials share (method, seed, cell):
// of two sweeps ("... seed 11 of PILCO in (tip, k = 1) is in sweep A (job
// 3) and in sweep B (job 41) ..."), or of one sweep twice (two variants
// mapping to one cell). Pooling them would count a seed twice.
absl::StatusOr<Table1> ComputeTable1(const std::vector<CompletedTrial>& trials);

}  // namespace totalgrad::results

#endif  // TOTALGRAD_RESULTS_TABLE1_H_
