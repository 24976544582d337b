// Particle upscaling (docs/chamber.md, Particle upscaling): [upscaling] factor N multiplies every
// length that belongs to a grain for the run and keeps the real ones in the configuration; the
// strength rule gives an upscaled grain the real grain's strength ("similar") or the Weibull
// size effect at its own size ("weibull"); a sample carries its factor and a run at another
// factor is refused.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "crushdem/core/error.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/io/config.hpp"
#include "crushdem/io/packing.hpp"
#include "crushdem/io/toml.hpp"
#include "crushdem/run/runner.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

namespace fs = std::filesystem;

RunConfig config(const std::string& text) {
  return run_config_from_toml(toml::parse(text, "test"), "test", ".");
}

const char* kUpscaled = R"(
[contact]
roughness_Sq = 0.6e-6
[sample]
count = 500
seed = 3
void_ratio = 0.76
[sample.grading]
diameter = [0.12e-3, 0.21e-3, 0.27e-3]
passing = [0.0, 0.5, 1.0]
[crushing]
d0 = 1.07e-3
d_min = 0.01e-3
v0 = 0.1
[upscaling]
factor = 20.0
[output]
progress_seconds = 0
)";

TEST(Upscaling, TheGrainLengthsAreMultipliedForTheRunAndTheConfigurationKeepsTheRealOnes) {
  const RunConfig c = config(kUpscaled);
  const RunConfig u = upscaled(c);
  EXPECT_DOUBLE_EQ(u.sample.grading.diameter[1], 20.0 * 0.21e-3);
  EXPECT_DOUBLE_EQ(u.simulation.contact.roughness_Sq, 20.0 * 0.6e-6);
  EXPECT_DOUBLE_EQ(u.crushing.d_min, 20.0 * 0.01e-3);
  EXPECT_DOUBLE_EQ(u.crushing.v0, 20.0 * 0.1);
  EXPECT_DOUBLE_EQ(u.crushing.d0, 1.07e-3);      // the key keeps the real d0 ...
  EXPECT_DOUBLE_EQ(u.crushing.d0_factor, 20.0);  // ... used at the simulated scale
  // 500 upscaled grains make a sample 20 times as wide: the box follows the grains.
  EXPECT_NEAR(u.simulation.walls[1].position / c.simulation.walls[1].position, 20.0, 1e-9);
  // The resolved configuration is the real one with the factor: read again, it gives itself.
  const std::string text = toml::serialize(to_toml(c));
  EXPECT_NE(text.find("[upscaling]"), std::string::npos);
  EXPECT_EQ(toml::serialize(to_toml(config(text))), text);
  // Without a factor nothing changes and nothing is written.
  const RunConfig plain =
      config(std::string(kUpscaled).replace(std::string(kUpscaled).find("[upscaling]"),
                                            std::string("[upscaling]\nfactor = 20.0").size(), ""));
  EXPECT_EQ(toml::serialize(to_toml(upscaled(plain))), toml::serialize(to_toml(plain)));
  EXPECT_EQ(toml::serialize(to_toml(plain)).find("upscaling"), std::string::npos);

  // The rule for d0 in use: d0 given or the initial d50 (already the upscaled grains').
  RunConfig w = c;
  w.upscaling.strength = UpscaledStrength::Weibull;
  EXPECT_DOUBLE_EQ(upscaled(w).crushing.d0_factor, 1.0);
  w.crushing.d0 = 0.0;
  EXPECT_DOUBLE_EQ(upscaled(w).crushing.d0_factor, 1.0 / 20.0);
  w.upscaling.strength = UpscaledStrength::Similar;
  EXPECT_DOUBLE_EQ(upscaled(w).crushing.d0_factor, 1.0);

  for (const char* bad : {"factor = 0.5", "factor = -2.0", "strength = \"scaled\""}) {
    std::string text_bad = kUpscaled;
    text_bad.replace(text_bad.find("factor = 20.0"), std::string("factor = 20.0").size(), bad);
    try {
      config(text_bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("upscaling."), std::string::npos) << e.what();
    }
  }
}

// Each grain's strength after Crusher::begin in a simulation of the given grain diameters.
std::vector<double> strengths(const CrushingConfig& k, const std::vector<double>& d) {
  SimulationConfig sc = testing::box_config(-0.2, 0.2, NormalLaw::Hertz);
  Simulation sim(sc);
  for (std::size_t i = 0; i < d.size(); ++i) {
    sim.add_particle({-0.15 + 0.06 * static_cast<double>(i), 0.0, 0.0}, 0.5 * d[i]);
  }
  Crusher crusher(k, SplitPattern::default14());
  crusher.begin(sim);
  std::vector<double> s;
  for (std::size_t i = 0; i < d.size(); ++i) {
    s.push_back(sim.particles().field(crusher.strength_field())[i]);
  }
  return s;
}

TEST(Upscaling, AnUpscaledGrainHasTheRealGrainsStrengthOrTheWeibullSizeEffect) {
  const double N = 20.0, m = 12.0;
  const std::vector<double> real = {0.12e-3, 0.18e-3, 0.21e-3, 0.27e-3};
  std::vector<double> big;
  for (double d : real) big.push_back(N * d);
  for (const double d0 : {1.07e-3, 0.0}) {  // d0 given, or the initial d50
    RunConfig c = config(kUpscaled);
    c.crushing.d0 = d0;
    const std::vector<double> s_real = strengths(c.crushing, real);
    const std::vector<double> s_similar = strengths(upscaled(c).crushing, big);
    c.upscaling.strength = UpscaledStrength::Weibull;
    const std::vector<double> s_weibull = strengths(upscaled(c).crushing, big);
    for (std::size_t i = 0; i < real.size(); ++i) {
      // The same draw f in each (one seed, one order): only the size term differs.
      EXPECT_NEAR(s_similar[i] / s_real[i], 1.0, 1e-12) << "d0 " << d0 << " grain " << i;
      EXPECT_NEAR(s_weibull[i] / s_real[i], std::pow(N, -3.0 / m), 1e-12)
          << "d0 " << d0 << " grain " << i;
    }
  }
}

TEST(Upscaling, ASampleCarriesItsFactorAndARunAtAnotherFactorIsRefused) {
  const testing::TempDir temp("upscaling");
  RunOptions opt;
  opt.progress = false;
  opt.out_dir = (temp.path() / "sample").string();
  run_to_directory(config(kUpscaled), opt);
  const Packing pk = read_packing((temp.path() / "sample" / "sample.txt").string());
  EXPECT_EQ(pk.header_number("upscaling_factor", "sample.txt"), 20.0);
  for (const PackingRow& r : pk.rows) {
    EXPECT_GE(r.diameter, 20.0 * 0.12e-3 * (1.0 - 1e-12));
    EXPECT_LE(r.diameter, 20.0 * 0.27e-3 * (1.0 + 1e-12));
  }
  EXPECT_NEAR(pk.header_number("void_ratio", "sample.txt"), 0.76, 0.005);

  const std::string file = (temp.path() / "sample" / "sample.txt").string();
  const std::string test = "[particles]\nfile = \"" + file + "\"\n[run]\nsteps = 10\n";
  opt.out_dir = (temp.path() / "without").string();
  try {
    run_to_directory(config(test), opt);
    ADD_FAILURE() << "an upscaled sample ran without its factor";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("upscaling.factor"), std::string::npos) << e.what();
  }
  opt.out_dir = (temp.path() / "with").string();
  EXPECT_NO_THROW(run_to_directory(config(test + "[upscaling]\nfactor = 20.0\n"), opt));
}

}  // namespace
}  // namespace crushdem
