// Malformed configurations fail before running, naming the key or file.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "crushdem/core/error.hpp"
#include "crushdem/io/config.hpp"
#include "fixtures.hpp"

namespace crushdem {
namespace {

namespace fs = std::filesystem;

// A valid configuration whose [material] and shear_modulus stand on lines 2 and 3.
const std::string kValid = testing::test_data("one_servo_wall.toml");

RunConfig parse(const std::string& text) {
  return run_config_from_toml(toml::parse(text, "cfg.toml"), "cfg.toml", ".");
}

// Replaces the first occurrence of `from` in the valid document.
std::string edit(const std::string& from, const std::string& to) {
  std::string s = kValid;
  const auto k = s.find(from);
  EXPECT_NE(k, std::string::npos) << from;
  return s.replace(k, from.size(), to);
}

void expect_error(const std::string& text, const std::vector<std::string>& fragments) {
  try {
    parse(text);
    ADD_FAILURE() << "accepted:\n" << text;
  } catch (const ConfigError& e) {
    for (const auto& f : fragments) {
      EXPECT_NE(std::string(e.what()).find(f), std::string::npos)
          << "message '" << e.what() << "' lacks '" << f << "'";
    }
  }
}

TEST(Config, ValidConfigurationRoundTrips) {
  const RunConfig c = parse(kValid);
  EXPECT_EQ(c.simulation.walls[5].mode, WallMode::Servo);
  EXPECT_EQ(c.particles.generate.count, 10u);
  // The resolved configuration reads back to the same values.
  const RunConfig again = run_config_from_toml(to_toml(c), "resolved", ".");
  EXPECT_EQ(toml::serialize(to_toml(again)), toml::serialize(to_toml(c)));
}

TEST(Config, UnknownKey) {
  expect_error(edit("shear_modulus = 32e9", "shear_modulus = 32e9\nshear_modulos = 1.0"),
               {"material.shear_modulos", "cfg.toml:4", "unknown key"});
  expect_error(kValid + "[bogus]\nx = 1\n", {"bogus"});
}

TEST(Config, WrongType) {
  expect_error(edit("shear_modulus = 32e9", "shear_modulus = \"stiff\""),
               {"material.shear_modulus", "\"stiff\"", "number"});
  expect_error(edit("count = 10", "count = 10.5"), {"particles.generate.count", "integer"});
}

TEST(Config, NegativeModulus) {
  expect_error(edit("shear_modulus = 32e9", "shear_modulus = -32e9"),
               {"material.shear_modulus", "-3.2e+10", "positive"});
}

TEST(Config, BoxSmallerThanGrain) {
  expect_error(edit("diameter_max = 2e-4", "diameter_max = 2e-3"),
               {"particles.generate.diameter_max", "box"});
}

TEST(Config, InvertedBox) {
  expect_error(edit("max = [1e-3, 1e-3, 1e-3]", "max = [1e-3, 1e-3, -1e-3]"),
               {"box.max[2]", "-0.001", "box.min[2] = 0"});
}

TEST(Config, BadWallMode) {
  expect_error(edit("mode = \"servo\"", "mode = \"servoo\""), {"walls.zmax.mode", "servoo"});
  expect_error(edit("target_stress = 1e6", "target_stress = -1e6"), {"walls.zmax.target_stress"});
}

TEST(Config, MissingParticleFile) {
  std::string text = kValid;
  const auto k = text.find("[particles.generate]");
  text = text.substr(0, k) + "[particles]\nfile = \"no_such_file.txt\"\n[run]\nsteps = 10\n";
  expect_error(text, {"particles.file", "no_such_file.txt"});
}

TEST(Config, KeyForAnotherWallMode) {
  // target_stress without mode = "servo" would silently run a fixed wall
  expect_error(edit("mode = \"servo\"\n", ""), {"walls.zmax.target_stress", "fixed"});
}

TEST(Config, RunLength) {
  expect_error(edit("steps = 10", "steps = 10\nduration = 1.0"), {"run.steps", "run.duration"});
}

TEST(Config, TooManyGrains) {
  expect_error(edit("count = 10", "count = 100000"), {"particles.generate.count"});
}

TEST(Config, SyntaxErrorNamesLine) {
  expect_error(edit("[run]", "[run"), {"cfg.toml:"});
}

}  // namespace
}  // namespace crushdem

namespace crushdem {
namespace {

const char* kSample = R"([sample]
count = 500
void_ratio = 0.75
[sample.grading]
diameter = [0.1e-3, 0.2e-3]
passing = [0.0, 1.0]
[[stage]]
type = "isotropic"
stress = 1e6
)";

std::string sample_with(const std::string& from, const std::string& to) {
  std::string s = kSample;
  return s.replace(s.find(from), from.size(), to);
}

TEST(Config, SampleVoidRatioAndCountAreChecked) {
  EXPECT_NO_THROW(parse(kSample));
  for (const char* e : {"void_ratio = 2.5", "void_ratio = 5", "void_ratio = 1e6"}) {
    expect_error(sample_with("void_ratio = 0.75", e), {"sample.void_ratio", "(0, 1.2)"});
  }
  expect_error(sample_with("count = 500", "count = 0"), {"sample.count", "a positive number"});
}

// Sample files: the five columns only, ids >= 0, no two grains at one point.
TEST(Config, ParticleFilesAreChecked) {
  const testing::TempDir temp("particles");
  const std::filesystem::path& dir = temp.path();
  const auto check = [&](const std::string& rows, const std::vector<std::string>& fragments) {
    std::ofstream((dir / "p.txt").string()) << rows;
    const std::string text =
        "[box]\nmin = [0, 0, 0]\nmax = [1e-3, 1e-3, 1e-3]\n[particles]\n"
        "file = \"" +
        (dir / "p.txt").string() + "\"\n[run]\nsteps = 10\n";
    if (fragments.empty()) {
      EXPECT_NO_THROW(parse(text)) << rows;
    } else {
      expect_error(text, fragments);
    }
  };
  check("1 1e-4 1e-4 1e-4 1e-4\n2 5e-4 5e-4 5e-4 1e-4\n", {});
  check("1 1e-4 1e-4 1e-4 1e-4 7\n2 5e-4 5e-4 5e-4 1e-4\n", {"p.txt:1", "5 columns"});
  check("1 1e-4 1e-4 1e-4 1e-4\n-1 5e-4 5e-4 5e-4 1e-4\n", {"p.txt:2", "id -1", ">= 0"});
  check("1 5e-4 5e-4 5e-4 1e-4\n2 5e-4 5e-4 5e-4 1e-4\n", {"particles 1 and 2", "same point"});
  // One grain 75 % into another (of radius 5e-5: the centres 2.5e-5 apart) is refused, a
  // contact-like overlap (1 %) is not.
  check("1 5e-4 5e-4 5e-4 1e-4\n2 5.25e-4 5e-4 5e-4 1e-4\n",
        {"particles 1 and 2", "overlap by 150 %"});
  check("1 5e-4 5e-4 5e-4 1e-4\n2 5.99e-4 5e-4 5e-4 1e-4\n", {});
  // A file cut short: inside a number (no newline at its end), or at a line end when its
  // header says how many grains it holds.
  check("1 1e-4 1e-4 1e-4 1e-4\n2 5e-4 5e-4 5e-4 1", {"p.txt:2", "ends inside a line"});
  check("# particles=3\n1 1e-4 1e-4 1e-4 1e-4\n2 5e-4 5e-4 5e-4 1e-4\n",
        {"particles=3", "holds 2 grains"});
  check("# particles=2\n1 1e-4 1e-4 1e-4 1e-4\n2 5e-4 5e-4 5e-4 1e-4\n", {});
}

}  // namespace
}  // namespace crushdem

namespace crushdem {
namespace {

TEST(Config, GrainsOutsideTheBoxAreFoundByCheck) {
  const testing::TempDir temp("particles");
  const std::filesystem::path& dir = temp.path();
  std::ofstream((dir / "p.txt").string()) << "1 1e-4 1e-4 1e-4 1e-4\n2 5e-4 5e-4 9.8e-4 1e-4\n";
  const std::string text =
      "[box]\nmin = [0, 0, 0]\nmax = [1e-3, 1e-3, 1e-3]\n[particles]\n"
      "file = \"" +
      (dir / "p.txt").string() + "\"\n[run]\nsteps = 10\n";
  expect_error(text, {"particle 2", "not inside the box"});
}

}  // namespace
}  // namespace crushdem
