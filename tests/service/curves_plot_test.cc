// `results curves --plot` at Table 1 scale (client/service_commands/
// curves_plot.h): one panel per task variant, one colour per method across
// panels, n in the legend, the threshold line, and a script that redraws
// from any directory.
#include "client/service_commands/curves_plot.h"
#include "client/service_commands/success_plot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "tests/service/process_util.h"
#include "tests/service/service_testutil.h"

namespace totalgrad::cli {

using results::CurvePoint;
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
        input.curves.push_back(
            {method, variant, episode, {method == "RP" ? 3 : 5, level - 2, level, level + 2, level}});
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
  EXPECT_NE(WriteCurvesPlot(TwoVariants(), "/tmp/x.jpg").find(".svg, .pdf or .png"),
            std::string::npos);
  CurvesPlotInput empty;
  EXPECT_NE(WriteCurvesPlot(empty, "/tmp/x.svg").find("nothing to plot"), std::string::npos);
}

TEST(CurvesPlotTest, WritesAPdf) {
  const std::string dir = testing::MakeTempDir();
  ASSERT_EQ(WriteCurvesPlot(TwoVariants(), dir + "/curves.pdf"), "");
  EXPECT_EQ(testing::ReadFile(dir + "/curves.pdf").substr(0, 4), "%PDF");
  EXPECT_NE(testing::ReadFile(dir + "/curves.pdf.gp").find("set terminal pdfcairo"), std::string::npos);
  std::filesystem::remove_all(dir);
}

// `results curves --top K --plot`: the paper's Figure 3, a row of three
// panels per variant (all runs' median and quartiles; their mean +- SE;
// the K best runs), the best runs' own blocks and n.
TEST(CurvesPlotTest, FigureThreeHasThreePanelsPerVariant) {
  CurvesPlotInput input = TwoVariants();
  for (CurvePoint& p : input.curves) {
    p.values.mean = p.values.median + 1;
    p.values.standard_error = 0.5;
  }
  input.top = 2;
  for (const CurvePoint& p : input.curves) {
    CurvePoint best = p;
    best.values.trials = 2;
    best.values.median = p.values.median - 3;
    input.best_curves.push_back(best);
  }
  const std::string dir = testing::MakeTempDir();
  const std::string path = dir + "/figure3.svg";
  ASSERT_EQ(WriteCurvesPlot(input, path), "");
  const std::string script = testing::ReadFile(path + ".gp");
  EXPECT_NE(script.find("set multiplot layout 2,3"), std::string::npos) << script;
  EXPECT_EQ(Count(script, ": all runs, median and quartiles\""), 2u) << script;
  EXPECT_EQ(Count(script, ": all runs, mean +- standard error\""), 2u) << script;
  EXPECT_EQ(Count(script, ": the 2 best runs, median and quartiles\""), 2u) << script;
  EXPECT_EQ(Count(script, "using 1:($6-$7):($6+$7) with filledcurves"), 4u) << script;
  EXPECT_EQ(Count(script, "title \"RP (n=2)\""), 2u) << script;  // the best runs' n
  EXPECT_EQ(Count(script, "title \"RP (n=3)\""), 4u) << script;  // all runs, twice per variant
  const std::string data = testing::ReadFile(path + ".dat");
  EXPECT_NE(data.find("# RP | noise_k=0.01 | the 2 best runs"), std::string::npos) << data;
  // RP, episode 1: all runs median 30, mean 31 +- 0.5; best runs median 27.
  EXPECT_NE(data.find("1 28 30 32 3 31 0.5\n"), std::string::npos) << data;
  EXPECT_NE(data.find("1 28 27 32 2 31 0.5\n"), std::string::npos) << data;
  EXPECT_NE(testing::ReadFile(path).find("the 2 best runs"), std::string::npos);
  std::filesystem::remove_all(dir);
}

// `results table --plot` and `results table1 --plot` (success_plot.h).
SuccessPlotInput TwoTasks() {
  SuccessPlotInput input;
  input.title = "two tasks";
  const auto point = [](const std::string& variant, const std::string& method, int successes,
                        int trials, double paper) {
    SuccessPoint p;
    p.variant = variant;
    p.method = method;
    p.success.trials = trials;
    p.success.successes = successes;
    p.success.rate = trials > 0 ? static_cast<double>(successes) / trials : std::nan("");
    p.success.low = trials > 0 ? p.success.rate / 2 : std::nan("");
    p.success.high = trials > 0 ? (1 + p.success.rate) / 2 : std::nan("");
    p.paper_rate = paper;
    return p;
  };
  input.points = {point("tip, k = 1", "PILCO", 8, 10, 0.73), point("tip, k = 1", "RP", 0, 10, 0.15),
                  point("tip, k = 0.01", "PILCO", 2, 3, 0.6), point("tip, k = 0.01", "RP", 0, 0, 0.2)};
  input.panel_variants = {"tip, k = 1"};
  input.panel_titles = {"cart-pole, tip, k = 1"};
  return input;
}

TEST(SuccessPlotTest, OnePanelPerTaskWilsonBarsCountsAndThePapersRate) {
  const std::string dir = testing::MakeTempDir();
  const std::string path = dir + "/rates.svg";
  ASSERT_EQ(WriteSuccessPlot(TwoTasks(), path), "");
  const std::string script = testing::ReadFile(path + ".gp");
  EXPECT_NE(script.find("set multiplot layout 1,2"), std::string::npos) << script;
  EXPECT_NE(script.find("set title \"cart-pole, tip, k = 1\""), std::string::npos) << script;
  EXPECT_NE(script.find("set title \"tip, k = 0.01\""), std::string::npos) << script;  // untitled
  EXPECT_NE(script.find("set xtics (\"PILCO\" 0, \"RP\" 1)"), std::string::npos) << script;
  EXPECT_EQ(Count(script, "with yerrorbars lc rgb \"" + MethodColour("PILCO") + "\""), 2u);
  EXPECT_EQ(Count(script, "title \"paper\""), 2u);  // once per panel
  EXPECT_EQ(Count(script, "using 1:7 with points"), 4u);  // every point has a paper rate
  const std::string data = testing::ReadFile(path + ".dat");
  EXPECT_NE(data.find("\n0 0.8 0.4 0.9 8 10 0.73\n"), std::string::npos) << data;
  EXPECT_NE(data.find("\n1 NaN NaN NaN 0 0 0.2\n"), std::string::npos) << data;  // no trial
  const std::string svg = testing::ReadFile(path);
  EXPECT_NE(svg.find("8/10"), std::string::npos);
  EXPECT_NE(svg.find("0/0"), std::string::npos);
  EXPECT_NE(svg.find("paper"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(SuccessPlotTest, RefusesBadExtensionsAndATableWithoutTrials) {
  EXPECT_NE(WriteSuccessPlot(TwoTasks(), "/tmp/x.gif").find(".svg, .pdf or .png"), std::string::npos);
  SuccessPlotInput none = TwoTasks();
  for (SuccessPoint& p : none.points) p.success.trials = 0;
  EXPECT_NE(WriteSuccessPlot(none, "/tmp/x.svg").find("no completed trial"), std::string::npos);
}

}  // namespace
}  // namespace totalgrad::cli
