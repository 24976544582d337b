// ParaView files: VTK XML PolyData (.vtp) with the arrays in one appended block of raw binary
// (little-endian, 64-bit sizes), and the .pvd collection that lists the snapshots of a run with
// their times, so that ParaView opens the run as one time series.
//   particles: one vertex per grain; id, parent id (-1: none), radius, velocity, angular
//              velocity, force and every per-grain field (strength, crack length, ...);
//   contacts:  one line per touching contact from the centre of grain i to the centre of grain
//              j (to the contact point for a wall); normal force, tangential force, overlap;
//   box:       the six walls as quadrilaterals;
//   bodies:    the bodies beyond the box as surfaces (48 segments around a circle; an infinite
//              plane as a square the box's diagonal across), each polygon with its body index
//              (6 is the first [[body]]) and part (a pile's tip 0, its shaft 1).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "crushdem/integrate/simulation.hpp"
#include "crushdem/particles/particle_store.hpp"

namespace crushdem {

/// The grains of `p`; the force as three arrays (the resultant before damping when the caller
/// has it; left out when empty).
void write_vtp_particles(const std::string& path, const ParticleStore& p,
                         const std::vector<double>& fx, const std::vector<double>& fy,
                         const std::vector<double>& fz);

/// The contact network: `contacts` as lines between the grains of `p` they join.
void write_vtp_contacts(const std::string& path, const ParticleStore& p,
                        const std::vector<ContactRecord>& contacts);

/// The walls at positions `box` (xmin, xmax, ymin, ymax, zmin, zmax).
void write_vtp_box(const std::string& path, const double box[6]);

/// The bodies of `walls` beyond the box, where their degrees of freedom have put them.
void write_vtp_bodies(const std::string& path, const Walls& walls);

/// One entry of a .pvd collection: a file (relative to the .pvd) at a time.
struct PvdEntry {
  double time = 0.0;
  std::string file;
};

/// The collection file of `entries`, written atomically (a reader never sees half of it).
void write_pvd(const std::string& path, const std::vector<PvdEntry>& entries);

}  // namespace crushdem
