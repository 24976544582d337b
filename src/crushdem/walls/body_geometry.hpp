// The shapes of the rigid bodies that bound the grains (walls), written once for every backend
// in the manner of HOOMD-blue's wall evaluators: for a grain centre, a shape gives the distance
// to its surface on the grains' side, the outward normal there (from the grain towards the
// body), and the principal curvatures of the surface, which enter the contact's effective
// radius. Pure, header-only, host and device.
//
// Shapes (docs/model.md 1.3):
//   AxisPlane        a wall of the box: the plane x_a = position (a = k / 2), the grains on the
//                    inner side (wall_geometry.hpp; its arithmetic is the box's since version 1)
//   Plane            an infinite plane through `origin` with normal `axis`, pointing into the
//                    body (the grains on the other side)
//   Disk             a flat disk of `radius` about `origin` with normal `axis` (into the body):
//                    a flat pile tip or a finite platen; its rim is a circle (an edge)
//   CylinderInside   the inside of a cylinder of `radius` about the line through `origin` along
//                    `axis`, between axial coordinates 0 and `length` (a chamber's lateral wall)
//   CylinderOutside  the outside of such a cylinder (a pile shaft), closed by nothing: a grain
//                    beyond its ends sees no surface
//   Cone             the outside of a cone with its apex at `origin`, opening along `axis` with
//                    half-angle alpha, up to the base radius `radius` at height `length`
//                    (a penetrometer's or a pile's conical tip); beyond the base its rim
//                    circle (an edge), which a pile's shaft covers where its range reaches
// A body is one shape or a union of convex parts (a pile: a cylinder on a cone): a grain touches
// the part nearest to it, so that it never meets a convex body twice at a junction.
//
// Effective radius: Hertz's contact of a sphere of radius r with a surface of principal
// curvatures kappa_1, kappa_2 (positive where convex, negative where concave) is elliptical,
// with relative radii R' = 1 / (1/r + kappa_1) and R'' = 1 / (1/r + kappa_2). Its force at an
// approach delta is that of a sphere of radius R* = f sqrt(R' R''): F = (4/3) E* sqrt(R*)
// delta^(3/2) exactly, with f a function of R'/R'' alone, 1 on a sphere (Johnson, Contact
// Mechanics, 1985, 4.2: the ellipse's eccentricity from the ratio of the curvatures, then its
// approach and load from the complete elliptic integrals K and E). hertz_ellipse_factor() gives
// f within 4e-8 of the elliptic solution for R'/R'' up to 10 (a rational fit in
// w = ((R' - R'')/(R' + R''))^2, tests/test_bodies.cpp checks it against the integrals), and
// holds it at its value for 10 beyond (only a grain within about its radius of a cone's apex
// meets larger ratios; there it underestimates R*: by 20 % at 30). The contact laws take R*;
// on a plane R* = r exactly. An edge (a disk's rim) or a point (a cone's apex) has no finite
// curvature: the laws take R* = r there, as against a plane (CHOICE, as mesh walls in LIGGGHTS
// do).
#pragma once

#include <cmath>
#include <cstdint>

#include "crushdem/core/types.hpp"
#include "crushdem/walls/wall_geometry.hpp"

namespace crushdem {

enum class Shape : std::int32_t { AxisPlane, Plane, Disk, CylinderInside, CylinderOutside, Cone };

/// One shape of a body where its degree of freedom is zero (plain values).
struct BodyPart {
  Shape shape = Shape::Plane;
  std::int32_t wall = 0;     // AxisPlane: the box wall k (0..5)
  Vec3 origin;               // a point of the plane, the disk's centre, the axis' start, the apex
  Vec3 axis{0.0, 0.0, 1.0};  // unit: the plane's or disk's normal into the body; the axis
  double radius = 0.0;       // disk, cylinder, cone base [m]
  double length = 0.0;       // cylinder length, cone height [m]
  double cos_alpha = 1.0, sin_alpha = 0.0;  // cone half-angle
};

/// What the nearest surface of a body offers a grain.
struct SurfacePoint {
  double dist = 1e300;  // centre to surface, positive on the grains' side (huge: none)
  Vec3 n;               // unit normal from the centre towards the surface (into the body)
  double kappa_1 = 0.0, kappa_2 = 0.0;  // principal curvatures there [1/m]
  Vec3 radial;                          // the unit radial direction at the point (cylinders, cones)
};

/// f of R* = f sqrt(R' R'') for Hertz's elliptical contact with relative radii R1 and R2 (see
/// above); only arithmetic, so that the host and the device give the same bits.
CD_HD inline double hertz_ellipse_factor(double R1, double R2) {
  constexpr double kMaxW = (9.0 / 11.0) * (9.0 / 11.0);  // R1/R2 = 10
  const double u = (R1 - R2) / (R1 + R2);
  const double w = u * u < kMaxW ? u * u : kMaxW;
  const double num =
      1.0 + w * (-1.7672472721234223 + w * (0.9141075408117976 + w * -0.12403038928892231));
  const double den =
      1.0 + w * (-1.9339133416225749 + w * (1.1206746255933298 + w * -0.17873145053810405));
  return num / den;
}

/// Effective radius of a grain of radius r on a surface of curvatures kappa_1, kappa_2.
CD_HD inline double surface_R_star(double r, double kappa_1, double kappa_2) {
  if (kappa_1 == 0.0 && kappa_2 == 0.0) return r;  // a plane: exactly the grain's radius
  const double R1 = 1.0 / (1.0 / r + kappa_1), R2 = 1.0 / (1.0 / r + kappa_2);
  return hertz_ellipse_factor(R1, R2) * std::sqrt(R1 * R2);
}

namespace detail {

/// The centre's axial coordinate along a unit axis from `origin`, its radial distance and unit
/// radial direction (any perpendicular unit vector on the axis itself).
struct AxialPosition {
  double a, rho;
  Vec3 e_rho;
};

CD_HD inline AxialPosition axial_position(Vec3 c, Vec3 origin, Vec3 axis) {
  const Vec3 d = c - origin;
  const double a = dot(d, axis);
  const Vec3 radial = d - a * axis;
  const double rho = std::sqrt(dot(radial, radial));
  Vec3 e_rho;
  if (rho > 0.0) {
    e_rho = (1.0 / rho) * radial;
  } else {  // on the axis: any direction perpendicular to it
    const Vec3 t = std::fabs(axis.x) < 0.9 ? Vec3{1.0, 0.0, 0.0} : Vec3{0.0, 1.0, 0.0};
    const Vec3 p = t - dot(t, axis) * axis;
    e_rho = (1.0 / std::sqrt(dot(p, p))) * p;
  }
  return {a, rho, e_rho};
}

}  // namespace detail

/// Part s where the degree of freedom q has put it: moved by q along `motion` (a unit vector),
/// or with `dilate` its radius grown by q.
CD_HD_INLINE BodyPart placed_part(const BodyPart& s, double q, Vec3 motion, bool dilate) {
  BodyPart p = s;
  if (dilate) {
    p.radius = s.radius + q;
  } else {
    p.origin = s.origin + q * motion;
  }
  return p;
}

/// The surface of one part for a grain centred at c, the part placed by q (placed_part()).
CD_HD_INLINE SurfacePoint part_surface(const BodyPart& s, double q, Vec3 motion, bool dilate,
                                       Vec3 c) {
  SurfacePoint out;
  if (s.shape == Shape::AxisPlane) {  // the box's walls: most entries, and their own arithmetic
    out.dist = wall_gap(s.wall, q, c.x, c.y, c.z);
    out.n = wall_outward_normal(s.wall);
    return out;
  }
  const BodyPart placed = placed_part(s, q, motion, dilate);
  const Vec3 origin = placed.origin;
  const double radius = placed.radius;
  switch (s.shape) {
    case Shape::AxisPlane:  // above
      break;
    case Shape::Plane:
      out.dist = dot(origin - c, s.axis);
      out.n = s.axis;
      break;
    case Shape::Disk: {
      const detail::AxialPosition p = detail::axial_position(c, origin, s.axis);
      if (p.rho <= radius) {
        out.dist = -p.a;
        out.n = s.axis;
      } else {  // beyond the rim: the nearest point of the rim circle (an edge)
        const Vec3 rim = origin + radius * p.e_rho;
        const Vec3 d = rim - c;
        out.dist = std::sqrt(dot(d, d));
        out.n = (1.0 / out.dist) * d;
      }
      out.radial = p.e_rho;
      break;
    }
    case Shape::CylinderInside: {
      const detail::AxialPosition p = detail::axial_position(c, origin, s.axis);
      if (p.a < 0.0 || p.a > s.length) break;
      out.dist = radius - p.rho;
      out.n = p.e_rho;
      out.kappa_1 = -1.0 / radius;  // concave around, straight along
      out.radial = p.e_rho;
      break;
    }
    case Shape::CylinderOutside: {
      const detail::AxialPosition p = detail::axial_position(c, origin, s.axis);
      if (p.a < 0.0 || p.a > s.length) break;
      out.dist = p.rho - radius;
      out.n = -p.e_rho;
      out.kappa_1 = 1.0 / radius;
      out.radial = p.e_rho;
      break;
    }
    case Shape::Cone: {
      // In the half-plane of the axis and the centre: the generator from the apex (0, 0) to
      // (length, radius) with unit direction (cos alpha, sin alpha), the outward normal
      // (-sin alpha, cos alpha).
      const detail::AxialPosition p = detail::axial_position(c, origin, s.axis);
      const double t = p.a * s.cos_alpha + p.rho * s.sin_alpha;  // along the generator
      const double slant = s.length / s.cos_alpha;
      if (t <= 0.0) {  // nearest to the apex (a point)
        const Vec3 d = origin - c;
        out.dist = std::sqrt(dot(d, d));
        out.n = (1.0 / out.dist) * d;
      } else if (t <= slant) {
        out.dist = -p.a * s.sin_alpha + p.rho * s.cos_alpha;
        out.n = s.sin_alpha * s.axis - s.cos_alpha * p.e_rho;
        // Around the cone, the normal section's radius is the local radius over cos alpha.
        const double local = t * s.sin_alpha;
        out.kappa_1 = local > 0.0 ? s.cos_alpha / local : 0.0;
      } else {
        // Beyond the base: the base's rim circle (an edge), as a disk's. Where a shaft is
        // joined on, it is nearer wherever its own range reaches (its distance is the rim's
        // radial part), so the rim answers only in the wedge outside the convex junction,
        // between the two faces' normals, which neither face covers.
        const Vec3 rim = origin + s.length * s.axis + radius * p.e_rho;
        const Vec3 d = rim - c;
        out.dist = std::sqrt(dot(d, d));
        out.n = (1.0 / out.dist) * d;
      }
      out.radial = p.e_rho;
      break;
    }
  }
  return out;
}

/// A body's geometry: one shape or a union of convex parts, and how its one degree of freedom q
/// moves it (the box walls: q is the plane's coordinate; otherwise a translation by q along
/// `motion`, or with `dilate` a change of radius by q). Plain values: the device holds an array
/// of them.
struct BodyShape {
  static constexpr int kMaxParts = 2;
  BodyPart part[kMaxParts];
  std::int32_t parts = 1;
  bool dilate = false;
  Vec3 motion{0.0, 0.0, 1.0};
  /// Increasing q moves the surface away from the grains (+1) or towards them (-1): the sign
  /// that turns the servo law's outward speed into dq/dt.
  double outward_sign = 1.0;
  double friction = 0.0;  // grain-body friction coefficient
  /// A chamber sample's (docs/chamber.md): the index of the chamber's cylinder, whose radius sets
  /// the servo area of the cylinder itself and of the platens (the box's z walls); -1: none.
  std::int32_t chamber = -1;
  /// The fraction of the circle a chamber sample fills (1; a half or a quarter between
  /// symmetry planes): it scales the chamber's servo areas, and the own area of a body on the
  /// sector's axis, of which the grains reach that fraction.
  double sector = 1.0;
};

/// The nearest surface of body b (degree of freedom q) to a grain centred at c; `part` is set to
/// the part it belongs to.
CD_HD_INLINE SurfacePoint body_surface(const BodyShape& b, double q, Vec3 c, int& part) {
  SurfacePoint best = part_surface(b.part[0], q, b.motion, b.dilate, c);
  part = 0;
  for (int k = 1; k < b.parts; ++k) {
    const SurfacePoint s = part_surface(b.part[k], q, b.motion, b.dilate, c);
    if (s.dist < best.dist) {
      best = s;
      part = k;
    }
  }
  return best;
}

/// The surface area of body b's parts at degree of freedom q (0 for an infinite plane): the area
/// a servo on a finite body takes its stress over.
CD_HD inline double body_own_area(const BodyShape& b, double q) {
  double A = 0.0;
  for (int k = 0; k < b.parts; ++k) {
    const BodyPart& s = b.part[k];
    const double R = b.dilate ? s.radius + q : s.radius;
    switch (s.shape) {
      case Shape::Disk: A += kPi * R * R; break;
      case Shape::CylinderInside:
      case Shape::CylinderOutside: A += 2.0 * kPi * R * s.length; break;
      case Shape::Cone: A += kPi * R * std::sqrt(R * R + s.length * s.length); break;
      case Shape::AxisPlane:
      case Shape::Plane: break;
    }
  }
  return A;
}

/// The servo area in a chamber sample, radius R between platens at z_bottom and z_top, filling
/// the fraction `sector` of the circle: the chamber's wall carries its lateral stress over
/// sector 2 pi R (z_top - z_bottom), a platen its vertical stress over sector pi R^2.
CD_HD inline double chamber_area(bool chamber_wall, double R, double z_bottom, double z_top,
                                 double sector) {
  return sector * (chamber_wall ? 2.0 * kPi * R * (z_top - z_bottom) : kPi * R * R);
}

/// The load conjugate to a body's degree of freedom, which the servo law holds at its target
/// stress times its area: a box wall's or a dilating cylinder's summed normal contact force; for
/// a translation, the force resisting the advance, -F . direction (the friction on a pile's shaft
/// included). normal_force: the sum of the contacts' normal forces; force: the total force of
/// the grains on the body.
CD_HD inline double body_load(const BodyShape& b, double normal_force, Vec3 force) {
  if (b.part[0].shape == Shape::AxisPlane || b.dilate) return normal_force;
  return -dot(force, b.motion);
}

/// The velocity of body b's surface at a point with radial direction `radial`, for dq/dt = v.
CD_HD inline Vec3 body_surface_velocity(const BodyShape& b, double v, Vec3 radial) {
  if (b.part[0].shape == Shape::AxisPlane) return wall_velocity_vector(b.part[0].wall, v);
  return b.dilate ? v * radial : v * b.motion;
}

/// What a contact needs of a body: for a grain of radius r centred at c, the distance to the
/// body's nearest surface, the normal towards it, the surface's velocity there (dq/dt = v) and
/// the contact's effective radius. One function for the CPU's wall loop and the device's.
struct BodyContact {
  double dist;
  Vec3 n, velocity;
  double R_star;
};

CD_HD_INLINE BodyContact body_contact(const BodyShape& b, double q, double v, Vec3 c, double r) {
  if (b.part[0].shape == Shape::AxisPlane) {  // a box wall (most contacts): its own arithmetic
    const int k = b.part[0].wall;
    return {wall_gap(k, q, c.x, c.y, c.z), wall_outward_normal(k), wall_velocity_vector(k, v), r};
  }
  int part = 0;
  const SurfacePoint s = body_surface(b, q, c, part);
  return {s.dist, s.n, body_surface_velocity(b, v, s.radial),
          surface_R_star(r, s.kappa_1, s.kappa_2)};
}

}  // namespace crushdem
