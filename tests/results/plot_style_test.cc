// The plots' shared style (results/plot_style.h): a fixed colour per
// method, a panel title naming scene, cost, noise level and the other swept
// keys, and the success threshold read from the options.
#include "results/plot_style.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>

namespace totalgrad::results {
namespace plot_style_test {

TEST(DescribePanelTest, NamesSceneCostNoiseAndOtherSweptKeys) {
  const CurvePanel panel = DescribePanel(
      "noise_k=0.01 particles=100",
      {{"scene", "cartpole-swingup"}, {"cost", "tip"}, {"noise_k", "0.01"}, {"threshold", "12.5"}});
  EXPECT_EQ(panel.title, "cartpole-swingup, tip cost, k = 0.01, particles=100");
  EXPECT_DOUBLE_EQ(panel.threshold, 12.5);
  const CurvePanel bare = DescribePanel("", {});
  EXPECT_EQ(bare.title, "all trials");
  EXPECT_TRUE(std::isnan(bare.threshold));
}

TEST(MethodColourTest, FixedAndDistinctForThePapersMethods) {
  std::set<std::string> colours;
  for (const char* method : {"PILCO", "RP", "GR", "LR", "TP", "GLR", "GTP", "GTP+sn", "DEL"}) {
    colours.insert(MethodColour(method));
  }
  EXPECT_EQ(colours.size(), 9u);
  EXPECT_EQ(MethodColour("RP"), "#e15759");
  EXPECT_EQ(MethodColour("my-new-method"), MethodColour("my-new-method"));
}

}  // namespace plot_style_test
}  // namespace totalgrad::results
