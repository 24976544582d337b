// A chamber sample (docs/chamber.md): a cylinder of grains prepared in its chamber to a void
// ratio and stress (the chamber's servo on its lateral surface between the platens, the platens'
// on its cross-section), the void ratio from the chamber's volume; a cone lowered to the top
// and pushed in while the chamber holds its stress; the run stopped during the penetration and
// resumed writes the files of an uninterrupted one byte for byte; bad input names its key.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "crushdem/experiments/protocol.hpp"
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

// `text` with `line` inserted after the first `after` (a key added to a table).
std::string with_line_after(std::string text, const std::string& after, const std::string& line) {
  text.replace(text.find(after), after.size(), after + line);
  return text;
}

TEST(Chamber, ACylinderIsPreparedInItsChamberAndAConeIsPushedInAndResumedExactly) {
  const testing::TempDir temp("chamber");
  const fs::path& base = temp.path();
  const RunConfig cfg = config(testing::test_data("chamber_400.toml"));
  RunOptions opt;
  opt.progress = false;
  opt.out_dir = (base / "whole").string();
  run_to_directory(cfg, opt);

  // The prepared sample: every servo at 100 kPa within the tolerance, the void ratio from the
  // chamber's volume pi R^2 H, every grain inside the chamber.
  auto prep = testing::read_csv((base / "whole" / "preparation.csv").string());
  const double R = 0.5 * cfg.sample.cube_side();  // at the target (the loose cloud's is larger)
  const double R_end = [&] {
    const Packing pk = read_packing((base / "whole" / "sample.txt").string());
    return std::stod(pk.header.at("chamber_radius"));
  }();
  EXPECT_NEAR(R_end / R, 1.0, 0.02);
  for (const char* col : {"body_chamber_stress_Pa", "wall_zmin_stress_Pa", "wall_zmax_stress_Pa"}) {
    EXPECT_NEAR(prep[col].back() / 1e5, 1.0, 0.01) << col;
  }
  const Packing pk = read_packing((base / "whole" / "sample.txt").string());
  double Vs = 0.0, outside = 0.0;
  for (const PackingRow& row : pk.rows) {
    const double r = 0.5 * row.diameter;
    Vs += 4.0 / 3.0 * kPi * r * r * r;
    outside = std::max(outside, std::hypot(row.position.x, row.position.y) + r - R_end);
  }
  EXPECT_LT(outside, 1e-2 * R_end) << "a grain beyond the chamber's wall (more than an overlap)";
  const double H = std::stod(pk.header.at("box_zmax")) - std::stod(pk.header.at("box_zmin"));
  const double e = (kPi * R_end * R_end * H - Vs) / Vs;
  EXPECT_NEAR(e, std::stod(pk.header.at("void_ratio")), 1e-9);
  EXPECT_NEAR(e, 0.75, cfg.sample.tolerance);

  // The cone: its tip lowered to the top platen at the start, q_c zero until it meets the
  // grains, positive in them; the chamber held at its stress by its servo meanwhile.
  auto pen = testing::read_csv((base / "whole" / "penetration.csv").string());
  ASSERT_GT(pen["travel_m"].size(), 20u);
  EXPECT_EQ(pen["tip_z_m"].front(), pen["wall_zmax_position_m"].front());
  EXPECT_EQ(pen["q_c_Pa"].front(), 0.0);
  EXPECT_GT(pen["q_c_Pa"].back(), 1e5);
  EXPECT_GE(pen["travel_m"].back(), 0.4e-3 * (1.0 - 1e-12));

  // Stopped as the cone starts (as SIGINT does), then resumed: the same files.
  EXPECT_GE(testing::expect_stopped_run_resumes_exactly(cfg, opt, base / "whole", base / "stopped",
                                                        "penetration.csv"),
            7u);
}

TEST(Chamber, AQuarterBetweenSymmetryPlanesIsPreparedAndPenetratedOnItsAxis) {
  // The sample of chamber_400.toml as a quarter (sector = 90): 400 grains in the quadrant
  // x, y > 0 between the frictionless planes x = 0 and y = 0, the cone on the z axis.
  std::string text = with_line_after(testing::test_data("chamber_400.toml"),
                                     "shape = \"cylinder\"\n", "sector = 90.0\n");
  const RunConfig cfg = config(text);
  const testing::TempDir temp("chamber");
  RunOptions opt;
  opt.progress = false;
  opt.out_dir = (temp.path() / "run").string();
  run_to_directory(cfg, opt);
  const Packing pk = read_packing((temp.path() / "run" / "sample.txt").string());
  const double R = std::stod(pk.header.at("chamber_radius"));
  EXPECT_EQ(pk.header.at("sector"), "90");  // read back by a test, the planes are rebuilt
  const double H = std::stod(pk.header.at("box_zmax")) - std::stod(pk.header.at("box_zmin"));
  double Vs = 0.0, beyond = 0.0;
  for (const PackingRow& row : pk.rows) {
    const double r = 0.5 * row.diameter;
    Vs += 4.0 / 3.0 * kPi * r * r * r;
    beyond = std::max({beyond, r - row.position.x, r - row.position.y,
                       std::hypot(row.position.x, row.position.y) + r - R});
  }
  EXPECT_LT(beyond, 1e-2 * R) << "a grain beyond a symmetry plane or the chamber";
  // The void ratio from the quarter's volume pi R^2 H / 4.
  EXPECT_NEAR((0.25 * kPi * R * R * H - Vs) / Vs, std::stod(pk.header.at("void_ratio")), 1e-9);
  // The servos' stresses on the quarter's areas agree with the grains' own (Love) mean stress,
  // which takes the quarter's volume: a wrong area would put them a factor apart.
  auto prep = testing::read_csv((temp.path() / "run" / "preparation.csv").string());
  EXPECT_NEAR(prep["love_mean_stress_Pa"].back() / prep["mean_stress_Pa"].back(), 1.0, 0.02);
  EXPECT_NEAR(prep["body_chamber_stress_Pa"].back() / 1e5, 1.0, 0.01);
  // The planes' stress, their load over the half-plane R H: the hoop stress, near the radial one
  // in a sample prepared isotropically.
  for (const char* plane : {"body_symmetry_x_stress_Pa", "body_symmetry_y_stress_Pa"}) {
    EXPECT_NEAR(prep[plane].back() / 1e5, 1.0, 0.05) << plane;
  }
  auto pen = testing::read_csv((temp.path() / "run" / "penetration.csv").string());
  EXPECT_EQ(pen["q_c_Pa"].front(), 0.0);
  EXPECT_GT(pen["q_c_Pa"].back(), 1e5);
  // Read back, a quarter's file without its sector line (as files written before it had one)
  // is refused: it would be taken for a full chamber.
  {
    std::string file = testing::read_file(temp.path() / "run" / "sample.txt");
    const std::string line = "# sector=90\n";
    file.erase(file.find(line), line.size());
    const fs::path old_file = temp.path() / "old_sample.txt";
    std::ofstream(old_file) << file;
    try {
      config("[particles]\nfile = \"" + old_file.string() + "\"\n[run]\nsteps = 1\n");
      ADD_FAILURE() << "a quarter without its sector was read as a full chamber";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("sector=90"), std::string::npos) << e.what();
    }
  }
  // A cone off the axis of a sector is refused with the configuration.
  text.replace(text.find("origin = [0.0, 0.0, 0.01]"), 25, "origin = [1e-4, 0.0, 0.01]");
  opt.out_dir = (temp.path() / "off_axis").string();
  try {
    run_to_directory(config(text), opt);
    ADD_FAILURE() << "a cone off the axis of a quarter ran";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("body[0].origin"), std::string::npos) << e.what();
  }
}

TEST(Chamber, AChamberSampleFromItsFileRestsUnderGravityWithItsWeightOnTheBase) {
  // A chamber sample prepared without gravity (400 grains, e = 0.75, 20 kPa), then read back by
  // a test (particles.file: the chamber rebuilt at the file's chamber_radius) and held at rest
  // under 1,000 g (a centrifuge model's gravity, so that the weight W is comparable with the
  // platens' loads), the chamber fixed (no lateral strain) and the top platen at 20 kPa. With
  // the force F_z of the grains on the chamber's wall, the base carries
  //   N_bottom = N_top + W + F_z,
  // all of W without wall friction (F_z = 0); with it the wall takes a share (a silo's). The
  // hold's stress profile (profile_bins) balances the same forces slice by slice.
  const testing::TempDir temp("chamber_gravity");
  RunOptions opt;
  opt.progress = false;
  opt.out_dir = (temp.path() / "sample").string();
  run_to_directory(config("[contact]\nrotation = \"blocked\"\n[sample]\nshape = \"cylinder\"\n"
                          "count = 400\nvoid_ratio = 0.75\nstress = 20e3\nseed = 4\n"),
                   opt);
  const std::string file = (temp.path() / "sample" / "sample.txt").string();
  const Packing pk = read_packing(file);
  const double R = pk.header_number("chamber_radius", file);
  double W = 0.0;
  for (const PackingRow& row : pk.rows) {
    W += 2650.0 * kPi / 6.0 * std::pow(row.diameter, 3) * 9810.0;
  }
  double rise[2] = {0.0, 0.0};  // sigma_zz's rise from the top slice to the bottom one
  for (const double mu_w : {0.0, 0.275}) {
    const std::string text =
        "[gravity]\ng = [0.0, 0.0, -9810.0]\n[contact]\nrotation = \"blocked\"\nwall_friction = " +
        std::to_string(mu_w) + "\n[particles]\nfile = \"" + file +
        "\"\n[[stage]]\ntype = \"hold\"\naxial = \"servo\"\naxial_stress = 20e3\nlateral = "
        "\"fixed\"\nsteps = 50000\nmax_strain_rate = 100.0\nprofile_bins = 4\n"
        "profile_radius = 1.0\n[output]\ninterval = 2000\nprogress_seconds = 0\n";
    opt.out_dir = (temp.path() / ("rest_" + std::to_string(mu_w))).string();
    run_to_directory(config(text), opt);
    auto ts = testing::read_csv(opt.out_dir + "/timeseries.csv");
    // The file's chamber: its radius, its stress and the sample's void ratio at the start.
    EXPECT_EQ(ts["body_chamber_position_m"].front(), 0.0);
    EXPECT_NEAR(ts["body_chamber_stress_Pa"].front() / 20e3, 1.0, 0.01);
    EXPECT_NEAR(ts["void_ratio"].front(), pk.header_number("void_ratio", file), 1e-9);
    const double A = kPi * R * R;
    const double N_bottom = ts["wall_zmin_stress_Pa"].back() * A;
    const double N_top = ts["wall_zmax_stress_Pa"].back() * A;
    const double F_z = ts["body_chamber_force_z_N"].back();
    EXPECT_LT(ts["unbalanced_force_ratio"].back(), 1e-3) << "mu_w " << mu_w;
    EXPECT_NEAR((N_bottom - N_top - F_z) / W, 1.0, 0.01) << "mu_w " << mu_w;
    if (mu_w == 0.0) {
      EXPECT_EQ(F_z, 0.0);
    } else {
      EXPECT_LT(F_z, -0.1 * W) << "the rough wall carries none of the weight";
    }
    // The stress profile at the hold's end, over the whole section (profile_radius = 1): four
    // slices from the bottom platen up. The Love-Weber sum over every grain balances the
    // boundary's forces and the weight's moment (at rest, no inertia):
    //   sum_s sigma_zz(s) V_s = N_top H - F_z,wall z_wall + W (z_g - z_bottom),
    // which for a frictionless wall is N_top H + W (z_g - z_bottom), z_g the grains' centre of
    // mass: about N_top H + W H / 2.
    auto prof = testing::read_csv(opt.out_dir + "/stress_profile.csv");
    ASSERT_EQ(prof["bin"].size(), 4u);
    const double H = ts["wall_zmax_position_m"].back() - ts["wall_zmin_position_m"].back();
    double sum = 0.0;
    for (std::size_t s = 0; s < 4; ++s) {
      sum += prof["sigma_zz_Pa"][s] * A * H / 4.0;
      EXPECT_NEAR(prof["depth_m"][s], H * (1.0 - (s + 0.5) / 4.0), 1e-12 * H);
      EXPECT_NEAR(prof["K"][s], prof["sigma_rr_Pa"][s] / prof["sigma_zz_Pa"][s], 1e-12);
    }
    // (measured: 0.5 % of W H / 2 from the estimate with z_g at mid-height)
    if (mu_w == 0.0) {
      EXPECT_NEAR(sum, N_top * H + W * H / 2.0, 0.03 * W * H / 2.0);
    }
    // The vertical stress grows with depth, and far less where the rough wall takes the weight
    // (Janssen's silo; measured: 16.5 kPa from the top slice to the bottom one without wall
    // friction, 2.6 kPa with it).
    rise[mu_w == 0.0 ? 0 : 1] = prof["sigma_zz_Pa"][0] - prof["sigma_zz_Pa"][3];
    if (mu_w == 0.0) {
      for (std::size_t s = 1; s < 4; ++s) {
        EXPECT_LT(prof["sigma_zz_Pa"][s], prof["sigma_zz_Pa"][s - 1]) << "slice " << s;
      }
    }
  }
  EXPECT_GT(rise[0], 0.5 * W / (kPi * R * R));
  EXPECT_LT(rise[1], 0.5 * rise[0]);

  // On a device the profile reads the grains brought back at the check that ends the hold (not
  // at every check): the emulation (the GPU's step) writes the CPU's profile to the order of
  // its sums. The weight is still loading the grains when the hold ends, so a profile of the
  // state at the hold's start would differ by far more.
  std::map<std::string, std::vector<double>> sigma_zz;
  for (const std::string backend : {"cpu", "emulated"}) {
    opt.backend = backend;
    opt.out_dir = (temp.path() / ("short_" + backend)).string();
    run_to_directory(config("[gravity]\ng = [0.0, 0.0, -9810.0]\n[contact]\nrotation = "
                            "\"blocked\"\n[particles]\nfile = \"" +
                            file +
                            "\"\n[[stage]]\ntype = \"hold\"\naxial = \"fixed\"\nlateral = "
                            "\"fixed\"\nsteps = 3000\nprofile_bins = 4\nprofile_radius = 1.0\n"
                            "[output]\ninterval = 1000000\nprogress_seconds = 0\n"),
                     opt);
    sigma_zz[backend] = testing::read_csv(opt.out_dir + "/stress_profile.csv")["sigma_zz_Pa"];
  }
  ASSERT_EQ(sigma_zz["emulated"].size(), 4u);
  for (std::size_t s = 0; s < 4; ++s) {
    EXPECT_NEAR(sigma_zz["emulated"][s] / sigma_zz["cpu"][s], 1.0, 1e-6) << "slice " << s;
  }
  EXPECT_GT(sigma_zz["cpu"][0] - sigma_zz["cpu"][3], 0.05 * W / (kPi * R * R));
}

// A symmetry plane's stress is over the part of it the grains press on: from the axis to the
// chamber in a quarter, across the whole diameter in a half.
TEST(Chamber, ASymmetryPlanesAreaIsWhereTheGrainsPressOnIt) {
  for (const double sector : {90.0, 180.0}) {
    SampleConfig sc;
    sc.shape = SampleShape::Cylinder;
    sc.sector = sector;
    sc.count = 50;
    const LooseCloud cloud = make_loose_cloud(sc, false);
    SimulationConfig sim_cfg;
    sim_cfg.walls[5].position = cloud.height;
    for (const BodyConfig& b : chamber_sample_bodies(cloud, 0.0)) sim_cfg.bodies.push_back(b);
    const Walls w(sim_cfg.walls, 0.0, [&] {
      std::vector<Body> bodies;
      for (const BodyConfig& b : sim_cfg.bodies) bodies.push_back(b.make(0.0));
      return bodies;
    }());
    const double R = w.chamber_radius(), H = cloud.height;
    const int planes = sector == 90.0 ? 2 : 1;
    ASSERT_EQ(w.size(), kNumWalls + 1 + planes);
    for (int k = w.size() - planes; k < w.size(); ++k) {
      EXPECT_DOUBLE_EQ(w.area(k), (sector == 90.0 ? 1.0 : 2.0) * R * H) << sector << " " << k;
    }
  }
}

TEST(Chamber, AffineCompactionCarriesTheCloudWithItsWallsThenPreparesTheSample) {
  // follow_walls: the velocity of the walls' homogeneous deformation at every grain of a loose
  // quarter cloud, radial about the chamber's axis in proportion to the radius and linear
  // between the platens: the chamber's wall and the platens, where the grains touch them,
  // move as fast as they do, so that the cloud contracts without being swept.
  SampleConfig sc;
  sc.shape = SampleShape::Cylinder;
  sc.sector = 90.0;
  sc.count = 300;
  const LooseCloud cloud = make_loose_cloud(sc);
  SimulationConfig sim_cfg;
  sim_cfg.walls[4].position = 0.0;
  sim_cfg.walls[5].position = cloud.height;
  for (int a = 0; a < 2; ++a) {
    sim_cfg.walls[static_cast<std::size_t>(2 * a)].position = -cloud.side;
    sim_cfg.walls[static_cast<std::size_t>(2 * a + 1)].position = cloud.side;
  }
  sim_cfg.bodies.push_back(chamber_body(cloud));
  for (const BodyConfig& plane : symmetry_planes(cloud)) sim_cfg.bodies.push_back(plane);
  Simulation sim(sim_cfg);
  for (std::size_t i = 0; i < cloud.radius.size(); ++i) {
    sim.add_particle(cloud.position[i], cloud.radius[i], {1.0, 2.0, 3.0});
  }
  Walls& w = sim.walls();
  ASSERT_GE(w.chamber(), 0);
  const double R = w.chamber_radius(), H = w.length(2);
  w.state(w.chamber()).velocity = -0.2;  // dR/dt
  w.state(4).velocity = 0.1;
  w.state(5).velocity = -0.3;
  follow_walls(sim);
  const ParticleStore& p = sim.particles();
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double r = std::hypot(p.x[i], p.y[i]);
    const double v_r = (p.vx[i] * p.x[i] + p.vy[i] * p.y[i]) / r;
    EXPECT_NEAR(v_r, -0.2 * r / R, 1e-15) << i;
    EXPECT_NEAR(p.vx[i] * p.y[i] - p.vy[i] * p.x[i], 0.0, 1e-15) << i;  // no swirl
    EXPECT_NEAR(p.vz[i], 0.1 + (p.z[i] / H) * (-0.3 - 0.1), 1e-15) << i;
    EXPECT_EQ(p.wx[i], 0.0);
  }

  // The preparation: the grains follow the walls (phase 3) until the walls carry
  // affine_release of the stress, then the walls finish as in the walls' compaction, to the
  // same target; on the emulation (the device's step), whose grains the controller changes on
  // the host, to the CPU's void ratio within the preparation's tolerance.
  std::string walls_text = testing::test_data("chamber_400.toml");
  walls_text.erase(walls_text.find("[[stage]]"),
                   walls_text.find("[output]") - walls_text.find("[[stage]]"));
  const RunConfig cfg =
      config(with_line_after(walls_text, "seed = 4\n", "compaction = \"affine\"\n"));
  const testing::TempDir temp("chamber_affine");
  RunOptions opt;
  opt.progress = false;
  std::map<std::string, double> e_end;
  std::map<std::string, std::map<std::string, std::vector<double>>> ts;
  for (const std::string run : {"cpu", "emulated", "walls"}) {
    opt.backend = run == "emulated" ? "emulated" : "cpu";
    opt.out_dir = (temp.path() / run).string();
    run_to_directory(run == "walls" ? config(walls_text) : cfg, opt);
    ts[run] = testing::read_csv(opt.out_dir + "/timeseries.csv");
    auto& t = ts[run];
    for (const char* col :
         {"body_chamber_stress_Pa", "wall_zmin_stress_Pa", "wall_zmax_stress_Pa"}) {
      EXPECT_NEAR(t[col].back() / 1e5, 1.0, 0.01) << run << " " << col;
    }
    const Packing pk = read_packing(opt.out_dir + "/sample.txt");
    e_end[run] = std::stod(pk.header.at("void_ratio"));
    EXPECT_NEAR(e_end[run], 0.75, cfg.sample.tolerance) << run;
    if (run == "walls") continue;
    // Following the walls for more than one check, the release at a tenth of the stress (the
    // checks every 1,000 steps, the rows every 2,000).
    ASSERT_GT(t["phase"].size(), 3u);
    EXPECT_EQ(t["phase"][0], 3.0) << run;
    EXPECT_EQ(t["phase"][1], 3.0) << run;
    EXPECT_NE(t["phase"].back(), 3.0) << run;
  }
  EXPECT_NEAR(e_end["emulated"], e_end["cpu"], cfg.sample.tolerance);
  // In the first rows the walls sweeping the cloud press on the grains they meet (measured:
  // 0.6 to 5 kPa), while the walls the affine cloud follows carry almost nothing (0.2 to 81 Pa).
  double swept = 0.0, followed = 0.0;
  for (std::size_t r = 1; r <= 3; ++r) {
    swept += ts["walls"]["mean_stress_Pa"][r];
    followed += ts["cpu"]["mean_stress_Pa"][r];
  }
  EXPECT_LT(followed, 0.1 * swept);
  // The affine run's config.toml names the key; the walls run's has no such line.
  EXPECT_NE(testing::read_file(temp.path() / "cpu" / "config.toml").find("compaction ="),
            std::string::npos);
  EXPECT_EQ(testing::read_file(temp.path() / "walls" / "config.toml").find("compaction ="),
            std::string::npos);
}

TEST(Chamber, BadChambersAreRefusedNamingTheKey) {
  const std::string sample = "[sample]\nshape = \"cylinder\"\ncount = 400\nvoid_ratio = 0.8\n";
  // (the configuration, the key its error must name)
  const std::pair<std::string, std::string> cases[] = {
      {sample + "[[body]]\nname = \"chamber\"\nshape = \"disk\"\nradius = 1e-3\n", "body[0].name"},
      {sample + "height_ratio = 10.0\n", "sample.height_ratio"},
      {"[sample]\nshape = \"sphere\"\n", "sample.shape"},
      {sample + "sector = 45.0\n", "sample.sector"},
      {"[sample]\nsector = 90.0\n", "sample.sector"},  // a cube has none
      {sample + "[[body]]\nname = \"symmetry_x\"\n", "body[0].name"},
      {"[sample]\nshape = \"cylinder\"\ncount = 100\nvoid_ratio = 0.9\n",
       "sample.count"},  // under 5 grains wide
  };
  for (const auto& [text, key] : cases) {
    std::string error;
    try {
      config(text);
    } catch (const ConfigError& e) {
      error = e.what();
    }
    EXPECT_NE(error.find(key), std::string::npos) << text << " -> " << error;
  }
}

}  // namespace
}  // namespace crushdem
