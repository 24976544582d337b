// Rigid bodies of any shape (walls/body_geometry.hpp, walls/body_config.hpp): a grain pressed
// against a curved surface carries Hertz's force for the surface's curvatures, checked against
// the exact elliptical solution (Johnson, Contact Mechanics, 1985, 4.2); the shapes' distances
// and normals; a pile's tip and shaft as one body; servo and prescribed motions; and the
// configuration's errors naming the key.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>

#include "crushdem/experiments/measurements.hpp"
#include "crushdem/io/config.hpp"
#include "crushdem/io/toml.hpp"
#include "crushdem/walls/body_probe.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

// Hertz's force for a contact with relative curvatures A <= B (the gap between the surfaces is
// A x^2 + B y^2) at approach delta, from the elliptical solution: the eccentricity e of the
// contact ellipse solves B/A = ((a/b)^2 E(e) - K(e)) / (K(e) - E(e)), then
// delta = p0 b K(e) / E*, A = p0 b (K(e) - E(e)) / (E* e^2 a^2) and P = (2/3) pi a b p0.
double elliptical_hertz_force(double A, double B, double delta, double E_star) {
  const auto ratio = [](double e) {
    const double K = std::comp_ellint_1(e), E = std::comp_ellint_2(e);
    return (E / (1.0 - e * e) - K) / (K - E);
  };
  double lo = 1e-9, hi = 1.0 - 1e-15;  // ratio(e) grows from 1 with e
  for (int k = 0; k < 200; ++k) {
    const double mid = 0.5 * (lo + hi);
    (ratio(mid) < B / A ? lo : hi) = mid;
  }
  const double e = 0.5 * (lo + hi);
  const double K = std::comp_ellint_1(e), E = std::comp_ellint_2(e);
  const double a = std::sqrt(delta * (K - E) / (A * K * e * e));
  const double b = a * std::sqrt(1.0 - e * e);
  const double p0 = delta * E_star / (b * K);
  return 2.0 / 3.0 * kPi * a * b * p0;
}

// A large box of fixed walls around the origin, Hertz contacts without friction or damping,
// and the given [[body]] tables.
SimulationConfig body_config(const std::string& bodies) {
  const std::string text =
      "[contact]\nlaw = \"hertz\"\n[damping]\nlocal_alpha = 0.0\n"
      "[box]\nmin = [-0.02, -0.02, -0.02]\nmax = [0.02, 0.02, 0.02]\n" +
      bodies;
  return simulation_config_from_toml(toml::parse(text, "bodies.toml"), "bodies.toml");
}

// The force on one grain of radius r at c (a single contact with a body).
Vec3 force_on_grain(const SimulationConfig& cfg, Vec3 c, double r) {
  Simulation sim(cfg);
  sim.add_particle(c, r);
  sim.compute_forces();
  return {sim.resultant_force(0)[0], sim.resultant_force(1)[0], sim.resultant_force(2)[0]};
}

TEST(Bodies, AGrainInsideACylinderCarriesHertzForceForTheConcaveSurface) {
  const double Rc = 5e-3, r = 0.1e-3, delta = 2e-7;
  const SimulationConfig cfg = body_config(
      "[[body]]\nname = \"chamber\"\nshape = \"cylinder_inside\"\norigin = [0, 0, -0.01]\n"
      "radius = 5e-3\nlength = 0.02\n");
  // On the x axis, pressed outwards by delta.
  const Vec3 F = force_on_grain(cfg, {Rc - r + delta, 0.0, 0.0}, r);
  const double E_star = cfg.material.E_star();
  const double R1 = 1.0 / (1.0 / r - 1.0 / Rc), R2 = r;  // around, along the axis
  const double exact = elliptical_hertz_force(0.5 / R1, 0.5 / R2, delta, E_star);
  EXPECT_NEAR(-F.x / exact, 1.0, 1e-6);  // towards the axis
  EXPECT_EQ(F.y, 0.0);
  EXPECT_EQ(F.z, 0.0);
  // The curvature matters: a plane at the same overlap carries less.
  const double plane = 4.0 / 3.0 * E_star * std::sqrt(r) * std::pow(delta, 1.5);
  EXPECT_GT(-F.x / plane - 1.0, 5e-3);
}

TEST(Bodies, AGrainOnAConeCarriesHertzForceForTheConvexSurface) {
  const double alpha = 30.0 * kPi / 180.0, R = 2e-3, r = 0.1e-3, delta = 3e-7;
  const SimulationConfig cfg = body_config(
      "[[body]]\nname = \"tip\"\nshape = \"cone\"\norigin = [0, 0, 0]\naxis = [0, 0, 1]\n"
      "radius = 2e-3\nhalf_angle = 30.0\n");
  // A grain beside the generator at height t along it: its centre lies r - delta off the
  // surface along the outward normal.
  const double t = 2.5e-3;  // along the generator from the apex (slant height 4 mm)
  const Vec3 surface{t * std::sin(alpha), 0.0, t * std::cos(alpha)};
  const Vec3 outward{std::cos(alpha), 0.0, -std::sin(alpha)};
  const Vec3 F = force_on_grain(cfg, surface + (r - delta) * outward, r);
  const double E_star = cfg.material.E_star();
  const double local = t * std::sin(alpha);
  const double R1 = 1.0 / (1.0 / r + std::cos(alpha) / local), R2 = r;
  EXPECT_NEAR(dot(F, outward) / norm(F), 1.0, 1e-12);  // along the outward normal
  const double exact = elliptical_hertz_force(0.5 / R2, 0.5 / R1, delta, E_star);
  EXPECT_NEAR(norm(F) / exact, 1.0, 1e-6);
  EXPECT_GT(R, t * std::sin(alpha));  // the point lies on the cone's flank
}

TEST(Bodies, AGrainOutsideACylinderCarriesHertzForceForTheConvexSurface) {
  const double Rc = 1e-3, r = 0.1e-3, delta = 2e-7;
  const SimulationConfig cfg = body_config(
      "[[body]]\nname = \"rod\"\nshape = \"cylinder_outside\"\norigin = [0, 0, -0.01]\n"
      "radius = 1e-3\nlength = 0.02\n");
  const Vec3 F = force_on_grain(cfg, {0.0, Rc + r - delta, 0.0}, r);
  const double E_star = cfg.material.E_star();
  const double R1 = 1.0 / (1.0 / r + 1.0 / Rc), R2 = r;
  const double exact = elliptical_hertz_force(0.5 / R2, 0.5 / R1, delta, E_star);
  EXPECT_NEAR(F.y / exact, 1.0, 1e-6);
  EXPECT_EQ(F.x, 0.0);
}

// The ellipse factor against the elliptic integrals over the ratios it is fitted on, and the
// sphere's limit.
TEST(Bodies, TheEllipseFactorFollowsHertzsEllipticalSolution) {
  EXPECT_EQ(hertz_ellipse_factor(1.0, 1.0), 1.0);
  for (double ratio : {1.001, 1.01, 1.1, 1.5, 2.0, 3.0, 5.0, 8.0, 10.0}) {
    const double R1 = ratio, R2 = 1.0, delta = 1e-6, E_star = 1e10;
    const double exact = elliptical_hertz_force(0.5 / R1, 0.5 / R2, delta, E_star);
    const double R_star = hertz_ellipse_factor(R1, R2) * std::sqrt(R1 * R2);
    const double fitted = 4.0 / 3.0 * E_star * std::sqrt(R_star) * std::pow(delta, 1.5);
    EXPECT_NEAR(fitted / exact, 1.0, 1e-7) << "R'/R'' = " << ratio;
    EXPECT_EQ(hertz_ellipse_factor(R1, R2), hertz_ellipse_factor(R2, R1));
  }
}

TEST(Bodies, APileTouchesAGrainOnceAtTheJunctionOfTipAndShaft) {
  // A pile of radius 1 mm with a 60 degree cone: the tip ends 1.732 mm above its apex. A grain
  // just outside the junction is nearer one part than the other; the body gives one contact.
  const SimulationConfig cfg = body_config(
      "[[body]]\nname = \"pile\"\nshape = \"pile\"\norigin = [0, 0, -5e-3]\naxis = [0, 0, 1]\n"
      "radius = 1e-3\nlength = 8e-3\nhalf_angle = 30.0\n");
  Simulation sim(cfg);
  const double r = 0.1e-3, h = 1e-3 / std::tan(kPi / 6.0);
  sim.add_particle({1e-3 + r - 1e-7, 0.0, -5e-3 + h + 0.02e-3}, r);
  sim.compute_forces();
  int touching = 0;
  for (const ContactRecord& c : sim.contacts()) touching += c.is_wall ? 1 : 0;
  EXPECT_EQ(touching, 1);
  // The surface a grain sees: the shaft above the junction, the cone below, the apex beneath.
  const Walls& w = sim.walls();
  const int pile = kNumWalls;
  EXPECT_NEAR(w.surface(pile, {3e-3, 0.0, 0.0}).dist, 2e-3, 1e-15);
  EXPECT_NEAR(w.surface(pile, {0.0, 0.0, -6e-3}).dist, 1e-3, 1e-15);
  const SurfacePoint side = w.surface(pile, {2e-3, 0.0, -5e-3 + 0.5 * h});
  EXPECT_NEAR(side.n.x, -std::cos(kPi / 6.0), 1e-12);
  EXPECT_NEAR(side.n.z, std::sin(kPi / 6.0), 1e-12);
}

TEST(Bodies, AGrainOutsideTheJunctionOfTipAndShaftTouchesItsRim) {
  // Outside the convex junction of the cone and the shaft lies a wedge (30 degrees for a 60
  // degree tip) that neither face covers: a grain there touches the rim circle, an edge.
  // Without it a grain in the wedge overlapping the rim carried no force, and the shaft found
  // it deep inside as soon as the pile moved past it (a load test's spikes of 27 times its
  // capacity, grains split at once at up to 3.3 times their strength).
  const SimulationConfig cfg = body_config(
      "[[body]]\nname = \"pile\"\nshape = \"pile\"\norigin = [0, 0, -5e-3]\naxis = [0, 0, 1]\n"
      "radius = 1e-3\nlength = 8e-3\nhalf_angle = 30.0\n");
  Simulation sim(cfg);
  const Walls& w = sim.walls();
  const int pile = kNumWalls;
  const double R = 1e-3, r = 0.1e-3, h = R / std::tan(kPi / 6.0), z_rim = -5e-3 + h;
  // In the wedge: 0.5 r out from the rim and 0.2 r below it.
  const SurfacePoint rim = w.surface(pile, {R + 0.5 * r, 0.0, z_rim - 0.2 * r});
  const double d = std::hypot(0.5 * r, 0.2 * r);
  EXPECT_NEAR(rim.dist, d, 1e-15);
  EXPECT_NEAR(rim.n.x, -0.5 * r / d, 1e-12);
  EXPECT_NEAR(rim.n.z, 0.2 * r / d, 1e-12);
  EXPECT_EQ(rim.kappa_1, 0.0);  // an edge: R* = r, as against a plane
  // Down a line 0.5 r outside the shaft, from the shaft past the rim onto the cone: the
  // distance is continuous (the faces' distances meet the rim's at the wedge's sides) and never
  // above the sphere's radius, so a grain sliding along it keeps its contact.
  double last = w.surface(pile, {R + 0.5 * r, 0.0, z_rim + 0.5 * r}).dist;
  for (int k = 1; k <= 200; ++k) {
    const double z = z_rim + 0.5 * r - k * 0.005 * r;
    const double dist = w.surface(pile, {R + 0.5 * r, 0.0, z}).dist;
    EXPECT_LT(dist, r) << "z - z_rim = " << (z - z_rim) / r << " r";
    EXPECT_LT(std::fabs(dist - last), 0.01 * r) << "z - z_rim = " << (z - z_rim) / r << " r";
    last = dist;
  }
  // A grain in the wedge overlapping the rim is pushed away from it, along the normal.
  sim.add_particle({R + 0.5 * r, 0.0, z_rim - 0.2 * r}, r);
  sim.compute_forces();
  const Vec3 F{sim.resultant_force(0)[0], sim.resultant_force(1)[0], sim.resultant_force(2)[0]};
  EXPECT_GT(F.x, 0.0);
  EXPECT_LT(F.z, 0.0);
  EXPECT_NEAR(F.z / F.x, -0.2 / 0.5, 1e-12);
}

TEST(Bodies, APrescribedVelocityMovesTheBodyAndAServoHoldsItsStress) {
  // A disk platen 2 um above a grain resting on the box floor: moved at 1 mm/s along -axis
  // for 1,000 steps, then servo-controlled to a stress over its area.
  SimulationConfig cfg = body_config(
      "[[body]]\nname = \"platen\"\nshape = \"disk\"\norigin = [0, 0, 1.02e-4]\n"
      "axis = [0, 0, 1]\nradius = 1e-3\nmode = \"velocity\"\nvelocity = 1e-3\n");
  for (int k = 0; k < kNumWalls; ++k) {
    cfg.walls[static_cast<std::size_t>(k)].position = wall_is_low(k) ? -1e-3 : 1e-3;
  }
  cfg.walls[4].position = -1e-4;  // the floor under a grain of radius 0.1 mm at the origin
  cfg.damping.local_alpha = 0.7;
  Simulation sim(cfg);
  sim.add_particle({0.0, 0.0, 0.0}, 1e-4);
  sim.set_dt(1e-8);
  sim.step(1000);
  const int platen = kNumWalls;
  EXPECT_NEAR(sim.walls().position(platen), 1e-3 * 1000 * 1e-8, 1e-15);
  // Servo to 2 kPa over the disk (pi mm^2: 6.3 mN), reached and held.
  WallConfig& c = sim.walls().config(platen);
  c.mode = WallMode::Servo;
  c.target_stress = 2e3;
  c.max_speed = 0.01;
  sim.step(200000);
  EXPECT_NEAR(sim.walls().stress(platen) / 2e3, 1.0, 1e-3);
  EXPECT_NEAR(sim.walls().state(platen).force.z / (2e3 * kPi * 1e-6), 1.0, 1e-3);
}

TEST(Bodies, DrivingABodyChecksTheChangeAndRefusesAServoWithoutAnArea) {
  // A front end's change of a body's drive (Python's set_wall): checked before anything
  // changes, a servo refused on a plane given no area, a velocity applied at once.
  SimulationConfig cfg = body_config(
      "[[body]]\nname = \"floor\"\nshape = \"plane\"\norigin = [0, 0, -1e-2]\n"
      "axis = [0, 0, -1]\n[[body]]\nname = \"platen\"\nshape = \"disk\"\n"
      "origin = [0, 0, 1e-2]\naxis = [0, 0, 1]\nradius = 1e-3\n");
  Simulation sim(cfg);
  Walls& w = sim.walls();
  const int floor = kNumWalls, platen = kNumWalls + 1;
  WallConfig servo = w.config(floor);
  servo.mode = WallMode::Servo;
  servo.target_stress = 1e5;
  // The message of a refused change ("" when it was accepted).
  const auto refusal = [&w](int k, const WallConfig& c, const std::string& key) {
    try {
      w.drive(k, c, key);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string no_area = refusal(floor, servo, "body[0]");
  EXPECT_NE(no_area.find("body[0].mode"), std::string::npos) << no_area;
  EXPECT_NE(no_area.find("body \"floor\", which has no area"), std::string::npos) << no_area;
  EXPECT_EQ(w.config(floor).mode, WallMode::Fixed);
  WallConfig bad = servo;
  bad.servo_alpha = 2.0;
  const std::string gain = refusal(platen, bad, "body[1]");
  EXPECT_NE(gain.find("body[1].servo_alpha"), std::string::npos) << gain;
  EXPECT_EQ(w.config(platen).mode, WallMode::Fixed);
  w.drive(platen, servo, "body[1]");  // a disk has its own area
  EXPECT_EQ(w.config(platen).mode, WallMode::Servo);
  WallConfig moving = w.config(platen);
  moving.mode = WallMode::Velocity;
  moving.velocity = -0.02;
  w.drive(platen, moving, "body[1]");
  EXPECT_EQ(w.state(platen).velocity, -0.02);
  moving.mode = WallMode::Fixed;
  w.drive(platen, moving, "body[1]");
  EXPECT_EQ(w.state(platen).velocity, 0.0);
}

TEST(Bodies, AServoOnALoadHoldsTheForceWhateverTheBodysArea) {
  // The platen above, servo-controlled to a load of 5 mN from the start: held over its own
  // area as a stress (5 mN / pi mm^2), and written back as the load, not as a stress.
  SimulationConfig cfg = body_config(
      "[[body]]\nname = \"platen\"\nshape = \"disk\"\norigin = [0, 0, 1.02e-4]\n"
      "axis = [0, 0, 1]\nradius = 1e-3\nmode = \"servo\"\ntarget_force = 5e-3\n"
      "max_speed = 0.01\n");
  for (int k = 0; k < kNumWalls; ++k) {
    cfg.walls[static_cast<std::size_t>(k)].position = wall_is_low(k) ? -1e-3 : 1e-3;
  }
  cfg.walls[4].position = -1e-4;
  cfg.damping.local_alpha = 0.7;
  const std::string text = toml::serialize(to_toml(cfg));
  EXPECT_NE(text.find("target_force = 0.005"), std::string::npos) << text;
  EXPECT_EQ(text.find("target_stress"), std::string::npos) << text;
  Simulation sim(cfg);
  const int platen = kNumWalls;
  EXPECT_NEAR(sim.walls().config(platen).target_stress * kPi * 1e-6 / 5e-3, 1.0, 1e-12);
  sim.add_particle({0.0, 0.0, 0.0}, 1e-4);
  sim.set_dt(1e-8);
  sim.step(200000);
  EXPECT_NEAR(sim.walls().state(platen).force.z / 5e-3, 1.0, 1e-3);
}

TEST(Bodies, AServoOnALoadInAQuarterChamberHoldsTheQuarterOfABodyOnItsAxisOnly) {
  // A quarter chamber of radius 10 mm; a plate 2 mm across on its axis stands for the whole
  // plate, of which the quarter's grains carry a quarter; one off the axis lies in the quarter.
  BodyConfig chamber;
  chamber.name = "chamber";
  chamber.kind = BodyKind::CylinderInside;
  chamber.origin = {0.0, 0.0, -0.01};
  chamber.radius = 0.01;
  chamber.length = 0.03;
  chamber.motion = BodyMotion::Dilate;
  chamber.chamber = true;
  chamber.sector = 0.25;
  BodyConfig plate;
  plate.kind = BodyKind::Disk;
  plate.radius = 1e-3;
  plate.mode = WallMode::Servo;
  plate.target_force = 0.2;
  BodyConfig on_axis = plate, off_axis = plate;
  on_axis.name = "on_axis";
  on_axis.origin = {0.0, 0.0, 5e-3};
  off_axis.name = "off_axis";
  off_axis.origin = {4e-3, 4e-3, 5e-3};
  std::array<WallConfig, kNumWalls> box{};
  for (int k = 0; k < kNumWalls; ++k) {
    box[static_cast<std::size_t>(k)].position = wall_is_low(k) ? -0.01 : 0.01;
  }
  const Walls w(box, 0.0, {on_axis.make(0.0), off_axis.make(0.0), chamber.make(0.0)});
  // The grains reach a quarter of the plate on the axis: its area is that quarter, and the
  // servo holds the load target_stress x area on them.
  const double A = kPi * 1e-6;
  EXPECT_NEAR(w.area(kNumWalls) / (0.25 * A), 1.0, 1e-15);
  EXPECT_NEAR(w.area(kNumWalls + 1) / A, 1.0, 1e-15);
  EXPECT_NEAR(w.config(kNumWalls).target_stress * w.area(kNumWalls) / (0.25 * 0.2), 1.0, 1e-12);
  EXPECT_NEAR(w.config(kNumWalls + 1).target_stress * w.area(kNumWalls + 1) / 0.2, 1.0, 1e-12);
}

TEST(Bodies, AProbeSplitsAPilesLoadIntoTipShaftAndBinsAlongTheShaft) {
  // A flat-ended pile of radius 1 mm, its tip at z = -5 mm, driven down (-axis); one grain
  // pressed on the tip from below, two on the shaft at heights 1.3 and 5.1 mm, one sliding
  // along it (the shaft's friction), in 8 bins of 1 mm.
  const double R = 1e-3, r = 0.1e-3, delta = 2e-7;
  SimulationConfig cfg = body_config(
      "[[body]]\nname = \"pile\"\nshape = \"pile\"\norigin = [0, 0, -5e-3]\naxis = [0, 0, 1]\n"
      "radius = 1e-3\nlength = 8e-3\ntip = \"flat\"\nfriction = 0.5\n");
  Simulation sim(cfg);
  sim.add_particle({0.0, 0.0, -5e-3 - r + delta}, r);
  sim.add_particle({R + r - delta, 0.0, -5e-3 + 1.3e-3}, r, {0.0, 0.0, 0.01});
  sim.add_particle({0.0, -(R + r - 2.0 * delta), -5e-3 + 5.1e-3}, r);
  sim.set_dt(1e-9);
  sim.step(1);
  const int pile = kNumWalls;
  const BodyProbe p = probe_body(sim.walls(), pile, sim.wall_contacts(), sim.particles(), 2e-3, 8);
  const WallContacts& wc = sim.wall_contacts();
  ASSERT_TRUE(probe_supports(sim.walls().shape(pile)));
  EXPECT_EQ(p.tip_contacts, 1u);
  EXPECT_EQ(p.shaft_contacts, 2u);
  ASSERT_EQ(p.sigma_r.size(), 8u);
  EXPECT_DOUBLE_EQ(p.bin_height, 1e-3);
  double F_n[3] = {0.0, 0.0, 0.0};
  for (std::size_t e = 0; e < wc.size(); ++e) {
    if (wc.wall[e] == pile) F_n[sim.particles().id[wc.particle[e]]] = wc.F_n[e];
  }
  // The tip: the grain's normal force, against the advance, over the tip's area.
  EXPECT_DOUBLE_EQ(p.tip_load, F_n[0]);
  EXPECT_NEAR(p.q_c() * kPi * R * R / F_n[0], 1.0, 1e-12);
  // The shaft: the radial stress in bins 1 and 5 only; the sliding grain's friction (it moves
  // up the shaft: the shaft drags it down, along the advance) is the shaft's load, all of it in
  // bin 1 and in the 2 mm sleeve.
  for (std::size_t j = 0; j < 8; ++j) {
    const double expected = j == 1 ? F_n[1] : j == 5 ? F_n[2] : 0.0;
    EXPECT_NEAR(p.sigma_r[j] * 2.0 * kPi * R * 1e-3, expected, 1e-12 * F_n[1]) << j;
  }
  EXPECT_GT(p.shaft_load, 0.0);
  EXPECT_NEAR(p.tau[1] * 2.0 * kPi * R * 1e-3, p.shaft_load, 1e-12 * F_n[1]);
  EXPECT_DOUBLE_EQ(p.sleeve_load, p.shaft_load);
  EXPECT_NEAR(p.f_s() * 2.0 * kPi * R * 2e-3, p.shaft_load, 1e-12 * F_n[1]);
  // Together, the load the body's servo would hold (walls/body_geometry.hpp body_load).
  const WallState& st = sim.walls().state(pile);
  EXPECT_NEAR(p.tip_load + p.shaft_load,
              body_load(sim.walls().shape(pile), st.normal_force, st.force), 1e-12 * F_n[0]);
}

TEST(Bodies, ThePilesMomentIsTheGrainsForcesAtTheirContactPointsAboutItsTip) {
  // The pile above, with friction, driven 0.4 um down: a grain on the tip off its centre, one
  // on the shaft sliding up it (a moment about y), one sliding sideways along it (about z).
  // Each entry's force on the body acts at its contact point on the surface, found here from
  // the shape; the moment is about the pile's origin (its tip's centre) where q put it.
  const double R = 1e-3, r = 0.1e-3, delta = 2e-7, q = 4e-7;
  SimulationConfig cfg = body_config(
      "[[body]]\nname = \"pile\"\nshape = \"pile\"\norigin = [0, 0, -5e-3]\naxis = [0, 0, 1]\n"
      "radius = 1e-3\nlength = 8e-3\ntip = \"flat\"\nfriction = 0.5\n");
  const Vec3 O{0.0, 0.0, -5e-3 - q};  // moved along -axis
  const Vec3 x_c[3] = {{0.4e-3, -0.2e-3, O.z}, {R, 0.0, O.z + 1.3e-3}, {-R, 0.0, O.z + 5.1e-3}};
  Simulation sim(cfg);
  const int pile = kNumWalls;
  sim.walls().state(pile).position = q;
  sim.add_particle(x_c[0] - Vec3{0.0, 0.0, r - delta}, r, {0.01, 0.0, 0.0});
  sim.add_particle(x_c[1] + Vec3{r - delta, 0.0, 0.0}, r, {0.0, 0.0, 0.01});
  sim.add_particle(x_c[2] - Vec3{r - delta, 0.0, 0.0}, r, {0.0, 0.01, 0.0});
  sim.set_dt(1e-9);
  sim.step(1);  // the friction's first increment
  // Where each grain now touches: below it on the tip, radially out from the axis on the shaft.
  const ParticleStore& g = sim.particles();
  Vec3 contact_point[3];
  for (std::size_t i = 0; i < g.size(); ++i) {
    const double rho = std::hypot(g.x[i], g.y[i]);
    contact_point[g.id[i]] =
        g.id[i] == 0 ? Vec3{g.x[i], g.y[i], O.z} : Vec3{R * g.x[i] / rho, R * g.y[i] / rho, g.z[i]};
  }
  const Vec3 O_body = body_reference_point(sim.walls(), pile);
  EXPECT_NEAR(norm(O_body - O), 0.0, 1e-18);
  const WallContacts& wc = sim.wall_contacts();
  Vec3 expected;
  double scale = 0.0;
  int touching = 0;
  for (std::size_t e = 0; e < wc.size(); ++e) {
    if (wc.wall[e] != pile) continue;
    const Vec3 F_body{-wc.fx[e], -wc.fy[e], -wc.fz[e]};
    expected += cross(contact_point[g.id[wc.particle[e]]] - O, F_body);
    scale = std::max(scale, norm(F_body) * 5.1e-3);
    touching += wc.F_n[e] > 0.0 ? 1 : 0;
  }
  ASSERT_EQ(touching, 3);
  const std::vector<Vec3> M = body_moments(sim.walls(), wc, sim.particles());
  ASSERT_EQ(M.size(), static_cast<std::size_t>(sim.walls().size()));
  EXPECT_NEAR(M[pile].x, expected.x, 1e-12 * scale);
  EXPECT_NEAR(M[pile].y, expected.y, 1e-12 * scale);
  EXPECT_NEAR(M[pile].z, expected.z, 1e-12 * scale);
  // The sliding grains' friction turns the pile about y (up the shaft at +x) and z (sideways
  // at -x) by far more than the check above resolves.
  EXPECT_GT(std::abs(M[pile].y), 1e-6 * scale);
  EXPECT_GT(std::abs(M[pile].z), 1e-6 * scale);
  // The box's walls have no reference point: zero; the time series carries the body's.
  for (int k = 0; k < kNumWalls; ++k) EXPECT_EQ(norm(M[static_cast<std::size_t>(k)]), 0.0);
  const Measurement row = measure(sim, StrainReference::from(sim.walls()));
  const auto column = [&](const std::string& name) {
    for (const auto& [key, value] : row) {
      if (key == name) return value;
    }
    ADD_FAILURE() << "no column " << name;
    return 0.0;
  };
  EXPECT_EQ(column("body_pile_moment_x_Nm"), M[pile].x);
  EXPECT_EQ(column("body_pile_moment_y_Nm"), M[pile].y);
  EXPECT_EQ(column("body_pile_moment_z_Nm"), M[pile].z);
}

TEST(Bodies, ACylinderShrunkPastZeroStopsTheRunNamingIt) {
  // A chamber's wall shrinking at 1 m/s: its radius of 1 mm is gone after 1,000 steps of 1 us.
  SimulationConfig cfg = body_config(
      "[[body]]\nname = \"chamber\"\nshape = \"cylinder_inside\"\nradius = 1e-3\nlength = 1e-3\n"
      "motion = \"dilate\"\nmode = \"velocity\"\nvelocity = -1.0\n");
  Simulation sim(cfg);
  sim.add_particle({0.01, 0.01, 0.01}, 1e-4);  // far from it
  sim.set_dt(1e-6);
  sim.step(999);
  EXPECT_NEAR(sim.walls().position(kNumWalls), -0.999e-3, 1e-15);
  try {
    sim.step(2);
    ADD_FAILURE() << "a cylinder of negative radius went on";
  } catch (const RuntimeFailure& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("\"chamber\""), std::string::npos) << what;
    EXPECT_NE(what.find("inside out"), std::string::npos) << what;
  }
}

std::string config_error(const std::string& bodies) {
  try {
    body_config(bodies);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(Bodies, BadBodiesAreRefusedNamingTheKey) {
  // (the [[body]] tables, the key the error must name)
  const std::pair<std::string, std::string> cases[] = {
      {"[[body]]\nname = \"tip\"\nshape = \"cone\"\nradius = 1e-3\nhalf_angle = 0.0\n",
       "body[0].half_angle"},
      {"[[body]]\nname = \"p\"\nshape = \"plane\"\nmotion = \"dilate\"\n", "body[0].motion"},
      {"[[body]]\nname = \"p\"\nshape = \"plane\"\nmode = \"servo\"\ntarget_stress = 1e5\n",
       "body[0].area"},
      {"[[body]]\nname = \"c\"\nshape = \"cylinder_inside\"\nlength = 1e-3\n", "body[0].radius"},
      {"[[body]]\nname = \"a\"\n[[body]]\nname = \"a\"\n", "body[1].name"},
      {"[[body]]\nname = \"zmax\"\n", "body[0].name"},
      {"[[body]]\nname = \"a\"\naxis = [0, 0, 0]\n", "body[0].axis"},
      {"[[body]]\nname = \"a\"\naxis = [0, 0, nan]\n", "body[0].axis"},
      {"[[body]]\nname = \"a\"\norigin = [0, 0, inf]\n", "body[0].origin"},
      // A length unit() cannot take (its square overflows).
      {"[[body]]\nname = \"a\"\naxis = [0, 0, 1e200]\n", "body[0].axis"},
      {"[[body]]\nname = \"a\"\ndirection = [0, 0, -1e200]\n", "body[0].direction"},
      {"[[body]]\nname = \"a\"\ndirection = [0, 0, 1e-200]\n", "body[0].direction"},
      {"[[body]]\nname = \"pile\"\nshape = \"pile\"\nradius = 1e-3\nlength = 1e-3\n",
       "body[0].length"},
      {"[[body]]\nname = \"a\"\nshape = \"plane\"\ntarget_stress = 1e5\n", "body[0].target_stress"},
      {"[[body]]\nname = \"a\"\nshape = \"sphere\"\n", "body[0].shape"},
      // A load servo on a dilating cylinder (its area changes), with a stress target too, and
      // without a servo.
      {"[[body]]\nname = \"c\"\nshape = \"cylinder_inside\"\nradius = 1e-3\nlength = 1e-3\n"
       "motion = \"dilate\"\nmode = \"servo\"\ntarget_force = 1.0\n",
       "body[0].target_force"},
      {"[[body]]\nname = \"d\"\nshape = \"disk\"\nradius = 1e-3\nmode = \"servo\"\n"
       "target_force = 1.0\ntarget_stress = 1e5\n",
       "body[0].target_stress"},
      {"[[body]]\nname = \"d\"\nshape = \"disk\"\nradius = 1e-3\ntarget_force = 1.0\n",
       "body[0].target_force"},
      {"[[body]]\nname = \"d\"\nshape = \"disk\"\nradius = 1e-3\nmode = \"servo\"\n"
       "target_force = -1.0\n",
       "body[0].target_force"},
  };
  for (const auto& [bodies, key] : cases) {
    const std::string error = config_error(bodies);
    EXPECT_NE(error.find(key), std::string::npos) << bodies << " -> " << error;
  }
}

TEST(Bodies, ABoxRunWritesNoBodyKeysAndABodyIsWrittenAndReadBack) {
  const SimulationConfig none = body_config("");
  EXPECT_EQ(to_toml(none).count("body"), 0u);
  const SimulationConfig one = body_config(
      "[[body]]\nname = \"pile\"\nshape = \"pile\"\norigin = [0, 0, -5e-3]\nradius = 1e-3\n"
      "length = 8e-3\ntip = \"flat\"\nmode = \"velocity\"\nvelocity = 0.01\n");
  const std::string text = toml::serialize(to_toml(one));
  const SimulationConfig again =
      simulation_config_from_toml(toml::parse(text, "again.toml"), "again.toml");
  EXPECT_EQ(toml::serialize(to_toml(again)), text);
  ASSERT_EQ(again.bodies.size(), 1u);
  EXPECT_EQ(again.bodies[0].tip, PileTip::Flat);
  EXPECT_EQ(again.bodies[0].velocity, 0.01);
}

}  // namespace
}  // namespace crushdem

namespace crushdem {
namespace {

// Gravity: a grain falls as z0 + g t^2 / 2 (velocity Verlet is exact for a constant force), and
// one at rest on the floor presses on it with its weight.
TEST(Gravity, AGrainFallsFreelyAndRestsOnTheFloorWithItsWeight) {
  SimulationConfig cfg = testing::box_config(-1e-3, 1e-3);
  cfg.gravity.g = {0.0, 0.0, -9.81};
  Simulation fall(cfg);
  const double r = 0.1e-3, z0 = 0.5e-3;
  fall.add_particle({0.0, 0.0, z0}, r);
  fall.set_dt(1e-6);
  fall.step(300);  // 0.3 ms: falls 0.44 um, far from the floor
  const double t = fall.time();
  EXPECT_NEAR(fall.particles().z[0], z0 - 0.5 * 9.81 * t * t, 1e-15);
  EXPECT_NEAR(fall.particles().vz[0], -9.81 * t, 1e-12);
  EXPECT_EQ(fall.particles().x[0], 0.0);

  cfg.damping.local_alpha = 0.7;
  Simulation rest(cfg);
  rest.add_particle({0.0, 0.0, -1e-3 + r}, r);
  rest.set_dt(2e-8);
  rest.step(300000);
  const double weight = rest.particles().mass[0] * 9.81;
  EXPECT_NEAR(rest.walls().state(4).normal_force / weight, 1.0, 1e-6);
  EXPECT_NEAR(rest.resultant_force(2)[0] / weight, 0.0, 1e-6);  // in equilibrium
  // Written to config.toml only when on.
  EXPECT_EQ(to_toml(testing::box_config(-1e-3, 1e-3)).count("gravity"), 0u);
  EXPECT_EQ(to_toml(cfg).count("gravity"), 1u);
}

}  // namespace
}  // namespace crushdem
