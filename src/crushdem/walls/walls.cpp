#include "crushdem/walls/walls.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <sstream>

#include "crushdem/core/deterministic.hpp"
#include "crushdem/core/error.hpp"

namespace crushdem {

const char* wall_name(int k) {
  static const char* names[kNumWalls] = {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"};
  return names[k];
}

const ParamTable<WallConfig>& wall_params() {
  using Row = Param<WallConfig>;
  static const ParamTable<WallConfig> table = {
      Row{"mode", enum_choice(&WallConfig::mode, kWallModeNames), "",
          "fixed, moving at `velocity`, or servo-controlled to `target_stress`"},
      Row{"velocity",
          &WallConfig::velocity,
          "m/s",
          "velocity mode: velocity along the coordinate axis (negative moves a max wall inwards)",
          [](double) { return true; },
          "a finite velocity in m/s",
          {},
          [](const WallConfig& w) { return w.mode == WallMode::Velocity; }},
      Row{"target_stress",
          &WallConfig::target_stress,
          "Pa",
          "servo mode: compressive normal stress to hold",
          [](double v) { return v > 0.0; },
          "a positive compressive stress in Pa for a servo wall",
          {},
          [](const WallConfig& w) { return w.mode == WallMode::Servo; }},
      Row{"servo_alpha",
          &WallConfig::servo_alpha,
          "-",
          "servo gain alpha in v = alpha A (sigma - sigma_target) / (sum k_n dt) (docs/model.md "
          "4.2)",
          [](double v) { return v > 0.0 && v <= 1.0; },
          "a gain in (0, 1]",
          {},
          [](const WallConfig& w) { return w.mode == WallMode::Servo; }},
      Row{"max_speed",
          &WallConfig::max_speed,
          "m/s",
          "servo mode: speed limit",
          [](double v) { return v > 0.0; },
          "a positive speed in m/s",
          {},
          [](const WallConfig& w) { return w.mode == WallMode::Servo; }},
  };
  return table;
}

void WallConfig::validate(const std::string& prefix) const {
  require_value(std::isfinite(position), prefix + ".position", position,
                "a finite coordinate in m");
  validate_params(*this, wall_params(), prefix);
}

Walls::Walls(const std::array<WallConfig, kNumWalls>& box, double wall_friction,
             std::vector<Body> bodies) {
  if (bodies.size() + kNumWalls > static_cast<std::size_t>(kMaxBodies)) {
    throw ConfigError(
        bad_value("body", std::to_string(bodies.size()) + " bodies",
                  "at most " + std::to_string(kMaxBodies - kNumWalls) + " bodies besides the box"));
  }
  for (int k = 0; k < kNumWalls; ++k) {
    cfg_.push_back(box[static_cast<std::size_t>(k)]);
    BodyShape b;
    b.part[0].shape = Shape::AxisPlane;
    b.part[0].wall = k;
    b.outward_sign = wall_outward_sign(k);
    b.friction = wall_friction;
    shape_.push_back(b);
  }
  area_.assign(kNumWalls, 0.0);
  symmetry_.assign(kNumWalls, false);
  double chamber_sector = 1.0;
  for (Body& body : bodies) {
    if (body.chamber) {
      if (chamber_ >= 0) throw ConfigError("body: a sample has one chamber, not two");
      chamber_ = static_cast<int>(cfg_.size());
      chamber_sector = body.sector;
    }
    cfg_.push_back(body.motion);
    shape_.push_back(body.shape);
    names_.push_back(std::move(body.name));
    area_.push_back(body.area);
    symmetry_.push_back(body.symmetry);
  }
  if (chamber_ >= 0) {
    for (const int k : {4, 5, chamber_}) {
      shape_[static_cast<std::size_t>(k)].chamber = chamber_;
      shape_[static_cast<std::size_t>(k)].sector = chamber_sector;
    }
    // A body on the sector's axis (a pile, a cone, a plate about it) stands for the whole body,
    // of which the grains reach the sector: its own area is the sector's too. One off the axis
    // lies wholly in the sector.
    for (int k = kNumWalls; k < size(); ++k) {
      const BodyPart& s = shape_[static_cast<std::size_t>(k)].part[0];
      if (k == chamber_ || symmetry_[static_cast<std::size_t>(k)]) continue;
      if (s.origin.x == 0.0 && s.origin.y == 0.0 && s.axis.x == 0.0 && s.axis.y == 0.0) {
        shape_[static_cast<std::size_t>(k)].sector = chamber_sector;
      }
    }
  }
  st_.resize(cfg_.size());
  for (std::size_t k = 0; k < cfg_.size(); ++k) st_[k].position = cfg_[k].position;
  // A servo on a load holds it as a stress over the body's area, which a translation does not
  // change; a body on a sector's axis holds the sector's share over the sector's area.
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    if (!(bodies[b].target_force > 0.0)) continue;
    const int k = kNumWalls + static_cast<int>(b);
    cfg_[static_cast<std::size_t>(k)].target_stress =
        bodies[b].target_force * shape(k).sector / area(k);
  }
  update_velocities(0.0);
}

std::string Walls::name(int k) const {
  return k < kNumWalls ? wall_name(k) : names_[static_cast<std::size_t>(k - kNumWalls)];
}

double Walls::area(int k) const {
  if (shape(k).chamber >= 0) {
    return chamber_area(k == chamber_, chamber_radius(), position(4), position(5), sector());
  }
  if (k < kNumWalls) {
    const int a = wall_axis(k);
    return length((a + 1) % 3) * length((a + 2) % 3);
  }
  if (symmetry_[static_cast<std::size_t>(k)] && chamber_ >= 0) {
    // A quarter presses on its planes from the axis to the chamber, a half on its one plane
    // across the whole diameter.
    return (sector() > 0.25 ? 2.0 : 1.0) * chamber_radius() * length(2);
  }
  const double given = area_[static_cast<std::size_t>(k)];
  return given > 0.0 ? given : shape(k).sector * body_own_area(shape(k), position(k));
}

void Walls::drive(int k, const WallConfig& c, const std::string& key) {
  c.validate(key);  // throws before anything changes
  if (c.mode == WallMode::Servo && !(area(k) > 0.0)) {
    throw ConfigError(bad_value(key + ".mode", "\"servo\"",
                                "\"fixed\" or \"velocity\" for body \"" + name(k) + "\"" +
                                    ", which has no area to hold a stress over (give a plane an "
                                    "`area` in its [[body]] table)"));
  }
  cfg_[static_cast<std::size_t>(k)] = c;
  WallState& s = st_[static_cast<std::size_t>(k)];
  if (c.mode == WallMode::Fixed) s.velocity = 0.0;
  if (c.mode == WallMode::Velocity) s.velocity = c.velocity;
}

void Walls::update_velocities(double dt) {
  for (int k = 0; k < size(); ++k) {
    const WallConfig& c = cfg_[static_cast<std::size_t>(k)];
    WallState& s = st_[static_cast<std::size_t>(k)];
    switch (c.mode) {
      case WallMode::Fixed: s.velocity = 0.0; break;
      case WallMode::Velocity: s.velocity = c.velocity; break;
      case WallMode::Servo:
        s.velocity =
            servo_velocity(shape(k).outward_sign, body_load(shape(k), s.normal_force, s.force),
                           area(k), s.stiffness, dt, c.target_stress, c.servo_alpha, c.max_speed);
        break;
    }
  }
}

void Walls::move(double dt) {
  for (auto& s : st_) {
    s.position += s.velocity * dt;
    s.displacement_since_build += std::abs(s.velocity * dt);
  }
  check_radii();
}

void Walls::check_radii() const {
  for (int k = kNumWalls; k < size(); ++k) {
    const BodyShape& b = shape(k);
    if (!b.dilate || b.part[0].radius + position(k) > 0.0) continue;
    throw RuntimeFailure(
        "body \"" + name(k) + "\": its radius would reach " +
        show_number(b.part[0].radius + position(k)) + " m (the cylinder would turn inside out): " +
        (config(k).mode == WallMode::Servo
             ? "its servo found too little stress; raise its target_stress or lower max_speed"
             : "its velocity shrinks it past zero; lower the velocity or the duration"));
  }
}

double Walls::max_displacement_since_build() const {
  double m = 0.0;
  for (const auto& s : st_) m = std::max(m, s.displacement_since_build);
  return m;
}

void Walls::reset_displacements() {
  for (auto& s : st_) s.displacement_since_build = 0.0;
}

void WallContacts::resize(std::size_t n) {
  particle.resize(n);
  wall.resize(n);
  for (auto* a : {&ft_x, &ft_y, &ft_z, &fx, &fy, &fz, &tx, &ty, &tz, &F_n, &k_n, &delta}) {
    a->assign(n, 0.0);
  }
}

void WallContacts::build(const std::vector<double>& x, const std::vector<double>& y,
                         const std::vector<double>& z, const std::vector<double>& radius,
                         const Walls& walls, double skin) {
  const std::size_t N = x.size();
  static_assert(kMaxBodies <= 16, "a grain's bodies are one bit each of a 16-bit mask");
  const int bodies = walls.size();
  // Two passes (which bodies each grain is near, then the entries) so that grains are visited
  // in parallel and the entries come in grain order, then body order, on any thread count.
  std::vector<std::uint16_t> near(N, 0);
  offsets.assign(N + 1, 0);
#pragma omp parallel for schedule(static) if (worth_threading(N))
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(N); ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    std::uint32_t n = 0;
    for (int k = 0; k < bodies; ++k) {
      if (walls.surface(k, {x[i], y[i], z[i]}).dist - radius[i] < skin) {
        near[i] = static_cast<std::uint16_t>(near[i] | (1u << k));
        ++n;
      }
    }
    offsets[i + 1] = n;
  }
  for (std::size_t i = 0; i < N; ++i) offsets[i + 1] += offsets[i];
  resize(offsets[N]);
#pragma omp parallel for schedule(static) if (worth_threading(N))
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(N); ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    std::uint32_t w = offsets[i];
    for (int k = 0; k < bodies; ++k) {
      if ((near[i] >> k & 1u) == 0) continue;
      particle[w] = static_cast<std::uint32_t>(i);
      wall[w++] = static_cast<std::uint8_t>(k);
    }
  }
}

void Walls::state(StateArchive& a) {
  a.section("walls");
  // The layout of the struct's bytes (the format since version 1): the mode, 4 bytes of
  // padding (written as zeros, so that equal states give equal files: saved stage states are
  // compared as results), then the five numbers.
  static_assert(offsetof(WallConfig, position) == 8 && sizeof(WallConfig) == 48);
  for (WallConfig& c : cfg_) {
    std::uint32_t padding = 0;
    a(c.mode, padding, c.position, c.velocity, c.target_stress, c.servo_alpha, c.max_speed);
  }
  for (WallState& st : st_) a(st);
}

void WallContacts::state(StateArchive& a) {
  a.section("wall_contacts");
  a(particle, wall, ft_x, ft_y, ft_z, fx, fy, fz, tx, ty, tz, F_n, k_n, delta);
}

}  // namespace crushdem
