// One contact's response, assembled from the pure parts of the contact law
// (contact/contact_model.hpp: normal law, viscous damping, Mindlin tangential with Coulomb cap;
// the couple sub-model, rolling resistance, adds its moment in the loops), in the manner of
// LAMMPS `pair granular`. The same function serves grain-grain and grain-wall contacts; only the
// geometry passed in differs.
#pragma once

#include "crushdem/contact/contact_model.hpp"
#include "crushdem/contact/damping.hpp"
#include "crushdem/contact/rolling.hpp"
#include "crushdem/contact/tangential.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

struct ContactResponse {
  Vec3 force;        // total force on body 1 [N]
  Vec3 F_t;          // new elastic tangential force on body 1 (the history to keep) [N]
  Vec3 tangential;   // total tangential force on body 1 (elastic + viscous) [N]
  double F_n = 0.0;  // elastic normal force magnitude [N]
  double k_n = 0.0;  // tangent normal stiffness [N/m]
};

/// n: unit normal from body 1 towards body 2; v_rel: velocity of body 1 relative to body 2 at
/// the contact point; F_t_old: stored tangential force on body 1; mu: friction of this contact.
/// kFastPath: the rare steps are left out (contact_plane_spring(), and the cap on the total
/// tangential force below); fast_path_inexact(r.F_t.x) tells where that changed the result.
template <class Law, bool kFastPath = false>
CD_HD_INLINE ContactResponse contact_response(const Law& law, double delta, double R_star,
                                              double sqrt_R_star, double m_eff, Vec3 n, Vec3 v_rel,
                                              Vec3 F_t_old, double mu, const ContactParams& p,
                                              double dt) {
  ContactResponse r;
  const NormalForce nf = law(delta, R_star, sqrt_R_star);
  r.F_n = nf.F_n;
  r.k_n = nf.k_n;
  const double v_n = dot(v_rel, n);  // > 0 while approaching
  const Vec3 v_t = v_rel - v_n * n;
  r.F_t =
      mindlin_tangential<kFastPath>(F_t_old, n, dt * v_t, p.tangential_ratio * nf.k_n, mu, nf.F_n);
  double F_normal = nf.F_n;
  Vec3 F_damp_t{};
  if (p.viscous.alpha_n > 0.0 && delta > 0.0) {
    const double eta_n = viscous_coefficient(p.viscous.alpha_n, m_eff, nf.k_secant);
    // No cohesion: damping may slow a separating pair but never pull it together.
    F_normal = F_normal + eta_n * v_n > 0.0 ? F_normal + eta_n * v_n : 0.0;
    F_damp_t = (-p.viscous.tangential_factor * eta_n) * v_t;
    // The total tangential force obeys the Coulomb cap as well.
    const Vec3 total = r.F_t + F_damp_t;
    const double t2 = dot(total, total), cap = mu * nf.F_n;
    if (exceeds_cap(t2, cap)) {
      if constexpr (kFastPath) {
        r.F_t = {kNeedsExactPath, kNeedsExactPath, kNeedsExactPath};
      } else {
        F_damp_t = (cap / std::sqrt(t2)) * total - r.F_t;
      }
    }
  }
  r.tangential = r.F_t + F_damp_t;
  r.force = (-F_normal) * n + r.tangential;
  return r;
}

/// After a kFastPath evaluation: whether a rare step applied, from one component of the new
/// history F_t (the fast path sets all three to kNeedsExactPath), so that the contact must be
/// evaluated again without kFastPath.
CD_HD inline bool fast_path_inexact(double F_t_x) {
  return F_t_x == kNeedsExactPath;
}

/// One grain-grain contact from its geometry, shared by every backend's pair loop.
struct PairContact {
  ContactResponse c;            // force and new tangential history on grain i
  Vec3 tn;                      // n x (tangential force): torque on i is a_i tn, on j a_j tn
  double a_i = 0.0, a_j = 0.0;  // lever arms r - delta/2
  double delta = 0.0;           // overlap [m]
  Vec3 n;                       // unit normal from i to j
};

/// dx = x_j - x_i (d2 = |dx|^2 < (r_i + r_j)^2), dv = v_i - v_j; R*, sqrt(R*) and the effective
/// mass come cached per pair. n points from i to j; v_rel = dv + (a_i w_i + a_j w_j) x n.
/// kFastPath: see contact_response().
template <class Law, bool kFastPath = false>
CD_HD_INLINE PairContact pair_contact(const Law& law, Vec3 dx, double d2, double r_i, double r_j,
                                      Vec3 dv, Vec3 w_i, Vec3 w_j, double R_star,
                                      double sqrt_R_star, double m_eff, Vec3 F_t_old,
                                      const ContactParams& p, double dt) {
  PairContact out;
  const double dist = std::sqrt(d2);
  // Coincident centres have no normal; any fixed one keeps the numbers finite.
  const Vec3 n = dist > 0.0 ? (1.0 / dist) * dx : Vec3{1.0, 0.0, 0.0};
  const double delta = r_i + r_j - dist;
  out.delta = delta;
  out.n = n;
  out.a_i = r_i - 0.5 * delta;
  out.a_j = r_j - 0.5 * delta;
  const Vec3 v_rel = dv + cross(out.a_i * w_i + out.a_j * w_j, n);
  out.c = contact_response<Law, kFastPath>(law, delta, R_star, sqrt_R_star, m_eff, n, v_rel,
                                           F_t_old, p.mu, p, dt);
  out.tn = cross(n, out.c.tangential);
  return out;
}

/// One grain-body contact, shared by every backend's wall loop. n: the unit normal from the
/// grain's centre towards the body (walls/body_geometry.hpp); dist: centre-to-surface distance
/// (delta = r - dist > 0); R_star: the contact's effective radius (the grain's radius against a
/// plane, surface_R_star() against a curved surface); m: the grain's mass (m* = m);
/// wall_velocity: the surface's velocity at the contact; mu: the body's friction.
struct WallContact {
  ContactResponse c;
  Vec3 torque;            // on the grain
  double F_n_wall = 0.0;  // normal force on the wall (elastic + viscous)
};

template <class Law>
CD_HD inline WallContact wall_contact(const Law& law, Vec3 n, double dist, double delta,
                                      double R_star, double m, Vec3 v, Vec3 w, Vec3 wall_velocity,
                                      Vec3 F_t_old, double mu, const ContactParams& p, double dt) {
  WallContact out;
  const Vec3 v_rel = v + cross(w, dist * n) - wall_velocity;
  out.c = contact_response(law, delta, R_star, std::sqrt(R_star), m, n, v_rel, F_t_old, mu, p, dt);
  out.torque = dist * cross(n, out.c.tangential);
  out.F_n_wall = -dot(out.c.force, n);
  return out;
}

}  // namespace crushdem
