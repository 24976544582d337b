// Macroscopic measurements of a Simulation at one instant (docs/model.md 4.3): wall stresses,
// Love-Weber stress, p and q, strains from the wall positions, void ratio, coordination number,
// contact-force statistics and kinetic energy. Compression is positive; the axial direction is z.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "crushdem/integrate/simulation.hpp"

namespace crushdem {

/// The reference state strains are measured from (box lengths at the start).
struct StrainReference {
  double length[3] = {0, 0, 0};
  double volume = 0.0;
  static StrainReference from(const Walls& w);
};

/// Named values in a fixed order, SI units in the names (e.g. "wall_zmax_stress_Pa").
using Measurement = std::vector<std::pair<std::string, double>>;

Measurement measure(const Simulation& sim, const StrainReference& ref);

/// Mean |resultant force| on a grain before local damping [N]; NaN when not available.
double mean_resultant_force(const Simulation& sim);
/// Mean |resultant force| over the mean grain-grain |F_n| (NaN when either is unknown).
double unbalanced_force_ratio(const Simulation& sim);

class Crusher;
/// Crushing measurements (docs/model.md 4.3): breakages by cause, removed volume and mass, the void
/// ratio with the removed volume counted as solid (fines), relative breakage B_r (Einav).
Measurement crushing_measurements(const Simulation& sim, const Crusher& crusher);

/// Sieve sizes for the grading output: 16, log-spaced from d_min (or d_max / 1000) to the largest
/// initial grain.
std::vector<double> grading_sieves(const Crusher& crusher);
/// Mass fraction passing each of those sieves now (removed volume counted as fines).
Measurement grading_measurements(const Simulation& sim, const Crusher& crusher,
                                 const std::vector<double>& sieves);

}  // namespace crushdem
