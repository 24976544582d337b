// The rigid bodies that bound the grains (docs/model.md 1.3, 4.2): the six planar walls of the
// box, then any further bodies of any shape (walls/body_geometry.hpp: planes, disks, cylinders
// inside and out, cones, a pile of a shaft and a tip). Every body is one degree of freedom q
// (a box wall's coordinate; a translation or a change of radius for the others) that is fixed,
// moves at a prescribed velocity, or is servo-controlled to a target normal stress with the
// PFC-style gain
//
//   v_out = g (sigma_measured - sigma_target),  g = alpha A / (sum k_n dt),
//
// clamped to a maximum speed (v_out moves the surface away from the grains, so a body carrying
// too much stress retreats). Stress = sum of the normal contact forces / the body's area: a box
// wall's current cross-section of the box, a finite body's own surface, or the area a plane
// body is given.
//
// Box wall k (0..5) is xmin, xmax, ymin, ymax, zmin, zmax: axis k/2, low side when k is even.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "crushdem/core/params.hpp"
#include "crushdem/core/state_io.hpp"
#include "crushdem/core/types.hpp"
#include "crushdem/walls/body_geometry.hpp"
#include "crushdem/walls/wall_geometry.hpp"

namespace crushdem {

const char* wall_name(int k);  // "xmin" ... "zmax"

enum class WallMode { Fixed, Velocity, Servo };
inline constexpr std::array<Named<WallMode>, 3> kWallModeNames = {
    {{WallMode::Fixed, "fixed"}, {WallMode::Velocity, "velocity"}, {WallMode::Servo, "servo"}}};
inline const char* to_string(WallMode m) {
  return name_of(kWallModeNames, m);
}
/// "fixed" | "velocity" | "servo"; anything else throws ConfigError naming `key`.
inline WallMode parse_wall_mode(const std::string& s, const std::string& key) {
  return parse_named(kWallModeNames, s, key);
}

struct WallConfig {
  WallMode mode = WallMode::Fixed;
  double position = 0.0;       // initial plane coordinate along its axis [m]
  double velocity = 0.0;       // Velocity mode: velocity along the coordinate axis [m/s]
  double target_stress = 0.0;  // Servo mode: compressive normal stress [Pa]
  double servo_alpha = 0.5;    // Servo gain factor alpha [-] (docs/model.md 4.2)
  double max_speed = 0.05;     // Servo speed limit [m/s]
  void validate(const std::string& prefix) const;
};

/// The keys of a [walls.NAME] section (core/params.hpp); the position comes from [box].
const ParamTable<WallConfig>& wall_params();

struct WallState {
  double position = 0.0;
  double velocity = 0.0;                  // along the coordinate axis [m/s]
  double normal_force = 0.0;              // sum of normal contact forces pressing on the wall [N]
  Vec3 force;                             // total force exerted by the particles on the wall [N]
  double stiffness = 0.0;                 // sum of k_n of its contacts [N/m]
  double displacement_since_build = 0.0;  // |travel| since the last neighbour build [m]
};

/// A body beyond the box: its name, its shape and how it moves (WallConfig: q's mode; position
/// is q at the start, velocity dq/dt), and for a servo on an infinite plane the area its stress
/// is taken over.
struct Body {
  std::string name;
  BodyShape shape;
  WallConfig motion;
  double area = 0.0;  // [m^2]; 0: the shape's own (a disk's, a cylinder's lateral surface)
  /// A servo on a load [N] (the whole body's, in a sector too) rather than on
  /// motion.target_stress, which Walls sets from it; 0: none.
  double target_force = 0.0;
  /// The lateral boundary of a chamber sample (a dilating cylinder_inside about z, the box's z
  /// walls its platens): the sample's volume, lateral size and stress are then the chamber's.
  bool chamber = false;
  double sector = 1.0;  // the chamber's: the fraction of the circle the sample fills
  /// A plane of symmetry of a chamber's sector: its stress is over the part the grains press on,
  /// R (z_top - z_bottom) in a quarter, 2 R (z_top - z_bottom) in a half (the mean hoop stress
  /// there).
  bool symmetry = false;
};

class Walls {
 public:
  Walls() = default;
  /// The box's six walls (their friction with the grains: wall_friction), then `bodies`.
  Walls(const std::array<WallConfig, kNumWalls>& box, double wall_friction,
        std::vector<Body> bodies = {});

  /// Bodies, the box's six walls first.
  int size() const { return static_cast<int>(cfg_.size()); }
  const WallConfig& config(int k) const { return cfg_[static_cast<std::size_t>(k)]; }
  WallConfig& config(int k) { return cfg_[static_cast<std::size_t>(k)]; }
  const WallState& state(int k) const { return st_[static_cast<std::size_t>(k)]; }
  WallState& state(int k) { return st_[static_cast<std::size_t>(k)]; }
  const BodyShape& shape(int k) const { return shape_[static_cast<std::size_t>(k)]; }
  /// "xmin" ... "zmax" for the box, the configured name beyond.
  std::string name(int k) const;
  /// Every body's shape, and the servo area each was given (0: the box's cross-section or the
  /// shape's own surface): what a device copy holds.
  const std::vector<BodyShape>& shapes() const { return shape_; }
  const std::vector<double>& given_areas() const { return area_; }

  double position(int k) const { return st_[static_cast<std::size_t>(k)].position; }
  /// The chamber's body (a chamber sample), or -1 (a box sample).
  int chamber() const { return chamber_; }
  /// The fraction of the circle a chamber sample fills (1 without symmetry planes); 1 for a box.
  double sector() const { return chamber_ >= 0 ? shape(chamber_).sector : 1.0; }
  /// The chamber's current radius (a chamber sample).
  double chamber_radius() const { return shape(chamber_).part[0].radius + position(chamber_); }
  /// The sample's size along an axis: the box's side, or in a chamber sample its diameter
  /// across (x, y) and the platens' distance along z.
  double length(int axis) const {
    if (chamber_ >= 0 && axis < 2) return 2.0 * chamber_radius();
    return position(2 * axis + 1) - position(2 * axis);
  }
  /// The sample's volume: the box's, or the chamber's between the platens.
  double volume() const {
    if (chamber_ >= 0) return sector() * kPi * chamber_radius() * chamber_radius() * length(2);
    return length(0) * length(1) * length(2);
  }
  /// The bodies that hold the sample laterally: the box's four side walls, or the chamber.
  std::vector<int> lateral_walls() const {
    return chamber_ >= 0 ? std::vector<int>{chamber_} : std::vector<int>{0, 1, 2, 3};
  }
  /// Every body that holds the sample: the lateral walls, then the platens (z walls).
  std::vector<int> sample_walls() const {
    std::vector<int> k = lateral_walls();
    k.insert(k.end(), {4, 5});
    return k;
  }
  /// The sample's size across which body k moves (a servo's speed limit is a strain rate of
  /// it): a box wall's axis length, the chamber's diameter; 0 for other bodies.
  double extent(int k) const {
    if (k < kNumWalls) return length(k / 2);
    return k == chamber_ ? 2.0 * chamber_radius() : 0.0;
  }
  /// Current area of body k: a box wall's cross-section of the box, a chamber sample's
  /// chamber and platens and symmetry planes their sector's, or the area the body was given, or
  /// its own (in a sector, a body on the axis: the sector's part of it).
  double area(int k) const;
  /// Compressive normal stress on body k [Pa]: its load (body_load()) over its area; NaN for a
  /// body without one (a plane given no `area`).
  double stress(int k) const {
    const double A = area(k);
    return A > 0.0 ? body_load(shape(k), state(k).normal_force, state(k).force) / A
                   : std::numeric_limits<double>::quiet_NaN();
  }
  /// Mean of the two walls of an axis [Pa], or across (x, y) in a chamber sample the chamber's
  /// radial stress; axial is z, lateral the mean of x and y.
  double axis_stress(int axis) const {
    if (chamber_ >= 0 && axis < 2) return stress(chamber_);
    return 0.5 * (stress(2 * axis) + stress(2 * axis + 1));
  }
  double axial_stress() const { return axis_stress(2); }
  double lateral_stress() const { return 0.5 * (axis_stress(0) + axis_stress(1)); }
  /// The mean normal stress on the sample's boundary (mean_stress_Pa, the preparation's
  /// decisions): of the six box walls, or in a chamber (2 sigma_r + sigma_z) / 3 from the
  /// chamber's wall and the platens.
  double mean_stress() const {
    if (chamber_ >= 0) return (2.0 * lateral_stress() + axial_stress()) / 3.0;
    double p = 0.0;
    for (int k = 0; k < kNumWalls; ++k) p += stress(k) / kNumWalls;
    return p;
  }
  /// Outward unit normal of box wall k (from the sample into the wall).
  Vec3 outward_normal(int k) const { return wall_outward_normal(k); }
  /// Body k's nearest surface to a grain centred at c (walls/body_geometry.hpp).
  SurfacePoint surface(int k, Vec3 c) const {
    int part = 0;
    return body_surface(shape(k), position(k), c, part);
  }

  /// Drives body k as `c` from the next step on (a front end's change of mode or target):
  /// checks `c` (errors name `key`.KEY) and refuses a servo on a body without an area; a fixed
  /// or prescribed velocity applies at once, a servo keeps the current velocity until its
  /// controller next chooses one.
  void drive(int k, const WallConfig& c, const std::string& key);
  /// Sets body velocities for the next step (fixed, prescribed or servo).
  void update_velocities(double dt);
  /// Moves the bodies by their velocities (check_radii() after).
  void move(double dt);
  /// Every dilating cylinder's radius still positive; RuntimeFailure naming the body otherwise.
  void check_radii() const;
  double max_displacement_since_build() const;
  void reset_displacements();
  /// Modes, targets, positions, velocities and servo state, bit for bit (checkpoints; the box
  /// walls' layout is that of format 1, the bodies beyond follow in the same layout: their
  /// number and shapes come from the configuration).
  void state(StateArchive& a);

 private:
  std::vector<WallConfig> cfg_;
  std::vector<WallState> st_;
  std::vector<BodyShape> shape_;
  std::vector<std::string> names_;  // of the bodies beyond the box
  std::vector<double> area_;        // configured servo areas (0: the box's or the shape's)
  std::vector<bool> symmetry_;      // a chamber sector's plane of symmetry
  int chamber_ = -1;
};

/// Candidate particle-body contacts (within the skin at the last build), with tangential
/// history keyed by (particle id, body) so it survives rebuilds and compaction (the engine's
/// ContactHistory carries it over). Entries are sorted by particle: those of particle i are
/// offsets[i] .. offsets[i + 1] (CSR).
struct WallContacts {
  std::vector<std::uint32_t> particle;
  std::vector<std::uint8_t> wall;  // the body
  std::vector<std::uint32_t> offsets;
  std::vector<double> ft_x, ft_y, ft_z;  // tangential force on the particle [N]
  // Results of the last force evaluation (per entry):
  std::vector<double> fx, fy, fz, tx, ty, tz, F_n, k_n, delta;

  std::size_t size() const { return particle.size(); }
  void resize(std::size_t n);
  /// The entries (with zero history) of every grain whose gap to a body is below r + skin.
  void build(const std::vector<double>& x, const std::vector<double>& y,
             const std::vector<double>& z, const std::vector<double>& radius, const Walls& walls,
             double skin);
  /// Entry list, history and last results (offsets are the engine's to save, see Simulation).
  void state(StateArchive& a);
};

/// The most bodies a run holds (the box's six walls included): entries name them in a byte.
inline constexpr int kMaxBodies = 16;

}  // namespace crushdem
