// Six rigid planar walls forming a box (docs/model.md 1.3, 4.2).
//
// Wall k (0..5) is xmin, xmax, ymin, ymax, zmin, zmax: axis k/2, low side when k is even. Each
// wall is fixed, moves at a prescribed velocity, or is servo-controlled to a target normal
// stress with the PFC-style gain
//
//   v_out = g (sigma_measured - sigma_target),  g = alpha A / (sum k_n dt),
//
// clamped to a maximum speed (v_out along the wall's outward normal, so a wall carrying too much
// stress retreats). Wall stress = sum of the normal contact forces / current wall area.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "crushdem/core/params.hpp"
#include "crushdem/core/state_io.hpp"
#include "crushdem/core/types.hpp"
#include "crushdem/walls/wall_geometry.hpp"

namespace crushdem {

const char* wall_name(int k);  // "xmin" ... "zmax"

enum class WallMode { Fixed, Velocity, Servo };
const char* to_string(WallMode m);
/// "fixed" | "velocity" | "servo"; anything else throws ConfigError naming `key`.
WallMode parse_wall_mode(const std::string& s, const std::string& key);

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

class Walls {
 public:
  Walls() = default;
  explicit Walls(const std::array<WallConfig, kNumWalls>& cfg);

  const WallConfig& config(int k) const { return cfg_[static_cast<std::size_t>(k)]; }
  WallConfig& config(int k) { return cfg_[static_cast<std::size_t>(k)]; }
  const WallState& state(int k) const { return st_[static_cast<std::size_t>(k)]; }
  WallState& state(int k) { return st_[static_cast<std::size_t>(k)]; }

  double position(int k) const { return st_[static_cast<std::size_t>(k)].position; }
  /// Side length of the box along an axis.
  double length(int axis) const { return position(2 * axis + 1) - position(2 * axis); }
  double volume() const { return length(0) * length(1) * length(2); }
  /// Current area of wall k (the box cross-section normal to its axis).
  double area(int k) const;
  /// Compressive normal stress on wall k [Pa].
  double stress(int k) const { return state(k).normal_force / area(k); }
  /// Mean of the two walls of an axis [Pa]; axial is z, lateral the mean of x and y.
  double axis_stress(int axis) const { return 0.5 * (stress(2 * axis) + stress(2 * axis + 1)); }
  double axial_stress() const { return axis_stress(2); }
  double lateral_stress() const { return 0.5 * (axis_stress(0) + axis_stress(1)); }
  /// Outward unit normal of wall k (from the sample into the wall).
  Vec3 outward_normal(int k) const { return wall_outward_normal(k); }

  /// Sets wall velocities for the next step (fixed, prescribed or servo).
  void update_velocities(double dt);
  /// Moves the walls by their velocities.
  void move(double dt);
  double max_displacement_since_build() const;
  void reset_displacements();
  /// Modes, targets, positions, velocities and servo state, bit for bit (checkpoints).
  void state(StateArchive& a);

 private:
  std::array<WallConfig, kNumWalls> cfg_{};
  std::array<WallState, kNumWalls> st_{};
};

/// Candidate particle-wall contacts (within the skin at the last build), with tangential
/// history keyed by (particle id, wall) so it survives rebuilds and compaction (the engine's
/// ContactHistory carries it over). Entries are sorted by particle: those of particle i are
/// offsets[i] .. offsets[i + 1] (CSR).
struct WallContacts {
  std::vector<std::uint32_t> particle;
  std::vector<std::uint8_t> wall;
  std::vector<std::uint32_t> offsets;
  std::vector<double> ft_x, ft_y, ft_z;  // tangential force on the particle [N]
  // Results of the last force evaluation (per entry):
  std::vector<double> fx, fy, fz, tx, ty, tz, F_n, k_n, delta;

  std::size_t size() const { return particle.size(); }
  void resize(std::size_t n);
  /// The entries (with zero history) of every grain whose gap to a wall is below r + skin.
  void build(const std::vector<double>& x, const std::vector<double>& y,
             const std::vector<double>& z, const std::vector<double>& radius, const Walls& walls,
             double skin);
  /// Entry list, history and last results (offsets are the engine's to save, see Simulation).
  void state(StateArchive& a);
};

}  // namespace crushdem
