// What the grains do to one body, by part and along its axis: the measurements of a penetration
// test (docs/chamber.md). From the wall loop's last results per contact (WallContacts), on the
// host, when a controller asks (the device brings them back with Sync::All):
//
//   tip load      F_tip   = -sum over the tip's contacts of F_body . m    (m: the motion's unit
//                                                                          direction, into the
//                                                                          grains)
//   cone resistance q_c   = F_tip / (pi R^2)                             (R: the tip's base)
//   shaft load    F_shaft = -sum over the shaft's contacts of F_body . m  (friction)
//   sleeve friction f_s   = F_sleeve / (2 pi R L_s)                      (the shaft's contacts
//                                                                          within L_s of the tip)
//   radial stress sigma_r(bin) = sum of F_n in the bin / (2 pi R dh)     (bins of height dh
//                                                                          along the shaft)
//   shear stress  tau(bin)     = -sum of F_body . m in the bin / (2 pi R dh)
//
// and of every body beyond the box, the moment of the grains' forces about its reference point
// O (its `origin` where its degree of freedom has put it: a pile's or cone's tip, a cylinder's
// axis start, a plane's point):
//
//   M = sum over its contacts of (x_c - O) x F_body = -sum of ((x_i - O) x F + T)
//
// F and T: the entry's force on the grain and its torque about the grain's centre x_i (the
// contact point x_c = x_i + d n; T = d n x F_t, since the grains' wall law has no rolling
// couple), so the moment needs no contact point of its own.
//
// F_body is the force of the grain on the body (minus the entry's force on the grain). A
// contact's height on the shaft is its grain centre's axial coordinate from the shaft's start
// (the normal of a cylinder is radial, so the contact point has the same height). These are the
// chamber-test conventions of Lunne, Robertson & Powell (1997) and ISO 22476-1, without the
// pore-pressure correction (dry grains).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "crushdem/core/types.hpp"
#include "crushdem/particles/particle_store.hpp"
#include "crushdem/walls/walls.hpp"

namespace crushdem {

/// Whether body b can be probed: a translating body with a tip (a cone or a disk), a shaft (the
/// outside of a cylinder) or both (a pile).
bool probe_supports(const BodyShape& b);

struct BodyProbe {
  Vec3 tip;                    // the tip's point: a cone's apex, a flat tip's centre [m]
  double radius = 0.0;         // the shaft's or the tip's base radius R [m]
  bool has_tip = false;        // a cone or a flat tip (a bare shaft has none)
  double tip_load = 0.0;       // F_tip [N]
  double shaft_load = 0.0;     // F_shaft [N]
  double sleeve_load = 0.0;    // F_sleeve [N]
  double sleeve_length = 0.0;  // L_s, the shaft's length at most [m]
  std::uint64_t tip_contacts = 0, shaft_contacts = 0;  // touching (F_n > 0)
  double bin_height = 0.0;                             // dh [m]
  std::vector<double> sigma_r, tau;                    // by bin, from the shaft's start up [Pa]
  std::vector<std::uint64_t> bin_contacts;

  double sector = 1.0;  // the fraction of the body's circumference the grains reach
  double q_c() const;   // F_tip / (sector pi R^2) [Pa]; 0 without a tip
  double f_s() const;   // F_sleeve / (sector 2 pi R L_s) [Pa]; 0 without a shaft
};

/// Every body beyond the box clear of every grain (no grain overlaps its surface or lies inside
/// it): a body placed into the grains would start with an explosive overlap. ConfigError naming
/// body[i].origin, the body, the grain and its position otherwise; and in a chamber sample a pile
/// or cone at least as wide as the chamber, naming body[i].radius; and a pile or cone that moves
/// (named in `driven`, the bodies the stages drive, or at a velocity of its own) whose tip starts
/// beyond the platen it moves toward, naming body[i].origin.
/// Only the first `bodies` [[body]] tables are checked (all: -1): the bodies a chamber sample
/// brings (its chamber and symmetry planes, after them) hold grains pressed against them.
void check_bodies_clear(const Walls& walls, const ParticleStore& p, int bodies = -1,
                        const std::vector<std::string>& driven = {});

/// Body k of `walls` as the last force evaluation left it (probe_supports() must hold).
/// sleeve_length: L_s, clamped to the shaft's length; 0: the standard sleeve, 150 cm^2 on a
/// 35.7 mm cone (ISO 22476-1), 133.7 mm long, so 3.75 diameters of the tip's base. bins: the
/// number of bins along the shaft.
/// In a chamber sample of a sector (Walls::sector() < 1) the body lies on the axis and the
/// grains touch that sector of it: every area above is taken over the sector.
BodyProbe probe_body(const Walls& walls, int k, const WallContacts& wc, const ParticleStore& p,
                     double sleeve_length, int bins);

/// The reference point of body k (beyond the box): its first part's origin placed by its degree
/// of freedom (a translation moves it, a dilation keeps it).
Vec3 body_reference_point(const Walls& walls, int k);

/// The moment of the grains' forces on every body about its reference point, as the last force
/// evaluation left them [N m], indexed as `walls` (the box's six walls, which have no reference
/// point, get zero). In a chamber sample of a sector it is the sector's grains' moment.
std::vector<Vec3> body_moments(const Walls& walls, const WallContacts& wc, const ParticleStore& p);

}  // namespace crushdem
