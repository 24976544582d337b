#include "crushdem/particles/particle_store.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "crushdem/core/deterministic.hpp"

namespace crushdem {

std::size_t ParticleStore::add_field(const std::string& name, double init) {
  for (std::size_t k = 0; k < extra_names_.size(); ++k) {
    if (extra_names_[k] == name) return k;
  }
  extra_names_.push_back(name);
  extra_init_.push_back(init);
  extra_.emplace_back(size(), init);
  return extra_names_.size() - 1;
}

std::size_t ParticleStore::field_index(const std::string& name) const {
  for (std::size_t k = 0; k < extra_names_.size(); ++k) {
    if (extra_names_[k] == name) return k;
  }
  throw std::out_of_range("no particle field named '" + name + "'");
}

bool ParticleStore::has_field(const std::string& name) const {
  return std::find(extra_names_.begin(), extra_names_.end(), name) != extra_names_.end();
}

template <class Fn>
void ParticleStore::for_each_array(Fn&& fn) {
  fn(id);
  fn(parent);
  for (auto* a : {&x, &y, &z, &vx, &vy, &vz, &wx, &wy, &wz, &fx, &fy, &fz, &tx, &ty, &tz, &radius,
                  &mass, &inv_mass, &inv_inertia}) {
    fn(*a);
  }
  for (auto& e : extra_) fn(e);
}

void ParticleStore::state(StateArchive& a) {
  a.section("particles");
  a(next_id_, extra_names_, extra_init_);
  if (a.loading()) extra_.assign(extra_names_.size(), {});
  for_each_array([&](auto& arr) { a(arr); });
  if (!a.loading()) return;
  for_each_array([&](auto& arr) {
    if (arr.size() != id.size()) {
      throw RuntimeFailure("checkpoint: particle arrays of different lengths");
    }
  });
}

namespace {
// Checked before any array changes, so a rejected insertion leaves the store as it was.
void check_new(const NewParticle& p, std::size_t k) {
  auto finite = [](Vec3 v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
  };
  auto where = [&]() { return "new particle " + std::to_string(k) + ": "; };
  if (!(p.radius > 0.0) || !std::isfinite(p.radius)) {
    throw std::invalid_argument(where() + "radius " + std::to_string(p.radius) +
                                ": expected a positive radius in m");
  }
  if (!(p.density > 0.0) || !std::isfinite(p.density)) {
    throw std::invalid_argument(where() + "density " + std::to_string(p.density) +
                                ": expected a positive density in kg/m^3");
  }
  if (!finite(p.position) || !finite(p.velocity) || !finite(p.angular_velocity)) {
    throw std::invalid_argument(where() + "non-finite position or velocity");
  }
}
}  // namespace

void ParticleStore::push_back(ParticleId pid, const NewParticle& p) {
  id.push_back(pid);
  parent.push_back(p.parent);
  x.push_back(p.position.x);
  y.push_back(p.position.y);
  z.push_back(p.position.z);
  vx.push_back(p.velocity.x);
  vy.push_back(p.velocity.y);
  vz.push_back(p.velocity.z);
  wx.push_back(p.angular_velocity.x);
  wy.push_back(p.angular_velocity.y);
  wz.push_back(p.angular_velocity.z);
  for (auto* a : {&fx, &fy, &fz, &tx, &ty, &tz}) a->push_back(0.0);
  const double r = p.radius;
  const double m = p.density * 4.0 / 3.0 * kPi * r * r * r;
  radius.push_back(r);
  mass.push_back(m);
  inv_mass.push_back(1.0 / m);
  inv_inertia.push_back(1.0 / (0.4 * m * r * r));
  for (std::size_t k = 0; k < extra_.size(); ++k) {
    extra_[k].push_back(k < p.extra.size() ? p.extra[k] : extra_init_[k]);
  }
}

void ParticleStore::insert_with_id(ParticleId pid, const NewParticle& p) {
  check_new(p, 0);
  if (pid < next_id_ && std::find(id.begin(), id.end(), pid) != id.end()) {
    throw std::invalid_argument("particle id " + std::to_string(pid) + " is already used");
  }
  push_back(pid, p);
  next_id_ = std::max(next_id_, pid + 1);
}

std::vector<ParticleId> ParticleStore::apply(const TopologyChange& change) {
  for (std::size_t k = 0; k < change.add.size(); ++k) check_new(change.add[k], k);
  for (std::size_t i : change.remove) {
    if (i >= size()) throw std::out_of_range("topology change removes a non-existent index");
  }
  if (!change.remove.empty()) {
    std::vector<char> gone(size(), 0);
    for (std::size_t i : change.remove) gone[i] = 1;
    // Stable compaction: survivors keep their order.
    for_each_array([&](auto& arr) {
      std::size_t w = 0;
      for (std::size_t i = 0; i < gone.size(); ++i) {
        if (!gone[i]) arr[w++] = arr[i];
      }
      arr.resize(w);
    });
  }
  std::vector<ParticleId> new_ids;
  new_ids.reserve(change.add.size());
  for (const NewParticle& p : change.add) {
    new_ids.push_back(next_id_);
    push_back(next_id_++, p);
  }
  return new_ids;
}

void ParticleStore::permute(const std::vector<std::size_t>& order) {
  const std::size_t n = order.size();
  for_each_array([&](auto& arr) {
    auto copy = arr;
#pragma omp parallel for schedule(static) if (worth_threading(n))
    for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(n); ++k) {
      arr[static_cast<std::size_t>(k)] = copy[order[static_cast<std::size_t>(k)]];
    }
  });
}

void ParticleStore::set_radius(std::size_t i, double r) {
  if (!(r > 0.0) || !std::isfinite(r)) {
    throw std::invalid_argument("radius " + std::to_string(r) + ": expected a positive radius");
  }
  const double scale = r / radius[i];
  mass[i] *= scale * scale * scale;  // same density
  radius[i] = r;
  inv_mass[i] = 1.0 / mass[i];
  inv_inertia[i] = 1.0 / (0.4 * mass[i] * r * r);
}

double ParticleStore::total_mass() const {
  return deterministic_sum(size(), [&](std::size_t i) { return mass[i]; });
}

double ParticleStore::solid_volume() const {
  return deterministic_sum(
      size(), [&](std::size_t i) { return 4.0 / 3.0 * kPi * radius[i] * radius[i] * radius[i]; });
}

std::vector<double> ParticleStore::diameters() const {
  std::vector<double> d(size());
  for (std::size_t i = 0; i < size(); ++i) d[i] = 2.0 * radius[i];
  return d;
}

}  // namespace crushdem
