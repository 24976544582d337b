#include "crushdem/walls/body_probe.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "crushdem/core/error.hpp"

namespace crushdem {
namespace {

bool is_tip(Shape s) {
  return s == Shape::Cone || s == Shape::Disk;
}

// A pile or cone that moves (driven by a stage, or at a velocity of its own) whose tip starts
// beyond the platen it moves toward (the bottom one for a body driven down): its shaft would also
// overlap grains, but the platen is what the user misplaced. A body that stays may pass through
// a platen (a rod through the sample).
void check_tip_inside(const Walls& walls, int k, const std::vector<std::string>& driven) {
  const BodyShape& b = walls.shape(k);
  const bool moves = walls.config(k).mode != WallMode::Fixed ||
                     std::find(driven.begin(), driven.end(), walls.name(k)) != driven.end();
  if (!probe_supports(b) || !is_tip(b.part[0].shape) || !moves || b.motion.z == 0.0) return;
  const double tip_z = placed_part(b.part[0], walls.position(k), b.motion, b.dilate).origin.z;
  const bool down = b.motion.z < 0.0;
  const double platen = walls.position(down ? 4 : 5);
  if (down ? tip_z > platen : tip_z < platen) return;
  throw ConfigError(
      bad_value("body[" + std::to_string(k - kNumWalls) + "].origin", show_vec(b.part[0].origin),
                std::string("a place where body \"") + walls.name(k) + "\"'s tip is " +
                    (down ? "above the bottom" : "below the top") +
                    " platen, which it moves toward (the tip is at z = " + show_number(tip_z) +
                    " m, the platen at " + show_number(platen) + " m)"));
}

}  // namespace

bool probe_supports(const BodyShape& b) {
  if (b.dilate || b.part[0].shape == Shape::AxisPlane) return false;
  for (int k = 0; k < b.parts; ++k) {
    const Shape s = b.part[k].shape;
    if (!is_tip(s) && s != Shape::CylinderOutside) return false;
  }
  return true;
}

void check_bodies_clear(const Walls& walls, const ParticleStore& p, int bodies,
                        const std::vector<std::string>& driven) {
  const int end = bodies < 0 ? walls.size() : std::min(walls.size(), kNumWalls + bodies);
  for (int k = kNumWalls; k < end; ++k) {
    // A pile or cone as wide as the chamber would crush the whole sample as it goes in.
    if (walls.chamber() >= 0 && k != walls.chamber() && probe_supports(walls.shape(k))) {
      double r = 0.0;
      for (int j = 0; j < walls.shape(k).parts; ++j) r = std::max(r, walls.shape(k).part[j].radius);
      if (r >= walls.chamber_radius()) {
        throw ConfigError(bad_value(
            "body[" + std::to_string(k - kNumWalls) + "].radius", show_number(r),
            "a radius below the chamber's (" + show_number(walls.chamber_radius()) + " m)"));
      }
    }
    check_tip_inside(walls, k, driven);
    for (std::size_t i = 0; i < p.size(); ++i) {
      const Vec3 c{p.x[i], p.y[i], p.z[i]};
      if (walls.surface(k, c).dist >= p.radius[i]) continue;
      throw ConfigError(bad_value("body[" + std::to_string(k - kNumWalls) + "].origin",
                                  show_vec(walls.shape(k).part[0].origin),
                                  "a place where body \"" + walls.name(k) +
                                      "\" is clear of the grains at the start (it "
                                      "overlaps grain id " +
                                      std::to_string(p.id[i]) + " of radius " +
                                      show_number(p.radius[i]) + " m at " + show_vec(c) + ")"));
    }
  }
}

double BodyProbe::q_c() const {
  return has_tip ? tip_load / (sector * kPi * radius * radius) : 0.0;
}

double BodyProbe::f_s() const {
  return sleeve_length > 0.0 ? sleeve_load / (sector * 2.0 * kPi * radius * sleeve_length) : 0.0;
}

BodyProbe probe_body(const Walls& walls, int k, const WallContacts& wc, const ParticleStore& p,
                     double sleeve_length, int bins) {
  const BodyShape& b = walls.shape(k);
  const double q = walls.position(k);
  BodyProbe out;
  const BodyPart* shaft = nullptr;
  int shaft_index = -1;
  for (int j = 0; j < b.parts; ++j) {
    if (b.part[j].shape == Shape::CylinderOutside) {
      shaft = &b.part[j];
      shaft_index = j;
    }
  }
  const BodyPart& first = b.part[0];
  out.tip = placed_part(first, q, b.motion, b.dilate).origin;
  out.radius = first.radius;
  out.has_tip = is_tip(first.shape);
  out.sector = walls.sector();
  Vec3 shaft_origin;
  double dh = 0.0;
  if (shaft != nullptr) {
    shaft_origin = placed_part(*shaft, q, b.motion, b.dilate).origin;
    const double standard = 0.1337 / 0.0357 * 2.0 * first.radius;  // ISO 22476-1
    out.sleeve_length = std::min(sleeve_length > 0.0 ? sleeve_length : standard, shaft->length);
    bins = std::max(bins, 1);
    dh = shaft->length / bins;
    out.bin_height = dh;
    out.sigma_r.assign(static_cast<std::size_t>(bins), 0.0);
    out.tau.assign(static_cast<std::size_t>(bins), 0.0);
    out.bin_contacts.assign(static_cast<std::size_t>(bins), 0);
  }
  for (std::size_t e = 0; e < wc.size(); ++e) {
    if (wc.wall[e] != k || !(wc.F_n[e] > 0.0)) continue;
    const std::uint32_t i = wc.particle[e];
    const Vec3 c{p.x[i], p.y[i], p.z[i]};
    int part = 0;
    (void)body_surface(b, q, c, part);
    // The grain's force on the body resisting the advance: minus the entry's force on the grain.
    const double load = dot(Vec3{wc.fx[e], wc.fy[e], wc.fz[e]}, b.motion);
    if (part != shaft_index) {
      out.tip_load += load;
      ++out.tip_contacts;
      continue;
    }
    out.shaft_load += load;
    ++out.shaft_contacts;
    const double h = dot(c - shaft_origin, shaft->axis);
    if (h < out.sleeve_length) out.sleeve_load += load;
    const auto bin = static_cast<std::size_t>(
        std::clamp(static_cast<int>(std::floor(h / dh)), 0, static_cast<int>(bins) - 1));
    out.sigma_r[bin] += wc.F_n[e];
    out.tau[bin] += load;
    ++out.bin_contacts[bin];
  }
  if (shaft != nullptr) {
    const double A_bin = out.sector * 2.0 * kPi * shaft->radius * dh;
    for (std::size_t j = 0; j < out.sigma_r.size(); ++j) {
      out.sigma_r[j] /= A_bin;
      out.tau[j] /= A_bin;
    }
  }
  return out;
}

Vec3 body_reference_point(const Walls& walls, int k) {
  const BodyShape& b = walls.shape(k);
  return placed_part(b.part[0], walls.position(k), b.motion, b.dilate).origin;
}

std::vector<Vec3> body_moments(const Walls& walls, const WallContacts& wc, const ParticleStore& p) {
  std::vector<Vec3> M(static_cast<std::size_t>(walls.size()));
  std::vector<Vec3> O(M.size());
  for (int k = kNumWalls; k < walls.size(); ++k) {
    O[static_cast<std::size_t>(k)] = body_reference_point(walls, k);
  }
  // In entry order, as the body totals: the same bits on every backend and thread count.
  for (std::size_t e = 0; e < wc.size(); ++e) {
    const std::size_t k = wc.wall[e];
    if (k < static_cast<std::size_t>(kNumWalls)) continue;
    const std::uint32_t i = wc.particle[e];
    const Vec3 arm = Vec3{p.x[i], p.y[i], p.z[i]} - O[k];
    M[k] -= cross(arm, Vec3{wc.fx[e], wc.fy[e], wc.fz[e]}) + Vec3{wc.tx[e], wc.ty[e], wc.tz[e]};
  }
  return M;
}

}  // namespace crushdem
