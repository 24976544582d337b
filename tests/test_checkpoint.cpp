// Checkpoint and resume: the saved state is complete, so a run continued from it gives
// bit-identical results, and a run stopped on request and resumed writes the same files as an
// uninterrupted one. (The SIGKILL case, through the command line, is in tests/python.)
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "crushdem/core/part_clock.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/io/config.hpp"
#include "crushdem/io/toml.hpp"
#include "crushdem/particles/generate.hpp"
#include "crushdem/run/checkpoint.hpp"
#include "crushdem/run/runner.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

namespace fs = std::filesystem;

using crushdem::testing::read_file;

// 300 grains squeezed by servo walls, weak enough to break, with crack growth: then a creep
// stage (servo walls during dynamic phases) with off-DEM ageing jumps.
const std::string kConfig =
    testing::test_data("grains_300.toml") + testing::test_data("creep_300.toml");

// The number after "key": in a JSON text (enough for timing.json); NaN when absent.
double json_number(const std::string& text, const std::string& key) {
  const std::size_t k = text.find("\"" + key + "\":");
  if (k == std::string::npos) return std::nan("");
  return std::strtod(text.c_str() + k + key.size() + 3, nullptr);
}

RunConfig config(const fs::path& base, double rolling_friction = 0.0) {
  std::string text(kConfig);
  if (rolling_friction > 0.0) {
    const std::string law = "law = \"rough\"\n";
    text.replace(text.find(law), law.size(),
                 law + "rolling_friction = " + std::to_string(rolling_friction) + "\n");
  }
  return run_config_from_toml(toml::parse(text, "test"), "test", base.string());
}

/// Runs 25,000 steps of servo compression with crushing, saves the state, loads it into a fresh
/// Simulation and Crusher, and checks that both continue identically for 3,000 steps.
void expect_saved_simulation_continues_bit_for_bit(const RunConfig& cfg) {
  auto build = [&](Simulation& sim) {
    add_configured_particles(sim, cfg);
    auto crusher = std::make_unique<Crusher>(cfg.crushing, SplitPattern::default14());
    crusher->begin(sim);
    return crusher;
  };
  Simulation a(cfg.simulation);
  auto ca = build(a);
  for (int k = 0; k < kNumWalls; ++k) {
    a.walls().config(k).mode = WallMode::Servo;
    a.walls().config(k).target_stress = 2e6;
    a.walls().config(k).max_speed = 2.0;
  }
  auto advance = [](Simulation& sim, Crusher& c, int n) {
    for (int s = 0; s < n; ++s) {
      sim.step(1);
      if (!c.apply(sim).empty()) sim.compute_forces();
    }
  };
  advance(a, *ca, 25000);
  ASSERT_GT(ca->breakages(BreakCause::Instant), 0u) << "nothing broke: the test is too gentle";

  StateWriter out;
  save_state(a, out);
  save_state(*ca, out);
  Simulation b(cfg.simulation);
  Crusher cb(cfg.crushing, SplitPattern::default14());
  StateReader in(out.bytes(), "memory");
  load_state(b, in);
  load_state(cb, in);
  EXPECT_TRUE(in.at_end());

  advance(a, *ca, 3000);
  advance(b, cb, 3000);
  const ParticleStore &pa = a.particles(), &pb = b.particles();
  ASSERT_EQ(pa.size(), pb.size());
  EXPECT_EQ(pa.id, pb.id);
  EXPECT_EQ(pa.x, pb.x);  // exact equality, every coordinate
  EXPECT_EQ(pa.y, pb.y);
  EXPECT_EQ(pa.z, pb.z);
  EXPECT_EQ(pa.wz, pb.wz);
  EXPECT_EQ(a.time(), b.time());
  EXPECT_EQ(a.walls().position(5), b.walls().position(5));
  EXPECT_EQ(ca->breakages(BreakCause::Instant), cb.breakages(BreakCause::Instant));
  EXPECT_EQ(ca->removed_volume(), cb.removed_volume());
  const std::size_t crack = ca->crack_field();
  // Bit for bit (grains that cannot crack hold NaN).
  const std::vector<double>&fa = pa.field(crack), &fb = pb.field(crack);
  ASSERT_EQ(fa.size(), fb.size());
  EXPECT_EQ(std::memcmp(fa.data(), fb.data(), fa.size() * sizeof(double)), 0);
  EXPECT_EQ(pa.wx, pb.wx);
  EXPECT_EQ(pa.wy, pb.wy);
}

TEST(Checkpoint, ASavedSimulationContinuesBitForBit) {
  expect_saved_simulation_continues_bit_for_bit(config(testing::TempDir("sim").path()));
}

TEST(Checkpoint, ASavedSimulationWithRollingResistanceContinuesBitForBit) {
  const RunConfig cfg = config(testing::TempDir("sim").path(), 0.2);
  ASSERT_EQ(cfg.simulation.contact.rolling_friction, 0.2);
  expect_saved_simulation_continues_bit_for_bit(cfg);
  // The rolling history is part of what was carried over: it is in use in such a run.
  Simulation sim(cfg.simulation);
  add_configured_particles(sim, cfg);
  for (int k = 0; k < kNumWalls; ++k) {
    sim.walls().config(k).mode = WallMode::Servo;
    sim.walls().config(k).target_stress = 2e6;
    sim.walls().config(k).max_speed = 2.0;
  }
  sim.step(5000);
  std::size_t loaded = 0;
  for (const ContactRecord& c : sim.contacts()) loaded += norm(c.M_r) > 0.0 ? 1 : 0;
  EXPECT_GT(loaded, 10u);
}

// A run stopped while it runs (as SIGINT does) and resumed writes the files of an uninterrupted
// one, byte for byte, on the backend `backend`.
void expect_stopped_run_resumes_exactly(const std::string& backend) {
  const testing::TempDir temp("run");
  const fs::path& base = temp.path();
  const RunConfig cfg = config(base);
  RunOptions opt;
  opt.progress = false;
  opt.backend = backend;
  opt.out_dir = (base / "whole").string();
  run_to_directory(cfg, opt);

  // The same run, asked to stop while it runs (as SIGINT does), then resumed.
  opt.out_dir = (base / "stopped").string();
  std::thread stopper([] {
    std::this_thread::sleep_for(std::chrono::milliseconds(400));
    request_stop(SIGINT);
  });
  bool interrupted = false;
  try {
    run_to_directory(cfg, opt);
  } catch (const Interrupted& e) {
    interrupted = true;
    EXPECT_EQ(e.signal(), SIGINT);
  }
  stopper.join();
  ASSERT_TRUE(interrupted) << "the run ended before the stop request: make it longer";
  ASSERT_TRUE(fs::exists(base / "stopped" / "checkpoint.bin"));
  ASSERT_FALSE(fs::exists(base / "stopped" / "summary.json"));
  // An interrupted run already says where its time went.
  EXPECT_NE(read_file(base / "stopped" / "timing.json").find("\"finished\": false"),
            std::string::npos);
  // A copy with one byte of its checkpoint changed (in the state, then in the checksum itself)
  // is refused and left as it was.
  for (const double where : {0.5, 1.0}) {
    const fs::path damaged = base / "damaged";
    fs::remove_all(damaged);
    fs::copy(base / "stopped", damaged, fs::copy_options::recursive);
    std::string bytes = read_file(damaged / "checkpoint.bin");
    const auto k = static_cast<std::size_t>(where * static_cast<double>(bytes.size() - 1));
    bytes[k] = static_cast<char>(bytes[k] ^ 0x10);
    std::ofstream(damaged / "checkpoint.bin", std::ios::binary) << bytes;
    try {
      resume_directory(damaged.string(), opt);
      ADD_FAILURE() << "resumed a checkpoint with byte " << k << " changed";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("damaged"), std::string::npos) << e.what();
      // The refusal is the log's last line.
      const std::string log = read_file(damaged / "run.log");
      const std::size_t last = log.rfind('\n', log.size() - 2);
      EXPECT_NE(log.find("error: resume refused: " + std::string(e.what()), last),
                std::string::npos)
          << log;
    }
    EXPECT_EQ(read_file(damaged / "checkpoint.bin"), bytes);
  }
  // A config.toml changed after the checkpoint is refused, naming the key and both values.
  {
    const fs::path changed = base / "changed";
    fs::remove_all(changed);
    fs::copy(base / "stopped", changed, fs::copy_options::recursive);
    std::string text = read_file(changed / "config.toml");
    const std::size_t k = text.find("n_break = 3\n");
    ASSERT_NE(k, std::string::npos) << text;
    text.replace(k, 11, "n_break = 4");
    std::ofstream(changed / "config.toml", std::ios::binary) << text;
    try {
      resume_directory(changed.string(), opt);
      ADD_FAILURE() << "resumed with a changed config.toml";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("stage[1].n_break = 4 (the checkpoint's: 3)"),
                std::string::npos)
          << e.what();
    }
  }
  // A result file changed after the checkpoint (one byte of a row it had written), or a
  // snapshot deleted: resume refuses (a ConfigError, exit status 2, for either), naming the
  // file, and changes nothing.
  std::string snapshot;
  for (const auto& e : fs::directory_iterator(base / "stopped" / "vtk")) {
    if (e.path().extension() == ".vtp") snapshot = "vtk/" + e.path().filename().string();
  }
  ASSERT_FALSE(snapshot.empty());
  for (const std::string& file : {std::string("timeseries.csv"), snapshot}) {
    const fs::path damaged = base / "damaged";
    fs::remove_all(damaged);
    fs::copy(base / "stopped", damaged, fs::copy_options::recursive);
    if (file == snapshot) {
      fs::remove(damaged / file);
    } else {
      std::string bytes = read_file(damaged / file);
      const std::size_t k = bytes.find('\n') + 3;  // in the first row
      bytes[k] = bytes[k] == '1' ? '2' : '1';
      std::ofstream(damaged / file, std::ios::binary) << bytes;
    }
    const std::string before = fs::exists(damaged / "timeseries.csv")
                                   ? read_file(damaged / "timeseries.csv")
                                   : std::string();
    try {
      resume_directory(damaged.string(), opt);
      ADD_FAILURE() << "resumed with " << file << " changed";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
    }
    EXPECT_EQ(read_file(damaged / "timeseries.csv"), before);
    EXPECT_TRUE(fs::exists(damaged / "checkpoint.bin"));
  }
  resume_directory((base / "stopped").string(), opt);
  EXPECT_FALSE(fs::exists(base / "stopped" / "checkpoint.bin")) << "kept after the run ended";

  const std::size_t compared = testing::expect_same_run_files(base / "whole", base / "stopped");
  // config, timeseries, summary, breakage, grading, events, phases and the snapshots.
  EXPECT_GE(compared, 9u);
  const std::string events = read_file(base / "whole" / "events.csv");
  EXPECT_GE(std::count(events.begin(), events.end(), '\n'), 3) << "too few dynamic phases";

  // timing.json: every second of both processes belongs to one part of the step.
  const std::string timing = read_file(base / "stopped" / "timing.json");
  double parts = 0.0;
  for (const std::string_view name : kPartNames) {
    const double s = json_number(timing, std::string(name));
    EXPECT_GE(s, 0.0) << name;
    parts += s;
  }
  EXPECT_NE(timing.find("\"finished\": true"), std::string::npos) << timing;
  const double wall = json_number(timing, "wall_seconds");
  EXPECT_NEAR(parts, wall, 0.05 * wall + 0.05) << timing;
  EXPECT_GT(json_number(timing, "contact_forces"), 0.0);
  EXPECT_GT(json_number(timing, "crushing"), 0.0);
  EXPECT_GT(json_number(timing, "ageing_jump"), 0.0);
  EXPECT_NE(timing.find("\"dominant_part\""), std::string::npos);
  EXPECT_NE(timing.find("\"backend\": \"" + backend + "\""), std::string::npos) << timing;
}

TEST(Checkpoint, AStoppedRunResumedWritesTheFilesOfAnUninterruptedOne) {
  expect_stopped_run_resumes_exactly("cpu");
}

// The device step (its host emulation here): sample preparation, stages, crushing, ageing and
// the checkpoint all go through the device copy and its syncs.
TEST(Checkpoint, AStoppedDeviceRunResumedWritesTheFilesOfAnUninterruptedOne) {
  expect_stopped_run_resumes_exactly("emulated");
}

// SIGTERM or SIGINT asks for a stop; the same signal delivered twice within kSameRequestMs (GNU
// timeout signals the process, then its group) is one request, not the second signal that ends
// the process at once; the other signal is another request; the same signal later ends it.
TEST(Checkpoint, ASignalRepeatedAtOnceIsOneStopRequest) {
  clear_stop_request();
  {
    const StopOnSignals on;
    std::raise(SIGTERM);
    std::raise(SIGTERM);
    EXPECT_EQ(stop_signal(), SIGTERM);
    std::this_thread::sleep_for(std::chrono::milliseconds(kSameRequestMs + 200));
    std::raise(SIGINT);  // a front end's SIGTERM after the terminal's Ctrl-C, say
    EXPECT_NE(stop_signal(), 0);
  }
  clear_stop_request();
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        const StopOnSignals on;
        std::raise(SIGTERM);
        std::this_thread::sleep_for(std::chrono::milliseconds(kSameRequestMs + 200));
        std::raise(SIGTERM);
        std::exit(0);
      },
      ::testing::KilledBySignal(SIGTERM), "");
}

// A state edited where no checksum can tell (the checksum recomputed, or a state handed over
// in memory): an index beyond the grains, two grains with one id, a grain outside the box or a
// NaN is refused with a RuntimeFailure when loaded, before any step reads it.
TEST(Checkpoint, ALoadedStateIsCheckedNotOnlyItsChecksum) {
  const testing::TempDir temp("invariants");
  const RunConfig cfg = config(temp.path());
  Simulation sim(cfg.simulation);
  add_configured_particles(sim, cfg);
  sim.step(50);
  const std::size_t n = sim.particles().size();
  StateWriter out;
  save_state(sim, out);
  const std::string good = out.bytes();
  // The bytes of an array as the state holds it (length, then the values), to find it there.
  const auto raw = [](const auto& v) {
    return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(v[0]));
  };
  const auto expect_refused = [&](const std::string& bytes, const std::string& what) {
    Simulation fresh(cfg.simulation);
    StateReader in(bytes, "edited");
    try {
      load_state(fresh, in);
      ADD_FAILURE() << "loaded a state with " << what;
    } catch (const RuntimeFailure& e) {
      EXPECT_NE(std::string(e.what()).find("checkpoint"), std::string::npos) << e.what();
    }
  };
  const auto edit = [&](const std::string& array, std::size_t k, const void* value,
                        std::size_t size) {
    std::string bytes = good;
    const std::size_t at = bytes.find(array);
    EXPECT_NE(at, std::string::npos);
    std::memcpy(bytes.data() + at + k * size, value, size);
    return bytes;
  };
  const auto& nl = sim.neighbors();
  ASSERT_GT(nl.neighbors.size(), 2u);
  const auto beyond = static_cast<NeighborList::Index>(n + 5);
  expect_refused(edit(raw(nl.neighbors), 1, &beyond, sizeof beyond), "a neighbour index");
  expect_refused(edit(raw(nl.offsets), 1, &beyond, sizeof beyond), "offsets");
  const ParticleId twin = sim.particles().id[0];
  expect_refused(edit(raw(sim.particles().id), 1, &twin, sizeof twin), "two grains, one id");
  const double far = 1.0, nan = std::nan("");
  expect_refused(edit(raw(sim.particles().x), 2, &far, sizeof far), "a grain outside the box");
  expect_refused(edit(raw(sim.particles().radius), 3, &nan, sizeof nan), "a NaN radius");
  // Edits of arrays whose bytes need not be unique in the state (zero velocities, say): the
  // simulation changed in memory, saved, and put back.
  const auto edited = [&](auto& value, auto bad) {
    const auto kept = value;
    value = bad;
    StateWriter w;
    save_state(sim, w);
    value = kept;
    return w.bytes();
  };
  expect_refused(edited(sim.particles().vy[4], nan), "a NaN velocity");
  // The wall contacts, read by grain through their offsets (CSR).
  WallContacts& wc = sim.wall_contacts();
  ASSERT_GT(wc.size(), 1u);
  expect_refused(edited(wc.offsets.back(), static_cast<std::uint32_t>(wc.size() + 3)),
                 "wall offsets");
  const std::uint32_t other = wc.particle[0] == 0 ? 1 : 0;
  expect_refused(edited(wc.particle[0], other), "a wall entry of another grain");
  expect_refused(edited(wc.delta[0], nan), "a NaN wall overlap");
  expect_refused(edited(wc.ft_y[1], nan), "a NaN wall history");
  // The unedited state loads.
  Simulation fresh(cfg.simulation);
  StateReader in(good, "good");
  EXPECT_NO_THROW(load_state(fresh, in));
}

TEST(Checkpoint, PartClockChargesEachSecondToOnePart) {
  PartClock c;
  {
    const PartScope outer(c, Part::Crushing);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    {
      const PartScope inner(c, Part::NeighborSearch);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  const auto s = c.seconds();
  const auto at = [&](Part p) { return s[static_cast<std::size_t>(p)]; };
  EXPECT_GE(at(Part::Crushing), 0.019);
  EXPECT_GE(at(Part::NeighborSearch), 0.019);
  // The nested rebuild is not charged to crushing as well.
  EXPECT_LT(at(Part::Crushing), at(Part::Crushing) + at(Part::NeighborSearch) - 0.015);
  EXPECT_EQ(at(Part::ContactForces), 0.0);
  c.add(s);
  EXPECT_GE(c.seconds()[static_cast<std::size_t>(Part::Crushing)], 2 * 0.019);
}

TEST(Checkpoint, ResumeRefusesAMissingOrFinishedRun) {
  const testing::TempDir temp("runs");
  const fs::path& base = temp.path();
  RunOptions opt;
  opt.progress = false;
  EXPECT_THROW(resume_directory((base / "nothing").string(), opt), ConfigError);
  // A finished run has no checkpoint left.
  RunConfig cfg = config(base);
  cfg.stages.resize(1);
  cfg.stages[0].steps = 200;
  opt.out_dir = (base / "done").string();
  run_to_directory(cfg, opt);
  const std::string log = read_file(base / "done" / "run.log");
  try {
    resume_directory(opt.out_dir, opt);
    ADD_FAILURE() << "resumed a finished run";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("finished"), std::string::npos) << e.what();
  }
  EXPECT_EQ(read_file(base / "done" / "run.log"), log) << "a finished run's log changed";
}

// The builds that ran a run: listed once per change in the checkpoint and summary.json; a
// resume or branch by another build says so in run.log and counts as a warning.
TEST(Checkpoint, ARunContinuedByAnotherBuildSaysSoAndListsEveryBuild) {
  std::vector<std::string> builds;
  EXPECT_EQ(note_build(builds, "0.1.0 (a)", "resumed"), "");  // the run's first build
  EXPECT_EQ(note_build(builds, "0.1.0 (a)", "resumed"), "");
  EXPECT_EQ(builds, std::vector<std::string>{"0.1.0 (a)"});
  const std::string w = note_build(builds, "0.2.0 (b)", "branched");
  EXPECT_NE(w.find("branched by crushdem 0.2.0 (b)"), std::string::npos) << w;
  EXPECT_NE(w.find("run so far by 0.1.0 (a)"), std::string::npos) << w;
  EXPECT_EQ(builds, (std::vector<std::string>{"0.1.0 (a)", "0.2.0 (b)"}));

  const testing::TempDir temp("builds");
  const fs::path& base = temp.path();
  RunConfig cfg = config(base);
  cfg.stages.resize(1);
  cfg.stages[0].steps = 200;
  RunOptions opt;
  opt.progress = false;
  opt.out_dir = (base / "first").string();
  run_to_directory(cfg, opt);
  const std::string summary = read_file(base / "first" / "summary.json");
  EXPECT_NE(summary.find("\"crushdem_builds\": [\"" + this_build() + "\"]"), std::string::npos)
      << summary;
  // Branched from its first stage by a stand-in for another build, then by this one again.
  const std::array<std::pair<const char*, const char*>, 2> branches = {
      {{"other", "first"}, {"again", "other"}}};
  for (const auto& [out, from] : branches) {
    RunOptions b = opt;
    b.out_dir = (base / out).string();
    b.branch_dir = (base / from).string();
    b.branch_stage = "0";
    b.build = std::string(out) == "other" ? "9.9.9 (another)" : "";
    run_to_directory(cfg, b);
  }
  const std::string log = read_file(base / "other" / "run.log");
  EXPECT_NE(log.find("branch with crushdem 9.9.9 (another)"), std::string::npos) << log;
  EXPECT_NE(log.find("warning: this run is branched by crushdem 9.9.9 (another); it was run so "
                     "far by " +
                     this_build()),
            std::string::npos)
      << log;
  const std::string other = read_file(base / "other" / "summary.json");
  EXPECT_NE(other.find("\"crushdem_builds\": [\"" + this_build() + "\", \"9.9.9 (another)\"]"),
            std::string::npos)
      << other;
  EXPECT_EQ(testing::json_number(other, "warnings"),
            testing::json_number(summary, "warnings") + 1.0);
  // The state "again" starts from, "other"'s first stage boundary, was saved before "other"
  // took a step: it is this build's alone, so "again" is this build's run, as "first" is.
  EXPECT_EQ(read_file(base / "again" / "run.log").find("warning: this run is branched"),
            std::string::npos);
  EXPECT_NE(read_file(base / "again" / "summary.json")
                .find("\"crushdem_builds\": [\"" + this_build() + "\"]"),
            std::string::npos);
  EXPECT_EQ(read_file(base / "first" / "timeseries.csv"),
            read_file(base / "again" / "timeseries.csv"));
}

}  // namespace
}  // namespace crushdem
