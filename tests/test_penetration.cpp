// The penetrate stage (experiments/stages/penetrate.cpp, docs/chamber.md): a cone driven into a
// compressed sample records q_c from the moment its tip reaches the grains, lands on its
// depth and stops; a run stopped while the cone moves and resumed writes the files of an
// uninterrupted one byte for byte; bad input names its key.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "crushdem/io/config.hpp"
#include "crushdem/io/toml.hpp"
#include "crushdem/run/runner.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

namespace fs = std::filesystem;

// The run: 300 grains compressed to 200 kPa, then a 60 degree cone 0.2 mm across driven 0.45 mm
// down at 2 m/s from 1.3 mm above the floor (tests/data/penetration_300.toml); or `text`.
RunConfig config(std::string text = "") {
  if (text.empty()) {
    text = testing::test_data("grains_300.toml") + testing::test_data("penetration_300.toml");
  }
  return run_config_from_toml(toml::parse(text, "test"), "test", ".");
}

// The run of config() on `backend`: the cone records q_c from the top of the sample on, lands
// on its depth and stays there.
void expect_cone_recorded_and_stopped(const std::string& backend) {
  const testing::TempDir temp("penetrate");
  RunOptions opt;
  opt.progress = false;
  opt.backend = backend;
  opt.out_dir = (temp.path() / "run").string();
  run_to_directory(config(), opt);
  auto pen = testing::read_csv((temp.path() / "run" / "penetration.csv").string());
  const std::vector<double>& travel = pen["travel_m"];
  ASSERT_GE(travel.size(), 60u) << backend;
  // Every record_interval (500) steps of the stage, and at its start and end.
  const double depth = 0.45e-3, v = 2.0;
  EXPECT_EQ(travel.front(), 0.0);
  EXPECT_GE(travel.back(), depth * (1.0 - 1e-12));
  const double dt = pen["time_s"][1] - pen["time_s"][0];  // 500 steps
  EXPECT_LT(travel.back() - depth, v * dt / 500.0 * 1.01) << "overshot its depth";
  // No grain lies above the top wall: q_c is zero until the tip passes it, then positive once
  // the cone is in.
  std::size_t above = 0, below = 0;
  double q_c_last = 0.0;  // summed over the last sixth of the rows
  const std::size_t n = travel.size();
  for (std::size_t i = 0; i < n; ++i) {
    const double q_c = pen["q_c_Pa"][i];
    EXPECT_GE(q_c, 0.0);
    if (pen["tip_z_m"][i] > pen["wall_zmax_position_m"][i] + 1e-6) {
      EXPECT_EQ(q_c, 0.0) << "row " << i;
      ++above;
    } else {
      ++below;
      if (i > n - n / 6) q_c_last += q_c;
    }
  }
  EXPECT_GT(above, 10u);
  ASSERT_GT(below, 10u);
  EXPECT_GT(q_c_last, 0.0);
  EXPECT_GT(pen["tip_contacts"].back(), 0.0);
  // The tip moves by the travel along -z.
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_NEAR(pen["tip_z_m"][i], 1.3e-3 - travel[i], 1e-15);
  }
  // The shaft's profile: 10 bins per record.
  auto shaft = testing::read_csv((temp.path() / "run" / "shaft_profile.csv").string());
  EXPECT_EQ(shaft["bin"].size(), 10 * n);
  // The stress field, every 2500 steps and at the end: 5 rings by 4 slices. Its rings reach
  // past the box's corners, so every grain is in a cell, and the trace of each grain's
  // Love-Weber term is the same in its cylindrical frame: summed over the cells, times each
  // cell's volume less the cone's share of it, the field gives the sample's Love-Weber mean
  // stress. The cone's shares add up to its volume below the top wall (its tip 0.1 mm in radius
  // and 0.1 / tan 30 mm high, then its shaft), a check of the cells' places.
  auto field = testing::read_csv((temp.path() / "run" / "penetration_field.csv").string());
  const std::vector<double>& t_field = field["time_s"];
  ASSERT_EQ(t_field.size() % 20, 0u);
  const std::size_t records = t_field.size() / 20;
  EXPECT_GE(records, 3u);
  EXPECT_EQ(t_field.front(), pen["time_s"].front());
  EXPECT_EQ(t_field.back(), pen["time_s"].back());
  for (std::size_t f = 0; f < records; ++f) {
    const std::size_t i = static_cast<std::size_t>(
        std::find(pen["time_s"].begin(), pen["time_s"].end(), t_field[20 * f]) -
        pen["time_s"].begin());
    ASSERT_LT(i, n) << "a field record at no row of penetration.csv";
    const double H = pen["wall_zmax_position_m"][i] - pen["wall_zmin_position_m"][i];
    const double V = (pen["wall_xmax_position_m"][i] - pen["wall_xmin_position_m"][i]) *
                     (pen["wall_ymax_position_m"][i] - pen["wall_ymin_position_m"][i]) * H;
    double trace = 0.0, grains = 0.0, body = 0.0;
    for (std::size_t c = 20 * f; c < 20 * (f + 1); ++c) {
      EXPECT_EQ(field["time_s"][c], t_field[20 * f]);
      EXPECT_EQ(field["tip_z_m"][c], pen["tip_z_m"][i]);
      const double r0 = field["r_in_m"][c], r1 = field["r_out_m"][c];
      EXPECT_NEAR(r1 - r0, 0.2e-3, 1e-15);
      EXPECT_NEAR(field["z_m"][c],
                  pen["wall_zmin_position_m"][i] + (field["bin"][c] + 0.5) * H / 4.0, 1e-15);
      const double in_cone = field["body_volume_m3"][c];
      if (field["ring"][c] > 0.0) {
        EXPECT_EQ(in_cone, 0.0);  // the cone is 0.1 mm across
      }
      trace += (field["sigma_rr_Pa"][c] + field["sigma_tt_Pa"][c] + field["sigma_zz_Pa"][c]) *
               (kPi * (r1 * r1 - r0 * r0) * H / 4.0 - in_cone);
      grains += field["grains"][c];
      body += in_cone;
    }
    EXPECT_EQ(grains, pen["n_particles"][i]);
    EXPECT_NEAR(trace / (3.0 * pen["love_mean_stress_Pa"][i] * V), 1.0, 1e-9) << "record " << f;
    const double R = 0.1e-3, h_tip = R / std::tan(kPi / 6.0);
    const double tip = pen["tip_z_m"][i], top = pen["wall_zmax_position_m"][i];
    double expected = 0.0;  // the cone's volume below the top wall
    if (tip < top) {
      const double in_tip = std::min(top - tip, h_tip);  // the tip's height below the top
      expected += kPi * R * R * in_tip * in_tip * in_tip / (3.0 * h_tip * h_tip);
      if (top - tip > h_tip) expected += kPi * R * R * (top - tip - h_tip);
    }
    EXPECT_NEAR(body, expected, 1e-3 * kPi * R * R * H) << "record " << f;
  }
  // The cone stays where the stage left it.
  auto ts = testing::read_csv((temp.path() / "run" / "timeseries.csv").string());
  EXPECT_EQ(ts["body_cone_position_m"].back(), travel.back());
  const std::string summary = testing::read_file(temp.path() / "run" / "summary.json");
  EXPECT_NE(summary.find("\"depth reached\""), std::string::npos) << summary;
}

TEST(Penetration, AConeRecordsTipResistanceFromTheSurfaceOnAndStopsAtItsDepth) {
  expect_cone_recorded_and_stopped("cpu");
}

// The device step (its host emulation): the records bring the grains and their contacts with
// the cone back from the device (Stage::reads_grains) at every record_interval.
TEST(Penetration, OnTheDeviceTooTheConeRecordsAndStops) {
  expect_cone_recorded_and_stopped("emulated");
}

// A penetration cut by max_steps between two records (rows every 2500 steps, the cut at the
// first check from 3700 steps on) ends with a row and a field record of its last step, the
// grains brought back from the device for them, and no step recorded twice.
TEST(Penetration, AStageCutByMaxStepsRecordsItsLastStateOnce) {
  const testing::TempDir temp("penetrate");
  std::string text =
      testing::test_data("grains_300.toml") + testing::test_data("penetration_300.toml");
  const std::string rows = "record_interval = 500\n";
  text.replace(text.find(rows), rows.size(), "record_interval = 2500\nmax_steps = 3700\n");
  RunOptions opt;
  opt.progress = false;
  opt.backend = "emulated";
  opt.out_dir = (temp.path() / "run").string();
  run_to_directory(config(text), opt);
  auto pen = testing::read_csv((temp.path() / "run" / "penetration.csv").string());
  const std::vector<double>& step = pen["step"];
  ASSERT_EQ(step.size(), 3u);  // the start, 2500 steps in, the cut
  EXPECT_EQ(step[1] - step[0], 2500.0);
  EXPECT_GE(step[2] - step[0], 3700.0);  // the first check at or past max_steps
  EXPECT_LT(step[2] - step[0], 4000.0 + 1.0);
  EXPECT_EQ(pen["moving"].back(), 1.0);  // cut on its way down
  auto field = testing::read_csv((temp.path() / "run" / "penetration_field.csv").string());
  ASSERT_EQ(field["time_s"].size(), 3u * 20u);  // at 0, 2500 and the cut
  EXPECT_EQ(field["time_s"].back(), pen["time_s"].back());
  EXPECT_EQ(field["tip_z_m"].back(), pen["tip_z_m"].back());
  double grains = 0.0;
  for (std::size_t c = 40; c < 60; ++c) grains += field["grains"][c];
  EXPECT_EQ(grains, pen["n_particles"].back());
  const std::string summary = testing::read_file(temp.path() / "run" / "summary.json");
  EXPECT_NE(summary.find("\"max_steps\""), std::string::npos) << summary;
}

TEST(Penetration, AStoppedPenetrationResumedWritesTheFilesOfAnUninterruptedOne) {
  const testing::TempDir temp("penetrate");
  const fs::path& base = temp.path();
  const RunConfig cfg = config();
  RunOptions opt;
  opt.progress = false;
  opt.out_dir = (base / "whole").string();
  run_to_directory(cfg, opt);

  // Stopped (as SIGINT does) as soon as the cone has begun to move, then resumed.
  const std::size_t compared = testing::expect_stopped_run_resumes_exactly(
      cfg, opt, base / "whole", base / "stopped", "penetration.csv");
  EXPECT_GE(compared,
            7u);  // config, timeseries, summary, penetration, shaft profile, field, snapshots
}

// The cone of config() jacked in strokes of 0.1 mm with pauses of 20 us (0.1, 0.2, 0.3 and
// 0.4 mm, each followed by a pause, then the last 0.05 mm to the depth), the penetrate stage's
// `keys` added and a row every `every` steps, run whole into base/whole.
struct Jacked {
  RunConfig cfg;
  RunOptions opt;
  std::map<std::string, std::vector<double>> pen;  // penetration.csv
};
Jacked run_jacked(const std::string& keys, int every, const fs::path& base) {
  std::string text =
      testing::test_data("grains_300.toml") + testing::test_data("penetration_300.toml");
  const std::string at = "depth = 0.45e-3\n";
  text.replace(text.find(at), at.size(), at + "stroke = 0.1e-3\npause = 20e-6\n" + keys);
  const std::string rows = "record_interval = 500\n";
  text.replace(text.find(rows), rows.size(), "record_interval = " + std::to_string(every) + "\n");
  Jacked j{config(text), {}, {}};
  j.opt.progress = false;
  j.opt.out_dir = (base / "whole").string();
  run_to_directory(j.cfg, j.opt);
  j.pen = testing::read_csv((base / "whole" / "penetration.csv").string());
  return j;
}

TEST(Penetration, AJackedConeAdvancesInStrokesAndStandsStillBetweenThem) {
  const testing::TempDir temp("jacked");
  const Jacked jacked = run_jacked("", 500, temp.path());
  const RunConfig& cfg = jacked.cfg;
  const RunOptions& opt = jacked.opt;
  auto pen = jacked.pen;
  const std::vector<double>& travel = pen["travel_m"];
  const std::vector<double>& time = pen["time_s"];
  const std::size_t n = travel.size();
  const double v = 2.0, dt = (time[1] - time[0]) / 500.0;  // the first rows: 500 steps apart
  EXPECT_EQ(pen["strokes"].back(), 4.0);
  EXPECT_GE(travel.back(), 0.45e-3 * (1.0 - 1e-12));
  EXPECT_LT(travel.back() - 0.45e-3, v * dt * 1.01);
  // Each pause: it begins on its stroke's end, the cone stands still through it, and it lasts
  // `pause` (to a step).
  int pauses = 0;
  for (std::size_t i = 1; i < n; ++i) {
    if (!(pen["moving"][i] == 0.0 && pen["moving"][i - 1] == 1.0) || i + 1 == n) continue;
    ++pauses;
    EXPECT_NEAR(travel[i], 1e-4 * pauses, v * dt * 1.01) << "stroke " << pauses;
    std::size_t j = i;
    while (j + 1 < n && pen["moving"][j + 1] == 0.0) {
      ++j;
      EXPECT_EQ(travel[j], travel[i]) << "the cone moved during pause " << pauses;
    }
    ASSERT_LT(j + 1, n);
    const double held = time[j + 1] - time[i];  // to the row where it moves again
    EXPECT_GE(held, 20e-6 * (1.0 - 1e-9)) << "pause " << pauses;
    EXPECT_LT(held, 20e-6 + 1.01 * dt) << "pause " << pauses;
  }
  EXPECT_EQ(pauses, 4);
  // Resumed in the middle of the jacking, the run writes the files of an uninterrupted one.
  const std::size_t compared = testing::expect_stopped_run_resumes_exactly(
      cfg, opt, temp.path() / "whole", temp.path() / "stopped", "penetration.csv");
  EXPECT_GE(compared, 6u);
}

TEST(Penetration, AJackedConeUnloadedBetweenStrokesReboundsAndGoesOnToItsDepth) {
  // The jacked cone of the test above with its head load taken off in each pause (`unload`):
  // the cone moves back up as the grains under it unload, the load on it falls to a small part
  // of what it carried at the stroke's end, and each next stroke starts where the cone came to
  // rest and ends at the next multiple of the stroke (the travel is counted from the start).
  // (the head's servo as fast as the walls' at 200 /s: the pause is 3,500 steps)
  const testing::TempDir temp("unloaded");
  const Jacked jacked = run_jacked("unload = true\nmax_strain_rate = 200.0\n", 100, temp.path());
  const RunConfig& cfg = jacked.cfg;
  const RunOptions& opt = jacked.opt;
  auto pen = jacked.pen;
  const std::vector<double>& travel = pen["travel_m"];
  const std::size_t n = travel.size();
  const double v = 2.0, dt = (pen["time_s"][1] - pen["time_s"][0]) / 100.0;
  EXPECT_EQ(pen["strokes"].back(), 4.0);
  EXPECT_GE(travel.back(), 0.45e-3 * (1.0 - 1e-12));
  EXPECT_LT(travel.back() - 0.45e-3, v * dt * 1.01);
  int pauses = 0;
  for (std::size_t i = 1; i < n; ++i) {
    if (!(pen["moving"][i] == 0.0 && pen["moving"][i - 1] == 1.0) || i + 1 == n) continue;
    ++pauses;
    EXPECT_NEAR(travel[i], 1e-4 * pauses, v * dt * 1.01) << "stroke " << pauses;
    const double loaded = pen["tip_load_N"][i] + pen["shaft_load_N"][i];
    std::size_t j = i;
    while (j + 1 < n && pen["moving"][j + 1] == 0.0) ++j;
    // j: the pause's last row, where the next stroke starts from
    const double rested = pen["tip_load_N"][j] + pen["shaft_load_N"][j];
    if (loaded > 0.0) {
      EXPECT_LT(travel[j], travel[i]) << "the cone did not rebound in pause " << pauses;
      EXPECT_LT(rested, 0.1 * loaded) << "pause " << pauses << ": " << loaded << " N at its start";
    }
  }
  EXPECT_EQ(pauses, 4);
  // Resumed in the middle of the jacking, the run writes the files of an uninterrupted one.
  const std::size_t compared = testing::expect_stopped_run_resumes_exactly(
      cfg, opt, temp.path() / "whole", temp.path() / "stopped", "penetration.csv");
  EXPECT_GE(compared, 6u);
}

std::string config_error(const std::string& text) {
  try {
    const RunConfig cfg = config(text);
    const testing::TempDir temp("penetrate");
    RunOptions opt;
    opt.progress = false;
    opt.out_dir = (temp.path() / "run").string();
    run_to_directory(cfg, opt);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(Penetration, BadPenetrationsAreRefusedNamingTheKey) {
  const std::string grains = testing::test_data("grains_300.toml");
  const std::string cone =
      "[[body]]\nname = \"cone\"\nshape = \"cone\"\norigin = [0.6e-3, 0.6e-3, 1.3e-3]\n"
      "radius = 1e-4\n";
  const std::string stage = "[[stage]]\ntype = \"penetrate\"\nvelocity = 1.0\ndepth = 1e-4\n";
  // (the configuration, the key its error must name)
  const std::pair<std::string, std::string> cases[] = {
      {cone + stage, "stage[0].body"},                        // no body named
      {cone + stage + "body = \"pile\"\n", "stage[0].body"},  // none of that name
      {"[[body]]\nname = \"chamber\"\nshape = \"cylinder_inside\"\norigin = [0.6e-3, 0.6e-3, 0]\n"
       "radius = 2e-3\nlength = 2e-3\nmotion = \"dilate\"\n" +
           stage + "body = \"chamber\"\n",
       "stage[0].body"},  // a chamber's wall is not driven in
      {cone + "[[stage]]\ntype = \"penetrate\"\nbody = \"cone\"\nvelocity = 0.0\ndepth = 1e-4\n",
       "stage[0].velocity"},
      // A motion of its own for a body the stages drive.
      {cone + "mode = \"servo\"\ntarget_force = 0.1\n" + stage + "body = \"cone\"\n",
       "body[0].mode' = \"servo\": expected \"fixed\" for a body a stage drives (stage[0]"},
      {cone + "[[stage]]\ntype = \"penetrate\"\nbody = \"cone\"\nvelocity = 1.0\n",
       "stage[0].depth"},
      // Unloading between strokes without strokes, or without a pause to unload in.
      {cone + stage + "body = \"cone\"\nunload = true\n", "stage[0].unload"},
      {cone + stage + "body = \"cone\"\nstroke = 1e-5\nunload = true\n", "stage[0].unload"},
      // A field without its interval; a field about a body that does not move along z; a
      // field interval that is not a multiple of the record interval.
      {cone + stage + "body = \"cone\"\nrings = 4\n", "stage[0].rings' = 4"},
      {cone + stage + "body = \"cone\"\nfield_radius = 3.0\nfield_bins = 5\n",
       "stage[0].field_radius' = 3"},
      {cone + "direction = [1, 0, 0]\n" + stage + "body = \"cone\"\nfield_interval = 2000\n",
       "stage[0].field_interval' = 2000: expected 0 for this body"},
      {cone + stage + "body = \"cone\"\nrecord_interval = 30\nfield_interval = 100\n",
       "stage[0].field_interval"},
      // A pile through the grains.
      {"[[body]]\nname = \"pile\"\nshape = \"pile\"\norigin = [0.6e-3, 0.6e-3, 0.1e-3]\n"
       "radius = 1e-4\nlength = 2e-3\n" +
           stage + "body = \"pile\"\n",
       "body[0].origin"},
  };
  for (const auto& [text, key] : cases) {
    const std::string error = config_error(grains + text);
    EXPECT_NE(error.find(key), std::string::npos) << text << " -> " << error;
  }
}

}  // namespace
}  // namespace crushdem
