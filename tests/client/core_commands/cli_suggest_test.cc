#include "client/core_commands/cli_suggest.h"

#include <gtest/gtest.h>

namespace totalgrad::cli {
namespace cli_suggest_test {

TEST(EditDistance, CountsInsertionsDeletionsAndSubstitutions) {
  EXPECT_EQ(EditDistance("sweep", "sweep"), 0);
  EXPECT_EQ(EditDistance("sweeps", "sweep"), 1);
  EXPECT_EQ(EditDistance("lst", "list"), 1);
  EXPECT_EQ(EditDistance("particels", "particles"), 2);
  EXPECT_EQ(EditDistance("", "abc"), 3);
  EXPECT_EQ(EditDistance("kitten", "sitting"), 3);
}

TEST(ClosestCandidate, SuggestsOnlyTyposAndUniquePrefixes) {
  const std::vector<std::string> names = {"sweep", "job", "results", "worker", "run", "results2"};
  EXPECT_EQ(ClosestCandidate("sweeps", names), "sweep");
  EXPECT_EQ(ClosestCandidate("reslts", names), "results");
  EXPECT_EQ(ClosestCandidate("wrk", names), "");      // 3 edits from "worker", and not a prefix
  EXPECT_EQ(ClosestCandidate("work", names), "worker");  // a unique prefix
  EXPECT_EQ(ClosestCandidate("sweep", names), "");   // exact: nothing to suggest
  EXPECT_EQ(ClosestCandidate("zzzzzz", names), "");
}

TEST(SuggestFor, NamesTheSubcommandOrFlagOfTheCommandBeingParsed) {
  CLI::App app{"t", "totalgrad"};
  CLI::App* sweep = app.add_subcommand("sweep", "");
  sweep->add_subcommand("list", "");
  sweep->add_subcommand("submit", "");
  CLI::App* trial = app.add_subcommand("trial", "");
  int particles = 0;
  trial->add_option("--particles", particles, "");
  EXPECT_EQ(SuggestFor(app, {"sweeps", "list"}), "did you mean 'totalgrad sweep'?");
  EXPECT_EQ(SuggestFor(app, {"sweep", "lst"}), "did you mean 'totalgrad sweep list'?");
  EXPECT_EQ(SuggestFor(app, {"trial", "--particels", "5"}),
            "did you mean '--particles'? (`totalgrad trial --help` lists the options)");
  EXPECT_EQ(SuggestFor(app, {"trial", "--particles", "5"}), "");
  EXPECT_EQ(SuggestFor(app, {"nothing-like-it"}), "");
}

}  // namespace cli_suggest_test
}  // namespace totalgrad::cli
