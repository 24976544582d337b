#include "crushdem/experiments/protocol.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "crushdem/core/deterministic.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/particles/generate.hpp"

namespace crushdem {

bool servo_walls_at_target(const Walls& w, double tol) {
  // A zero target (a pile's head load taken off) has no relative error: it counts as met within
  // tol of the largest target.
  double scale = 0.0;
  for (int k = 0; k < w.size(); ++k) {
    if (w.config(k).mode == WallMode::Servo) {
      scale = std::max(scale, std::abs(w.config(k).target_stress));
    }
  }
  for (int k = 0; k < w.size(); ++k) {
    const WallConfig& c = w.config(k);
    if (c.mode != WallMode::Servo) continue;
    const bool met = c.target_stress != 0.0 ? std::abs(w.stress(k) / c.target_stress - 1.0) <= tol
                                            : std::abs(w.stress(k)) <= tol * scale;
    if (!met) return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------

double SampleConfig::cube_side() const {
  if (side > 0.0) return side;
  if (count > 0) {
    const double V = static_cast<double>(count) * grading.mean_grain_volume() * (1.0 + void_ratio);
    // A cylinder's sector: V = f pi D^2 H / 4 with H = height_ratio D.
    return shape == SampleShape::Cube
               ? std::cbrt(V)
               : std::cbrt(4.0 * V / (kPi * height_ratio * sector_fraction()));
  }
  return 4e-3;
}

double SampleConfig::height() const {
  return shape == SampleShape::Cube ? cube_side() : height_ratio * cube_side();
}

namespace {
constexpr double kLoosestVoidRatio = 1.2;
}  // namespace

const ParamTable<SampleConfig>& sample_params() {
  using Row = Param<SampleConfig>;
  static const ParamTable<SampleConfig> table = {
      Row{"shape",
          enum_choice(&SampleConfig::shape, kSampleShapeNames),
          "",
          "a cube between the box's six walls, or a cylinder in a chamber (docs/chamber.md): a "
          "servo-controlled cylinder_inside named \"chamber\", the box's z walls its platens",
          nullptr,
          {},
          {},
          // Written for a cylinder only: a cube's config.toml is as it was before the key.
          [](const SampleConfig& c) { return c.shape == SampleShape::Cylinder; }},
      Row{"side", &SampleConfig::side, "m",
          "cube side, or cylinder diameter, at the target void ratio (give side or count)",
          [](double v) { return v >= 0.0; }, "a cube side or cylinder diameter in m (> 0)",
          "4e-3 (unless count)", [](const SampleConfig& c) { return c.count == 0; }},
      Row{"height_ratio",
          &SampleConfig::height_ratio,
          "-",
          "a cylinder's height / diameter",
          [](double v) { return v >= 0.2 && v <= 5.0; },
          "a ratio in [0.2, 5]",
          {},
          [](const SampleConfig& c) { return c.shape == SampleShape::Cylinder; }},
      Row{"sector",
          &SampleConfig::sector,
          "deg",
          "the part of a cylinder simulated: 360, or a half (180) or a quarter (90) between "
          "frictionless symmetry planes through the axis (bodies symmetry_x, symmetry_y; "
          "docs/chamber.md)",
          [](double v) { return v == 360.0 || v == 180.0 || v == 90.0; },
          "360, 180 or 90",
          {},
          [](const SampleConfig& c) { return c.shape == SampleShape::Cylinder; }},
      Row{"count",
          &SampleConfig::count,
          "",
          "about how many grains; sets the side",
          nullptr,
          {},
          "-",
          [](const SampleConfig& c) { return c.count > 0; }},
      Row{"void_ratio", &SampleConfig::void_ratio, "-", "target void ratio e (STUDY)",
          [](double v) { return v > 0.0 && v < kLoosestVoidRatio; },
          "a void ratio in (0, 1.2): random packings of spheres in equilibrium are not looser "
          "than about e = 0.8-1.0"},
      Row{"tolerance", &SampleConfig::tolerance, "-",
          "accepted abs(e - void_ratio); a warning (summary.json, terminal) if missed",
          [](double v) { return v > 0.0 && v < 0.1; }, "a void-ratio tolerance in (0, 0.1)"},
      Row{"stress", &SampleConfig::stress, "Pa", "isotropic stress of the prepared sample",
          [](double v) { return v > 0.0; }, "a positive isotropic stress in Pa"},
      Row{"seed", &SampleConfig::seed, "", "grain sizes and positions; same seed, same sample"},
      Row{"friction_start", &SampleConfig::friction_start, "-",
          "preparation friction to start from (in [material.friction, 2])"},
      Row{"friction_factor", &SampleConfig::friction_factor, "-",
          "each lowering multiplies the preparation friction by this",
          [](double v) { return v > 0.0 && v < 1.0; }, "a factor in (0, 1)"},
      Row{"placement_fraction", &SampleConfig::placement_fraction, "-",
          "solid fraction of the loose initial cloud", [](double v) { return v > 0.0 && v <= 0.3; },
          "a solid fraction in (0, 0.3] (random placement jams above)"},
      Row{"max_speed", &SampleConfig::max_speed, "m/s", "wall speed limit during preparation",
          [](double v) { return v > 0.0; }, "a positive speed in m/s"},
      Row{"compaction",
          enum_choice(&SampleConfig::compaction, kCompactionNames),
          "",
          "how the loose cloud is compacted (CHOICE; docs/chamber.md, A chamber sample): "
          "\"walls\", the servo walls sweep it inwards; \"affine\", every grain moves with the "
          "walls' homogeneous strain until they carry affine_release x stress, then as walls. "
          "A sample more than 40 d50 across compacted by its walls warns",
          nullptr,
          {},
          {},
          // Written when affine: a walls run's config.toml has no such line.
          [](const SampleConfig& c) { return c.compaction != Compaction::Walls; }},
      Row{"affine_release",
          &SampleConfig::affine_release,
          "-",
          "affine compaction: the grains follow the walls until the walls' mean stress is this "
          "fraction of stress",
          [](double v) { return v > 0.0 && v < 1.0; },
          "a fraction of sample.stress in (0, 1)",
          {},
          [](const SampleConfig& c) { return c.compaction == Compaction::Affine; }},
      Row{"unbalanced", &SampleConfig::unbalanced, "-",
          "equilibrium: unbalanced-force ratio below this",
          [](double v) { return v > 0.0 && v < 1.0; }, "an unbalanced-force ratio in (0, 1)"},
      Row{"stress_tolerance", &SampleConfig::stress_tolerance, "-",
          "equilibrium: every wall within this relative error of stress",
          [](double v) { return v > 0.0 && v < 0.5; }, "a relative tolerance in (0, 0.5)"},
      Row{"check_interval", &SampleConfig::check_interval, "", "steps between checks",
          [](double v) { return v >= 1.0; }, "a number of steps >= 1"},
      Row{"max_steps", &SampleConfig::max_steps, "", "error after this many steps",
          [](double v) { return v >= 1.0; }, "a number of steps >= 1"},
  };
  return table;
}

void SampleConfig::validate(const SimulationConfig& sim) const {
  grading.validate("sample.grading");
  if (side != 0.0 && count != 0) {
    throw ConfigError(
        "sample: give either 'sample.side' (the cube side in m) or 'sample.count' (about how "
        "many grains), not both");
  }
  validate_params(*this, sample_params(), "sample");
  if (shape == SampleShape::Cube && sector != 360.0) {
    throw ConfigError(bad_value("sample.sector", show_number(sector),
                                "360 for a cube (a sector is a cylinder's: shape = \"cylinder\")"));
  }
  // The wall effect of the narrower of the cylinder's diameter and height.
  const double e_min = densest_void_ratio(grading, std::min(cube_side(), height()));
  if (void_ratio < e_min) {
    throw ConfigError(bad_value(
        "sample.void_ratio", show_number(void_ratio),
        "a void ratio this grading can reach in this sample: random close packing gives about e "
        "= " +
            show_number(std::round(e_min * 1000.0) / 1000.0) +
            " here (Desmond & Weeks 2014, with a looser layer along the walls), and no random "
            "packing is denser: more grains than fit (a wider sample packs denser)"));
  }
  require_value(friction_start >= sim.material.friction && friction_start <= 2.0,
                "sample.friction_start", friction_start,
                "a friction coefficient in [material.friction, 2] to start the preparation from");
  const double L = std::min(cube_side(), height());
  const double d_max = grading.diameter.back();
  if (L < 5.0 * d_max) {
    throw ConfigError(bad_value(side > 0 ? "sample.side" : "sample.count",
                                side > 0 ? show_number(side) : std::to_string(count),
                                "a sample at least 5 largest grains wide and high (" +
                                    show_number(5.0 * d_max) + " m; this gives " + show_number(L) +
                                    " m)"));
  }
  const double V = shape == SampleShape::Cube
                       ? L * L * L
                       : sector_fraction() * kPi / 4.0 * cube_side() * cube_side() * height();
  const double n = V / (1.0 + void_ratio) / grading.mean_grain_volume();
  if (n > 5e7) {
    throw ConfigError(bad_value(
        side > 0 ? "sample.side" : "sample.count",
        side > 0 ? show_number(side) : std::to_string(count),
        "a sample of at most 5e7 grains (this is about " + show_number(std::round(n)) + ")"));
  }
}

LooseCloud make_loose_cloud(const SampleConfig& cfg, bool place) {
  const bool cylinder = cfg.shape == SampleShape::Cylinder;
  const double f = cfg.sector_fraction();
  const double L = cfg.cube_side();
  const double V = cylinder ? f * kPi / 4.0 * L * L * cfg.height() : L * L * L;
  const std::vector<double> d = draw_diameters(cfg.grading, V / (1.0 + cfg.void_ratio), cfg.seed);
  double vol = 0.0;
  for (double x : d) vol += kPi / 6.0 * x * x * x;
  LooseCloud c;
  const double V_loose = vol / cfg.placement_fraction;
  c.side = cylinder ? std::cbrt(4.0 * V_loose / (kPi * cfg.height_ratio * f)) : std::cbrt(V_loose);
  c.height = cylinder ? cfg.height_ratio * c.side : c.side;
  c.sector = f;
  if (!place) return c;
  std::vector<double> radii(d.size());
  for (std::size_t i = 0; i < d.size(); ++i) radii[i] = 0.5 * d[i];
  // A cube with its lower corner at the origin; a cylinder about the z axis, its base at z = 0,
  // a half at x > 0, a quarter at x, y > 0.
  std::array<double, 6> box{0.0, c.side, 0.0, c.side, 0.0, c.height};
  PlaceTest in_cylinder;
  if (cylinder) {
    const double R = 0.5 * c.side;
    box = {f < 1.0 ? 0.0 : -R, R, f < 0.5 ? 0.0 : -R, R, 0.0, c.height};
    in_cylinder = [R](Vec3 p, double r) { return std::hypot(p.x, p.y) <= R - r; };
  }
  for (const PlacedSphere& s :
       random_sequential_addition(radii, box, cfg.seed, 100000, in_cylinder)) {
    c.position.push_back(s.position);
    c.radius.push_back(s.radius);
  }
  return c;
}

BodyConfig chamber_body(const LooseCloud& cloud) {
  BodyConfig b;
  b.name = kSampleBodyNames[0];
  b.kind = BodyKind::CylinderInside;
  b.origin = {0.0, 0.0, -cloud.height};
  b.axis = {0.0, 0.0, 1.0};
  b.radius = 0.5 * cloud.side;
  b.length = 3.0 * cloud.height;
  b.motion = BodyMotion::Dilate;
  b.chamber = true;
  b.sector = cloud.sector;
  return b;
}

std::vector<BodyConfig> symmetry_planes(const LooseCloud& cloud) {
  std::vector<BodyConfig> planes;
  for (int a = 0; a < 2; ++a) {
    if (cloud.sector > (a == 0 ? 0.5 : 0.25)) continue;  // x = 0 from a half, y = 0 a quarter
    BodyConfig b;
    b.name = kSampleBodyNames[static_cast<std::size_t>(1 + a)];
    b.kind = BodyKind::Plane;
    b.axis = a == 0 ? Vec3{-1.0, 0.0, 0.0} : Vec3{0.0, -1.0, 0.0};  // into the body: x, y < 0
    b.friction = 0.0;  // a plane of symmetry carries no shear
    b.symmetry = true;
    planes.push_back(b);
  }
  return planes;
}

std::vector<BodyConfig> chamber_sample_bodies(const LooseCloud& size, double z_bottom) {
  std::vector<BodyConfig> bodies{chamber_body(size)};
  bodies.front().origin.z += z_bottom;
  for (const BodyConfig& plane : symmetry_planes(size)) bodies.push_back(plane);
  return bodies;
}

std::vector<BodyConfig> file_chamber_bodies(double radius, double sector_degrees, double z_bottom,
                                            double z_top) {
  LooseCloud size;
  size.side = 2.0 * radius;
  size.height = z_top - z_bottom;
  size.sector = sector_degrees / 360.0;
  return chamber_sample_bodies(size, z_bottom);
}

// ---------------------------------------------------------------------------------------------

namespace {

// The walls' homogeneous deformation along one axis: v(q) = v_lo + rate (q - lo), the velocity
// field that moves with both walls of the axis (a chamber's radial one about its axis, x = y = 0,
// with lo = v_lo = 0).
struct AxisMotion {
  double lo = 0.0, v_lo = 0.0, rate = 0.0;
};

std::array<AxisMotion, 3> wall_motion(const Walls& w) {
  std::array<AxisMotion, 3> m{};
  for (int a = 0; a < 3; ++a) {
    AxisMotion& ax = m[static_cast<std::size_t>(a)];
    if (w.chamber() >= 0 && a < 2) {  // the chamber's radius rate over its radius
      ax.rate = w.state(w.chamber()).velocity / w.chamber_radius();
    } else {
      ax.lo = w.position(2 * a);
      ax.v_lo = w.state(2 * a).velocity;
      const double L = w.length(a);
      ax.rate = L > 0 ? (w.state(2 * a + 1).velocity - ax.v_lo) / L : 0.0;
    }
  }
  return m;
}

}  // namespace

void follow_walls(Simulation& sim) {
  // The forces kept from the last step (their damping terms of the old velocities) give the next
  // half kick, as after any change between steps: a loose cloud carries almost none.
  const std::array<AxisMotion, 3> m = wall_motion(sim.walls());
  ParticleStore& p = sim.particles();
  for (std::size_t i = 0; i < p.size(); ++i) {
    p.vx[i] = m[0].v_lo + m[0].rate * (p.x[i] - m[0].lo);
    p.vy[i] = m[1].v_lo + m[1].rate * (p.y[i] - m[1].lo);
    p.vz[i] = m[2].v_lo + m[2].rate * (p.z[i] - m[2].lo);
    p.wx[i] = p.wy[i] = p.wz[i] = 0.0;
  }
}

double inertial_number(const Walls& w, double d50, double density) {
  double rate = 0.0;
  for (const AxisMotion& ax : wall_motion(w)) rate = std::max(rate, std::abs(ax.rate));
  const double p = w.mean_stress();
  if (!(p > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  return rate * d50 * std::sqrt(density / p);
}

// ---------------------------------------------------------------------------------------------

PreparationController::PreparationController(const SampleConfig& cfg, double material_friction)
    : cfg_(cfg), mu_material_(material_friction) {}

void PreparationController::begin(Simulation& sim) {
  Walls& w = sim.walls();
  // The box's six walls, or in a chamber the chamber's wall and the platens.
  for (const int k : w.sample_walls()) {
    WallConfig& c = w.config(k);
    c.mode = WallMode::Servo;
    c.target_stress = cfg_.stress;
    c.max_speed = cfg_.max_speed;
  }
  w.update_velocities(sim.current_dt());
  mu_ = cfg_.friction_start;
  sim.set_friction(mu_);
  start_step_ = sim.step_count();
  phase_ = cfg_.compaction == Compaction::Affine ? Phase::Affine : Phase::Compact;
  if (phase_ == Phase::Affine) follow_walls(sim);
}

bool PreparationController::update(Simulation& sim) {
  const double Vs = sim.particles().solid_volume();
  e_ = (sim.walls().volume() - Vs) / Vs;
  const std::uint64_t done = sim.step_count() - start_step_;
  if (done >= cfg_.max_steps) {
    throw RuntimeFailure("sample preparation did not finish within sample.max_steps = " +
                         std::to_string(cfg_.max_steps) + " steps (e = " + show_number(e_) +
                         ", preparation friction " + show_number(mu_) +
                         "); raise sample.max_steps or sample.max_speed");
  }
  const bool at_stress = servo_walls_at_target(sim.walls(), cfg_.stress_tolerance);
  const double ub = unbalanced_force_ratio(sim);
  const bool equilibrium = at_stress && ub <= cfg_.unbalanced;
  const double e_target = cfg_.void_ratio;
  switch (phase_) {
    case Phase::Affine:
      // The cloud contracts evenly until it carries load (or reaches the target), then the
      // walls alone compact it as in the walls' compaction.
      if (sim.walls().mean_stress() >= cfg_.affine_release * cfg_.stress ||
          e_ <= e_target + 0.5 * cfg_.tolerance) {
        phase_ = Phase::Compact;
      } else {
        follow_walls(sim);
      }
      return false;
    case Phase::Compact:
      // Restore the material friction a little before the target: the packing still settles.
      if (e_ <= e_target + 0.5 * cfg_.tolerance) {
        mu_found_ = mu_;
        sim.set_friction(mu_material_);
        phase_ = Phase::Settle;
      } else if (equilibrium) {
        if (mu_ == 0.0) {
          throw RuntimeFailure(
              "sample.void_ratio = " + show_number(e_target) +
              " cannot be reached: even frictionless compaction to sample.stress stops at e = " +
              show_number(e_) + " with this grading and box; ask for a looser sample");
        }
        mu_ *= cfg_.friction_factor;
        if (mu_ < 1e-3) mu_ = 0.0;
        sim.set_friction(mu_);
      }
      return false;
    case Phase::Settle:
      if (!equilibrium) return false;
      if (std::abs(e_ - e_target) > cfg_.tolerance) {
        // The compaction reached the target; the difference comes from the settling at the
        // material's friction, which the preparation's own friction cannot change.
        warning_ =
            "prepared void ratio " + show_number(e_) +
            " differs from sample.void_ratio = " + show_number(e_target) +
            " by more than sample.tolerance = " + show_number(cfg_.tolerance) +
            (e_ < e_target
                 ? ": the grains reached the target and then settled, at the material's "
                   "friction (material.friction = " +
                       show_number(mu_material_) +
                       ") under sample.stress = " + show_number(cfg_.stress) +
                       " Pa, to this denser packing; a packing looser than that does not "
                       "stand with this friction at this stress (ask for e <= " +
                       show_number(std::floor(e_ * 100.0) / 100.0) + " or a lower sample.stress)"
                 : std::string(" (too loose)"));
      }
      phase_ = Phase::Done;
      return true;
    case Phase::Done: return true;
  }
  return true;
}

Measurement PreparationController::columns(const Simulation& sim) const {
  return {{"friction", sim.contact_params().mu},
          {"phase", static_cast<double>(static_cast<int>(phase_))}};
}

// ---------------------------------------------------------------------------------------------

std::uint64_t PreparationController::steps_to_check(Simulation& sim) {
  const std::uint64_t done = sim.step_count() - start_step_;
  return cfg_.check_interval - done % cfg_.check_interval;
}

// --- checkpoints -------------------------------------------------------------------------------

void PreparationController::state(StateArchive& a) {
  a.section("preparation");
  a(mu_, mu_found_, e_, phase_, start_step_, warning_);
}

}  // namespace crushdem
