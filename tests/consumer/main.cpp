// Two equal grains pressed together between walls: the installed headers and library build a
// Simulation, step it and read the contact back. Exit status 0 when the contact force is the
// Hertz force of its overlap, F = 4/3 E* sqrt(R*) delta^1.5.
#include <cmath>
#include <cstdio>

#include "crushdem/integrate/simulation.hpp"

int main() {
  using namespace crushdem;
  SimulationConfig cfg;
  cfg.contact.law = NormalLaw::Hertz;
  cfg.damping.local_alpha = 0.0;
  for (int k = 0; k < kNumWalls; ++k) {
    cfg.walls[static_cast<std::size_t>(k)].position = k % 2 == 0 ? -1e-3 : 1e-3;
  }
  Simulation sim(cfg);
  const double R = 0.1e-3, delta = 1e-6;
  sim.add_particle({-R + 0.5 * delta, 0.0, 0.0}, R);
  sim.add_particle({R - 0.5 * delta, 0.0, 0.0}, R);
  sim.compute_forces();
  const auto contacts = sim.contacts();
  if (contacts.size() != 1) {
    std::printf("expected one contact, found %zu\n", contacts.size());
    return 1;
  }
  const double G = cfg.material.shear_modulus, nu = cfg.material.poisson_ratio;
  const double E_star = G / (1.0 - nu);  // E / (2 (1 - nu^2)) for two equal materials
  const double F = 4.0 / 3.0 * E_star * std::sqrt(0.5 * R) * std::pow(delta, 1.5);
  const double F_n = contacts[0].F_n;
  std::printf("crushdem %s: F_n = %.6g N, Hertz %.6g N\n", CRUSHDEM_VERSION, F_n, F);
  return std::fabs(F_n - F) <= 1e-9 * F ? 0 : 1;
}
