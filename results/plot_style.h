// What the curve plots of `results curves --plot` and the dashboard share:
// one colour per estimation method (the same in every panel and in both, so
// a method is found by its colour), and one panel per task variant with a
// title naming the scene, cost and noise level and the success threshold.
#ifndef TOTALGRAD_RESULTS_PLOT_STYLE_H_
#define TOTALGRAD_RESULTS_PLOT_STYLE_H_

#include <string>
#include <utility>
#include <vector>

namespace totalgrad::results {

// "#rrggbb". The paper's methods (PILCO, RP, GR, LR, TP, GLR, GTP, GTP+sn,
// DEL) have fixed, distinct colours; any other name gets one of a further
// set chosen by a hash of the name (stable across runs and machines; two
// unknown names may share one).
std::string MethodColour(const std::string& method);

struct CurvePanel {
  std::string variant;
  // "cartpole-swingup, angle cost, k = 0.01", then any other swept
  // "key=value" of the variant.
  std::string title;
  // The trial option "threshold": success means a final evaluation cost
  // below it. NaN if the options do not say.
  double threshold = 0;
};

// The panel of `variant` from the options of one of its jobs ((key,
// canonical value) pairs as stored). Missing keys are left out of the title.
CurvePanel DescribePanel(const std::string& variant,
                         const std::vector<std::pair<std::string, std::string>>& options);

}  // namespace totalgrad::results

#endif  // TOTALGRAD_RESULTS_PLOT_STYLE_H_
