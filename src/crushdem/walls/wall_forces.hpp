// The grain-wall contact loop of the CPU engine: every candidate entry of WallContacts
// evaluated with wall_contact() (contact/contact_kernel.hpp, the kernel the device step runs
// too), then the totals of each wall (normal force, force, summed k_n) that the servo law and
// the wall stresses read. Chunks of entries in three passes (collect the touching entries,
// evaluate them in vector lanes, write back): bit for bit a one-by-one loop.
#pragma once

#include "crushdem/contact/contact_model.hpp"
#include "crushdem/particles/particle_store.hpp"
#include "crushdem/walls/walls.hpp"

namespace crushdem {

/// Evaluates every entry of `wc` with the contact law's wall evaluator (its tangential history
/// advanced by the step h; 0 refreshes the current state), stores each entry's results, and sets
/// each wall's normal force, force and stiffness in `walls` (summed in entry order:
/// deterministic).
void wall_forces(const ContactLaw& law, double h, const ParticleStore& p, Walls& walls,
                 WallContacts& wc);

}  // namespace crushdem
