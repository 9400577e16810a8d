// `results curves --plot` at Table 1 scale (client/service_commands/
// curves_plot.h): one panel per task variant, one colour per method across
// panels, n in the legend, the threshold line, and a script that redraws
// from any directory.
#include "client/service_commands/curves_plot.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "tests/service/process_util.h"
#include "tests/service/service_testutil.h"

namespace totalgrad::cli {

using results::DescribePanel;
using results::MethodColour;

namespace {

CurvesPlotInput TwoVariants() {
  CurvesPlotInput input;
  input.sweep_name = "table1-like";
  for (const std::string variant : {"noise_k=0.01", "noise_k=1"}) {
    for (const std::string method : {"RP", "TP"}) {
      for (int episode = 1; episode <= 4; ++episode) {
        const double level = (method == "RP" ? 30.0 : 20.0) / episode;
        input.curves.push_back({method, variant, episode, method == "RP" ? 3 : 5, level - 2,
                                level, level + 2});
      }
    }
  }
  input.panels = {
      DescribePanel("noise_k=0.01", {{"scene", "cartpole-swingup"}, {"cost", "angle"},
                                     {"noise_k", "0.01"}, {"threshold", "15"}}),
      DescribePanel("noise_k=1", {{"scene", "cartpole-swingup"}, {"cost", "angle"},
                                  {"noise_k", "1"}, {"threshold", "15"}})};
  return input;
}

size_t Count(const std::string& text, const std::string& what) {
  size_t count = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++count;
  return count;
}

TEST(CurvesPlotTest, OnePanelPerVariantFixedColoursThresholdAndN) {
  const std::string dir = testing::MakeTempDir();
  const std::string path = dir + "/curves.svg";
  ASSERT_EQ(WriteCurvesPlot(TwoVariants(), path), "");
  const std::string script = testing::ReadFile(path + ".gp");
  EXPECT_NE(script.find("set multiplot layout 1,2"), std::string::npos) << script;
  EXPECT_EQ(Count(script, "set title \"cartpole-swingup, angle cost, k = "), 2u) << script;
  // Each method keeps its colour in both panels (band and median: 2 per panel).
  EXPECT_EQ(Count(script, "lc rgb \"" + MethodColour("RP") + "\""), 4u) << script;
  EXPECT_EQ(Count(script, "lc rgb \"" + MethodColour("TP") + "\""), 4u) << script;
  EXPECT_EQ(Count(script, "title \"RP (n=3)\""), 2u) << script;
  EXPECT_EQ(Count(script, "title \"TP (n=5)\""), 2u) << script;
  EXPECT_EQ(Count(script, "15 with lines dt 2"), 2u) << script;
  const std::string svg = testing::ReadFile(path);
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_NE(svg.find("RP (n=3)"), std::string::npos);
  EXPECT_NE(svg.find("success threshold 15"), std::string::npos);
  EXPECT_NE(svg.find("k = 0.01"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(CurvesPlotTest, ScriptUsesAbsolutePathsAndRedrawsFromAnotherDirectory) {
  const std::string dir = testing::MakeTempDir();
  const std::filesystem::path before = std::filesystem::current_path();
  std::filesystem::current_path(dir);
  const std::string problem = WriteCurvesPlot(TwoVariants(), "relative.png");
  std::filesystem::current_path(before);
  ASSERT_EQ(problem, "");
  const std::string script = testing::ReadFile(dir + "/relative.png.gp");
  EXPECT_NE(script.find("set output \"" + dir + "/relative.png\""), std::string::npos) << script;
  EXPECT_NE(script.find("\"" + dir + "/relative.png.dat\" index 0"), std::string::npos) << script;
  std::filesystem::remove(dir + "/relative.png");
  std::string out, err;
  ASSERT_EQ(testing::RunCommand({"/bin/sh", "-c", "cd / && gnuplot '" + dir + "/relative.png.gp'"},
                                &out, &err),
            0)
      << err;
  EXPECT_TRUE(std::filesystem::exists(dir + "/relative.png"));
  EXPECT_GT(std::filesystem::file_size(dir + "/relative.png"), 1000u);
  std::filesystem::remove_all(dir);
}

TEST(CurvesPlotTest, RefusesBadExtensionsAndEmptyCurves) {
  EXPECT_NE(WriteCurvesPlot(TwoVariants(), "/tmp/x.pdf").find(".svg or .png"), std::string::npos);
  CurvesPlotInput empty;
  EXPECT_NE(WriteCurvesPlot(empty, "/tmp/x.svg").find("nothing to plot"), std::string::npos);
}

}  // namespace
}  // namespace totalgrad::cli
