// results/diagnostics.h: the estimator statistics' median and quartiles per
// method, variant and episode, against values worked by hand; absent values
// (NaN, empty LR shares) left out; the LR share's two summaries.
#include "results/diagnostics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

namespace totalgrad::results {
namespace diagnostics_test {

EpisodeStatistics Row(const std::string& method, int episode, double snr,
                      std::vector<double> lr_share = {}) {
  EpisodeStatistics row;
  row.method = method;
  row.variant = "noise_k=0.01";
  row.episode.episode = episode;
  row.episode.gradient_snr_mean = snr;
  row.episode.lr_share = std::move(lr_share);
  return row;
}

const DiagnosticPoint* Find(const std::vector<DiagnosticPoint>& points, const std::string& statistic,
                            const std::string& method, int episode) {
  for (const DiagnosticPoint& p : points)
    if (p.statistic == statistic && p.curve.method == method && p.curve.episode == episode) return &p;
  return nullptr;
}

TEST(DiagnosticsTest, MedianAndQuartilesByHand) {
  const std::vector<EpisodeStatistics> rows = {
      Row("RP", 1, 4.0), Row("RP", 1, 1.0), Row("RP", 1, 3.0), Row("RP", 1, 2.0),
      Row("RP", 2, 0.5),
      Row("TP", 1, 1.0, {0.2, 0.4, 0.6}), Row("TP", 1, 3.0, {0.0, 0.0, 1.0}),
      Row("PILCO", 1, std::nan("")),
  };
  const std::vector<DiagnosticPoint> points = DiagnosticCurves(rows);
  // RP episode 1: {1, 2, 3, 4}; quantiles by linear interpolation at (n-1) q.
  const DiagnosticPoint* rp = Find(points, "gradient_snr_mean", "RP", 1);
  ASSERT_NE(rp, nullptr);
  EXPECT_EQ(rp->curve.values.trials, 4);
  EXPECT_DOUBLE_EQ(rp->curve.values.q25, 1.75);
  EXPECT_DOUBLE_EQ(rp->curve.values.median, 2.5);
  EXPECT_DOUBLE_EQ(rp->curve.values.q75, 3.25);
  EXPECT_EQ(rp->curve.variant, "noise_k=0.01");
  const DiagnosticPoint* rp2 = Find(points, "gradient_snr_mean", "RP", 2);
  ASSERT_NE(rp2, nullptr);
  EXPECT_EQ(rp2->curve.values.median, 0.5);
  EXPECT_EQ(rp2->curve.values.q25, 0.5);
  // PILCO has no SNR: no point; nor has any method a statistic left NaN.
  EXPECT_EQ(Find(points, "gradient_snr_mean", "PILCO", 1), nullptr);
  EXPECT_EQ(Find(points, "ess_min", "RP", 1), nullptr);
  // TP's LR share: means 0.4 and 1/3 (median 0.3666...), last 0.6 and 1.
  const DiagnosticPoint* mean = Find(points, "lr_share_mean", "TP", 1);
  ASSERT_NE(mean, nullptr);
  EXPECT_EQ(mean->curve.values.trials, 2);
  EXPECT_DOUBLE_EQ(mean->curve.values.median, (0.4 + 1.0 / 3.0) / 2);
  const DiagnosticPoint* last = Find(points, "lr_share_last", "TP", 1);
  ASSERT_NE(last, nullptr);
  EXPECT_DOUBLE_EQ(last->curve.values.median, 0.8);
  EXPECT_EQ(Find(points, "lr_share_mean", "RP", 1), nullptr);  // RP has no LR part
  // Ordered by statistic first: every gradient_snr_mean point before any lr_share one.
  size_t first_lr = points.size(), last_snr = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    if (points[i].statistic == "gradient_snr_mean") last_snr = i;
    if (points[i].statistic.rfind("lr_share", 0) == 0) first_lr = std::min(first_lr, i);
  }
  EXPECT_LT(last_snr, first_lr);
}

TEST(DiagnosticsTest, OneStatisticAlone) {
  const std::vector<EpisodeStatistics> rows = {Row("RP", 1, 2.0, {}), Row("TP", 1, 1.0, {0.5})};
  const std::vector<DiagnosticPoint> points = DiagnosticCurves(rows, "lr_share_last");
  ASSERT_EQ(points.size(), 1u);
  EXPECT_EQ(points[0].curve.method, "TP");
  EXPECT_EQ(points[0].curve.values.median, 0.5);
}

TEST(DiagnosticsTest, TheStatisticsAreTheRecordsDiagnostics) {
  const std::vector<std::string>& names = DiagnosticStatistics();
  EXPECT_EQ(names.front(), "gradient_norm_first");
  EXPECT_EQ(names.size(), 15u + 2u);  // 12 gradient/step statistics, 3 ESS, 2 LR-share summaries
  for (const std::string& name : names) {
    EXPECT_NE(name, "real_cost");
    EXPECT_NE(name, "held_fraction");
  }
}

}  // namespace diagnostics_test
}  // namespace totalgrad::results
