#include "crushdem/experiments/pile_field.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "crushdem/walls/body_geometry.hpp"

namespace crushdem {
namespace {

/// Where a point lies in the field: its ring and slice (-1 outside), and its frame.
struct FieldPlace {
  int ring = -1, bin = -1;
  Vec3 e_r, e_t;
};

/// Rings about an axis (radii `edges`, increasing) cut into `bins` slices from `base` up to
/// `h_top` along `up`.
class FieldGrid {
 public:
  FieldGrid(Vec3 base, Vec3 up, std::vector<double> edges, double h_top, int bins)
      : base_(base), up_(up), bins_(bins), h_top_(h_top), edges_(std::move(edges)) {}
  FieldPlace place(Vec3 x) const {
    FieldPlace f;
    // (the bodies' own cylindrical coordinates, with their radial direction on the axis)
    const detail::AxialPosition p = detail::axial_position(x, base_, up_);
    if (!(p.a >= 0.0 && p.a < h_top_)) return f;
    if (!(p.rho >= edges_.front() && p.rho < edges_.back())) return f;
    const auto it = std::upper_bound(edges_.begin(), edges_.end(), p.rho);
    f.ring = static_cast<int>(it - edges_.begin()) - 1;
    f.bin = std::min(static_cast<int>(p.a / h_top_ * bins_), bins_ - 1);
    f.e_r = p.e_rho;
    f.e_t = cross(up_, f.e_r);
    return f;
  }
  int rings() const { return static_cast<int>(edges_.size()) - 1; }
  int bins() const { return bins_; }
  double edge(int m) const { return edges_[static_cast<std::size_t>(m)]; }
  double slice() const { return h_top_ / bins_; }
  std::size_t cell(const FieldPlace& f) const {
    return static_cast<std::size_t>(f.ring) * static_cast<std::size_t>(bins_) +
           static_cast<std::size_t>(f.bin);
  }
  const Vec3& up() const { return up_; }

 private:
  Vec3 base_, up_;
  int bins_;
  double h_top_;
  std::vector<double> edges_;
};

/// u . (F_n n n^T - n F_t^T) . v
double component(Vec3 u, Vec3 v, double F_n, Vec3 n, Vec3 F_t) {
  return dot(u, n) * (F_n * dot(n, v) - dot(F_t, v));
}

/// The Love-Weber stress of each ring and slice of `grid` (ring-major), in the cylindrical
/// frame at each grain's own azimuth; `near` sees every grain-grain contact with its midpoint.
template <class Near>
std::vector<RingStress> ring_stresses(const Simulation& sim, const FieldGrid& grid, Near&& near) {
  const ParticleStore& p = sim.particles();
  const int rings = grid.rings(), bins = grid.bins();
  const std::size_t cells = static_cast<std::size_t>(rings) * static_cast<std::size_t>(bins);
  std::vector<double> s_rr(cells, 0.0), s_tt(cells, 0.0), s_zz(cells, 0.0), t_rz(cells, 0.0);
  std::vector<std::uint64_t> grains(cells, 0);
  std::vector<std::int64_t> index(static_cast<std::size_t>(p.next_id()), -1);
  std::vector<FieldPlace> place(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p.id[i] < index.size()) index[p.id[i]] = static_cast<std::int64_t>(i);
    place[i] = grid.place({p.x[i], p.y[i], p.z[i]});
    if (place[i].ring >= 0) ++grains[grid.cell(place[i])];
  }
  // One contact end: grain i's term a (F_n n n^T - n F_t^T) in its own cylindrical frame.
  auto add = [&](std::size_t i, double a, double F_n, Vec3 n, Vec3 F_t) {
    const FieldPlace& f = place[i];
    if (f.ring < 0) return;
    const std::size_t c = grid.cell(f);
    const Vec3 e_z = grid.up();
    s_rr[c] += a * component(f.e_r, f.e_r, F_n, n, F_t);
    s_tt[c] += a * component(f.e_t, f.e_t, F_n, n, F_t);
    s_zz[c] += a * component(e_z, e_z, F_n, n, F_t);
    t_rz[c] += 0.5 * a * (component(f.e_r, e_z, F_n, n, F_t) + component(e_z, f.e_r, F_n, n, F_t));
  };
  for (const ContactRecord& c : sim.contacts()) {
    const auto i = static_cast<std::size_t>(index[c.id_i]);
    if (c.is_wall) {
      add(i, p.radius[i] - c.delta, c.F_n, c.normal, c.F_t);
      continue;
    }
    const auto j = static_cast<std::size_t>(index[c.id_j]);
    // The grain-grain term: F_t is the force on i, so j's is -F_t, and j's normal is -n.
    add(i, p.radius[i] - 0.5 * c.delta, c.F_n, c.normal, c.F_t);
    add(j, p.radius[j] - 0.5 * c.delta, c.F_n, -1.0 * c.normal, -1.0 * c.F_t);
    const Vec3 xi{p.x[i], p.y[i], p.z[i]}, xj{p.x[j], p.y[j], p.z[j]};
    near(0.5 * (xi + xj), c);
  }
  std::vector<RingStress> out;
  const double dh = grid.slice();
  for (int m = 0; m < rings; ++m) {
    const double r0 = grid.edge(m), r1 = grid.edge(m + 1);
    const double V = sim.walls().sector() * kPi * (r1 * r1 - r0 * r0) * dh;
    for (int s = 0; s < bins; ++s) {
      const std::size_t c = static_cast<std::size_t>(m) * static_cast<std::size_t>(bins) +
                            static_cast<std::size_t>(s);
      RingStress r;
      r.ring = m;
      r.bin = s;
      r.r_in = r0;
      r.r_out = r1;
      r.height = (s + 0.5) * dh;
      r.sigma_rr = s_rr[c] / V;
      r.sigma_tt = s_tt[c] / V;
      r.sigma_zz = s_zz[c] / V;
      r.tau_rz = t_rz[c] / V;
      r.grains = grains[c];
      out.push_back(r);
    }
  }
  return out;
}

/// A body's tip (its first part's origin where its degree of freedom puts it) and the radius of
/// its shaft (of its tip where it has none).
struct TipAndRadius {
  Vec3 apex;
  double R = 0.0;
};
TipAndRadius tip_and_radius(const Walls& w, int k) {
  const BodyShape& b = w.shape(k);
  TipAndRadius t{placed_part(b.part[0], w.position(k), b.motion, b.dilate).origin,
                 b.part[0].radius};
  for (int j = 0; j < b.parts; ++j) {
    if (b.part[j].shape == Shape::CylinderOutside) t.R = b.part[j].radius;
  }
  return t;
}

}  // namespace

PileField measure_pile_field(const Simulation& sim, int k, int rings, double field_radius,
                             int bins) {
  PileField out;
  const Walls& w = sim.walls();
  const BodyShape& b = w.shape(k);
  const TipAndRadius tip = tip_and_radius(w, k);
  const Vec3 apex = tip.apex;  // (plain names: a lambda below reads them)
  const double R = tip.R;
  const Vec3 up = (-1.0 / norm(b.motion)) * b.motion;
  // The slices reach the top wall (the sample's surface) along the axis.
  const double h_top = up.z > 0.5 ? (w.position(5) - apex.z) / up.z : 0.0;
  if (!(h_top > 0.0) || rings < 1 || bins < 1 || !(field_radius > 1.0)) return out;
  std::vector<double> edges(static_cast<std::size_t>(rings) + 1);
  for (int m = 0; m <= rings; ++m) {
    edges[static_cast<std::size_t>(m)] = R * std::pow(field_radius, static_cast<double>(m) / rings);
  }
  const FieldGrid grid(apex, up, std::move(edges), h_top, bins);
  double sum_fn = 0.0, sum_fn2 = 0.0, sum_ft = 0.0, sum_ft2 = 0.0;
  out.rings = ring_stresses(sim, grid, [&](Vec3 mid, const ContactRecord& c) {
    const Vec3 d = mid - apex;
    const double h = dot(d, up);
    if (!(h >= 0.0 && h < h_top) || !(norm(d - h * up) < field_radius * R)) return;
    ++out.near_contacts;
    const double ft = norm(c.F_t);
    sum_fn += c.F_n;
    sum_fn2 += c.F_n * c.F_n;
    sum_ft += ft;
    sum_ft2 += ft * ft;
  });
  if (out.near_contacts > 0) {
    const double n = static_cast<double>(out.near_contacts);
    out.mean_Fn = sum_fn / n;
    out.mean_Ft = sum_ft / n;
    out.std_Fn = std::sqrt(std::max(0.0, sum_fn2 / n - out.mean_Fn * out.mean_Fn));
    out.std_Ft = std::sqrt(std::max(0.0, sum_ft2 / n - out.mean_Ft * out.mean_Ft));
  }
  return out;
}

std::vector<RingStress> measure_body_field(const Simulation& sim, int k, int rings,
                                           double field_radius, int bins) {
  const Walls& w = sim.walls();
  const double h = w.position(5) - w.position(4);
  if (!(h > 0.0) || rings < 1 || bins < 1 || !(field_radius > 0.0)) return {};
  const auto [apex, R] = tip_and_radius(w, k);
  std::vector<double> edges(static_cast<std::size_t>(rings) + 1);
  for (int m = 0; m <= rings; ++m) {
    edges[static_cast<std::size_t>(m)] = field_radius * R * m / rings;
  }
  const FieldGrid grid({apex.x, apex.y, w.position(4)}, {0.0, 0.0, 1.0}, std::move(edges), h, bins);
  std::vector<RingStress> cells = ring_stresses(sim, grid, [](Vec3, const ContactRecord&) {});
  // The body's volume in each cell, taken out of it: the stress is the sand's. The body's
  // radius at height z is the largest of its solid parts' (cones and shafts along z), integrated
  // over each slice by the midpoint rule (exact for a shaft).
  const BodyShape& b = w.shape(k);
  std::vector<BodyPart> solids;
  for (int j = 0; j < b.parts; ++j) {
    const BodyPart s = placed_part(b.part[j], w.position(k), b.motion, b.dilate);
    if ((s.shape == Shape::Cone || s.shape == Shape::CylinderOutside) &&
        std::abs(std::abs(s.axis.z) - 1.0) < 1e-12) {
      solids.push_back(s);
    }
  }
  const auto body_radius = [&solids](double z) {
    double rho = 0.0;
    for (const BodyPart& s : solids) {
      const double a = (z - s.origin.z) * s.axis.z;  // along the part's axis from its start
      if (!(a >= 0.0 && a <= s.length)) continue;
      rho = std::max(rho, s.shape == Shape::Cone ? s.radius * a / s.length : s.radius);
    }
    return rho;
  };
  constexpr int kSamples = 64;  // per slice
  const double dh = h / bins;
  for (RingStress& c : cells) {
    double area = 0.0;  // sum over the samples of the body's section within the ring / pi
    for (int m = 0; m < kSamples; ++m) {
      const double z = w.position(4) + (c.bin + (m + 0.5) / kSamples) * dh;
      const double rho = std::clamp(body_radius(z), c.r_in, c.r_out);
      area += rho * rho - c.r_in * c.r_in;
    }
    c.body_volume = w.sector() * kPi * area * dh / kSamples;
    const double V = w.sector() * kPi * (c.r_out * c.r_out - c.r_in * c.r_in) * dh;
    const double scale = V > c.body_volume ? V / (V - c.body_volume) : 0.0;
    c.sigma_rr *= scale;
    c.sigma_tt *= scale;
    c.sigma_zz *= scale;
    c.tau_rz *= scale;
  }
  return cells;
}

std::vector<RingStress> measure_chamber_profile(const Simulation& sim, double radius, int bins) {
  const Walls& w = sim.walls();
  const int k = w.chamber();
  const double h = w.position(5) - w.position(4);
  if (k < 0 || bins < 1 || !(radius > 0.0) || !(h > 0.0)) return {};
  const Vec3 axis = w.shape(k).part[0].origin;
  const FieldGrid grid({axis.x, axis.y, w.position(4)}, {0.0, 0.0, 1.0}, {0.0, radius}, h, bins);
  return ring_stresses(sim, grid, [](Vec3, const ContactRecord&) {});
}

}  // namespace crushdem
