// The keys of a [[body]] table: a rigid body besides the box (docs/configuration.md [[body]],
// docs/chamber.md): its shape, where it is, how it moves and its friction with the grains.
//
//   shape = "plane"             infinite plane through `origin`, `axis` its normal into the body
//           "disk"              a flat disk of `radius` (a finite platen)
//           "cylinder_inside"   the inside of a cylinder (a chamber's lateral wall): axis from
//                               `origin`, `radius`, `length`
//           "cylinder_outside"  the outside of one (a rod, a pile shaft without its tip)
//           "cone"              a cone, apex at `origin`, opening along `axis` with `half_angle`
//                               up to `radius` (a penetrometer tip)
//           "pile"              a closed-ended pile: a shaft of `radius` and `length` on a tip at
//                               `origin`, conical (`tip = "cone"`, `half_angle`) or flat
// Motion: the body's one degree of freedom q is fixed, moves at `velocity` or is servo-
// controlled to `target_stress` (the keys of [walls.NAME]); `motion = "translate"` moves the
// body by q along `direction` (default: -axis, into the grains below a pile or above a platen),
// `motion = "dilate"` changes a cylinder's radius by q.
#pragma once

#include <string>
#include <vector>

#include "crushdem/core/params.hpp"
#include "crushdem/core/types.hpp"
#include "crushdem/walls/walls.hpp"

namespace crushdem {

enum class BodyKind { Plane, Disk, CylinderInside, CylinderOutside, Cone, Pile };
enum class PileTip { Cone, Flat };
enum class BodyMotion { Translate, Dilate };
/// The `shape` key's value of a kind ("plane", ..., "pile").
const char* to_string(BodyKind k);

struct BodyConfig : WallConfig {
  std::string name;
  BodyKind kind = BodyKind::Plane;  // key "shape"
  Vec3 origin;                      // [m]
  Vec3 axis{0.0, 0.0, 1.0};         // normal into the body, or the axis (normalised)
  double radius = 0.0;              // [m]
  double length = 0.0;              // [m]
  double half_angle = 30.0;         // [degrees]: the standard penetrometer's 60 degree apex
  PileTip tip = PileTip::Cone;
  BodyMotion motion = BodyMotion::Translate;
  Vec3 direction;             // translate: where q advances; zero: -axis
  double friction = -1.0;     // grain-body friction; negative: contact.wall_friction
  double area = 0.0;          // [m^2] a servo's area; 0: the shape's own surface
  double target_force = 0.0;  // [N] servo: the load to hold instead of target_stress (0: none)
  bool chamber = false;       // a chamber sample's lateral boundary (set by [sample], not a key)
  double sector = 1.0;        // the chamber's: the fraction of the circle the sample fills
  bool symmetry = false;      // a plane of symmetry of a chamber's sector (set by [sample])
  /// Range checks and the checks joining keys; errors name prefix.key.
  void validate(const std::string& prefix) const;
  /// The body (its geometry at q = 0, its motion), with `wall_friction` where none is given.
  Body make(double wall_friction) const;
};

/// The keys of a [[body]] table (core/params.hpp), `name` and the motion keys of [walls.NAME]
/// included.
const ParamTable<BodyConfig>& body_params();

/// Every body's checks, and names unique and none a box wall's; errors name "body[i].key".
void validate_bodies(const std::vector<BodyConfig>& bodies);

}  // namespace crushdem
