#include "crushdem/walls/body_config.hpp"

#include <algorithm>
#include <cmath>
#include <set>

#include "crushdem/core/error.hpp"

namespace crushdem {
namespace {

constexpr std::array<Named<BodyKind>, 6> kKindNames = {
    {{BodyKind::Plane, "plane"},
     {BodyKind::Disk, "disk"},
     {BodyKind::CylinderInside, "cylinder_inside"},
     {BodyKind::CylinderOutside, "cylinder_outside"},
     {BodyKind::Cone, "cone"},
     {BodyKind::Pile, "pile"}}};
constexpr std::array<Named<PileTip>, 2> kTipNames = {
    {{PileTip::Cone, "cone"}, {PileTip::Flat, "flat"}}};
constexpr std::array<Named<BodyMotion>, 2> kMotionNames = {
    {{BodyMotion::Translate, "translate"}, {BodyMotion::Dilate, "dilate"}}};

bool is_cylinder(BodyKind k) {
  return k == BodyKind::CylinderInside || k == BodyKind::CylinderOutside;
}
bool has_radius(BodyKind k) {
  return k != BodyKind::Plane;
}
bool has_length(BodyKind k) {
  return is_cylinder(k) || k == BodyKind::Pile;
}

Vec3 unit(Vec3 v) {
  return (1.0 / std::sqrt(dot(v, v))) * v;
}

/// The cone's height for a base radius R and half-angle alpha [degrees].
double cone_height(double R, double alpha_deg) {
  return R / std::tan(alpha_deg * kPi / 180.0);
}

BodyPart cone_part(Vec3 apex, Vec3 axis, double R, double alpha_deg) {
  BodyPart p;
  p.shape = Shape::Cone;
  p.origin = apex;
  p.axis = axis;
  p.radius = R;
  p.length = cone_height(R, alpha_deg);
  p.cos_alpha = std::cos(alpha_deg * kPi / 180.0);
  p.sin_alpha = std::sin(alpha_deg * kPi / 180.0);
  return p;
}

}  // namespace

const char* to_string(BodyKind k) {
  return name_of(kKindNames, k);
}

const ParamTable<BodyConfig>& body_params() {
  using B = BodyConfig;
  static const ParamTable<B> table = [] {
    ParamTable<B> t = {
        {"name", &B::name, "", "the body's name in the outputs (timeseries columns body_NAME_...)"},
        {"shape", enum_choice(&B::kind, kKindNames), "",
         "the body's shape (walls/body_geometry.hpp, docs/chamber.md)"},
        {"origin", &B::origin, "m",
         "a point of the plane, the disk's centre, the start of a cylinder's axis, the cone's "
         "apex, the pile's tip (its apex or the centre of its flat end)",
         nullptr, "an array of 3 numbers [x, y, z] in m"},
        {"axis", &B::axis, "-",
         "a plane's or disk's normal pointing into the body; a cylinder's, cone's or pile's axis "
         "(a pile's from its tip up its shaft); normalised",
         nullptr, "an array of 3 numbers [x, y, z], not all zero"},
        {"radius", &B::radius, "m", "disk, cylinder, cone base or pile shaft radius",
         [](double v) { return v >= 0.0; }, "a radius > 0 in m"},
        {"length", &B::length, "m", "cylinder length along its axis from `origin`; pile length",
         [](double v) { return v >= 0.0; }, "a length > 0 in m"},
        {"half_angle", &B::half_angle, "deg",
         "cone half-angle (a cone, a pile's conical tip); 30 is the standard penetrometer's 60 "
         "degree apex (ISO 22476-1)",
         [](double v) { return v > 0.0 && v < 90.0; }, "an angle in (0, 90) degrees"},
        {"tip",
         enum_choice(&B::tip, kTipNames),
         "",
         "a pile's tip",
         nullptr,
         {},
         {},
         [](const B& b) { return b.kind == BodyKind::Pile; }},
        {"motion", enum_choice(&B::motion, kMotionNames), "",
         "what the degree of freedom q does: translate the body by q along `direction`, or "
         "(a cylinder) change its radius by q"},
        {"direction", &B::direction, "-",
         "translate: the direction q advances in (into the grains), normalised; [0, 0, 0] means "
         "-axis",
         nullptr, "an array of 3 numbers [x, y, z]"},
        {"friction", &B::friction, "-",
         "grain-body friction coefficient; negative: contact.wall_friction",
         [](double) { return true; }, "a friction coefficient (negative: contact.wall_friction)"},
        {"area", &B::area, "m^2",
         "the area a servo takes the body's stress over; 0: the shape's own surface (a plane "
         "has none: give it)",
         [](double v) { return v >= 0.0; }, "an area >= 0 in m^2"},
    };
    append_rows(t, wall_params());
    for (Param<B>& p : t) {  // a body's q is not a box wall's coordinate
      if (p.key == std::string_view("velocity")) {
        p.doc =
            "velocity mode: dq/dt, along `direction` for a translating body (positive: into the "
            "grains) or the radius's rate of change for a dilating cylinder";
      }
      if (p.key == std::string_view("target_stress")) {  // or the load, target_force
        p.doc = "servo mode: compressive normal stress to hold (or give target_force)";
        p.applies = [](const B& b) { return b.mode == WallMode::Servo && !(b.target_force > 0.0); };
      }
    }
    // Before target_stress, whose check it decides: a bad load is named as itself.
    const auto stress_row = std::find_if(t.begin(), t.end(), [](const Param<B>& p) {
      return p.key == std::string_view("target_stress");
    });
    t.insert(stress_row,
             Param<B>{"target_force",
                      &B::target_force,
                      "N",
                      "servo mode: the load to hold instead of a stress, the force resisting the "
                      "body's advance (a translating body; one on a chamber sector's axis: the "
                      "whole body's, as a pile stage's head_load); 0: hold target_stress",
                      [](double v) { return v >= 0.0; },
                      "a load >= 0 in N",
                      {},
                      [](const B& b) { return b.mode == WallMode::Servo; }});
    return t;
  }();
  return table;
}

void BodyConfig::validate(const std::string& prefix) const {
  validate_params(*this, body_params(), prefix);
  const auto fail = [&](const std::string& key, const std::string& value,
                        const std::string& expected) {
    throw ConfigError(bad_value(prefix + "." + key, value, expected));
  };
  if (name.empty()) fail("name", "\"\"", "a name for the body");
  // unit() divides by the square root of the squared length: it must be a finite, non-zero
  // double, or the body would be built along a zero or NaN direction.
  const auto zero = [](Vec3 v) { return v.x == 0.0 && v.y == 0.0 && v.z == 0.0; };
  const auto usable = [](Vec3 v) { return dot(v, v) > 0.0 && std::isfinite(dot(v, v)); };
  const char* scaled =
      "a direction whose components are between 1e-150 and 1e150 in size "
      "(their scale does not matter: [0, 0, 1], say)";
  if (zero(axis)) fail("axis", show_vec(axis), "a direction, not [0, 0, 0]");
  if (!usable(axis)) fail("axis", show_vec(axis), scaled);
  if (!zero(direction) && !usable(direction)) {
    fail("direction", show_vec(direction), std::string(scaled) + ", or [0, 0, 0] for -axis");
  }
  if (has_radius(kind) && !(radius > 0.0)) {
    fail("radius", show_number(radius), std::string("a radius > 0 in m for a ") + to_string(kind));
  }
  if (has_length(kind) && !(length > 0.0)) {
    fail("length", show_number(length), std::string("a length > 0 in m for a ") + to_string(kind));
  }
  if (kind == BodyKind::Pile && tip == PileTip::Cone &&
      !(length > cone_height(radius, half_angle))) {
    fail("length", show_number(length),
         "a pile longer than its conical tip (" + show_number(cone_height(radius, half_angle)) +
             " m for this radius and half_angle)");
  }
  if (motion == BodyMotion::Dilate && !is_cylinder(kind)) {
    fail("motion", "\"dilate\"",
         "\"translate\" for a " + std::string(to_string(kind)) + " (only a cylinder dilates)");
  }
  if (target_force > 0.0 && motion == BodyMotion::Dilate) {
    fail("target_force", show_number(target_force),
         "0 for a dilating cylinder, whose area changes with its radius: give target_stress");
  }
  if (mode == WallMode::Servo && kind == BodyKind::Plane && !(area > 0.0)) {
    fail("area", show_number(area), "an area > 0 in m^2 for a servo-controlled plane");
  }
}

Body BodyConfig::make(double wall_friction) const {
  Body b;
  b.name = name;
  b.motion = *this;
  b.motion.position = 0.0;
  b.area = area;
  b.target_force = target_force;
  b.chamber = chamber;
  b.sector = sector;
  b.symmetry = symmetry;
  BodyShape& s = b.shape;
  const Vec3 a = unit(axis);
  s.friction = friction < 0.0 ? wall_friction : friction;
  s.dilate = motion == BodyMotion::Dilate;
  s.motion = dot(direction, direction) > 0.0 ? unit(direction) : -a;
  // q advances into the grains for a translation; a dilating cylinder's inside retreats from
  // them as it grows, its outside advances into them.
  s.outward_sign = s.dilate ? (kind == BodyKind::CylinderInside ? 1.0 : -1.0) : -1.0;
  s.parts = 1;
  BodyPart& p = s.part[0];
  p.origin = origin;
  p.axis = a;
  p.radius = radius;
  p.length = length;
  switch (kind) {
    case BodyKind::Plane: p.shape = Shape::Plane; break;
    case BodyKind::Disk: p.shape = Shape::Disk; break;
    case BodyKind::CylinderInside: p.shape = Shape::CylinderInside; break;
    case BodyKind::CylinderOutside: p.shape = Shape::CylinderOutside; break;
    case BodyKind::Cone: p = cone_part(origin, a, radius, half_angle); break;
    case BodyKind::Pile:
      // The tip, then the shaft on it: a grain touches whichever is nearer.
      s.parts = 2;
      if (tip == PileTip::Cone) {
        p = cone_part(origin, a, radius, half_angle);
      } else {
        p.shape = Shape::Disk;
      }
      {
        BodyPart& shaft = s.part[1];
        const double h = tip == PileTip::Cone ? p.length : 0.0;
        shaft.shape = Shape::CylinderOutside;
        shaft.origin = origin + h * a;
        shaft.axis = a;
        shaft.radius = radius;
        shaft.length = length - h;
      }
      break;
  }
  return b;
}

void validate_bodies(const std::vector<BodyConfig>& bodies) {
  std::set<std::string> names;
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const std::string prefix = "body[" + std::to_string(i) + "]";
    bodies[i].validate(prefix);
    const std::string& n = bodies[i].name;
    bool box = false;
    for (int k = 0; k < kNumWalls; ++k) box |= n == wall_name(k);
    if (box || !names.insert(n).second) {
      throw ConfigError(bad_value(
          prefix + ".name", "\"" + n + "\"",
          box ? "a name that is not a box wall's (xmin ... zmax)" : "a name no other body has"));
    }
  }
  if (bodies.size() + kNumWalls > static_cast<std::size_t>(kMaxBodies)) {
    throw ConfigError(bad_value("body", std::to_string(bodies.size()) + " bodies",
                                "at most " + std::to_string(kMaxBodies - kNumWalls)));
  }
}

}  // namespace crushdem
