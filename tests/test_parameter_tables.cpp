// The parameter tables (core/params.hpp): one row per key drives the reader, the writer, the
// range checks and docs/configuration.md. The docs test fails when the reference is out of
// date; CRUSHDEM_UPDATE_DOCS=1 rewrites the generated tables in place.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <string_view>

#include "crushdem/core/error.hpp"
#include "crushdem/io/config.hpp"
#include "crushdem/io/param_io.hpp"
#include "crushdem/io/toml.hpp"

namespace crushdem {
namespace {

const std::string kDocs = std::string(CRUSHDEM_TEST_DATA_DIR) + "/../../docs/configuration.md";

std::string begin_marker(const std::string& section) {
  return "<!-- parameters [" + section + "]: generated from its table, do not edit -->\n";
}
const std::string kEndMarker = "<!-- end of generated parameters -->\n";

TEST(ParameterTables, DocsHoldEveryGeneratedTable) {
  std::ifstream in(kDocs);
  ASSERT_TRUE(in) << kDocs;
  std::stringstream buf;
  buf << in.rdbuf();
  std::string docs = buf.str();
  const bool update = std::getenv("CRUSHDEM_UPDATE_DOCS") != nullptr;
  for (const auto& [section, table] : parameter_reference()) {
    const std::size_t b = docs.find(begin_marker(section));
    ASSERT_NE(b, std::string::npos)
        << "docs/configuration.md has no block for [" << section << "]; add the two marker lines";
    const std::size_t start = b + begin_marker(section).size();
    const std::size_t end = docs.find(kEndMarker, start);
    ASSERT_NE(end, std::string::npos) << "unterminated block for [" << section << "]";
    if (update) {
      docs.replace(start, end - start, table);
    } else {
      EXPECT_EQ(docs.substr(start, end - start), table)
          << "docs/configuration.md [" << section
          << "] is out of date: run the test with CRUSHDEM_UPDATE_DOCS=1";
    }
  }
  if (update) std::ofstream(kDocs) << docs;
}

// A key is one row: it is read, written back and range-checked from that row alone.
TEST(ParameterTables, EveryRowIsReadWrittenAndChecked) {
  const toml::Table t = toml::parse(
      "[material]\nfriction = 0.4\n[contact]\nlaw = \"hertz\"\nrotation = \"blocked\"\n"
      "[damping]\nlocal_alpha = 0.25\n[timestep]\nupdate_interval = 7\n[neighbor]\nprune = false\n"
      "[box]\nmin = [0, 0, 0]\nmax = [1e-3, 1e-3, 1e-3]\n[particles.generate]\ncount = 10\n"
      "diameter_min = 1e-4\ndiameter_max = 1e-4\n[crushing]\nd0 = 1e-3\n"
      "distribution = \"uniform\"\nvar = 0.2\n[output]\nvtk_interval = 500\n[run]\nsteps = 10\n",
      "cfg.toml");
  const RunConfig c = run_config_from_toml(t, "cfg.toml", ".");
  EXPECT_EQ(c.simulation.material.friction, 0.4);
  EXPECT_EQ(c.simulation.contact.law, NormalLaw::Hertz);
  EXPECT_EQ(c.simulation.contact.rotation, Rotation::Blocked);
  EXPECT_EQ(c.simulation.damping.local_alpha, 0.25);
  EXPECT_EQ(c.simulation.timestep.update_interval, 7u);
  EXPECT_FALSE(c.simulation.neighbor.prune);
  EXPECT_TRUE(c.crushing.enabled);
  EXPECT_EQ(c.crushing.d0, 1e-3);
  EXPECT_EQ(c.crushing.distribution, StrengthDistribution::Uniform);
  EXPECT_EQ(c.output.vtk_interval, 500u);
  // Written back, every key of every table is there and reads back to the same values.
  const toml::Table back = to_toml(c);
  const RunConfig again = run_config_from_toml(back, "back.toml", ".");
  EXPECT_EQ(toml::serialize(to_toml(again)), toml::serialize(back));
  for (const auto& p : crushing_params()) {
    EXPECT_TRUE(back.at("crushing").table->count(std::string(p.key))) << p.key;
  }
  for (const auto& p : contact_params()) {
    EXPECT_TRUE(back.at("contact").table->count(std::string(p.key))) << p.key;
  }
  // A range from a row, with the row's message.
  const auto message = [](const std::string& text) {
    try {
      run_config_from_toml(toml::parse(text, "bad.toml"), "bad.toml", ".");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string box =
      "[box]\nmin = [0, 0, 0]\nmax = [1e-3, 1e-3, 1e-3]\n[particles.generate]\ncount = 10\n"
      "diameter_min = 1e-4\ndiameter_max = 1e-4\n[run]\nsteps = 10\n";
  EXPECT_NE(message(box + "[damping]\nlocal_alpha = 1.5\n").find("damping.local_alpha"),
            std::string::npos);
  EXPECT_NE(message(box + "[crushing]\nv0 = -1\n").find("a positive crack velocity"),
            std::string::npos);
  EXPECT_NE(message(box + "[output]\ninterval = 0\n").find("output.interval"), std::string::npos);
  EXPECT_NE(message(box + "[contact]\nrotation = \"spinning\"\n").find("\"blocked\""),
            std::string::npos);
}

}  // namespace
}  // namespace crushdem

namespace crushdem {
namespace {

// A made-up section with a made-up key: declaring the row is all it takes for the key to be
// read (with its type and range checked), written back and documented.
struct Widget {
  double width = 2e-3;
  bool enabled = true;
};

const ParamTable<Widget>& widget_params() {
  static const ParamTable<Widget> table = {
      {"width", &Widget::width, "m", "how wide the widget is", [](double v) { return v > 0.0; },
       "a positive width in m"},
      {"enabled", &Widget::enabled, "", "whether the widget works"},
  };
  return table;
}

TEST(ParameterTables, AMadeUpKeyIsOneRow) {
  const toml::Table t = toml::parse("[widget]\nwidth = 5e-3\n", "w.toml");
  param_io::Section root(&t, "", "w.toml");
  param_io::Section s = root.sub("widget");
  Widget w;
  param_io::read_params(s, w, widget_params());
  s.finish();
  EXPECT_EQ(w.width, 5e-3);
  EXPECT_TRUE(w.enabled);  // the default, untouched
  validate_params(w, widget_params(), "widget");
  // Written back with every key.
  const toml::Table back = param_io::write_params(w, widget_params());
  EXPECT_EQ(toml::serialize(back), "enabled = true\nwidth = 0.005\n");
  // Documented: default, unit, meaning and range, from the row.
  const std::string doc = param_io::markdown(widget_params());
  EXPECT_NE(doc.find("| `width` | 0.002 | m | how wide the widget is; expected: a positive width "
                     "in m |"),
            std::string::npos)
      << doc;
  EXPECT_NE(doc.find("| `enabled` | true |  | whether the widget works |"), std::string::npos);
  // Checked: the type by the reader (naming file, line and key), the range by the row.
  const toml::Table bad = toml::parse("[widget]\n\nwidth = \"wide\"\n", "w.toml");
  param_io::Section root2(&bad, "", "w.toml");
  param_io::Section s2 = root2.sub("widget");
  try {
    param_io::read_params(s2, w, widget_params());
    ADD_FAILURE() << "a string width was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("w.toml:3: "), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("widget.width"), std::string::npos) << e.what();
  }
  w.width = -1.0;
  EXPECT_THROW(validate_params(w, widget_params(), "widget"), ConfigError);
  // An unknown key next to it is still refused.
  const toml::Table extra = toml::parse("[widget]\nwidht = 1e-3\n", "w.toml");
  param_io::Section root3(&extra, "", "w.toml");
  param_io::Section s3 = root3.sub("widget");
  param_io::read_params(s3, w, widget_params());
  EXPECT_THROW(s3.finish(), ConfigError);
}

// Each stage kind reads, writes and checks the rows of its own table; a key of another kind is
// named as such, and the stage built for a kind is that kind's class.
TEST(ParameterTables, EachStageKindHasItsOwnTable) {
  const std::string head =
      "[box]\nmin = [0, 0, 0]\nmax = [1e-3, 1e-3, 1e-3]\n[particles.generate]\ncount = 10\n"
      "diameter_min = 1e-4\ndiameter_max = 1e-4\n";
  const auto config = [&](const std::string& stages) {
    return run_config_from_toml(toml::parse(head + stages, "s.toml"), "s.toml", ".");
  };
  const RunConfig c = config(
      "[[stage]]\ntype = \"triaxial\"\nsigma_3 = 1e7\nstrain_rate = 50.0\naxial_strain = 0.3\n"
      "[[stage]]\ntype = \"hold\"\nlateral = \"servo\"\nlateral_stress = 2e6\nsteps = 100\n");
  ASSERT_EQ(c.stages.size(), 2u);
  EXPECT_EQ(c.stages[0].sigma_3, 1e7);
  EXPECT_EQ(c.stages[1].lateral, WallControl::Servo);
  // Written back: exactly the kind's rows that apply (no servo target for the fixed top wall,
  // no duration for a hold given in steps), plus type and name.
  const toml::Table back = to_toml(c);
  const auto& written = back.at("stage").array;
  ASSERT_EQ(written.size(), 2u);
  const toml::Table& hold = *written[1].table;
  EXPECT_TRUE(hold.count("lateral_stress"));
  EXPECT_FALSE(hold.count("axial_stress"));
  EXPECT_FALSE(hold.count("duration"));
  EXPECT_FALSE(hold.count("sigma_3"));
  EXPECT_EQ(written[0].table->size(), stage_kind("triaxial").params.size() + 2);
  const RunConfig again = run_config_from_toml(back, "back.toml", ".");
  EXPECT_EQ(toml::serialize(to_toml(again)), toml::serialize(back));
  const auto message = [&](const std::string& stages) {
    try {
      config(stages);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("[[stage]]\ntype = \"isotropic\"\nstress = 1e5\nsigma_3 = 1e5\n")
                .find("no 'sigma_3' in a \"isotropic\" stage"),
            std::string::npos);
  EXPECT_NE(message("[[stage]]\ntype = \"triaxial\"\nsigma_3 = 1e7\nstrain_rate = 50.0\n"
                    "axial_strain = 0.95\n")
                .find("stage[0].axial_strain"),
            std::string::npos);
  EXPECT_NE(
      message("[[stage]]\ntype = \"hold\"\naxial = \"loose\"\nsteps = 10\n").find("stage[0].axial"),
      std::string::npos);
  EXPECT_NE(
      message("[[stage]]\ntype = \"hold\"\nsteps = 10\nduration = 1.0\n").find("exactly one of"),
      std::string::npos);
  // A key without its switch is refused, naming both; with its switch given as off it passes (a
  // sweep's variant), and a stage's own switches are checked by the stage.
  EXPECT_NE(
      message("[[stage]]\ntype = \"hold\"\nsteps = 10\naxial_stress = 1e5\n")
          .find("stage[0].axial_stress' = 100000: expected no 'axial_stress' without 'axial'"),
      std::string::npos);
  EXPECT_NE(message("[[stage]]\ntype = \"hold\"\nsteps = 10\nprofile_radius = 0.3\n")
                .find("stage[0].profile_radius' = 0.3: expected no 'profile_radius' without "
                      "'profile_bins'"),
            std::string::npos);
  EXPECT_NE(message("[[stage]]\ntype = \"hold\"\nsteps = 10\nhead = \"load\"\n")
                .find("stage[0].head' = \"load\""),
            std::string::npos);
  EXPECT_EQ(message("[[stage]]\ntype = \"hold\"\nsteps = 10\nsettle = false\nprofile_bins = 0\n"
                    "profile_radius = 0.7\naxial = \"fixed\"\naxial_stress = 1e5\n"),
            "no error");
  EXPECT_NE(message("[[stage]]\ntype = \"hold\"\nduration = -1.0\n").find("exactly one of"),
            std::string::npos);
  EXPECT_EQ(make_stage(c.stages[0], 1e-4, nullptr)->result().kind, "triaxial");
  EXPECT_EQ(make_stage(c.stages[1], 1e-4, nullptr)->result().kind, "hold");
  StageConfig age;
  age.kind = &stage_kind("age");
  age.duration = 60.0;
  EXPECT_THROW(make_stage(age, 1e-4, nullptr), ConfigError);  // an age stage needs a crusher
}

// Every kind is its registry entry: the reader knows it by name and refuses the keys of the
// others, the docs hold its heading and table, the runner makes its class, and a kind that needs
// crack growth is refused without it. Nothing here names a kind, so a new kind is covered.
TEST(ParameterTables, EveryStageKindWorksFromItsEntry) {
  const std::string head =
      "[box]\nmin = [0, 0, 0]\nmax = [1e-3, 1e-3, 1e-3]\n[particles.generate]\ncount = 10\n"
      "diameter_min = 1e-4\ndiameter_max = 1e-4\n";
  const auto message = [&](const std::string& stages) {
    try {
      run_config_from_toml(toml::parse(head + stages, "k.toml"), "k.toml", ".");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  std::string reference;
  for (const auto& [section, text] : parameter_reference()) {
    if (section == "stage") reference = text;
  }
  const std::string names = stage_kind_names();
  EXPECT_NE(message("[[stage]]\nname = \"x\"\n").find("expected " + names), std::string::npos);
  EXPECT_NE(message("[[stage]]\ntype = \"shake\"\n").find("expected " + names), std::string::npos);
  std::set<std::string_view> seen;
  for (const StageKind* kind : stage_kinds()) {
    const std::string type(kind->name);
    EXPECT_TRUE(seen.insert(kind->name).second) << "two kinds named " << type;
    EXPECT_EQ(&stage_kind(type), kind);
    EXPECT_NE(names.find("\"" + type + "\""), std::string::npos) << type;
    EXPECT_NE(reference.find("### type = \"" + type + "\": " + std::string(kind->description) +
                             "\n\n| key | default | unit | meaning |\n"),
              std::string::npos)
        << type;
    ASSERT_NE(kind->make, nullptr) << type;
    // A key of another kind, named as such.
    for (const StageKind* other : stage_kinds()) {
      for (const Param<StageConfig>& p : other->params) {
        const bool mine = std::any_of(kind->params.begin(), kind->params.end(),
                                      [&](const Param<StageConfig>& q) { return q.key == p.key; });
        if (mine) continue;
        const std::string k(p.key);
        EXPECT_NE(message("[[stage]]\ntype = \"" + type + "\"\n" + k + " = 1\n")
                      .find("key 'stage[0]." + k + "' = given: expected no '" + k + "' in a \"" +
                            type + "\" stage"),
                  std::string::npos)
            << type << " " << k;
      }
    }
    StageConfig c;
    c.kind = kind;
    if (kind->needs_crack_growth) {
      EXPECT_THROW(make_stage(c, 1e-4, nullptr), ConfigError) << type;
      EXPECT_NE(message("[[stage]]\ntype = \"" + type + "\"\n").find("needs crack growth"),
                std::string::npos)
          << type;
    } else {
      EXPECT_EQ(make_stage(c, 1e-4, nullptr)->result().kind, type);
    }
  }
}

}  // namespace
}  // namespace crushdem
