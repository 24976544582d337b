// The command line (cli/cli.cpp, CLI11) and the run-directory rules (run/run_directory.cpp): every
// command has -h/--help and --version, misuse exits with 2 and names the option, a run never
// overwrites or mixes with an old run's files without --overwrite, a run stopped before its
// first checkpoint starts again on resume, and a locked directory is refused.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "crushdem/cli/cli.hpp"
#include "crushdem/core/build_info.hpp"
#include "crushdem/run/run_directory.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

namespace fs = std::filesystem;

struct Outcome {
  int rc = 0;
  std::string out, err;
};

Outcome cli(const std::vector<std::string>& args,
            const std::vector<cli::FrontEndCommand>& front_end = {}) {
  ::testing::internal::CaptureStdout();
  ::testing::internal::CaptureStderr();
  Outcome o;
  o.rc = cli::cli_main(args, front_end);
  std::fflush(stdout);
  std::fflush(stderr);
  o.out = ::testing::internal::GetCapturedStdout();
  o.err = ::testing::internal::GetCapturedStderr();
  return o;
}

bool has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(Cli, EveryCommandHasHelp) {
  const std::map<std::string, std::vector<std::string>> options = {
      {"run", {"CONFIG", "--out", "--threads", "--backend", "--overwrite", "--quiet"}},
      {"resume", {"DIR", "--threads", "--quiet"}},
      {"check", {"CONFIG"}},
      {"bench", {"--packing", "--steps", "--warm", "--law", "--settle", "--prune"}}};
  for (const auto& [command, expected] : options) {
    for (const char* flag : {"-h", "--help"}) {
      const Outcome o = cli({command, flag});
      EXPECT_EQ(o.rc, 0) << command << " " << flag << ": " << o.err;
      EXPECT_TRUE(has(o.out, "Usage: crushdem-sand " + command)) << o.out;
      for (const std::string& opt : expected) EXPECT_TRUE(has(o.out, opt)) << command << opt;
      // A command's help is its own: the footer naming the Python package's commands is the
      // top's.
      EXPECT_FALSE(has(o.out, "come with the Python package")) << command << o.out;
    }
  }
  const Outcome top = cli({"--help"});
  EXPECT_EQ(top.rc, 0);
  EXPECT_TRUE(has(top.out, "come with the Python package")) << top.out;
  for (const char* c : {"run", "resume", "check", "bench", "plot", "reproduce", "sensitivity"}) {
    EXPECT_TRUE(has(top.out, c)) << c;
  }
  // A front end's commands join the one list of subcommands, described in its words; one it
  // failed to handle itself is refused, not run.
  const std::vector<cli::FrontEndCommand> front_end = {{"plot", "draw the figures of a run"}};
  const Outcome listed = cli({"--help"}, front_end);
  EXPECT_EQ(listed.rc, 0);
  const std::string subcommands = listed.out.substr(listed.out.find("Subcommands:"));
  EXPECT_TRUE(has(subcommands, "plot")) << listed.out;
  EXPECT_TRUE(has(subcommands, "draw the figures of a run")) << listed.out;
  EXPECT_FALSE(has(listed.out, "come with the Python package")) << listed.out;
  EXPECT_EQ(cli({"plot", "DIR"}, front_end).rc, 2);
  EXPECT_EQ(cli({"help"}).rc, 0);
  const Outcome bare = cli({});
  EXPECT_EQ(bare.rc, 2);
  EXPECT_TRUE(has(bare.err, "Usage: crushdem-sand"));
}

TEST(Cli, VersionAnywhere) {
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"--version"}, {"run", "x.toml", "--version"}, {"bench", "--version"}}) {
    const Outcome o = cli(args);
    EXPECT_EQ(o.rc, 0) << args.size();
    EXPECT_TRUE(has(o.out, std::string("crushdem-sand ") + CRUSHDEM_VERSION)) << o.out;
  }
}

TEST(Cli, MisuseExitsWithTwoAndNamesTheOption) {
  const Outcome unknown = cli({"run", "a.toml", "--out", "d", "--steps", "5"});
  EXPECT_EQ(unknown.rc, 2);
  EXPECT_TRUE(has(unknown.err, "--steps")) << unknown.err;
  EXPECT_TRUE(has(unknown.err, "crushdem-sand run --help")) << unknown.err;
  const Outcome missing = cli({"run", "a.toml"});
  EXPECT_EQ(missing.rc, 2);
  EXPECT_TRUE(has(missing.err, "--out")) << missing.err;
  const Outcome threads = cli({"resume", "d", "--threads", "-3"});
  EXPECT_EQ(threads.rc, 2);
  EXPECT_TRUE(has(threads.err, "--threads")) << threads.err;
  const Outcome prune = cli({"bench", "--prune", "3"});
  EXPECT_EQ(prune.rc, 2);
  EXPECT_TRUE(has(prune.err, "--prune")) << prune.err;
  const Outcome command = cli({"frobnicate"});
  EXPECT_EQ(command.rc, 2);
  EXPECT_TRUE(has(command.err, "frobnicate")) << command.err;
  const Outcome file = cli({"check", "no-such-file.toml"});
  EXPECT_EQ(file.rc, 2);
  EXPECT_TRUE(has(file.err, "no-such-file.toml")) << file.err;
}

// --- run directories ---------------------------------------------------------------------------

const std::string kTinyRun = testing::tiny_run_toml();

class RunDirectory : public ::testing::Test {
 protected:
  void SetUp() override {
    base_ = fs::temp_directory_path() /
            ("crushdem_cli_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(base_);
    fs::create_directories(base_);
    config_ = (base_ / "tiny.toml").string();
    std::ofstream(config_) << kTinyRun;
    out_ = (base_ / "out").string();
  }
  void TearDown() override { fs::remove_all(base_); }
  static std::string slurp(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
  }
  fs::path base_;
  std::string config_, out_;
};

TEST_F(RunDirectory, ASecondRunIsRefusedAndLeavesTheFilesAsTheyWere) {
  ASSERT_EQ(cli({"run", config_, "--out", out_, "--quiet"}).rc, 0);
  const std::string summary = slurp(fs::path(out_) / "summary.json");
  // The results say what made them: the version and the source commit.
  EXPECT_TRUE(has(summary, std::string("\"crushdem_version\": \"") + CRUSHDEM_VERSION + "\""));
  const std::string commit = build_commit();
  EXPECT_TRUE(has(summary, "\"crushdem_commit\": \"" + commit + "\""));
  // 12 hex digits, "-dirty" after them when the tree had changes, or "unknown".
  const std::string hex = commit.substr(0, 12);
  const bool hash = hex.size() == 12 &&
                    hex.find_first_not_of("0123456789abcdef") == std::string::npos &&
                    (commit.size() == 12 || commit.substr(12) == "-dirty");
  EXPECT_TRUE(hash || commit == "unknown") << commit;
  const std::string series = slurp(fs::path(out_) / "timeseries.csv");
  const Outcome again = cli({"run", config_, "--out", out_, "--quiet"});
  EXPECT_EQ(again.rc, 2);
  EXPECT_TRUE(has(again.err, "finished run")) << again.err;
  EXPECT_TRUE(has(again.err, "--overwrite")) << again.err;
  EXPECT_EQ(slurp(fs::path(out_) / "summary.json"), summary);
  EXPECT_EQ(slurp(fs::path(out_) / "timeseries.csv"), series);
  // --overwrite replaces it: a file the old run wrote (its manifest lists it) does not survive,
  // the user's own files do.
  RunManifest(out_).add("grading.csv");
  std::ofstream(fs::path(out_) / "grading.csv") << "stale\n";
  std::ofstream(fs::path(out_) / "notes.txt") << "mine";
  fs::create_directories(fs::path(out_) / "data");
  std::ofstream(fs::path(out_) / "data" / "lab.csv") << "mine";
  EXPECT_EQ(cli({"run", config_, "--out", out_, "--quiet", "--overwrite"}).rc, 0);
  EXPECT_FALSE(fs::exists(fs::path(out_) / "grading.csv"));
  EXPECT_EQ(slurp(fs::path(out_) / "timeseries.csv"), series);
  EXPECT_EQ(slurp(fs::path(out_) / "notes.txt"), "mine");
  EXPECT_EQ(slurp(fs::path(out_) / "data" / "lab.csv"), "mine");
  const std::string manifest = slurp(fs::path(out_) / "manifest.json");
  for (const char* name : {"config.toml", "timeseries.csv", "summary.json", "vtk"}) {
    EXPECT_TRUE(has(manifest, std::string("\"") + name + "\"")) << name << manifest;
  }
  EXPECT_FALSE(has(manifest, "notes.txt")) << manifest;
  // run.log, written with --quiet too: how the run went, with UTC time stamps.
  const std::string log = slurp(fs::path(out_) / "run.log");
  EXPECT_TRUE(has(log, std::string("run with crushdem ") + CRUSHDEM_VERSION)) << log;
  EXPECT_TRUE(has(log, "Z  run  step")) << log;  // a progress line
  EXPECT_TRUE(has(log, "Z  finished: ")) << log;
  EXPECT_TRUE(has(manifest, "\"run.log\"")) << manifest;
}

TEST_F(RunDirectory, AbsurdButValidParametersWarn) {
  std::ofstream(config_, std::ios::app)
      << "[material]\ndensity = 1e300\n[crushing]\nweibull_m = 1e-3\nv0 = 1e300\n"
         "sigma_lim0 = 1\n";
  const Outcome check = cli({"check", config_});
  EXPECT_EQ(check.rc, 0) << check.err;
  for (const char* key :
       {"material.density", "crushing.weibull_m", "crushing.v0", "crushing.sigma_lim0"}) {
    EXPECT_TRUE(has(check.out, std::string("warning: ") + key)) << key << "\n" << check.out;
  }
  // A physical value gives none.
  std::ofstream(config_) << kTinyRun;
  const Outcome plain = cli({"check", config_});
  EXPECT_FALSE(has(plain.out, "warning")) << plain.out;
  // A sample 50 d50 across compacted by its walls warns (docs/chamber.md, Compaction); the
  // same sample compacted affinely, and one 20 d50 across, do not.
  const std::string wide = "[sample]\nside = 10.5e-3\n";
  std::ofstream(config_) << wide;
  const Outcome swept = cli({"check", config_});
  EXPECT_EQ(swept.rc, 0) << swept.err;
  EXPECT_TRUE(has(swept.out, "warning: sample.compaction = \"walls\" on a sample 50 d50 across"))
      << swept.out;
  std::ofstream(config_) << "[sample]\nside = 10.5e-3\ncompaction = \"affine\"\n";
  EXPECT_FALSE(has(cli({"check", config_}).out, "warning")) << "affine";
  std::ofstream(config_) << "[sample]\nside = 4.2e-3\n";
  EXPECT_FALSE(has(cli({"check", config_}).out, "warning")) << "20 d50 across";
}

TEST_F(RunDirectory, AFolderWithAConfigTomlIsNotARun) {
  // As a user's project folder: a configuration beside notes and data, no manifest.
  fs::create_directories(fs::path(out_) / "data");
  std::ofstream(fs::path(out_) / "config.toml") << kTinyRun;
  std::ofstream(fs::path(out_) / "notes.txt") << "mine";
  std::ofstream(fs::path(out_) / "data" / "lab.csv") << "mine";
  const Outcome resume = cli({"resume", out_});
  EXPECT_EQ(resume.rc, 2);
  EXPECT_TRUE(has(resume.err, "manifest.json")) << resume.err;
  const Outcome over = cli({"run", config_, "--out", out_, "--quiet", "--overwrite"});
  EXPECT_EQ(over.rc, 2);
  EXPECT_TRUE(has(over.err, "not a crushdem run directory")) << over.err;
  // A run of an earlier release (no manifest) is not cleared either.
  std::ofstream(fs::path(out_) / "summary.json") << "{}";
  const Outcome earlier = cli({"run", config_, "--out", out_, "--quiet", "--overwrite"});
  EXPECT_EQ(earlier.rc, 2);
  EXPECT_TRUE(has(earlier.err, "earlier crushdem")) << earlier.err;
  // Nor does a resume that finds nothing to continue leave a manifest behind.
  EXPECT_EQ(cli({"resume", out_}).rc, 2);
  EXPECT_FALSE(fs::exists(fs::path(out_) / "manifest.json"));
  EXPECT_EQ(slurp(fs::path(out_) / "notes.txt"), "mine");
  EXPECT_EQ(slurp(fs::path(out_) / "data" / "lab.csv"), "mine");
  EXPECT_EQ(slurp(fs::path(out_) / "config.toml"), kTinyRun);
}

TEST_F(RunDirectory, TheCurrentDirectoryIsNeverCleared) {
  ASSERT_EQ(cli({"run", config_, "--out", out_, "--quiet"}).rc, 0);
  const std::string summary = slurp(fs::path(out_) / "summary.json");
  fs::create_directories(fs::path(out_) / "inner");
  const fs::path cwd = fs::current_path();
  for (const fs::path& here : {fs::path(out_), fs::path(out_) / "inner"}) {
    fs::current_path(here);
    const Outcome o = cli(
        {"run", config_, "--out", here == fs::path(out_) ? "." : "..", "--quiet", "--overwrite"});
    fs::current_path(cwd);
    EXPECT_EQ(o.rc, 2);
    EXPECT_TRUE(has(o.err, "current directory")) << o.err;
  }
  EXPECT_EQ(slurp(fs::path(out_) / "summary.json"), summary);
}

TEST_F(RunDirectory, AStoppedRunPointsToResume) {
  fs::create_directories(out_);
  std::ofstream(fs::path(out_) / "config.toml") << kTinyRun;
  std::ofstream(fs::path(out_) / "checkpoint.bin") << "state";
  const Outcome o = cli({"run", config_, "--out", out_, "--quiet"});
  EXPECT_EQ(o.rc, 2);
  EXPECT_TRUE(has(o.err, "crushdem-sand resume " + out_)) << o.err;
  EXPECT_EQ(slurp(fs::path(out_) / "checkpoint.bin"), "state");
}

TEST_F(RunDirectory, OtherFilesAreNeverRemoved) {
  fs::create_directories(out_);
  std::ofstream(fs::path(out_) / "notes.txt") << "mine";
  for (const bool overwrite : {false, true}) {
    std::vector<std::string> args = {"run", config_, "--out", out_, "--quiet"};
    if (overwrite) args.push_back("--overwrite");
    const Outcome o = cli(args);
    EXPECT_EQ(o.rc, 2);
    EXPECT_TRUE(has(o.err, "not a crushdem run directory")) << o.err;
  }
  EXPECT_EQ(slurp(fs::path(out_) / "notes.txt"), "mine");
}

TEST_F(RunDirectory, ResumeBeforeTheFirstCheckpointStartsAgain) {
  ASSERT_EQ(cli({"run", config_, "--out", out_, "--quiet"}).rc, 0);
  const std::string series = slurp(fs::path(out_) / "timeseries.csv");
  // As a run killed during its set-up leaves it: config.toml and a partial series.
  fs::remove(fs::path(out_) / "summary.json");
  std::ofstream(fs::path(out_) / "timeseries.csv") << "partial\n";
  // From inside it: starting again removes only the run's listed files, so "." is accepted.
  const fs::path cwd = fs::current_path();
  fs::current_path(out_);
  const Outcome o = cli({"resume", "."});
  fs::current_path(cwd);
  EXPECT_EQ(o.rc, 0) << o.err;
  EXPECT_TRUE(has(o.err, "starting the run again")) << o.err;
  EXPECT_EQ(slurp(fs::path(out_) / "timeseries.csv"), series);
  // A finished run has nothing to resume.
  const Outcome done = cli({"resume", out_});
  EXPECT_EQ(done.rc, 2);
  EXPECT_TRUE(has(done.err, "finished")) << done.err;
}

TEST_F(RunDirectory, ALockedDirectoryIsRefused) {
  fs::create_directories(out_);
  const int fd = ::open((fs::path(out_) / ".lock").c_str(), O_RDWR | O_CREAT, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
  const Outcome o = cli({"run", config_, "--out", out_, "--quiet"});
  EXPECT_EQ(o.rc, 2);
  EXPECT_TRUE(has(o.err, "another crushdem run")) << o.err;
  EXPECT_FALSE(fs::exists(fs::path(out_) / "config.toml"));
  ::close(fd);
  EXPECT_EQ(cli({"run", config_, "--out", out_, "--quiet"}).rc, 0);
}

}  // namespace
}  // namespace crushdem

namespace crushdem {
namespace {

// Branches (crushdem-sand run --from DIR:STAGE): the lattice of tests/data compressed, then held.
std::string staged_config(const std::string& data, long hold_steps, double friction = 0.275) {
  return "[material]\nfriction = " + std::to_string(friction) +
         "\n[contact]\nlaw = \"hertz\"\n[particles]\nfile = \"" + data +
         "/lattice_64.txt\"\n[[stage]]\ntype = \"isotropic\"\nname = \"compress\"\nstress = "
         "1e6\n[[stage]]\ntype = \"hold\"\nname = \"hold\"\nsteps = " +
         std::to_string(hold_steps) +
         "\n[output]\ninterval = 2000\nvtk_interval = 20000\nprogress_seconds = 0\n";
}

double timing_number(const std::string& text, const std::string& key) {
  const std::size_t k = text.find("\"" + key + "\":");
  return k == std::string::npos ? -1.0 : std::strtod(text.c_str() + k + key.size() + 3, nullptr);
}

class Branch : public RunDirectory {
 protected:
  std::string write(const std::string& name, const std::string& text) {
    const std::string p = (base_ / name).string();
    std::ofstream(p) << text;
    return p;
  }
  const std::string data_ = CRUSHDEM_TEST_DATA_DIR;
};

TEST_F(Branch, AnUnchangedBranchGivesTheOriginalsFiles) {
  const std::string cfg = write("a.toml", staged_config(data_, 30000));
  const std::string orig = (base_ / "orig").string(), br = (base_ / "branch").string();
  ASSERT_EQ(cli({"run", cfg, "--out", orig, "--quiet"}).rc, 0);
  EXPECT_TRUE(fs::exists(fs::path(orig) / "stages" / "stage_1.bin"));
  const Outcome o = cli({"run", cfg, "--out", br, "--quiet", "--from", orig + ":hold"});
  ASSERT_EQ(o.rc, 0) << o.err;
  std::size_t compared = 0;
  for (const auto& e : fs::recursive_directory_iterator(orig)) {
    const std::string rel = fs::relative(e.path(), orig).string();
    // Wall-clock times; the entries in the order this run created them.
    if (!e.is_regular_file() || rel == "timing.json" || rel == "manifest.json" ||
        rel == "run.log") {
      continue;
    }
    ASSERT_TRUE(fs::exists(fs::path(br) / rel)) << rel;
    const std::string a = slurp(e.path());
    std::string b = slurp(fs::path(br) / rel);
    if (rel == "summary.json") {  // the branch says where it started, and is otherwise the same
      const std::size_t k = b.find("\"branched_from\"");
      ASSERT_NE(k, std::string::npos);
      const std::size_t end = b.find('}', k);
      EXPECT_NE(b.substr(k, end - k).find("\"stage\": 1"), std::string::npos)
          << b.substr(k, end - k);
      const std::size_t line = b.rfind('\n', k) + 1;
      b.erase(line, b.find('\n', end) + 1 - line);
    }
    EXPECT_TRUE(a == b) << rel << " differs";
    ++compared;
  }
  EXPECT_GE(compared, 5u);
}

TEST_F(Branch, TheOriginalIsCheckedAndNeverWritten) {
  const std::string cfg = write("a.toml", staged_config(data_, 2000));
  const std::string orig = (base_ / "orig").string();
  ASSERT_EQ(cli({"run", cfg, "--out", orig, "--quiet"}).rc, 0);
  const std::string summary = slurp(fs::path(orig) / "summary.json");
  // Into the run it branches from, or into a folder that holds it: refused, nothing removed.
  for (const std::string& out : {orig, base_.string()}) {
    const Outcome o =
        cli({"run", cfg, "--out", out, "--quiet", "--overwrite", "--from", orig + ":hold"});
    EXPECT_EQ(o.rc, 2);
    EXPECT_TRUE(has(o.err, "branches from")) << o.err;
  }
  EXPECT_EQ(slurp(fs::path(orig) / "summary.json"), summary);
  // A branch replacing a run keeps the user's files there and refuses to copy over one.
  const std::string b2 = (base_ / "b2").string();
  ASSERT_EQ(cli({"run", cfg, "--out", b2, "--quiet"}).rc, 0);
  std::ofstream(fs::path(b2) / "my_fit.csv") << "mine";
  ASSERT_EQ(cli({"run", cfg, "--out", b2, "--quiet", "--overwrite", "--from", orig + ":hold"}).rc,
            0);
  EXPECT_EQ(slurp(fs::path(b2) / "my_fit.csv"), "mine");
  const std::string b3 = (base_ / "b3").string();
  fs::create_directories(b3);
  std::ofstream(fs::path(b3) / "manifest.json") << "{\"entries\": []}\n";
  std::ofstream(fs::path(b3) / "timeseries.csv") << "mine";
  const Outcome clash =
      cli({"run", cfg, "--out", b3, "--quiet", "--overwrite", "--from", orig + ":hold"});
  EXPECT_EQ(clash.rc, 2);
  EXPECT_TRUE(has(clash.err, "timeseries.csv")) << clash.err;
  EXPECT_EQ(slurp(fs::path(b3) / "timeseries.csv"), "mine");
  // A file the saved state lists, changed in the original: the branch refuses, naming it.
  std::string vtk;
  for (const auto& e : fs::directory_iterator(fs::path(orig) / "vtk")) {
    if (e.path().extension() == ".vtp" && vtk.empty()) vtk = "vtk/" + e.path().filename().string();
  }
  std::ofstream(fs::path(orig) / vtk, std::ios::app) << " ";
  const Outcome o =
      cli({"run", cfg, "--out", (base_ / "b").string(), "--quiet", "--from", orig + ":hold"});
  EXPECT_EQ(o.rc, 2);
  EXPECT_TRUE(has(o.err, vtk)) << o.err;
}

TEST_F(Branch, AChangedStageRunsOnlyFromThere) {
  const std::string orig = (base_ / "orig").string(), br = (base_ / "branch").string();
  ASSERT_EQ(cli({"run", write("a.toml", staged_config(data_, 30000)), "--out", orig, "--quiet"}).rc,
            0);
  // A longer hold: the branch point is found (the first stage that changed).
  ASSERT_EQ(cli({"run", write("b.toml", staged_config(data_, 50000)), "--out", br, "--quiet",
                 "--from", orig})
                .rc,
            0);
  const std::string timing = slurp(fs::path(br) / "timing.json");
  const double particle_steps =
      timing_number(timing, "particle_steps_per_second") * timing_number(timing, "wall_seconds");
  EXPECT_NEAR(particle_steps / (64.0 * 50000.0), 1.0, 0.01) << timing;  // the hold only
  const std::string a = slurp(fs::path(orig) / "timeseries.csv");
  const std::string b = slurp(fs::path(br) / "timeseries.csv");
  const std::size_t held = a.find("\n", a.find(",1,"));  // compare through the first hold row
  ASSERT_NE(held, std::string::npos);
  EXPECT_EQ(a.substr(0, a.rfind('\n', a.find(",1,"))), b.substr(0, a.rfind('\n', a.find(",1,"))));
}

TEST_F(Branch, ChangesBeforeTheBranchAreRefusedNamingTheKey) {
  const std::string orig = (base_ / "orig").string();
  ASSERT_EQ(cli({"run", write("a.toml", staged_config(data_, 2000)), "--out", orig, "--quiet"}).rc,
            0);
  const Outcome friction = cli({"run", write("f.toml", staged_config(data_, 2000, 0.5)), "--out",
                                (base_ / "f").string(), "--quiet", "--from", orig + ":1"});
  EXPECT_EQ(friction.rc, 2);
  // The key, its value here and the original's.
  EXPECT_TRUE(has(friction.err, "material.friction = 0.5 (the original run's: 0.275)"))
      << friction.err;
  std::string text = staged_config(data_, 2000);
  text.replace(text.find("stress = 1e6"), 12, "stress = 2e6");
  const Outcome stage0 = cli({"run", write("s.toml", text), "--out", (base_ / "s").string(),
                              "--quiet", "--from", orig + ":hold"});
  EXPECT_EQ(stage0.rc, 2);
  EXPECT_TRUE(has(stage0.err, "stage[0].stress = ")) << stage0.err;
  EXPECT_TRUE(has(stage0.err, "(the original run's: ")) << stage0.err;
  const Outcome huge =
      cli({"run", write("h.toml", staged_config(data_, 2000)), "--out", (base_ / "h").string(),
           "--quiet", "--from", orig + ":99999999999999999999999"});
  EXPECT_EQ(huge.rc, 2);
  EXPECT_TRUE(has(huge.err, "a stage index below 2")) << huge.err;
  // A refused branch writes nothing: no folder (which `resume` would start again as a run from
  // its own sample), and a finished run that --overwrite would replace keeps its files.
  for (const char* out : {"f", "s", "h"}) EXPECT_FALSE(fs::exists(base_ / out)) << out;
  const std::string kept = (base_ / "kept").string();
  ASSERT_EQ(cli({"run", write("k.toml", staged_config(data_, 2000)), "--out", kept, "--quiet"}).rc,
            0);
  const std::string summary = slurp(fs::path(kept) / "summary.json");
  const Outcome over = cli({"run", (base_ / "f.toml").string(), "--out", kept, "--quiet",
                            "--overwrite", "--from", orig + ":1"});
  EXPECT_EQ(over.rc, 2);
  EXPECT_TRUE(has(over.err, "material.friction")) << over.err;
  EXPECT_EQ(slurp(fs::path(kept) / "summary.json"), summary);
  EXPECT_TRUE(fs::exists(fs::path(kept) / "timeseries.csv"));
  const Outcome none = cli({"run", write("n.toml", staged_config(data_, 2000)), "--out",
                            (base_ / "n").string(), "--quiet", "--from", orig});
  EXPECT_EQ(none.rc, 2);
  EXPECT_TRUE(has(none.err, "name the stage")) << none.err;
  const Outcome bad = cli({"run", write("x.toml", staged_config(data_, 2000)), "--out",
                           (base_ / "x").string(), "--quiet", "--from", orig + ":shear"});
  EXPECT_EQ(bad.rc, 2);
  EXPECT_TRUE(has(bad.err, "compress, hold")) << bad.err;
}

}  // namespace
}  // namespace crushdem

namespace crushdem {
namespace {

/// A run of the 64-grain lattice (hertz) with `sections` added, from a fresh directory `name`:
/// the outcome and summary.json.
struct LatticeRun {
  Outcome outcome;
  std::string summary;
};
LatticeRun run_lattice(const std::string& name, const std::string& sections) {
  const testing::TempDir temp(name);
  const fs::path& dir = temp.path();
  std::ofstream(dir / "c.toml") << "[contact]\nlaw = \"hertz\"\n[particles]\nfile = \""
                                << CRUSHDEM_TEST_DATA_DIR << "/lattice_64.txt\"\n"
                                << sections << "[output]\nprogress_seconds = 0\n";
  LatticeRun r;
  r.outcome = cli({"run", (dir / "c.toml").string(), "--out", (dir / "out").string()});
  std::ifstream in(dir / "out" / "summary.json");
  std::stringstream summary;
  summary << in.rdbuf();
  r.summary = summary.str();
  return r;
}

// A fixed time step above the automatic one is run, with a warning that says by how much.
TEST(RunWarnings, AFixedStepAboveTheAutomaticOneIsWarnedAbout) {
  for (const double dt : {1e-10, 2e-8}) {
    std::ostringstream timestep;
    timestep << "[timestep]\ndt = " << dt << "\n[run]\nsteps = 5\n";
    const LatticeRun r = run_lattice("dt_warning", timestep.str());
    const Outcome& o = r.outcome;
    EXPECT_EQ(o.rc, 0) << o.err;
    if (dt < 1e-9) {
      EXPECT_FALSE(has(o.err, "times the automatic step")) << o.err;
      EXPECT_TRUE(has(r.summary, "\"warnings\": 0")) << r.summary;
    } else {
      EXPECT_TRUE(has(o.err, "timestep.dt = 2e-08 s is")) << o.err;
      EXPECT_TRUE(has(o.err, "times the automatic step")) << o.err;
      EXPECT_TRUE(has(r.summary, "\"warnings\": 1")) << r.summary;
    }
  }
}

// A stage whose target is met when it starts (an unloading stage where there is nothing to
// unload) ends at once, and says so.
TEST(RunWarnings, AStageWhoseTargetIsMetAtTheStartIsWarnedAbout) {
  const LatticeRun r = run_lattice("target_met",
                                   "[[stage]]\ntype = \"oedometric\"\nname = \"unload\"\n"
                                   "stress = 1e6\nstrain_rate = -10.0\n");
  const Outcome& o = r.outcome;
  EXPECT_EQ(o.rc, 0) << o.err;
  EXPECT_TRUE(has(o.err, "stage 'unload': its target stress 1e+06 Pa is met at the start"))
      << o.err;
  EXPECT_TRUE(has(r.summary, "the stage ends at once")) << r.summary;
  EXPECT_TRUE(has(r.summary, "\"warnings\": 1")) << r.summary;
}

}  // namespace
}  // namespace crushdem
