// The stress field around a pile's shaft and the contact forces near it (docs/pile.md): what the
// set-up explanations of Axelsson (2000) and Zhang & Wang (2015) look at, measured in rings of
// grains about the pile's axis. On the host, from the last force evaluation.
//
// A ring is a cylindrical shell r_{m-1} <= r < r_m about the axis (r_0 = R, the shaft's radius;
// the outer radii geometric up to field_radius R), cut into `bins` slices of height dh from the
// tip's apex up to the top wall. Its stress is the Love-Weber average over the grains whose
// centres lie in it (Christoffersen et al. 1981; Bagi 1996):
//
//   sigma = (1 / V_ring) sum_{g in ring} sum_{c of g} a_c (F_n n n^T - n F_t^T)   (compression +)
//
// n the unit normal from the grain to contact c, a_c the distance from the grain's centre to the
// contact point (r - delta/2 between grains, r - delta at a body), F_t the tangential force on the
// grain; V_ring = sector pi (r_m^2 - r_{m-1}^2) dh, voids included. Each grain's term is turned
// into the cylindrical frame (e_r, e_theta, e_z) at its own azimuth before the sum: sigma_rr is
// radial, sigma_tt circumferential (hoop), sigma_zz vertical, tau_rz the shear on horizontal
// planes. The near-field force statistics count the grain-grain contacts whose midpoint lies
// within field_radius R of the axis and between the apex and the top wall.
#pragma once

#include <cstdint>
#include <vector>

#include "crushdem/integrate/simulation.hpp"

namespace crushdem {

struct RingStress {
  int ring = 0, bin = 0;
  double r_in = 0.0, r_out = 0.0;  // [m]
  double height = 0.0;             // the slice's middle above the apex [m]
  double sigma_rr = 0.0, sigma_tt = 0.0, sigma_zz = 0.0, tau_rz = 0.0;  // [Pa]
  std::uint64_t grains = 0;
  double body_volume = 0.0;  // [m^3] the body's share of the cell (measure_body_field), not in V
};

struct PileField {
  std::vector<RingStress> rings;  // ring-major: ring 0's slices from the apex up, then ring 1's
  std::uint64_t near_contacts = 0;
  double mean_Fn = 0.0, std_Fn = 0.0, mean_Ft = 0.0, std_Ft = 0.0;  // near the shaft [N]
};

/// The field around body k (a translating pile or cone on the z axis; probe_supports()).
/// rings >= 1, field_radius > 1 (in shaft radii), bins >= 1.
PileField measure_pile_field(const Simulation& sim, int k, int rings, double field_radius,
                             int bins);

/// The stress field about body k as a penetrate stage drives it (penetration_field.csv): rings of
/// equal width from the vertical line through its tip (ring 0 from r = 0: the sand under the
/// tip) out to field_radius R, R its shaft's radius, cut into `bins` slices from the bottom
/// platen to the top one (height above the bottom platen). A cell's volume leaves out the
/// body's share of it (its cones and shafts along z; `body_volume`): the stress is the sand's.
/// Empty without a positive sample height. rings >= 1, field_radius > 0, bins >= 1.
std::vector<RingStress> measure_body_field(const Simulation& sim, int k, int rings,
                                           double field_radius, int bins);

/// A chamber sample's stress profile with depth: the Love-Weber stress, in the cylindrical frame
/// about the chamber's axis, of the grains within `radius` of the axis (the core, clear of the
/// chamber wall's layers), in `bins` slices from the bottom platen to the top one (ring 0, bin
/// 0 at the bottom; height above the bottom platen). Empty without a chamber.
std::vector<RingStress> measure_chamber_profile(const Simulation& sim, double radius, int bins);

}  // namespace crushdem
