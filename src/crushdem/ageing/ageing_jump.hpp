// Off-DEM ageing jump (docs/model.md 3.1; the on-off scheme of the reference study).
//
// Between dynamic DEM phases the clock jumps: with every crack velocity frozen at the end of the
// phase (fracture/crack_growth.hpp), grain i would fail after t_f,i = (0.5 d_i - a_i) / v_i.
// The jump lasts the n_break-th smallest t_f (at most max_dt, the time left to the target);
// every crack grows by v_i dt, and the grains that reach failure get a = 0.5 d exactly, so that
// they break at the first crushing check of the next dynamic phase. Grains whose particle stress
// is already at their strength are left to instant failure at that check.
#pragma once

#include <cstddef>
#include <vector>

namespace crushdem {

class Crusher;
class Simulation;

struct AgeingJump {
  double dt = 0.0;          // ageing time jumped [s]
  std::size_t failing = 0;  // grains brought to failure (n_break; fewer when capped)
};

/// The length of a jump: the n_break-th smallest of the times to failure, capped at max_dt
/// (max_dt when fewer than n_break grains can fail at all).
double ageing_jump_duration(std::vector<double> t_fail, std::size_t n_break, double max_dt);

/// Performs one jump on the simulation's grains: computes the forces (and so the particle
/// stresses), the frozen velocities and the jump, and advances every crack.
AgeingJump ageing_jump(Simulation& sim, Crusher& crusher, std::size_t n_break, double max_dt);

}  // namespace crushdem
