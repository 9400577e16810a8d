// The `totalgrad` CLI against a real coordinator: sweep files with errors,
// submit --wait, results table/curves/export in every format, job and worker
// listings, backups, and `totalgrad run` (the embedded default).
#include <signal.h>
#include <sys/wait.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_split.h"
#include "results/plot_style.h"
#include "tests/service/e2e_util.h"
#include "tests/service/service_testutil.h"

namespace totalgrad::testing {
namespace cli_test {

using std::chrono::seconds;

constexpr char kTinySweep[] = R"(# a tiny sweep
name = "cli"
[grid]
method = ["RP"]
seed = [1, 2, 3]
[protocol]
episodes = 2
policy_steps = 3
particles = 8
eval_rollouts = 2
horizon = 10
)";

class CliTest : public ServiceFixture {
 protected:
  // Runs `totalgrad ARGS... --coordinator ... --insecure --token-file user.token`.
  int Cli(std::vector<std::string> args, std::string* out, std::string* err,
          bool connection_flags = true) {
    std::vector<std::string> argv = {TOTALGRAD_CLI_BIN};
    argv.insert(argv.end(), args.begin(), args.end());
    if (connection_flags) {
      for (const std::string& flag : {std::string("--coordinator"), absl::StrCat("127.0.0.1:", port_),
                                      std::string("--insecure"), std::string("--token-file"),
                                      dir_ + "/user.token"}) {
        argv.push_back(flag);
      }
    }
    return RunCommand(argv, out, err);
  }
  std::string WriteSweep(const std::string& name, const std::string& text) {
    const std::string path = dir_ + "/" + name;
    WriteFile(path, text);
    return path;
  }
};

TEST_F(CliTest, MalformedSweepFilesAreRefusedWithFileLineAndFieldBeforeAnythingIsStored) {
  StartCoordinator();
  struct Case {
    std::string text;
    std::string expected;  // in stderr, after the file name
  };
  const std::vector<Case> cases = {
      {"name = \"x\"\n[grid]\nmethod = [\"RP\",\n  \"NOT-A-METHOD\"]\n",
       ":4:3: grid.method[1]: option 'method': unknown method 'NOT-A-METHOD'"},
      {"name = \"x\"\n[grid]\nmethod = [\"RP\"]\n[protocol]\nparticles = -5\n",
       ":5:13: protocol.particles:"},
      {"name = \"x\"\n[grid]\nmethod = [\"RP\"]\n[protocol]\nparticels = 5\n",
       ":5:13: protocol.particels: unknown option 'particels'; did you mean 'particles'?"},
      {"name = \"x\"\n[grid]\nmethod = [\"RP\"]\nseed = [1, 1]\n", ": grid.seed[1]: '1' repeats"},
      {"name = \"x\"\nmax_attempts = \"three\"\n[grid]\nmethod = [\"RP\"]\n",
       ":2:16: max_attempts: must be an integer"},
      {"name = \"x\"\n[grid\nmethod = [\"RP\"]\n", ":2:"},
      {"name = \"x\"\ncolour = 3\n[grid]\nmethod = [\"RP\"]\n", ":2:10: colour: unknown field"},
      {"name = \"x\"\n[grid]\nseed = [1]\n", ": grid.method: missing"},
      {"[grid]\nmethod = [\"RP\"]\n", ": name: missing"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const std::string path = WriteSweep(absl::StrCat("bad", i, ".toml"), cases[i].text);
    std::string out, err;
    EXPECT_EQ(Cli({"sweep", "submit", path}, &out, &err), 2) << err;
    EXPECT_NE(err.find(path + cases[i].expected), std::string::npos)
        << "case " << i << ": expected '" << path + cases[i].expected << "' in: " << err;
  }
  std::string out, err;
  ASSERT_EQ(Cli({"sweep", "list", "-f", "json"}, &out, &err), 0) << err;
  EXPECT_EQ(nlohmann::json::parse(out).size(), 0u);
}

TEST_F(CliTest, SubmitWaitAndQueryResultsInEveryFormat) {
  StartCoordinator();
  auto worker = StartWorker("cli-worker");
  const std::string path = WriteSweep("cli.toml", kTinySweep);
  std::string out, err;
  ASSERT_EQ(Cli({"sweep", "submit", path, "--wait"}, &out, &err), 0) << out << err;
  EXPECT_NE(out.find("submitted: sweep cli, 3 jobs"), std::string::npos) << out;
  EXPECT_NE(err.find("jobs 3/3"), std::string::npos) << err;
  // Resubmitting is a no-op.
  ASSERT_EQ(Cli({"sweep", "submit", path}, &out, &err), 0) << err;
  EXPECT_NE(out.find("already submitted (no change)"), std::string::npos) << out;

  ASSERT_EQ(Cli({"results", "table", "cli"}, &out, &err), 0) << err;
  EXPECT_NE(out.find("RP      1.00 [0.44, 1.00] n=3"), std::string::npos) << out;
  // Every trial classified its final policy's rollouts (the rollout verdict).
  EXPECT_NE(out.find("n=3; held "), std::string::npos) << out;
  EXPECT_NE(out.find("/3"), std::string::npos) << out;
  ASSERT_EQ(Cli({"results", "table", "cli", "-f", "csv"}, &out, &err), 0) << err;
  EXPECT_EQ(out.substr(0, out.find('\n')),
            "method,variant,trials,successes,success_rate,wilson95_low,wilson95_high,"
            "median_final_cost,classified,held,held_rate,held_wilson95_low,held_wilson95_high");
  ASSERT_EQ(Cli({"results", "table", "cli", "-f", "json"}, &out, &err), 0) << err;
  const nlohmann::json table = nlohmann::json::parse(out);
  ASSERT_EQ(table.size(), 1u);
  EXPECT_EQ(table[0]["trials"], 3);
  EXPECT_EQ(table[0]["successes"], 3);

  // Issue 29: the success rates as a figure, one colour per method.
  const std::string rates = dir_ + "/rates.svg";
  ASSERT_EQ(Cli({"results", "table", "cli", "--plot", rates}, &out, &err), 0) << err;
  EXPECT_NE(err.find("plot written to " + rates), std::string::npos) << err;
  const std::string rates_svg = ReadFile(rates);
  EXPECT_NE(rates_svg.find("<svg"), std::string::npos);
  EXPECT_NE(rates_svg.find("3/3"), std::string::npos);
  EXPECT_NE(ReadFile(rates + ".gp").find("with yerrorbars lc rgb \"" + results::MethodColour("RP")),
            std::string::npos);

  const std::string plot = dir_ + "/curves.svg";
  ASSERT_EQ(Cli({"results", "curves", "cli", "-f", "json", "--plot", plot}, &out, &err), 0) << err;
  const nlohmann::json curves = nlohmann::json::parse(out);
  ASSERT_EQ(curves.size(), 2u);  // episodes 1 and 2 have evaluation costs
  EXPECT_EQ(curves[0]["trials"], 3);
  EXPECT_TRUE(std::filesystem::file_size(plot) > 1000) << err;
  EXPECT_NE(ReadFile(plot).find("<svg"), std::string::npos);
  // Mean and standard error beside the quartiles; Figure 3 with --top.
  EXPECT_TRUE(curves[0]["mean"].is_number()) << curves[0];
  EXPECT_TRUE(curves[0]["standard_error"].is_number()) << curves[0];
  const std::string figure3 = dir_ + "/figure3.pdf";
  ASSERT_EQ(Cli({"results", "curves", "cli", "--top", "2", "--plot", figure3}, &out, &err), 0) << err;
  EXPECT_EQ(ReadFile(figure3).substr(0, 4), "%PDF");
  EXPECT_NE(ReadFile(figure3 + ".gp").find("the 2 best runs, median and quartiles"), std::string::npos);
  EXPECT_EQ(Cli({"results", "curves", "cli", "--top", "2"}, &out, &err), 2);
  EXPECT_NE(err.find("give --plot FILE"), std::string::npos) << err;

  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "csv"}, &out, &err), 0) << err;
  std::vector<std::string> lines = absl::StrSplit(out, '\n', absl::SkipEmpty());
  EXPECT_EQ(lines.size(), 1u + 9u);
  EXPECT_NE(lines[0].find(",optimisation_seconds,cpu_seconds,"), std::string::npos) << lines[0];
  std::string default_format;
  ASSERT_EQ(Cli({"results", "export", "cli"}, &default_format, &err), 0) << err;  // csv
  EXPECT_EQ(default_format, out);
  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "jsonl"}, &out, &err), 0) << err;
  lines = absl::StrSplit(out, '\n', absl::SkipEmpty());
  ASSERT_EQ(lines.size(), 9u);
  const nlohmann::json row = nlohmann::json::parse(lines[1]);
  EXPECT_EQ(row["episode"], 1);
  EXPECT_TRUE(row["seed"].is_number_integer()) << row;
  EXPECT_GT(row["cpu_seconds"].get<double>(), 0.0) << row;
  EXPECT_TRUE(row["details"].is_object());
  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "json"}, &out, &err), 0) << err;
  const nlohmann::json archive = nlohmann::json::parse(out);
  EXPECT_EQ(archive["format"], "totalgrad-sweep-archive");
  EXPECT_EQ(archive["sweep"]["name"], "cli");
  ASSERT_EQ(archive["jobs"].size(), 3u);
  // Options as [key, text] pairs, in the job's order.
  bool particles_seen = false;
  for (const auto& pair : archive["jobs"][0]["options"]) {
    if (pair.at(0) == "particles") {
      EXPECT_EQ(pair.at(1), "8");
      particles_seen = true;
    }
  }
  EXPECT_TRUE(particles_seen) << archive["jobs"][0]["options"];
  EXPECT_EQ(archive["jobs"][0]["attempt_log"][0]["episodes"].size(), 3u);
  EXPECT_NE(archive["jobs"][0]["attempt_log"][0]["worker_build"].get<std::string>().find("totalgrad"),
            std::string::npos);
  EXPECT_EQ(Cli({"results", "export", "cli", "-f", "table"}, &out, &err), 2);  // not an export format

  ASSERT_EQ(Cli({"job", "list", "--sweep", "cli", "-f", "json"}, &out, &err), 0) << err;
  const nlohmann::json jobs = nlohmann::json::parse(out);
  ASSERT_EQ(jobs.size(), 3u);
  // The job's record (server/storage/service_records.h), named as in JobInfo.
  EXPECT_EQ(jobs[0]["state"], "completed");
  EXPECT_EQ(jobs[0]["kind"], "trial");
  EXPECT_EQ(jobs[0]["sweep_name"], "cli");
  EXPECT_EQ(jobs[0]["episodes_stored"], 3);
  EXPECT_EQ(jobs[0]["episodes_expected"], 3);
  EXPECT_EQ(jobs[0]["success"], true);
  EXPECT_TRUE(jobs[0]["final_eval_cost"].is_number()) << jobs[0];
  EXPECT_EQ(jobs[0]["lost_leases"], 0);
  // A job's options, in their order, as [key, text] pairs.
  ASSERT_TRUE(jobs[0]["options"].is_array()) << jobs[0];
  ASSERT_FALSE(jobs[0]["options"].empty()) << jobs[0];
  EXPECT_EQ(jobs[0]["options"][0].size(), 2u) << jobs[0];
  ASSERT_EQ(Cli({"job", "list", "--sweep", "cli", "-f", "csv"}, &out, &err), 0) << err;
  EXPECT_EQ(out.substr(0, out.find('\n')),
            "job_id,sweep_name,kind,ordinal,method,seed,variant,options,state,attempts,failures,"
            "lost_leases,episodes_stored,episodes_expected,worker_id,success,final_eval_cost,"
            "held_fraction,last_error");
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1 + 3) << out;
  ASSERT_EQ(Cli({"job", "logs", jobs[0]["job_id"].dump()}, &out, &err), 0) << err;
  EXPECT_NE(out.find("lease_granted"), std::string::npos) << out;
  EXPECT_NE(out.find("particles=8"), std::string::npos) << out;
  EXPECT_EQ(Cli({"job", "retry", jobs[0]["job_id"].dump()}, &out, &err), 1);  // completed: refused
  EXPECT_NE(err.find("FAILED_PRECONDITION"), std::string::npos) << err;

  ASSERT_EQ(Cli({"worker", "list", "-f", "csv"}, &out, &err), 0) << err;
  EXPECT_NE(out.find("cli-worker,active"), std::string::npos) << out;
  ASSERT_EQ(Cli({"sweep", "status", "cli", "-f", "json"}, &out, &err), 0) << err;
  const nlohmann::json status = nlohmann::json::parse(out);
  EXPECT_EQ(status[0]["jobs_completed"], 3);
  EXPECT_EQ(status[0]["jobs_total"], 3);
  EXPECT_EQ(status[0]["finished"], true);
  EXPECT_EQ(status[0]["state"], "running");
  EXPECT_EQ(status[0]["episodes_stored"], 9);
  EXPECT_TRUE(status[0]["canonical_spec"].is_string());
  ASSERT_EQ(Cli({"sweep", "list", "-f", "csv"}, &out, &err), 0) << err;
  EXPECT_EQ(out.substr(0, out.find('\n')),
            "name,description,state,finished,jobs_total,jobs_queued,jobs_running,jobs_completed,"
            "jobs_failed,jobs_cancelled,episodes_stored,episodes_expected,created_unix_ms,"
            "spec_hash,source_name,coordinator_build,max_attempts,max_lost_leases,"
            "max_concurrent");
  ASSERT_EQ(Cli({"sweep", "list"}, &out, &err), 0) << err;  // the text view
  EXPECT_EQ(out.rfind("name  state    finished", 0), 0u) << out;
  EXPECT_NE(out.find("cli   running  yes"), std::string::npos) << out;
  EXPECT_EQ(Cli({"sweep", "status", "nope"}, &out, &err), 2);
  EXPECT_NE(err.find("NOT_FOUND: no sweep named 'nope'"), std::string::npos) << err;
}

// Issue 15: a sweep moves between coordinators. The archive of a finished
// sweep, imported into a fresh coordinator, gives the same rows (ids,
// attempts, costs, report times); importing it again takes over nothing; the
// results can be read from either database file without a coordinator, and
// writes through --db are refused.
TEST_F(CliTest, ExportImportMovesASweepAndDatabasesReadWithoutACoordinator) {
  StartCoordinator();
  auto worker = StartWorker("mover");
  const std::string path = WriteSweep("cli.toml", kTinySweep);
  std::string out, err;
  ASSERT_EQ(Cli({"sweep", "submit", path, "--wait"}, &out, &err), 0) << out << err;
  const std::string archive = dir_ + "/cli-archive.json";
  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "json", "--checkpoints", "-o", archive}, &out,
                &err),
            0)
      << err;
  // Issue 25: every completed trial's final checkpoint is kept, its size said.
  EXPECT_NE(err.find("3 checkpoints kept"), std::string::npos) << err;
  std::string artifacts_a;
  ASSERT_EQ(Cli({"job", "artifacts", "1", "--out", dir_ + "/artifacts-a"}, &out, &err), 0) << err;
  artifacts_a = ReadFile(dir_ + "/artifacts-a/snapshot.json");
  std::string rows_a, table_a;
  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "csv"}, &rows_a, &err), 0) << err;
  ASSERT_EQ(Cli({"results", "table", "cli"}, &table_a, &err), 0) << err;
  // The file, read while its coordinator runs and holds it.
  const std::string db_a = db_;
  ASSERT_EQ(Cli({"results", "table", "cli", "--db", db_a}, &out, &err, false), 0) << err;
  EXPECT_EQ(out, table_a);
  EXPECT_NE(Cli({"sweep", "cancel", "cli", "--db", db_a}, &out, &err, false), 0);
  EXPECT_NE(err.find("read-only"), std::string::npos) << err;
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(seconds(20)), 0);
  coordinator_.reset();
  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "csv", "--db", db_a}, &out, &err, false), 0) << err;
  EXPECT_EQ(out, rows_a);

  db_ = dir_ + "/second.db";
  // What a coordinator killed mid-import left beside its database is removed
  // when the next one opens it; another database's is not its to remove.
  WriteFile(dir_ + "/.second.db.import-Ab12Cd", "half an archive");
  WriteFile(dir_ + "/.other.db.import-Ab12Cd", "another store's");
  StartCoordinator();
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/.second.db.import-Ab12Cd"));
  EXPECT_TRUE(std::filesystem::exists(dir_ + "/.other.db.import-Ab12Cd"));
  ASSERT_EQ(Cli({"results", "import", archive}, &out, &err), 0) << err;
  EXPECT_NE(out.find("created sweep cli: 3 jobs taken over (9 episodes, 0 study rows, 3 checkpoints)"),
            std::string::npos)
      << out;
  // Same build: the trials' options are the sweep's own, nothing kept apart.
  EXPECT_EQ(out.find("keep the options"), std::string::npos) << out;
  // The imported trial's final policy and model are there, as they were.
  ASSERT_EQ(Cli({"job", "artifacts", "1", "--out", dir_ + "/artifacts-b"}, &out, &err), 0) << err;
  EXPECT_EQ(ReadFile(dir_ + "/artifacts-b/snapshot.json"), artifacts_a);
  std::string rows_b;
  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "csv"}, &rows_b, &err), 0) << err;
  EXPECT_EQ(rows_b, rows_a);
  // The archive of the imported sweep is the archive it came from (archive
  // version 4: export -> import -> export; the sweep's submission time and
  // the checkpoints included), but for when it was exported, from which file
  // the sweep was created here, and the ids this coordinator gave the jobs.
  std::string exported_again;
  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "json", "--checkpoints"}, &exported_again, &err),
            0)
      << err;
  const auto comparable = [](nlohmann::json doc) {
    doc.erase("exported_unix_ms");
    doc["sweep"].erase("source_name");
    for (nlohmann::json& job : doc["jobs"]) job.erase("job_id");
    return doc;
  };
  const nlohmann::json exported_first = nlohmann::json::parse(ReadFile(archive));
  EXPECT_EQ(exported_first["version"], 4);
  EXPECT_TRUE(exported_first["jobs"][0]["attempt_log"][0].contains("checkpoint"));
  EXPECT_EQ(comparable(nlohmann::json::parse(exported_again)), comparable(exported_first))
      << nlohmann::json::diff(comparable(exported_first),
                              comparable(nlohmann::json::parse(exported_again)));
  ASSERT_EQ(Cli({"results", "table", "cli"}, &out, &err), 0) << err;
  EXPECT_EQ(out, table_a);
  // Again: every job is complete here; no row is stored twice.
  ASSERT_EQ(Cli({"results", "import", archive}, &out, &err), 0) << err;
  EXPECT_NE(out.find("0 jobs taken over (0 episodes, 0 study rows, 0 checkpoints); 3 already complete here"),
            std::string::npos) << out;
  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "csv"}, &out, &err), 0) << err;
  EXPECT_EQ(out, rows_a);
  // The sweep file resubmitted here is the same sweep: nothing to run.
  ASSERT_EQ(Cli({"sweep", "submit", path}, &out, &err), 0) << err;
  EXPECT_NE(out.find("already submitted (no change)"), std::string::npos) << out;
  EXPECT_TRUE(Sweep("cli").finished());
  // A broken archive is refused naming what is wrong, and changes nothing.
  WriteFile(dir_ + "/broken.json", "{\"format\": \"totalgrad-sweep-archive\", \"version\": 7}");
  EXPECT_EQ(Cli({"results", "import", dir_ + "/broken.json"}, &out, &err), 2);
  EXPECT_NE(err.find("version 7"), std::string::npos) << err;
  // An archive whose last job does not read (the jobs are read one at a time,
  // inside the import's transaction: issue 28) creates nothing, not even
  // the sweep, and the copy the coordinator kept while reading it is gone.
  {
    nlohmann::json late = nlohmann::json::parse(ReadFile(archive));
    late["jobs"].back()["state"] = "sleeping";
    WriteFile(dir_ + "/late.json", late.dump());
    const std::string fresh = dir_ + "/fresh.db";
    EXPECT_EQ(Cli({"results", "import", dir_ + "/late.json", "--db", fresh}, &out, &err, false), 2);
    EXPECT_NE(err.find("jobs[2].state: 'sleeping'"), std::string::npos) << err;
    ASSERT_EQ(Cli({"sweep", "list", "--db", fresh}, &out, &err, false), 0) << err;
    EXPECT_EQ(out.find("cli"), std::string::npos) << out;
    for (const auto& entry : std::filesystem::directory_iterator(dir_)) {
      const std::string name = entry.path().filename().string();
      EXPECT_TRUE(name.find(".import-") == std::string::npos || name == ".other.db.import-Ab12Cd")
          << entry.path();
    }
  }
  // Into a database file without a coordinator: a new file reads as the
  // sweep did; the file a coordinator holds is refused, naming the holder.
  const std::string third = dir_ + "/third.db";
  ASSERT_EQ(Cli({"results", "import", archive, "--db", third}, &out, &err, false), 0) << err;
  EXPECT_NE(out.find("created sweep cli: 3 jobs taken over (9 episodes, 0 study rows, 3 checkpoints)"),
            std::string::npos)
      << out;
  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "csv", "--db", third}, &out, &err, false), 0)
      << err;
  EXPECT_EQ(out, rows_a);
  EXPECT_EQ(Cli({"results", "import", archive, "--db", db_}, &out, &err, false), 1) << out;
  EXPECT_NE(err.find("pid"), std::string::npos) << err;
}

// Issue 15: `sweep delete` writes the sweep's archive first (never over an
// existing file), deletes only then, and `results import` of that archive
// brings the results back row for row.
TEST_F(CliTest, SweepDeleteArchivesFirstAndImportRestoresIt) {
  StartCoordinator();
  auto worker = StartWorker("deleter");
  const std::string path = WriteSweep("cli.toml", kTinySweep);
  std::string out, err;
  ASSERT_EQ(Cli({"sweep", "submit", path, "--wait"}, &out, &err), 0) << out << err;
  std::string other = kTinySweep;
  other.replace(other.find("name = \"cli\""), 12, "name = \"other\"");
  ASSERT_EQ(Cli({"sweep", "submit", WriteSweep("other.toml", other), "--wait"}, &out, &err), 0)
      << out << err;
  std::string rows_cli, rows_other;
  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "csv"}, &rows_cli, &err), 0) << err;
  ASSERT_EQ(Cli({"results", "export", "other", "-f", "csv"}, &rows_other, &err), 0) << err;
  // An archive path that exists is never overwritten; nothing is deleted.
  const std::string taken = dir_ + "/taken.json";
  WriteFile(taken, "mine");
  EXPECT_EQ(Cli({"sweep", "delete", "cli", "--archive", taken}, &out, &err), 1);
  EXPECT_NE(err.find("already exists; not overwriting it"), std::string::npos) << err;
  EXPECT_NE(err.find("nothing was deleted"), std::string::npos) << err;
  EXPECT_EQ(ReadFile(taken), "mine");
  EXPECT_EQ(Jobs("cli").size(), 3u);

  const std::string archive = dir_ + "/cli.deleted.json";
  ASSERT_EQ(Cli({"sweep", "delete", "cli", "--archive", archive}, &out, &err), 0) << err;
  EXPECT_NE(out.find("deleted sweep cli (3 jobs, 3 attempts, 9 episodes, 0 study rows)"),
            std::string::npos) << out;
  EXPECT_NE(out.find("restore with: totalgrad results import " + archive), std::string::npos)
      << out;
  EXPECT_TRUE(std::filesystem::exists(archive));
  EXPECT_FALSE(std::filesystem::exists(archive + ".partial"));
  EXPECT_EQ(Cli({"results", "table", "cli"}, &out, &err), 2);
  EXPECT_NE(err.find("no sweep named 'cli'"), std::string::npos) << err;
  std::string rows;
  ASSERT_EQ(Cli({"results", "export", "other", "-f", "csv"}, &rows, &err), 0) << err;
  EXPECT_EQ(rows, rows_other);  // the other sweep untouched
  // Deleting what is gone: NOT_FOUND, and no archive written.
  const std::string again = dir_ + "/again.json";
  EXPECT_EQ(Cli({"sweep", "delete", "cli", "--archive", again}, &out, &err), 2);
  EXPECT_FALSE(std::filesystem::exists(again));

  ASSERT_EQ(Cli({"results", "import", archive}, &out, &err), 0) << err;
  EXPECT_NE(out.find("created sweep cli: 3 jobs taken over (9 episodes"), std::string::npos) << out;
  ASSERT_EQ(Cli({"results", "export", "cli", "-f", "csv"}, &rows, &err), 0) << err;
  // Row for row, but under the new job ids the import gave the jobs.
  const auto without_job_ids = [](const std::string& csv) {
    std::string kept;
    for (absl::string_view line : absl::StrSplit(csv, '\n', absl::SkipEmpty())) {
      absl::StrAppend(&kept, line.substr(line.find(',') + 1), "\n");
    }
    return kept;
  };
  EXPECT_NE(rows, rows_cli);
  EXPECT_EQ(without_job_ids(rows), without_job_ids(rows_cli));
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(seconds(20)), 0);
}

// Issue 15: sweeps that grow. A job's identity is (method, seed, variant), so
// resubmitting the file with more seeds or methods adds only the new jobs;
// the old file is then part of the sweep (no change); another protocol is
// refused naming what changed.
TEST_F(CliTest, ResubmittingWithMoreValuesGrowsTheSweep) {
  StartCoordinator();
  auto worker = StartWorker("grower");
  const std::string path = WriteSweep("cli.toml", kTinySweep);
  std::string out, err;
  ASSERT_EQ(Cli({"sweep", "submit", path, "--wait"}, &out, &err), 0) << out << err;
  std::string more = kTinySweep;
  more.replace(more.find("seed = [1, 2, 3]"), 16, "seed = [1, 2, 3, 4, 5]");
  ASSERT_EQ(Cli({"sweep", "submit", WriteSweep("more.toml", more), "--wait"}, &out, &err), 0)
      << out << err;
  EXPECT_NE(out.find("grew sweep cli by 2 jobs (now 5 jobs"), std::string::npos) << out;
  // Issue 29: the estimate is of the two jobs it adds, not of all five.
  EXPECT_NE(err.find("estimated cost of the jobs this adds to sweep cli: about "), std::string::npos)
      << err;
  EXPECT_NE(err.find(" for 2 trials"), std::string::npos) << err;
  std::vector<v1::JobInfo> jobs = Jobs("cli");
  ASSERT_EQ(jobs.size(), 5u);
  for (const v1::JobInfo& job : jobs) {
    EXPECT_EQ(job.state(), v1::JOB_STATE_COMPLETED) << job.seed();
    EXPECT_EQ(job.attempts(), 1) << job.seed();  // the first three did not run again
  }
  ASSERT_EQ(Cli({"sweep", "submit", path}, &out, &err), 0) << err;
  EXPECT_NE(out.find("already submitted (no change): sweep cli, 5 jobs"), std::string::npos) << out;
  EXPECT_NE(err.find("estimated cost: nothing new to run"), std::string::npos) << err;
  std::string methods = more;
  const std::string one_method = "method = [\"RP\"]";
  methods.replace(methods.find(one_method), one_method.size(), "method = [\"RP\", \"GR\"]");
  ASSERT_EQ(Cli({"sweep", "submit", WriteSweep("methods.toml", methods), "--wait"}, &out, &err), 0)
      << out << err;
  EXPECT_NE(out.find("grew sweep cli by 5 jobs (now 10 jobs"), std::string::npos) << out;
  ExpectRowsEqualReference("cli", TinyProtocol());
  std::string other = kTinySweep;
  other.replace(other.find("particles = 8"), 13, "particles = 9");
  EXPECT_NE(Cli({"sweep", "submit", WriteSweep("other.toml", other)}, &out, &err), 0);
  EXPECT_NE(err.find("protocol (particles = 8 there, 9 here)"), std::string::npos) << err;
  EXPECT_EQ(Jobs("cli").size(), 10u);
}

// Issue 25 item 5: `results table1` lays the completed trials of several
// sweeps out in the paper's grid. The committed archives (docs/results/
// table1/): table1-tip-k1 ran the paper's protocol on (tip, k = 1): PILCO
// 8/10, RP 0/10, TP 5/10, GTP 4/10; balance-del ran RP, LR and DEL on
// scene cartpole-balance, angle cost, k = 1, so its RP and LR land on
// (angle, k = 1) marked as off the protocol and DEL is outside the grid;
// table1-tip-k1-pilco-rerun re-ran PILCO seeds 10 and 11 of tip-k1.
TEST_F(CliTest, Table1LaysSweepsOutInThePapersGridAndRefusesASeedCountedTwice) {
  StartCoordinator();
  std::string out, err;
  for (const char* sweep : {"table1-tip-k1", "balance-del", "table1-tip-k1-pilco-rerun"}) {
    const std::string archive =
        absl::StrCat(TOTALGRAD_SOURCE_DIR, "/docs/results/table1/", sweep, ".archive.json");
    ASSERT_EQ(Cli({"results", "import", archive}, &out, &err), 0) << err;
    if (std::string(sweep) == "table1-tip-k1") {
      // Its trials ran before gp_variance_tolerance (default 0.01 since) and
      // the rollout verdict existed: they keep the exact variance and no
      // verdict rollouts in their stored options, and the import says so.
      EXPECT_NE(out.find("40 keep the options their trials ran with (this build's defaults "
                         "differ in gp_variance_tolerance, verdict_rollouts)"),
                std::string::npos)
          << out;
    }
  }
  {
    ASSERT_EQ(Cli({"job", "list", "--sweep", "table1-tip-k1", "-f", "json"}, &out, &err), 0) << err;
    const nlohmann::json jobs = nlohmann::json::parse(out);
    ASSERT_EQ(jobs.size(), 40u);
    for (const nlohmann::json& job : jobs) {
      std::map<std::string, std::string> options;
      for (const nlohmann::json& pair : job["options"]) options[pair[0]] = pair[1];
      EXPECT_EQ(options["gp_variance_tolerance"], "0") << job.dump();
      EXPECT_EQ(options["verdict_rollouts"], "0") << job.dump();
      EXPECT_EQ(options["particles"], "300");
    }
  }

  ASSERT_EQ(Cli({"results", "table1", "table1-tip-k1", "balance-del", "-f", "json"}, &out, &err), 0)
      << err;
  const nlohmann::json cells = nlohmann::json::parse(out);
  ASSERT_EQ(cells.size(), 32u);
  const auto cell = [&](const std::string& cost, double noise_k, const std::string& method) {
    for (const nlohmann::json& c : cells) {
      if (c["cost"] == cost && c["noise_k"] == noise_k && c["method"] == method) return c;
    }
    ADD_FAILURE() << "no cell " << cost << " " << noise_k << " " << method;
    return nlohmann::json();
  };
  // 9 of 10 (the archive carries PILCO's re-runs of seeds 10 and 11 as
  // supersessions): Wilson [0.595850, 0.982124] holds the paper's 0.73.
  const nlohmann::json pilco = cell("tip", 1, "PILCO");
  EXPECT_EQ(pilco["trials"], 10);
  EXPECT_EQ(pilco["successes"], 9);
  EXPECT_NEAR(pilco["wilson95_low"].get<double>(), 0.595850, 1e-6);
  EXPECT_NEAR(pilco["wilson95_high"].get<double>(), 0.982124, 1e-6);
  EXPECT_EQ(pilco["paper_success_rate"], 0.73);
  EXPECT_EQ(pilco["paper_in_interval"], "yes");
  EXPECT_EQ(pilco["off_protocol_trials"], 0);
  // All ten count their table1-tip-k1-rerun runs (same costs) since the
  // export of 2026-11-30 13:33, with their rollout verdicts: 3 held.
  EXPECT_EQ(pilco["classified"], 10);
  EXPECT_EQ(pilco["held"], 3);
  EXPECT_DOUBLE_EQ(pilco["held_rate"].get<double>(), 0.3);
  EXPECT_EQ(pilco["sweeps"], nlohmann::json::array({"table1-tip-k1"}));
  // 4 of 10: [0.168180, 0.687326], just below the paper's 0.69.
  EXPECT_EQ(cell("tip", 1, "GTP")["successes"], 4);
  EXPECT_EQ(cell("tip", 1, "GTP")["paper_in_interval"], "no");
  EXPECT_EQ(cell("tip", 1, "RP")["successes"], 0);
  EXPECT_EQ(cell("tip", 1, "RP")["paper_in_interval"], "yes");  // 0.15 in [0, 0.278]
  const nlohmann::json balance_rp = cell("angle", 1, "RP");
  EXPECT_EQ(balance_rp["trials"], 10);
  EXPECT_EQ(balance_rp["successes"], 8);
  EXPECT_EQ(balance_rp["off_protocol_trials"], 10);
  EXPECT_EQ(balance_rp["protocol_differences"], "scene = cartpole-balance (paper cartpole-swingup)");
  EXPECT_EQ(balance_rp["sweeps"], nlohmann::json::array({"balance-del"}));
  EXPECT_EQ(cell("angle", 1, "LR")["successes"], 10);
  EXPECT_EQ(cell("tip", 0.01, "PILCO")["trials"], 0);
  EXPECT_TRUE(cell("tip", 0.01, "PILCO")["success_rate"].is_null());
  EXPECT_TRUE(cell("tip", 1, "GTP+sn")["paper_success_rate"].is_null());
  EXPECT_NE(err.find("note: not in the grid: 10 trials of method DEL (not a Table 1 method)"),
            std::string::npos) << err;

  ASSERT_EQ(Cli({"results", "table1", "table1-tip-k1", "balance-del", "-f", "csv"}, &out, &err), 0)
      << err;
  EXPECT_EQ(out.substr(0, out.find('\n')),
            "cost,noise_k,method,trials,successes,success_rate,wilson95_low,wilson95_high,"
            "classified,held,held_rate,held_wilson95_low,held_wilson95_high,paper_success_rate,"
            "paper_in_interval,off_protocol_trials,protocol_differences,sweeps");
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 33);

  std::string text;
  ASSERT_EQ(Cli({"results", "table1", "table1-tip-k1", "balance-del"}, &text, &err), 0) << err;
  EXPECT_NE(text.find("from sweeps table1-tip-k1, balance-del: 60 completed trials in the grid"),
            std::string::npos) << text;
  EXPECT_NE(text.find("task             PILCO"), std::string::npos) << text;
  EXPECT_NE(text.find("0.80 [0.49, 0.94] n=10*"), std::string::npos) << text;  // balance RP
  EXPECT_NE(text.find("0.40 [0.17, 0.69] n=10 "), std::string::npos) << text;  // tip GTP
  // 0.69 against [0.168, 0.687], which prints as [0.17, 0.69]: the bound
  // follows at three decimals.
  EXPECT_NE(text.find("0.69 OUT (high 0.687)"), std::string::npos) << text;
  EXPECT_NE(text.find("0.73 in"), std::string::npos) << text;
  EXPECT_NE(text.find("angle, k = 1, RP: 10 of 10 trials: scene = cartpole-balance (paper "
                      "cartpole-swingup)"),
            std::string::npos) << text;
  EXPECT_NE(text.find("not in the grid: 10 trials of method DEL"), std::string::npos) << text;
  // The database file read directly gives the same table.
  ASSERT_EQ(Cli({"results", "table1", "table1-tip-k1", "balance-del", "--db", db_}, &out, &err,
                false),
            0) << err;
  EXPECT_EQ(out, text);
  // Issue 29: the grid as a figure: a panel per task with trials, the
  // Wilson bars, successes/trials and the paper's rate as a marker.
  const std::string grid_pdf = dir_ + "/table1.pdf";
  ASSERT_EQ(Cli({"results", "table1", "table1-tip-k1", "balance-del", "--plot", grid_pdf}, &out,
                &err),
            0) << err;
  EXPECT_EQ(ReadFile(grid_pdf).substr(0, 4), "%PDF");
  const std::string grid_script = ReadFile(grid_pdf + ".gp");
  EXPECT_NE(grid_script.find("set multiplot layout 1,2"), std::string::npos) << grid_script;
  EXPECT_NE(grid_script.find("cart-pole swing-up, tip, k = 1"), std::string::npos) << grid_script;
  EXPECT_NE(grid_script.find("title \"paper\""), std::string::npos) << grid_script;
  const std::string grid_data = ReadFile(grid_pdf + ".dat");
  // tip, k = 1, PILCO: 9 of 10, Wilson [0.595850, 0.982124], paper 0.73.
  EXPECT_NE(grid_data.find("# PILCO | tip, k = 1\n# x rate wilson95_low wilson95_high successes "
                           "trials paper_rate\n0 0.9 0.59584997"),
            std::string::npos) << grid_data;
  EXPECT_NE(grid_data.find(" 9 10 0.73\n"), std::string::npos) << grid_data;
  EXPECT_EQ(Cli({"results", "table1", "table1-tip-k1", "--view", "sensitivity", "--plot",
                 grid_pdf}, &out, &err), 2);
  EXPECT_NE(err.find("--plot draws the grid view"), std::string::npos) << err;
  EXPECT_EQ(Cli({"results", "table1", "table1-tip-k1", "--plot", dir_ + "/grid.jpg"}, &out, &err), 1);
  EXPECT_NE(err.find("the file must end in .svg, .pdf or .png"), std::string::npos) << err;

  // PILCO seeds 10 and 11 of (tip, k = 1) are in both: refused, naming both.
  EXPECT_EQ(Cli({"results", "table1", "table1-tip-k1", "table1-tip-k1-pilco-rerun"}, &out, &err), 2);
  EXPECT_NE(err.find("of PILCO in (tip, k = 1) is in sweep table1-tip-k1 (job "), std::string::npos)
      << err;
  EXPECT_NE(err.find(") and in sweep table1-tip-k1-pilco-rerun (job "), std::string::npos) << err;
  EXPECT_EQ(Cli({"results", "table1", "table1-tip-k1", "nope"}, &out, &err), 2);
  EXPECT_NE(err.find("no sweep named 'nope'"), std::string::npos) << err;

  // Issue 25 items 4 and 6 on the same archives. Threshold sensitivity:
  // TP's costs lie outside 13..17, GTP's seed 12 (14.00) and seed 10 (16.98)
  // change verdict at 13 and 17.
  ASSERT_EQ(Cli({"results", "table1", "table1-tip-k1", "--view", "sensitivity", "-f", "json"}, &out,
                &err),
            0) << err;
  const nlohmann::json rates = nlohmann::json::parse(out);
  ASSERT_EQ(rates.size(), 20u);  // 4 methods x 5 thresholds
  std::map<std::string, std::vector<int>> successes;
  for (const auto& rate : rates) {
    EXPECT_EQ(rate["trials"], 10) << rate;
    successes[rate["method"]].push_back(rate["successes"]);
  }
  EXPECT_EQ(successes["RP"], (std::vector<int>{0, 0, 0, 0, 0}));
  EXPECT_EQ(successes["TP"], (std::vector<int>{5, 5, 5, 5, 5}));
  EXPECT_EQ(successes["GTP"], (std::vector<int>{3, 4, 4, 4, 5}));
  ASSERT_EQ(Cli({"results", "table1", "table1-tip-k1", "--view", "sensitivity"}, &text, &err), 0);
  EXPECT_NE(text.find("GTP at 13: seed 12: 14.00 succeeds -> fails"), std::string::npos) << text;
  EXPECT_NE(text.find("GTP at 17: seed 10: 16.98 fails -> succeeds"), std::string::npos) << text;

  // The claims, paired by seed: TP - GTP on (tip, k = 1), 10 pairs.
  ASSERT_EQ(Cli({"results", "table1", "table1-tip-k1", "--view", "comparisons", "-f", "json"},
                &out, &err),
            0) << err;
  const nlohmann::json claims = nlohmann::json::parse(out);
  ASSERT_EQ(claims.size(), 6u);
  nlohmann::json tp_gtp;
  for (const auto& claim : claims) {
    if (claim["noise_k"] == 0.01) {
      EXPECT_EQ(claim["pairs"], 0) << claim;  // not in this sweep
    }
    if (claim["noise_k"] == 1 && claim["method"] == "TP") tp_gtp = claim;
  }
  ASSERT_FALSE(tp_gtp.is_null()) << out;
  EXPECT_EQ(tp_gtp["other"], "GTP");
  EXPECT_EQ(tp_gtp["pairs"], 10);
  EXPECT_EQ(tp_gtp["both_succeeded"], 3);
  EXPECT_EQ(tp_gtp["method_only"], 2);
  EXPECT_EQ(tp_gtp["other_only"], 1);
  EXPECT_NEAR(tp_gtp["success_difference95_low"].get<double>(), -0.200240, 1e-6);
  EXPECT_NEAR(tp_gtp["success_difference95_high"].get<double>(), 0.370677, 1e-6);
  EXPECT_NEAR(tp_gtp["cost_shift"].get<double>(), -2.076058, 1e-6);
  EXPECT_NEAR(tp_gtp["cost_shift95_low"].get<double>(), -7.010961, 1e-6);
  EXPECT_NEAR(tp_gtp["cost_shift95_high"].get<double>(), 0.963506, 1e-6);
  EXPECT_DOUBLE_EQ(tp_gtp["wilcoxon_p"].get<double>(), 198.0 / 1024);  // exact, n = 10
  // By the rollout verdict, seeds 10-19 (all classified): both held at 11,
  // 12 and 19, TP alone at 10 and 14, GTP alone at 18: (2 - 1) / 10.
  EXPECT_EQ(tp_gtp["verdict_pairs"], 10);
  EXPECT_DOUBLE_EQ(tp_gtp["verdict_difference"].get<double>(), 0.1);

  // What 10 pairs can settle needs no coordinator.
  ASSERT_EQ(Cli({"results", "power", "--pairs", "10", "-f", "csv"}, &out, &err, false), 0) << err;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 20);  // header + 19
  EXPECT_NE(out.find("\n10,0.5,0,0.5,0.3769531250"), std::string::npos) << out;  // 386/1024
}

// Issue 15: no coordinator at the address: the client gives up within its
// connect timeout (5 s) and says what to do, instead of retrying for a minute.
TEST_F(CliTest, NoCoordinatorFailsFastWithWhatToDo) {
  std::string out, err;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(Cli({"sweep", "list", "--coordinator", "127.0.0.1:9", "--insecure"}, &out, &err,
                false),
            3);
  EXPECT_LT(std::chrono::steady_clock::now() - start, seconds(8));
  EXPECT_NE(err.find("no coordinator answered at 127.0.0.1:9"), std::string::npos) << err;
  EXPECT_NE(err.find("--db FILE"), std::string::npos) << err;
  EXPECT_EQ(Cli({"results", "table", "x", "--db", dir_ + "/missing.db"}, &out, &err, false), 1);
  EXPECT_NE(err.find("does not exist"), std::string::npos) << err;
}

// Issue 29: a dry run counts the jobs without a coordinator; with one it asks
// it (growth of a stored sweep), and both count the same.
TEST_F(CliTest, DryRunCountsTheJobsWithoutACoordinator) {
  const std::string path = WriteSweep("cli.toml", kTinySweep);
  std::string out, err;
  ASSERT_EQ(Cli({"sweep", "submit", path, "--dry-run", "--coordinator", "127.0.0.1:9",
                 "--insecure"},
                &out, &err, false),
            0)
      << out << err;
  EXPECT_NE(out.find("no coordinator answered"), std::string::npos) << out;
  EXPECT_NE(out.find("sweep cli would have 3 jobs (0 studies) and 9 episodes"), std::string::npos)
      << out;
  const std::string local_hash = out.substr(out.rfind("(spec ") + 6, 12);
  StartCoordinator();
  ASSERT_EQ(Cli({"sweep", "submit", path, "--dry-run"}, &out, &err), 0) << out << err;
  EXPECT_NE(out.find("sweep cli would have 3 jobs (0 studies) and 9 episodes (spec " +
                     local_hash + ")"),
            std::string::npos)
      << out;
  // A malformed spec still fails as bad input, coordinator or not.
  const std::string bad = WriteSweep("bad.toml", "name = \"x\"\n[grid]\nseed = [1]\n");
  EXPECT_EQ(Cli({"sweep", "submit", bad, "--dry-run", "--coordinator", "127.0.0.1:9",
                 "--insecure"},
                &out, &err, false),
            2);
  ASSERT_EQ(Cli({"sweep", "list", "-f", "json"}, &out, &err), 0) << err;
  EXPECT_EQ(nlohmann::json::parse(out).size(), 0u);  // nothing stored
}

TEST_F(CliTest, PauseResumeAndCancelFromTheCli) {
  StartCoordinator();
  const std::string path = WriteSweep("cli.toml", kTinySweep);
  std::string out, err;
  ASSERT_EQ(Cli({"sweep", "submit", path}, &out, &err), 0) << err;
  ASSERT_EQ(Cli({"sweep", "pause", "cli", "-f", "json"}, &out, &err), 0) << err;
  EXPECT_EQ(nlohmann::json::parse(out)[0]["state"], "paused");
  auto worker = StartWorker("w");
  // A paused sweep hands out nothing: the worker registers and stays idle.
  ASSERT_TRUE(WaitFor([&] { return Cli({"worker", "list", "-f", "csv"}, &out, &err) == 0 &&
                                   out.find("w,active") != std::string::npos; },
                      seconds(20)));
  EXPECT_EQ(Sweep("cli").jobs_queued(), 3);
  ASSERT_EQ(Cli({"sweep", "resume", "cli"}, &out, &err), 0) << err;
  ASSERT_EQ(Cli({"sweep", "status", "cli", "--wait"}, &out, &err), 0) << err;
  ASSERT_EQ(Cli({"sweep", "cancel", "cli"}, &out, &err), 0) << err;  // finished: results kept
  EXPECT_EQ(Sweep("cli").jobs_completed(), 3);
  EXPECT_EQ(Cli({"sweep", "pause", "cli"}, &out, &err), 1);
  EXPECT_NE(err.find("cancelled sweep cannot be paused, only resumed"), std::string::npos) << err;
  // Resuming is the user's way out of a cancel; completed jobs stay completed.
  ASSERT_EQ(Cli({"sweep", "resume", "cli", "-f", "json"}, &out, &err), 0) << err;
  EXPECT_EQ(nlohmann::json::parse(out)[0]["state"], "running");
  EXPECT_EQ(Sweep("cli").jobs_completed(), 3);
}

// Issue 29: Ctrl-C on `sweep submit --wait` stops the wait, not the sweep, and
// says so (before: the default SIGINT action killed the CLI silently).
TEST_F(CliTest, CtrlCOnSubmitWaitSaysTheSweepGoesOn) {
  StartCoordinator();  // no worker: the sweep stays queued while the CLI waits
  const std::string path = WriteSweep("cli.toml", kTinySweep);
  Process cli({TOTALGRAD_CLI_BIN, "sweep", "submit", path, "--wait", "--coordinator",
               absl::StrCat("127.0.0.1:", port_), "--insecure", "--token-file",
               dir_ + "/user.token"},
              dir_ + "/cli-wait.log");
  ASSERT_TRUE(WaitFor([&] { return cli.Log().find("jobs 0/3") != std::string::npos; },
                      seconds(20)))
      << cli.Log();
  cli.Signal(SIGINT);
  const int status = cli.Wait(seconds(10));
  ASSERT_TRUE(WIFEXITED(status)) << "status " << status << ": " << cli.Log();
  EXPECT_EQ(WEXITSTATUS(status), 130);
  EXPECT_NE(cli.Log().find("sweep cli goes on at the coordinator"), std::string::npos)
      << cli.Log();
  EXPECT_NE(cli.Log().find("totalgrad sweep cancel cli"), std::string::npos) << cli.Log();
  EXPECT_EQ(Sweep("cli").state(), v1::SWEEP_STATE_RUNNING);
  EXPECT_EQ(Sweep("cli").jobs_queued(), 3);
}

// Issue 12.7: `job artifacts` writes the final policy and GP model of a job
// as a trial snapshot file, and `evaluate` runs that policy on the real
// plant: with the trial's own evaluation draws it reproduces the job's final
// evaluation cost bit for bit; on another task it runs too.
TEST_F(CliTest, JobArtifactsAndEvaluateReproduceTheFinalEvaluation) {
  StartCoordinator();
  auto worker = StartWorker("w");
  const std::string path = WriteSweep("cli.toml", kTinySweep);
  std::string out, err;
  ASSERT_EQ(Cli({"sweep", "submit", path, "--wait"}, &out, &err), 0) << err;
  const v1::JobInfo job = Jobs("cli")[0];
  ASSERT_EQ(job.state(), v1::JOB_STATE_COMPLETED);
  const std::string artifacts = dir_ + "/artifacts";
  ASSERT_EQ(Cli({"job", "artifacts", std::to_string(job.job_id()), "--out", artifacts}, &out,
                &err),
            0)
      << err;
  const nlohmann::json manifest = nlohmann::json::parse(ReadFile(artifacts + "/artifacts.json"));
  EXPECT_EQ(manifest["job"], job.job_id());
  EXPECT_EQ(manifest["episode"], 2);
  EXPECT_EQ(manifest["final_eval_cost"].get<double>(), job.final_eval_cost());
  const nlohmann::json snapshot = nlohmann::json::parse(ReadFile(artifacts + "/snapshot.json"));
  EXPECT_EQ(snapshot["format"], "totalgrad-trial-snapshots");
  EXPECT_EQ(snapshot["snapshots"][0]["episode"], 2);
  EXPECT_EQ(snapshot["snapshots"][0]["states"].size(), 20u);  // episodes 0 and 1, horizon 10

  ASSERT_EQ(Cli({"evaluate", "--policy", artifacts + "/snapshot.json", "--rollouts", "2",
                 "--json"},
                &out, &err, /*connection_flags=*/false),
            0)
      << err;
  const nlohmann::json evaluation = nlohmann::json::parse(out);
  EXPECT_EQ(evaluation["mean"].get<double>(), job.final_eval_cost());
  ASSERT_EQ(Cli({"evaluate", "--policy", artifacts + "/snapshot.json", "--rollouts", "3",
                 "--noise-k", "0.5", "--seed", "99"},
                &out, &err, /*connection_flags=*/false),
            0)
      << err;
  EXPECT_NE(out.find("noise_k 0.5: mean cost"), std::string::npos) << out;
  // Bad input is named.
  EXPECT_EQ(Cli({"evaluate", "--policy", dir_ + "/missing.json", "--rollouts", "2"}, &out, &err,
                /*connection_flags=*/false),
            2);
  EXPECT_EQ(Cli({"job", "artifacts", "424242", "--out", artifacts}, &out, &err), 2);
  EXPECT_NE(err.find("no job with id 424242"), std::string::npos) << err;

  // Issue 27: `job trajectory` prints what the trial recorded of an episode
  // from the same checkpoint: rows t = 0..H with the prediction's columns,
  // the real episode's cost, the verdict rollouts of the last episode.
  const std::string id = std::to_string(job.job_id());
  ASSERT_EQ(Cli({"job", "trajectory", id, "--episode", "2", "-f", "csv"}, &out, &err), 0) << err;
  const std::vector<std::string> lines = absl::StrSplit(absl::StripTrailingAsciiWhitespace(out), '\n');
  ASSERT_EQ(lines.size(), 12u) << out;  // the header and t = 0..10
  EXPECT_EQ(lines[0],
            "t,time,s,beta,s_dot,beta_dot,force,mean_s,mean_beta,mean_s_dot,mean_beta_dot,std_s,"
            "std_beta,std_s_dot,std_beta_dot");
  EXPECT_TRUE(absl::StartsWith(lines[11], "10,1,")) << lines[11];
  ASSERT_EQ(Cli({"job", "trajectory", id, "--episode", "2", "-f", "json"}, &out, &err), 0) << err;
  const nlohmann::json trajectory = nlohmann::json::parse(out);
  EXPECT_EQ(trajectory["job"], job.job_id());
  EXPECT_EQ(trajectory["states"].size(), 11u);
  EXPECT_EQ(trajectory["verdict_rollouts"], 100);
  ASSERT_EQ(Cli({"job", "trajectory", id, "--episode", "0", "-f", "json"}, &out, &err), 0) << err;
  EXPECT_EQ(nlohmann::json::parse(out)["predicted_mean"].size(), 0u);  // the random episode
  ASSERT_EQ(Cli({"job", "trajectory", id, "--episode", "2", "--rollout", "99"}, &out, &err), 0)
      << err;
  EXPECT_EQ(Cli({"job", "trajectory", id, "--episode", "2", "--rollout", "100"}, &out, &err), 1);
  EXPECT_NE(err.find("holds 100 verdict rollouts (0..99); rollout 100 is not one of them"),
            std::string::npos)
      << err;
  EXPECT_EQ(Cli({"job", "trajectory", id, "--episode", "3"}, &out, &err), 1);
  EXPECT_NE(err.find("episode 3 is not recorded: the trial holds episodes 0..2"), std::string::npos)
      << err;

  // `sweep size` and `sweep prune`: each of the three completed trials'
  // final state is its checkpoint; a plain prune keeps them, --completed
  // removes them (and the trajectories with them).
  ASSERT_EQ(Cli({"sweep", "size", "cli", "-f", "json"}, &out, &err), 0) << err;
  const nlohmann::json size = nlohmann::json::parse(out);
  EXPECT_EQ(size["episodes"], 9);
  EXPECT_EQ(size["checkpoints_completed"]["count"], 3);
  EXPECT_GT(size["checkpoints_completed"]["bytes"].get<int64_t>(), 10000);  // with 100 rollouts
  EXPECT_EQ(size["checkpoints_stale"]["count"], 0);
  ASSERT_EQ(Cli({"sweep", "prune", "cli"}, &out, &err), 0) << err;
  EXPECT_NE(out.find("removed 0 checkpoints"), std::string::npos) << out;
  ASSERT_EQ(Cli({"sweep", "prune", "cli", "--completed", "--dry-run"}, &out, &err), 0) << err;
  EXPECT_NE(out.find("would remove 3 checkpoints"), std::string::npos) << out;
  ASSERT_EQ(Cli({"job", "trajectory", id, "--episode", "1"}, &out, &err), 0) << err;
  ASSERT_EQ(Cli({"sweep", "prune", "cli", "--completed"}, &out, &err), 0) << err;
  EXPECT_NE(out.find("removed 3 checkpoints"), std::string::npos) << out;
  EXPECT_EQ(Cli({"job", "trajectory", id, "--episode", "1"}, &out, &err), 2);
  EXPECT_NE(err.find("has no trial checkpoint"), std::string::npos) << err;
  EXPECT_EQ(Cli({"sweep", "size", "nope"}, &out, &err), 2);
  EXPECT_NE(err.find("no sweep named 'nope'"), std::string::npos) << err;
}

TEST_F(CliTest, BackupsByRpcAndOneShotAreConsistentCopies) {
  const std::string backups = dir_ + "/backups";
  std::filesystem::create_directories(backups);
  StartCoordinator(0, {"--backup-dir", backups});
  const std::string path = WriteSweep("cli.toml", kTinySweep);
  std::string out, err;
  ASSERT_EQ(Cli({"sweep", "submit", path}, &out, &err), 0) << err;
  ASSERT_EQ(Cli({"admin", "backup", "copy.db"}, &out, &err), 0) << err;
  EXPECT_NE(out.find(backups + "/copy.db"), std::string::npos) << out;
  EXPECT_EQ(Cli({"admin", "backup", "copy.db"}, &out, &err), 2);  // exists: refused
  EXPECT_EQ(Cli({"admin", "backup", "../escape.db"}, &out, &err), 2);
  EXPECT_NE(err.find("plain file name"), std::string::npos) << err;
  // One-shot copy of a live database, then serve the copy: the sweep is there.
  ASSERT_EQ(RunCommand({TOTALGRAD_COORDINATOR_BIN, "--db", db_, "--backup", dir_ + "/oneshot.db"},
                       &out, &err),
            0)
      << err;
  coordinator_->Signal(SIGTERM);
  ASSERT_EQ(coordinator_->Wait(seconds(20)), 0);
  for (const std::string& copy : {backups + "/copy.db", dir_ + "/oneshot.db"}) {
    db_ = copy;
    StartCoordinator();
    EXPECT_EQ(Sweep("cli").jobs_total(), 3) << copy;
    coordinator_->Signal(SIGTERM);
    ASSERT_EQ(coordinator_->Wait(seconds(20)), 0);
  }
}

TEST_F(CliTest, RunStartsEverythingPrintsTheTableAndStopsEverything) {
  const std::string path = WriteSweep("cli.toml", kTinySweep);
  const std::string run_dir = dir_ + "/run";
  std::string out, err;
  ASSERT_EQ(Cli({"run", path, "--workers", "2", "--dir", run_dir}, &out, &err,
                /*connection_flags=*/false),
            0)
      << out << err;
  EXPECT_NE(out.find("RP      1.00 [0.44, 1.00] n=3"), std::string::npos) << out;
  EXPECT_NE(err.find("plot written to " + run_dir + "/cli-curves.svg"), std::string::npos) << err;
  EXPECT_TRUE(std::filesystem::exists(run_dir + "/cli.db"));
  // Everything was stopped cleanly: the WAL was checkpointed away.
  EXPECT_FALSE(std::filesystem::exists(run_dir + "/cli.db-wal"));
  EXPECT_NE(ReadFile(run_dir + "/cli-coordinator.log").find("coordinator stopped"), std::string::npos);
  // Running the same file again is a no-op that prints the stored results.
  ASSERT_EQ(Cli({"run", path, "--workers", "1", "--dir", run_dir, "--no-plot"}, &out, &err,
                /*connection_flags=*/false),
            0)
      << err;
  EXPECT_NE(err.find("already in the database"), std::string::npos) << err;
  EXPECT_NE(out.find("n=3"), std::string::npos) << out;
}

TEST_F(CliTest, TlsWithDevCertificatesAndTokens) {
  const std::string certs = dir_ + "/certs";
  std::string out, err;
  ASSERT_EQ(RunCommand({"/bin/bash", std::string(TOTALGRAD_SOURCE_DIR) + "/deploy/make-dev-certs.sh",
                        certs},
                       &out, &err),
            0)
      << err;
  const std::string port_file = dir_ + "/tls.port";
  Process coordinator({TOTALGRAD_COORDINATOR_BIN, "--db", db_, "--listen", "127.0.0.1:0",
                       "--tls-cert", certs + "/server.pem", "--tls-key", certs + "/server.key",
                       "--worker-token-file", certs + "/worker.token", "--user-token-file",
                       certs + "/user.token", "--port-file", port_file,
                       "--heartbeat-interval", "0.2", "--lease-timeout", "2"},
                      dir_ + "/tls-coordinator.log");
  int port = 0;
  ASSERT_TRUE(WaitFor([&] {
    std::ifstream in(port_file);
    return (in >> port) && port > 0;
  }, seconds(30))) << coordinator.Log();
  const std::string address = absl::StrCat("127.0.0.1:", port);
  Process worker({TOTALGRAD_WORKER_BIN, "--coordinator", address, "--ca-cert", certs + "/ca.pem",
                  "--token-file", certs + "/worker.token", "--slots", "1", "--acquire-wait", "1",
                  "--state-dir", dir_ + "/worker-state"},
                 dir_ + "/tls-worker.log");
  const std::string path = WriteSweep("cli.toml", kTinySweep);
  const std::vector<std::string> tls = {"--coordinator", address, "--ca-cert", certs + "/ca.pem",
                                        "--token-file", certs + "/user.token"};
  std::vector<std::string> submit = {TOTALGRAD_CLI_BIN, "sweep", "submit", path, "--wait"};
  submit.insert(submit.end(), tls.begin(), tls.end());
  ASSERT_EQ(RunCommand(submit, &out, &err), 0) << out << err << worker.Log();
  // Plaintext to the TLS port fails; so does TLS without the right CA.
  EXPECT_EQ(RunCommand({TOTALGRAD_CLI_BIN, "admin", "health", "--coordinator", address,
                        "--insecure", "--token-file", certs + "/user.token", "--timeout", "2"},
                       &out, &err),
            3);
  EXPECT_EQ(RunCommand({TOTALGRAD_CLI_BIN, "admin", "health", "--coordinator", address,
                        "--token-file", certs + "/user.token", "--timeout", "2"},
                       &out, &err),
            3);
  // The worker token is not a user token, even over TLS.
  EXPECT_EQ(RunCommand({TOTALGRAD_CLI_BIN, "admin", "health", "--coordinator", address, "--ca-cert",
                        certs + "/ca.pem", "--token-file", certs + "/worker.token"},
                       &out, &err),
            2);
  EXPECT_NE(err.find("PERMISSION_DENIED"), std::string::npos) << err;
  // Plaintext to a non-loopback address is refused by the client itself.
  EXPECT_EQ(RunCommand({TOTALGRAD_CLI_BIN, "admin", "health", "--coordinator", "192.0.2.1:7070",
                        "--insecure"},
                       &out, &err),
            2);
  EXPECT_NE(err.find("--insecure is only allowed for a loopback"), std::string::npos) << err;
}

}  // namespace cli_test
}  // namespace totalgrad::testing
