// The CPU engine's integration passes of velocity Verlet with PFC local damping (docs/model.md
// 1.4), each grain by the rules of step_rules.hpp:
//
//   kick_drift()       the first half kick and the drift of every grain, writing the pair loop's
//                      packed copies from values already in registers, with the two
//                      displacement maxima (since the last neighbour build: the rebuild rule;
//                      in this step, from the position the last pair loop saw: the pruned
//                      list's);
//   gather_and_damp()  each grain's wall contacts (and its weight, with gravity) added to its
//                      pair sums, its undamped resultant kept, local damping, the second half kick,
//                      and (drift_next) the next step's kick and drift in the same pass, on values
//                      still in registers.
//
// Both run in vector lanes (`omp simd`): each element gets the same operations as a scalar loop
// and max() is exact, so lanes and threads change no bit.
#pragma once

#include <vector>

#include "crushdem/integrate/pair_loop.hpp"
#include "crushdem/neighbor/neighbor_list.hpp"
#include "crushdem/particles/particle_store.hpp"
#include "crushdem/walls/walls.hpp"

namespace crushdem {

/// The squared-displacement maxima of a drift.
struct DriftMaxima {
  double since_build2;  // largest squared displacement since the last neighbour build [m^2]
  double step2;         // largest squared displacement in this step [m^2]
};

/// First half kick and drift of every grain over the step h, with its displacement maxima.
DriftMaxima kick_drift(ParticleStore& p, const NeighborList& nl, CpuPairLoop& loop, double h,
                       double spin_scale);

/// Moves the pair loop's sums and the wall contacts' forces to the store (undamped resultant
/// into fu_*; damped force and torque into fx ... tz), zeroing the sums; a non-zero `gravity`
/// adds each grain's weight m g after its contacts; with kick the second half kick; with
/// drift_next also the next step's first half kick and drift (returns its maxima; otherwise
/// zeros).
DriftMaxima gather_and_damp(ParticleStore& p, const NeighborList& nl, CpuPairLoop& loop,
                            const WallContacts& wc, double h, double spin_scale, double alpha,
                            Vec3 gravity, bool kick, bool drift_next, std::vector<double>& fu_x,
                            std::vector<double>& fu_y, std::vector<double>& fu_z);

}  // namespace crushdem
