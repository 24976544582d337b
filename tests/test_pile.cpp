// A pile's set-up experiment (docs/pile.md; tests/data/pile_400.toml): a pile jacked into a
// chamber sample, its head load taken off, the sand aged to 1 hour and to 1 day on one ageing
// clock with the pile's shaft, the rings of grains about it and its loads recorded at every
// ageing event, then a compression load test; stopped in each phase and resumed, the run writes
// the files of an uninterrupted one; a load test branched from the aged state equals the same
// test run on from the installation; without crushing and without crack growth the capacity
// does not change with ageing time; bad input names its key.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "crushdem/io/config.hpp"
#include "crushdem/io/toml.hpp"
#include "crushdem/run/runner.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

namespace fs = std::filesystem;

/// tests/data/pile_400.toml with its sample file's path filled in.
std::string pile_text() {
  std::string text = testing::test_data("pile_400.toml");
  const std::string at = "\"@DATA@";
  text.replace(text.find(at), at.size(), "\"" CRUSHDEM_TEST_DATA_DIR);
  return text;
}

RunConfig config(const std::string& text) {
  return run_config_from_toml(toml::parse(text, "test"), "test", ".");
}

/// `text` without the [[stage]] table named `name`.
std::string without_stage(std::string text, const std::string& name) {
  const std::size_t named = text.find("name = \"" + name + "\"");
  const std::size_t start = text.rfind("[[stage]]", named);
  const std::size_t end = text.find("\n[", named);
  return text.erase(start, end + 1 - start);
}

RunOptions options(const fs::path& dir) {
  RunOptions opt;
  opt.progress = false;
  opt.out_dir = dir.string();
  return opt;
}

double last_capacity(const fs::path& run) {
  const std::string summary = testing::read_file(run / "summary.json");
  return testing::json_number(summary, "capacity_N");
}

TEST(Pile, APileIsInstalledAgedAndLoadTestedAndEachPhaseResumesExactly) {
  const testing::TempDir temp("pile");
  const fs::path whole = temp.path() / "whole";
  const RunConfig cfg = config(pile_text());
  run_to_directory(cfg, options(whole));

  // The installation's largest head load, and the head load once the hold has taken it off.
  auto pen = testing::read_csv((whole / "penetration.csv").string());
  double installed = 0.0;
  for (std::size_t i = 0; i < pen["tip_load_N"].size(); ++i) {
    installed = std::max(installed, pen["tip_load_N"][i] + pen["shaft_load_N"][i]);
  }
  ASSERT_GT(installed, 0.0);

  // Ageing: one clock through both age stages (0 and 1 h in the first, 1 h and 1 day in the
  // second), the pile held where the hold left it, its head load small beside the installation's.
  auto age = testing::read_csv((whole / "pile_ageing.csv").string());
  const std::vector<double> clock = {0.0, 3600.0, 3600.0, 86400.0};
  ASSERT_EQ(age["ageing_time_s"].size(), clock.size());
  for (std::size_t i = 0; i < clock.size(); ++i) {
    EXPECT_EQ(age["ageing_time_s"][i], clock[i]) << "event " << i;
    EXPECT_EQ(age["head_position_m"][i], age["head_position_m"][0]) << "the pile moved";
    EXPECT_NEAR(age["head_load_N"][i], age["shaft_load_N"][i] + age["base_load_N"][i],
                1e-12 * installed);
    EXPECT_GT(age["near_contacts"][i], 0.0);
    EXPECT_GT(age["std_Fn_near_N"][i], 0.0);
  }
  EXPECT_LT(std::abs(age["head_load_N"][0]), 0.1 * installed) << "the head load was not taken off";
  auto events = testing::read_csv((whole / "events.csv").string());
  EXPECT_EQ(events["ageing_time_s"].back(), 86400.0);
  const std::string summary = testing::read_file(whole / "summary.json");
  EXPECT_EQ(testing::json_number(summary, "ageing_time_s", 2), 3600.0);   // age_1h
  EXPECT_EQ(testing::json_number(summary, "ageing_time_s", 3), 82800.0);  // age_1d adds 23 h

  // The shaft (4 bins) and the rings (3 rings x 4 slices) at each of the 4 events: the ring
  // next to the shaft is compressed radially and circumferentially somewhere along it.
  auto shaft = testing::read_csv((whole / "pile_shaft.csv").string());
  EXPECT_EQ(shaft["bin"].size(), 4u * 4u);
  auto rings = testing::read_csv((whole / "pile_rings.csv").string());
  ASSERT_EQ(rings["ring"].size(), 4u * 3u * 4u);
  double rr = 0.0, tt = 0.0, grains = 0.0;
  for (std::size_t i = 0; i < 12; ++i) {  // the first event
    grains += rings["grains"][i];
    if (rings["ring"][i] != 0.0) continue;
    rr = std::max(rr, rings["sigma_rr_Pa"][i]);
    tt = std::max(tt, rings["sigma_tt_Pa"][i]);
  }
  EXPECT_GT(rr, 0.0);
  EXPECT_GT(tt, 0.0);
  EXPECT_GT(grains, 0.0);
  EXPECT_LE(grains, 600.0);
  EXPECT_EQ(rings["r_in_m"][0], 0.2e-3);
  EXPECT_NEAR(rings["r_out_m"].back(), 4.0 * 0.2e-3, 1e-15);

  // The load test: the head pushed 0.04 mm at the ageing time of 1 day, head = shaft + base in
  // every row; the capacity the largest median of 5 rows in a row (capacity_window), above the
  // load it started from.
  auto load = testing::read_csv((whole / "load_test.csv").string());
  const std::vector<double>& u = load["head_displacement_m"];
  ASSERT_GT(u.size(), 10u);
  EXPECT_EQ(u.front(), 0.0);
  EXPECT_GE(u.back(), 0.04e-3 * (1.0 - 1e-12));
  EXPECT_LT(u.back(), 0.041e-3);
  double q_max = 0.0, median_max = 0.0;
  for (std::size_t i = 0; i < u.size(); ++i) {
    EXPECT_EQ(load["ageing_time_s"][i], 86400.0);
    EXPECT_NEAR(load["head_load_N"][i], load["shaft_load_N"][i] + load["base_load_N"][i],
                1e-12 * installed);
    q_max = std::max(q_max, load["head_load_N"][i]);
    if (i + 1 < 5) continue;
    std::vector<double> last5(load["head_load_N"].begin() + static_cast<long>(i) - 4,
                              load["head_load_N"].begin() + static_cast<long>(i) + 1);
    std::nth_element(last5.begin(), last5.begin() + 2, last5.end());
    median_max = std::max(median_max, last5[2]);
  }
  EXPECT_EQ(last_capacity(whole), median_max);
  EXPECT_LE(median_max, q_max);
  EXPECT_GT(median_max, 2.0 * load["head_load_N"].front());

  // Stopped (as SIGTERM and SIGINT do) in the installation, in the ageing and in the load test,
  // then resumed: the files of the uninterrupted run.
  for (const char* marker : {"penetration.csv", "pile_ageing.csv", "load_test.csv"}) {
    const fs::path stopped = temp.path() / (std::string("stopped_") + marker);
    EXPECT_GE(
        testing::expect_stopped_run_resumes_exactly(cfg, options(stopped), whole, stopped, marker),
        12u)
        << marker;
  }
}

TEST(Pile, ALoadTestBranchedFromTheAgedStateEqualsTheSameTestRunOn) {
  // The test at 1 hour: run on from the installation, and branched from the run that aged on to
  // 1 day, at the start of its stage 3 (the end of age_1h).
  const testing::TempDir temp("pile_branch");
  const std::string text = pile_text();
  const std::string at_1h = without_stage(text, "age_1d");
  run_to_directory(config(text), options(temp.path() / "aged"));
  run_to_directory(config(at_1h), options(temp.path() / "on"));
  RunOptions branch = options(temp.path() / "branch");
  branch.branch_dir = (temp.path() / "aged").string();
  branch.branch_stage = "3";
  run_to_directory(config(at_1h), branch);
  for (const char* f : {"load_test.csv", "pile_ageing.csv", "pile_rings.csv", "events.csv"}) {
    EXPECT_EQ(testing::read_file(temp.path() / "on" / f),
              testing::read_file(temp.path() / "branch" / f))
        << f;
  }
  EXPECT_EQ(last_capacity(temp.path() / "on"), last_capacity(temp.path() / "branch"));
  EXPECT_GT(last_capacity(temp.path() / "branch"), 0.0);
}

TEST(Pile, WithoutCrushingOrCrackGrowthTheCapacityDoesNotChangeWithAgeingTime) {
  // Grains far too strong to break and cracks that do not grow: an ageing jump then changes
  // nothing but the clock, so a pile aged to 1 day and one aged to 1 month (the same dynamic
  // phases) have the same capacity to the last bit: the set-up comes from the grains, not from
  // the bookkeeping.
  std::string text = pile_text();
  text.replace(text.find("sigma_lim0 = 3.75e9"), 19, "sigma_lim0 = 3.75e15");
  text.replace(text.find("v0 = 0.1"), 8, "v0 = 1e-30");
  std::string month = text;
  month.replace(month.find("until = 86400.0"), 15, "until = 2592000.0");
  const testing::TempDir temp("pile_inert");
  run_to_directory(config(text), options(temp.path() / "day"));
  RunOptions branch = options(temp.path() / "month");
  branch.branch_dir = (temp.path() / "day").string();
  branch.branch_stage = "3";
  run_to_directory(config(month), branch);
  auto ts = testing::read_csv((temp.path() / "day" / "timeseries.csv").string());
  EXPECT_EQ(ts["breakages_instant"].back() + ts["breakages_crack"].back(), 0.0);
  auto day = testing::read_csv((temp.path() / "day" / "load_test.csv").string());
  auto mon = testing::read_csv((temp.path() / "month" / "load_test.csv").string());
  EXPECT_EQ(day["ageing_time_s"].back(), 86400.0);
  EXPECT_EQ(mon["ageing_time_s"].back(), 2592000.0);
  EXPECT_EQ(day["head_load_N"], mon["head_load_N"]);
  EXPECT_EQ(day["shaft_load_N"], mon["shaft_load_N"]);
  EXPECT_GT(last_capacity(temp.path() / "day"), 0.0);
  EXPECT_EQ(last_capacity(temp.path() / "day"), last_capacity(temp.path() / "month"));
}

std::string run_error(const std::string& text) {
  try {
    const testing::TempDir temp("pile_bad");
    run_to_directory(config(text), options(temp.path() / "run"));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

// What the stages ask of a body is checked with the configuration, before a sample is prepared
// or a stage has run: a second push of an installed pile cannot start from the top, and a pile
// driven in a sector of a chamber is on its axis.
TEST(Pile, ABodyTheStagesCannotDriveIsRefusedWithTheConfiguration) {
  const std::string text = pile_text();
  const auto error = [](const std::string& t) {
    try {
      (void)config(t);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  std::string again = text;
  again.insert(again.find("[[stage]]", again.find("name = \"install\"")),
               "[[stage]]\ntype = \"penetrate\"\nname = \"again\"\nbody = \"pile\"\n"
               "from_top = true\nvelocity = 1.0\ndepth = 0.1e-3\n");
  EXPECT_NE(error(again).find("stage[1].from_top' = true: expected false"), std::string::npos)
      << error(again);
  std::string quarter = text;
  const std::size_t p = quarter.find("[particles]");
  quarter.replace(p, quarter.find("[[body]]") - p,
                  "[sample]\nshape = \"cylinder\"\nsector = 90\ncount = 400\n"
                  "void_ratio = 0.75\nstress = 100e3\n[sample.grading]\n"
                  "diameter = [0.12e-3, 0.27e-3]\npassing = [0.0, 1.0]\n");
  EXPECT_EQ(error(quarter), "");
  for (const auto& [from, to, key] :
       {std::array<std::string, 3>{"origin = [0.0, 0.0, 0.01]", "origin = [1e-4, 0.0, 0.01]",
                                   "body[0].origin"},
        {"tip = \"flat\"", "tip = \"flat\"\naxis = [0.1, 0, 1]", "body[0].axis"}}) {
    std::string off = quarter;
    off.replace(off.find(from), from.size(), to);
    EXPECT_NE(error(off).find(key + "'"), std::string::npos) << key << ": " << error(off);
    EXPECT_NE(error(off).find("on that axis"), std::string::npos) << error(off);
  }
}

// A stage cut short at max_steps stops the body it drives, as its own end does: the next stage
// finds the pile still; a load test cut between two of its rows takes a row of its last step. A
// load test of fewer rows than capacity_window takes the median of those it has (not a capacity of
// 0), with a warning.
TEST(Pile, AStageEndedAtMaxStepsStopsItsBodyAndAShortLoadTestHasACapacity) {
  const testing::TempDir temp("max_steps");
  std::string text = without_stage(without_stage(pile_text(), "age_1h"), "age_1d");
  text = without_stage(text, "unload");
  text.replace(text.find("max_strain_rate = 100.0\n"), 24,
               "max_strain_rate = 100.0\nmax_steps = 2000\n[[stage]]\ntype = \"hold\"\n"
               "name = \"still\"\nsteps = 1000\n");
  // The load test cut too, between two rows (every 300 steps, checks every 250, the cut at the
  // check at 750): it takes a last row of its own.
  text.replace(text.find("record_interval = 200"), 21,
               "record_interval = 300\ncapacity_window = 50\nmax_steps = 700\n"
               "check_interval = 250");
  text.replace(text.find("interval = 2000"), 15, "interval = 100");
  run_to_directory(config(text), options(temp.path() / "run"));
  const std::string summary = testing::read_file(temp.path() / "run" / "summary.json");
  EXPECT_NE(summary.find("\"max_steps\""), std::string::npos) << summary;
  auto ts = testing::read_csv((temp.path() / "run" / "timeseries.csv").string());
  const std::vector<double>& stage = ts["stage"];
  const std::vector<double>& q = ts["body_pile_position_m"];
  std::vector<double> held;
  for (std::size_t i = 0; i < stage.size(); ++i) {
    if (stage[i] == 1.0) held.push_back(q[i]);
  }
  ASSERT_GE(held.size(), 5U);
  EXPECT_EQ(held.front(), held.back());
  auto load = testing::read_csv((temp.path() / "run" / "load_test.csv").string());
  const std::vector<double>& Q = load["head_load_N"];
  ASSERT_LT(Q.size(), 50U);
  ASSERT_EQ(Q.size(), 4U);  // at 0, 300, 600 and 750 steps
  EXPECT_EQ(load["step"].back() - load["step"].front(), 750.0);
  EXPECT_EQ(load["step"][2] - load["step"].front(), 600.0);
  const double capacity = testing::json_number(summary, "capacity_N");
  EXPECT_GT(capacity, 0.0);
  EXPECT_LT(capacity, *std::max_element(Q.begin(), Q.end()));
  EXPECT_NE(summary.find("fewer than capacity_window = 50"), std::string::npos) << summary;
}

// A hold with `settle` ends once the head load is off and the sand at rest, before its longest
// length; the same hold without it runs that length.
TEST(Pile, AHoldThatSettlesEndsWhenTheHeadLoadIsOffAndTheSandAtRest) {
  const testing::TempDir temp("settle");
  std::string text = pile_text();
  text.erase(text.find("[[stage]]\ntype = \"age\""));  // installation and unloading only
  const std::string hold = "steps = 3000\n";
  text.replace(text.find(hold), hold.size(),
               "steps = 200000\nsettle = true\ntolerance = 0.05\nunbalanced = 0.02\n");
  run_to_directory(config(text), options(temp.path() / "settle"));
  const std::string summary = testing::read_file(temp.path() / "settle" / "summary.json");
  EXPECT_NE(summary.find("\"end\": \"settled\""), std::string::npos) << summary;
  const double steps = testing::json_number(summary, "steps", 2);  // the run, install, unload
  EXPECT_GT(steps, 0.0);
  EXPECT_LT(steps, 200000.0);
  // Settled: the head load within 5 % of the platen's target over the pile's area.
  auto ts = testing::read_csv((temp.path() / "settle" / "timeseries.csv").string());
  EXPECT_LT(std::abs(ts["body_pile_stress_Pa"].back()), 0.05 * 100e3 + 1e-9);
  EXPECT_LT(ts["unbalanced_force_ratio"].back(), 0.02 + 1e-12);
  // `settle` is written to config.toml only where it is on.
  const std::string written = testing::read_file(temp.path() / "settle" / "config.toml");
  EXPECT_EQ(written.find("settle"), written.rfind("settle")) << written;
}

TEST(Pile, BadPileRunsAreRefusedNamingTheKey) {
  const std::string text = pile_text();
  auto changed = [&](const std::string& from, const std::string& to) {
    std::string t = text;
    t.replace(t.find(from), from.size(), to);
    return t;
  };
  // (the configuration, the key its error must name)
  const std::pair<std::string, std::string> cases[] = {
      // An ageing time before the previous one.
      {changed("until = 86400.0", "until = 1800.0"), "stage[3].until"},
      {changed("until = 86400.0", "until = 86400.0\nduration = 10.0"), "stage[3].duration"},
      {changed("until = 86400.0", "until = -5.0"), "stage[3].until"},
      // A pile wider than the chamber (0.73 mm in radius).
      {changed("radius = 0.2e-3", "radius = 1.0e-3"), "body[0].radius"},
      // The pile pushed through the sample (1.43 mm high) into the bottom platen.
      {changed("depth = 0.6e-3", "depth = 1.5e-3"), "stage[0].depth"},
      // A load test before the installation.
      {without_stage(
           without_stage(without_stage(without_stage(text, "install"), "unload"), "age_1h"),
           "age_1d"),
       "stage[0].body"},
      {changed("head_load = 0.0", "head_load = -1.0"), "stage[1].head_load"},
      {changed("direction = \"compression\"", "direction = \"sideways\""), "stage[4].direction"},
      {changed("name = \"age_1h\"\nbody = \"pile\"", "name = \"age_1h\"\nbody = \"pole\""),
       "stage[2].body"},
      {changed("rings = 3\n", "rings = 0\n"), "stage[2].rings"},
      // A head load without the pile it holds.
      {changed("name = \"unload\"\nbody = \"pile\"\n", "name = \"unload\"\n"), "stage[1].head"},
      {changed("record_interval = 200", "record_interval = 200\ncapacity_window = 0"),
       "stage[4].capacity_window"},
      // A shaft without a tip, driven into the grains.
      {[&] {
         std::string t = changed("shape = \"pile\"", "shape = \"cylinder_outside\"");
         return t.erase(t.find("tip = \"flat\"\n"), 13);
       }(),
       "stage[0].body\' = \"pile\": expected a body with a leading end"},
      // A count that is no integer hears its range too.
      {changed("bins = 4", "bins = 1e20"),
       "stage[2].bins' = 1e+20: expected an integer: a number "
       "of bins in [1, 10000]"},
  };
  for (const auto& [bad, key] : cases) {
    const std::string error = run_error(bad);
    EXPECT_NE(error.find(key), std::string::npos) << key << " -> " << error;
  }
  // A body that stays may pass through the bottom platen: a rod, or a pile no stage drives.
  for (const char* shape : {"cylinder_outside", "pile\"\ntip = \"flat"}) {
    const std::string rod = testing::tiny_run_toml() + "[[body]]\nname = \"rod\"\nshape = \"" +
                            shape +
                            "\"\norigin = [0.95e-3, 0.5e-3, -0.5e-3]\nradius = 1e-5\n"
                            "length = 2e-3\n";
    EXPECT_NO_THROW(check_start(config(rod))) << shape;
  }
  // A run that stops on an error ends its run.log with it.
  {
    const testing::TempDir temp("pile_log");
    const std::string bad = changed("origin = [0.0, 0.0, 0.01]", "origin = [0.0, 0.0, 0.1e-3]");
    EXPECT_THROW(run_to_directory(config(bad), options(temp.path() / "run")), ConfigError);
    const std::string log = testing::read_file(temp.path() / "run" / "run.log");
    EXPECT_NE(log.find("error: key 'body[0].origin'"), std::string::npos) << log;
  }
  // A tip inside the bottom platen (at z = 0.19 mm) is refused for the platen, ahead of the
  // grains its shaft overlaps.
  for (const char* tip : {"tip = \"flat\"", "half_angle = 30.0"}) {
    std::string bad = changed("origin = [0.0, 0.0, 0.01]", "origin = [0.0, 0.0, 0.1e-3]");
    bad.replace(bad.find("tip = \"flat\""), std::string("tip = \"flat\"").size(), tip);
    const std::string error = run_error(bad);
    EXPECT_NE(error.find("body[0].origin"), std::string::npos) << error;
    EXPECT_NE(error.find("above the bottom platen"), std::string::npos) << error;
    // `crushdem-sand check` (check_start) finds it without running, as it finds a pile that
    // overlaps grains.
    for (const std::string& checked :
         {bad, changed("origin = [0.0, 0.0, 0.01]", "origin = [0.0, 0.0, 1.0e-3]")}) {
      std::string found;
      try {
        check_start(config(checked));
      } catch (const ConfigError& e) {
        found = e.what();
      }
      EXPECT_EQ(found, run_error(checked));
      EXPECT_NE(found.find("body[0].origin"), std::string::npos) << found;
    }
  }
}

}  // namespace
}  // namespace crushdem
