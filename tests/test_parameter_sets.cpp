// Named parameter sets (io/parameter_sets.hpp): crushdem's set is the default of the engine, the
// file reader and the Python API; `parameters = "table1"` selects Table 1 as printed; a key the
// file gives wins over its set; `crushdem-sand check` says where each of the set's keys came from.
#include <gtest/gtest.h>

#include "crushdem/io/config.hpp"
#include "crushdem/run/run_directory.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

RunConfig parse(const std::string& top, const std::string& tail = "") {
  const std::string text = top + testing::tiny_run_toml() + tail;
  return run_config_from_toml(toml::parse(text, "cfg.toml"), "cfg.toml", ".");
}

std::string error_of(const std::string& top) {
  try {
    parse(top);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(ParameterSets, TheEngineDefaultsAreCrushdemsSet) {
  // Default-constructed structs, a file without the key and the set named "crushdem" agree.
  ContactConfig contact;
  CrushingConfig crushing;
  apply_parameter_set(parameter_set(kDefaultParameterSet), contact, crushing);
  EXPECT_EQ(contact.rotation, ContactConfig{}.rotation);
  EXPECT_EQ(crushing.d0, CrushingConfig{}.d0);
  EXPECT_EQ(ContactConfig{}.rotation, Rotation::Blocked);
  EXPECT_EQ(CrushingConfig{}.d0, 1.07e-3);
  const RunConfig c = parse("", "[crushing]\n");
  EXPECT_EQ(c.parameters.name, "crushdem");
  EXPECT_FALSE(c.parameters.named);
  EXPECT_EQ(c.simulation.contact.rotation, Rotation::Blocked);
  EXPECT_EQ(c.crushing.d0, 1.07e-3);
  EXPECT_EQ(parameter_sets().front().name, kDefaultParameterSet);
}

TEST(ParameterSets, Table1IsOneLineAndTheFilesOwnKeysWin) {
  const RunConfig t = parse("parameters = \"table1\"\n", "[crushing]\n");
  EXPECT_TRUE(t.parameters.named);
  EXPECT_EQ(t.simulation.contact.rotation, Rotation::Free);
  EXPECT_EQ(t.crushing.d0, 0.0);
  EXPECT_TRUE(t.parameters.given.empty());
  const RunConfig mixed = parse("parameters = \"table1\"\n", "[crushing]\nd0 = 2e-3\n");
  EXPECT_EQ(mixed.crushing.d0, 2e-3);
  EXPECT_EQ(mixed.simulation.contact.rotation, Rotation::Free);
  ASSERT_EQ(mixed.parameters.given.size(), 1u);
  EXPECT_EQ(mixed.parameters.given[0], "crushing.d0");
  // rolling_friction without a rotation key still means rolling resistance in either set.
  const RunConfig rolling = parse("", "[contact]\nrolling_friction = 0.3\n");
  EXPECT_EQ(rolling.simulation.contact.rotation, Rotation::Rolling);
}

TEST(ParameterSets, CheckSaysWhereEachKeyCameFrom) {
  const RunConfig c = parse("parameters = \"table1\"\n", "[crushing]\nd0 = 2e-3\n");
  const std::vector<std::string> lines =
      parameter_set_report(c.parameters, c.simulation.contact, c.crushing, true);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_NE(lines[0].find("parameters = \"table1\" (named by the file)"), std::string::npos)
      << lines[0];
  EXPECT_NE(lines[1].find("contact.rotation = \"free\" (from the set)"), std::string::npos)
      << lines[1];
  EXPECT_NE(lines[2].find("crushing.d0 = 0.002 (set by the file)"), std::string::npos) << lines[2];
  // rolling_friction > 0 without a rotation key implies rolling: not the set's value.
  const RunConfig rolling = parse("", "[contact]\nrolling_friction = 0.3\n");
  const auto implied =
      parameter_set_report(rolling.parameters, rolling.simulation.contact, rolling.crushing, false);
  EXPECT_NE(implied[1].find("contact.rotation = \"rolling\" (implied by contact.rolling_friction"),
            std::string::npos)
      << implied[1];
  // Without crushing, d0 is not in use and not reported.
  const RunConfig plain = parse("");
  const auto short_report =
      parameter_set_report(plain.parameters, plain.simulation.contact, plain.crushing, false);
  ASSERT_EQ(short_report.size(), 2u);
  EXPECT_NE(short_report[0].find("\"crushdem\" (the default)"), std::string::npos);
}

TEST(ParameterSets, TheResolvedConfigurationNamesItsSetAndReadsBackTheSame) {
  const RunConfig t = parse("parameters = \"table1\"\n", "[crushing]\n");
  const std::string text = toml::serialize(to_toml(t));
  EXPECT_NE(text.find("parameters = \"table1\""), std::string::npos);
  const RunConfig again =
      run_config_from_toml(toml::parse(text, "config.toml"), "config.toml", ".");
  EXPECT_EQ(again.parameters.name, "table1");
  EXPECT_EQ(again.simulation.contact.rotation, Rotation::Free);
  EXPECT_EQ(again.crushing.d0, 0.0);
  EXPECT_EQ(toml::serialize(to_toml(again)), text);
}

TEST(ParameterSets, ARunDirectorysConfigurationWithoutTheKeyIsReadAsTheEarlierDefaults) {
  // A config.toml written before `parameters` existed was resolved under the earlier defaults.
  const std::string text = testing::tiny_run_toml() + "[crushing]\n";
  const RunConfig saved = saved_run_config_from_toml(toml::parse(text, "c"), "c", ".");
  EXPECT_EQ(saved.parameters.name, "table1");
  EXPECT_EQ(saved.simulation.contact.rotation, Rotation::Free);
  EXPECT_EQ(saved.crushing.d0, 0.0);
  // One that names its set keeps it.
  const RunConfig named =
      saved_run_config_from_toml(toml::parse("parameters = \"crushdem\"\n" + text, "c"), "c", ".");
  EXPECT_EQ(named.simulation.contact.rotation, Rotation::Blocked);
}

TEST(ParameterSets, AnUnknownSetOrAWrongTypeIsRefusedNamingTheKey) {
  const std::string unknown = error_of("parameters = \"table2\"\n");
  EXPECT_NE(unknown.find("cfg.toml:1: "), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("parameters"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("\"table2\""), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("\"crushdem\" or \"table1\""), std::string::npos) << unknown;
  const std::string number = error_of("parameters = 1\n");
  EXPECT_NE(number.find("the name of a parameter set"), std::string::npos) << number;
}

TEST(ParameterSets, TheSimulationReaderTakesTheKeyToo) {
  const std::string box = "[box]\nmin = [0.0, 0.0, 0.0]\nmax = [1e-3, 1e-3, 1e-3]\n";
  EXPECT_EQ(simulation_config_from_toml(toml::parse(box, "s"), "s").contact.rotation,
            Rotation::Blocked);
  EXPECT_EQ(simulation_config_from_toml(toml::parse("parameters = \"table1\"\n" + box, "s"), "s")
                .contact.rotation,
            Rotation::Free);
}

}  // namespace
}  // namespace crushdem

namespace crushdem {
namespace {

TEST(ParameterSets, ABranchComparesTheSetsValuesNotItsName) {
  const std::string base =
      "[box]\nmin = [0.0, 0.0, 0.0]\nmax = [1e-3, 1e-3, 1e-3]\n"
      "[particles.generate]\ncount = 10\ndiameter_min = 1e-4\ndiameter_max = 2e-4\n"
      "[[stage]]\ntype = \"hold\"\nsteps = 10\n[[stage]]\ntype = \"hold\"\nsteps = 10\n";
  const std::string original = "parameters = \"table1\"\n" + base;
  const auto cfg = [&](const std::string& contact) {
    const std::string text = base + "[contact]\n" + contact;
    return run_config_from_toml(toml::parse(text, "b.toml"), "b.toml", ".");
  };
  // The same values, given key by key instead of by the set's name: the branch may start.
  EXPECT_EQ(branch_stage(original, cfg("rotation = \"free\"\n"), "1", "."), 1u);
  // Another value is refused, naming the key.
  try {
    branch_stage(original, cfg(""), "1", ".");
    ADD_FAILURE() << "a branch with rotation blocked from a run with free rotation";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("contact.rotation"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace crushdem
