// Messages name the user's key and say why: a bad sample key is named by itself, not by the wall
// position it made; a box coordinate by its index; a key given twice as the file writes it; a
// grain that leaves the box with the likely cause.
#include <gtest/gtest.h>

#include <cstdlib>

#include "box_config.hpp"
#include "crushdem/io/config.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

const std::string kSample =
    "[sample]\ncount = 500\nvoid_ratio = 0.8\n"
    "[sample.grading]\ndiameter = [0.12e-3, 0.21e-3, 0.27e-3]\npassing = [0.0, 0.5, 1.0]\n"
    "[[stage]]\ntype = \"isotropic\"\nstress = 1e6\n";

std::string error_of(const std::string& text) {
  try {
    run_config_from_toml(toml::parse(text, "cfg.toml"), "cfg.toml", ".");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string with(const std::string& from, const std::string& to) {
  std::string s = kSample;
  const std::size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

// A number reads as the shortest form that gives it back, without an exponent below 10^6.
TEST(Messages, NumbersAreShownShortAndReadBackExactly) {
  EXPECT_EQ(show_number(90.0), "90");
  EXPECT_EQ(show_number(1800.0), "1800");
  EXPECT_EQ(show_number(-3600.0), "-3600");
  EXPECT_EQ(show_number(1234.5), "1234.5");
  EXPECT_EQ(show_number(1e6), "1e+06");
  EXPECT_EQ(show_number(2.5e-4), "0.00025");
  EXPECT_EQ(show_number(0.1), "0.1");
  EXPECT_EQ(show_number(1.0 / 3.0), "0.3333333333333333");
  for (const double v : {90.0, 1800.0, 999999.0, 123456.75, 1.0 / 3.0, 6.02e23, -1e-300}) {
    EXPECT_EQ(std::strtod(show_number(v).c_str(), nullptr), v) << show_number(v);
  }
}

TEST(Messages, ABadSampleKeyIsNamedNotTheWallItMade) {
  EXPECT_EQ(error_of(kSample), "");
  for (const char* bad : {"nan", "inf", "-inf"}) {
    const std::string e = error_of(with("void_ratio = 0.8", std::string("void_ratio = ") + bad));
    EXPECT_NE(e.find("sample.void_ratio"), std::string::npos) << e;
    EXPECT_EQ(e.find("walls."), std::string::npos) << e;
  }
  std::string e = error_of(with("passing = [0.0,", "passing = [nan,"));
  EXPECT_NE(e.find("sample.grading.passing[0]"), std::string::npos) << e;
  e = error_of(with("diameter = [0.12e-3", "diameter = [-0.12e-3"));
  EXPECT_NE(e.find("sample.grading.diameter[0]"), std::string::npos) << e;
  EXPECT_EQ(e.find("box."), std::string::npos) << e;
}

TEST(Messages, ANonFiniteBoxCoordinateIsNamedByItsIndex) {
  const std::string text = testing::tiny_run_toml();
  std::string bad = text;
  bad.replace(bad.find("max = [1e-3,"), 12, "max = [nan,");
  const std::string e = error_of(bad);
  EXPECT_NE(e.find("box.max[0]"), std::string::npos) << e;
  EXPECT_EQ(e.find("walls."), std::string::npos) << e;
}

TEST(Messages, AKeyGivenTwiceIsNamedAsTheFileWritesIt) {
  const auto message = [](const std::string& key) {
    try {
      toml::parse("[material]\n" + key + " = 1\n" + key + " = 2\n", "cfg.toml");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  for (const std::string& key : {std::string("\"a b\""), std::string("\"den\\\"sity\"")}) {
    const std::string m = message(key);
    EXPECT_NE(m.find("cfg.toml:3: key '" + key + "' is given twice"), std::string::npos) << m;
  }
  const std::string bare = message("density");  // toml++ names a bare key well
  EXPECT_NE(bare.find("cfg.toml:3: "), std::string::npos) << bare;
  EXPECT_NE(bare.find("'density'"), std::string::npos) << bare;
}

std::string run_until_failure(Simulation& sim) {
  try {
    sim.step(50);
  } catch (const RuntimeFailure& e) {
    return e.what();
  }
  return "";
}

TEST(Messages, AGrainThatLeavesTheBoxSaysWhy) {
  // So fast that it crosses the zmax wall within one step: a blow-up.
  {
    Simulation sim(testing::box_config(0.0, 1e-3));
    sim.add_particle({5e-4, 5e-4, 5e-4}, 4e-5, {0.0, 0.0, 1e7});
    const std::string e = run_until_failure(sim);
    EXPECT_NE(e.find("left the box through wall zmax"), std::string::npos) << e;
    EXPECT_NE(e.find("of its radius in the last step"), std::string::npos) << e;
  }
  // A wall driven through a resting grain faster than it can respond.
  {
    SimulationConfig cfg = testing::box_config(0.0, 1e-3);
    cfg.walls[5].mode = WallMode::Velocity;
    cfg.walls[5].velocity = -2e4;
    Simulation sim(cfg);
    sim.add_particle({5e-4, 5e-4, 9.5e-4}, 4e-5, {0.0, 0.0, 0.0});
    const std::string e = run_until_failure(sim);
    EXPECT_NE(e.find("left the box through wall zmax"), std::string::npos) << e;
    EXPECT_NE(e.find("towards the grains"), std::string::npos) << e;
  }
}

}  // namespace
}  // namespace crushdem
