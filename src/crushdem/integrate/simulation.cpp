#include "crushdem/integrate/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <tuple>
#include <type_traits>

#include "crushdem/contact/contact_kernel.hpp"
#include "crushdem/contact/contact_stress.hpp"
#include "crushdem/core/deterministic.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/walls/wall_forces.hpp"

namespace crushdem {
namespace {

using Idx = std::ptrdiff_t;

}  // namespace

const ParamTable<DampingConfig>& damping_params() {
  using D = DampingConfig;
  static const ParamTable<D> table = {
      {"local_alpha", &D::local_alpha, "-",
       "PFC local damping: each force and torque component F_j -= alpha |F_j| sign(v_j); 0 = off "
       "(CHOICE)",
       [](double v) { return v >= 0.0 && v < 1.0; }, "a value in [0, 1)"},
  };
  return table;
}

const ParamTable<NeighborConfig>& neighbor_params() {
  using N = NeighborConfig;
  static const ParamTable<N> table = {
      {"skin", &N::skin, "m", "Verlet skin; 0 = half the smallest radius at the first build",
       [](double v) { return v >= 0.0; }, "a skin >= 0 in m (0 = automatic)"},
      {"sort_particles", &N::sort_particles, "",
       "reorder particles in cell order at each rebuild (speed only; results stay "
       "deterministic)"},
      {"prune", &N::prune, "",
       "the pair loop walks a pruned copy of the list: the pairs with a gap below an inner skin "
       "chosen from the grains' speed, remade when they have moved half of it (speed only; "
       "results bit-identical with it off)"},
  };
  return table;
}

const ParamTable<GravityConfig>& gravity_params() {
  using G = GravityConfig;
  static const ParamTable<G> table = {
      {"g", &G::g, "m/s^2",
       "gravitational acceleration, a weight m g on every grain (not in the study, whose tests "
       "are at stresses where it is negligible; a chamber or a pile under gravity: [0, 0, "
       "-9.81])",
       nullptr, "an array of 3 finite numbers [x, y, z] in m/s^2"},
  };
  return table;
}

void SimulationConfig::validate() const {
  // The sections whose checks are all in their tables.
  validate_params(material, material_params(), "material");
  validate_params(gravity, gravity_params(), "gravity");
  validate_params(damping, damping_params(), "damping");
  validate_params(timestep, timestep_params(), "timestep");
  validate_params(neighbor, neighbor_params(), "neighbor");
  contact.validate();
  for (int k = 0; k < kNumWalls; ++k) {
    walls[static_cast<std::size_t>(k)].validate(std::string("walls.") + wall_name(k));
  }
  validate_bodies(bodies);
  for (int a = 0; a < 3; ++a) {
    const double lo = walls[static_cast<std::size_t>(2 * a)].position;
    const double hi = walls[static_cast<std::size_t>(2 * a + 1)].position;
    if (!(hi > lo)) {
      std::string idx = "[0]";
      idx[1] = static_cast<char>('0' + a);
      throw ConfigError(bad_value("box.max" + idx, show_number(hi),
                                  "a value above box.min" + idx + " = " + show_number(lo)));
    }
  }
}

Simulation::Simulation(const SimulationConfig& cfg) : cfg_(cfg) {
  cfg_.validate();
  law_ = ContactLaw(cfg_.material, cfg_.contact);
  history_.declare(law_.pair_history());
  std::vector<Body> bodies;
  for (const BodyConfig& b : cfg_.bodies) bodies.push_back(b.make(law_.params().mu_wall));
  walls_ = Walls(cfg_.walls, law_.params().mu_wall, std::move(bodies));
  time_step_ = TimeStep(cfg_.timestep);
  skin_ = cfg_.neighbor.skin;
}

ParticleId Simulation::add_particle(Vec3 position, double radius, Vec3 velocity,
                                    Vec3 angular_velocity) {
  NewParticle np;
  np.position = position;
  np.velocity = velocity;
  np.angular_velocity = angular_velocity;
  np.radius = radius;
  np.density = cfg_.material.density;
  TopologyChange ch;
  ch.add.push_back(np);
  return apply_topology(ch).front();
}

std::vector<ParticleId> Simulation::add_particles(std::vector<NewParticle> grains) {
  const auto vec = [](const Vec3& v) {
    return "[" + show_number(v.x) + ", " + show_number(v.y) + ", " + show_number(v.z) + "]";
  };
  const Vec3 lo{walls_.position(0), walls_.position(2), walls_.position(4)};
  const Vec3 hi{walls_.position(1), walls_.position(3), walls_.position(5)};
  for (std::size_t i = 0; i < grains.size(); ++i) {
    const NewParticle& g = grains[i];
    const std::string which = "add_particles: grain " + std::to_string(i);
    if (!(g.radius > 0.0) || !std::isfinite(g.radius)) {
      throw ConfigError(which + ": radius " + show_number(g.radius) +
                        " m: expected a positive radius in m");
    }
    const Vec3& x = g.position;
    const Vec3& v = g.velocity;
    if (!std::isfinite(x.x + x.y + x.z) || !std::isfinite(v.x + v.y + v.z)) {
      throw ConfigError(which + ": expected finite positions and velocities (got centre " + vec(x) +
                        " m, velocity " + vec(v) + " m/s)");
    }
    const double reach = 0.9 * g.radius;
    if (x.x - reach < lo.x || x.y - reach < lo.y || x.z - reach < lo.z || x.x + reach > hi.x ||
        x.y + reach > hi.y || x.z + reach > hi.z) {
      throw ConfigError(which + " (centre " + vec(x) + " m, radius " + show_number(g.radius) +
                        " m) is not inside the box " + vec(lo) + " - " + vec(hi) +
                        " m: expected every grain between the walls");
    }
    grains[i].density = cfg_.material.density;
  }
  TopologyChange ch;
  ch.add = std::move(grains);
  return apply_topology(ch);
}

std::vector<ParticleId> Simulation::apply_topology(const TopologyChange& change) {
  invalidate();             // history read with the old indices, before the arrays are compacted
  return p_.apply(change);  // validates everything before changing anything
}

void Simulation::invalidate() {
  if (nl_valid_) history_.capture(p_, nl_, wc_);
  nl_valid_ = false;
  forces_valid_ = false;
  time_step_.invalidate();
  inspection_ = {};
  ++layout_version_;
}

std::string Simulation::left_the_box(std::size_t i, int k) const {
  // What one step moved the grain and the wall, in the grain's radii: which of the usual causes
  // it was.
  const double r = p_.radius[i], dt = time_step_.value();
  const double v = std::sqrt(p_.vx[i] * p_.vx[i] + p_.vy[i] * p_.vy[i] + p_.vz[i] * p_.vz[i]);
  // Positive: the wall moves towards the grains (a low wall up, a high wall down).
  const double v_wall = (wall_is_low(k) ? 1.0 : -1.0) * walls_.state(k).velocity;
  const double grain_per_step = v * dt / r, wall_per_step = v_wall * dt / r;
  std::string cause;
  if (grain_per_step > 0.1) {
    cause = "the grain moved " + show_number(grain_per_step) +
            " of its radius in the last step (|v| = " + show_number(v) +
            " m/s): the grains blew up, from a time step too large for the contact stiffness "
            "(timestep keys) or from deep overlaps in the sample";
  } else if (wall_per_step > 0.01) {
    cause = "the wall moves " + show_number(wall_per_step) +
            " of the grain's radius per step towards the grains (" + show_number(v_wall) +
            " m/s): faster than the grains can follow; lower the strain rate or the servo's "
            "speed limit";
  } else {
    cause = "it was pressed through the wall slowly (|v| = " + show_number(v) +
            " m/s, the wall at " + show_number(v_wall) +
            " m/s towards the grains): a wall stress far beyond what the contact law holds "
            "for a grain of this size (check the target stresses and the grains' sizes)";
  }
  return "particle id " + std::to_string(p_.id[i]) + " (radius " + show_number(r) +
         " m) left the box through wall " + wall_name(k) + " at t = " + show_number(time_) +
         " s: " + cause;
}

void Simulation::rebuild_neighbors() {
  const PartScope timed(part_clock_, Part::NeighborSearch);
  const std::size_t N = p_.size();
  if (skin_ <= 0.0 && N > 0) {
    skin_ = 0.5 * *std::min_element(p_.radius.begin(), p_.radius.end());
  }
  // A non-finite coordinate or a grain entirely outside a wall: the state is no longer a valid
  // sample (checked before sorting, which needs finite coordinates).
  for (std::size_t i = 0; i < N; ++i) {
    if (!std::isfinite(p_.x[i]) || !std::isfinite(p_.y[i]) || !std::isfinite(p_.z[i])) {
      throw RuntimeFailure("particle id " + std::to_string(p_.id[i]) +
                           " has a non-finite position at t = " + show_number(time_) +
                           " s (time step too large for the contact stiffness?)");
    }
    for (int k = 0; k < kNumWalls; ++k) {
      if (!(wall_gap(k, walls_.position(k), p_.x[i], p_.y[i], p_.z[i]) > -p_.radius[i])) {
        throw RuntimeFailure(left_the_box(i, k));
      }
    }
  }
  // The same grains as at the last build: the history goes over by index (ContactHistory::
  // carry); after a topology change invalidate() has kept it by ids.
  const bool same_grains =
      nl_valid_ && !history_.kept && nl_.num_particles() == N && wc_.offsets.size() == N + 1;
  ContactHistory::Previous previous;
  if (same_grains) {
    previous = history_.take(nl_, wc_);
  } else if (nl_valid_) {
    history_.capture(p_, nl_, wc_);
  }
  nl_valid_ = false;  // until the new lists stand
  std::vector<std::size_t> order;
  if (cfg_.neighbor.sort_particles && N > 1) {
    order = NeighborList::spatial_order(p_, skin_);
    p_.permute(order);
  }
  pair_loop_.mark_stale();  // the packed copies follow the old order
  nl_.build(p_, skin_ > 0.0 ? skin_ : 1.0);
  wc_.build(p_.x, p_.y, p_.z, p_.radius, walls_, skin_);
  if (same_grains) {
    history_.carry(previous, order, nl_, wc_);
  } else {
    history_.rebuild(p_, nl_, wc_);  // every declared history vector by ids
  }
  walls_.reset_displacements();
  nl_valid_ = true;
  ++layout_version_;
}

// --- forces ------------------------------------------------------------------------------------

void Simulation::compute_forces() {
  // Evaluating forces advances the tangential history by one increment, so it is done once per
  // state: a second call without a step in between does nothing.
  if (forces_valid_ && nl_valid_) return;
  if (!nl_valid_) rebuild_neighbors();
  if (time_step_.value() <= 0.0) dt();
  // A refresh of the current state (start, or after a topology change): the tangential history
  // already holds this step's increment, so none is added (increment time 0).
  evaluate_forces(0.0, false);
}

void Simulation::evaluate_forces(double increment_dt, bool kick, bool drift_next) {
  const PartScope timed(part_clock_, Part::ContactForces);
  const bool prune = cfg_.neighbor.prune;
  ContactLoad* load = load_factor_ > 0.0 ? &load_ : nullptr;
  // The loops are instantiated for every combination of the law's sub-models, so a law without
  // a couple (rolling resistance) carries none of its cost.
  pair_loop_.evaluate(law_, increment_dt, p_, nl_, prune, history_, load, load_factor_);
  {
    const PartScope walls(part_clock_, Part::WallForces);
    wall_forces(law_, increment_dt, p_, walls_, wc_);
    if (load) wall_contact_load();
  }
  const DriftMaxima next = gather_and_damp(p_, nl_, pair_loop_, wc_, time_step_.value(),
                                           law_.params().spin_scale, cfg_.damping.local_alpha,
                                           cfg_.gravity.g, kick, drift_next, fu_x_, fu_y_, fu_z_);
  if (drift_next) next_drift_ = next;
  forces_valid_ = true;
  inspection_ = {};  // a device's reduction is of the state before
}

void Simulation::wall_contact_load() {
  for (std::size_t e = 0; e < wc_.size(); ++e) {
    if (wc_.delta[e] <= 0.0) continue;
    const std::size_t i = wc_.particle[e];
    const SurfacePoint s = walls_.surface(wc_.wall[e], {p_.x[i], p_.y[i], p_.z[i]});
    const double R_star = surface_R_star(p_.radius[i], s.kappa_1, s.kappa_2);
    const double F_el = normal_force(wc_.delta[e], R_star, true).F_n;  // no dashpot
    const double sig = contact_stress(F_el, load_factor_ * R_star, wc_.delta[e]);
    take_contact_load(load_.sigma[i], load_.F_n_max[i], load_.nx[i], load_.ny[i], load_.nz[i], sig,
                      F_el, s.n);
  }
}

void Simulation::track_contact_load(double r_prime_factor) {
  if (!(r_prime_factor >= 0.0) || !std::isfinite(r_prime_factor)) {
    throw ConfigError(bad_value("r_prime_factor", show_number(r_prime_factor), "a factor >= 0"));
  }
  load_factor_ = r_prime_factor;
  forces_valid_ = false;  // the next evaluation fills the load arrays
}

// --- checkpoints -------------------------------------------------------------------------------

void Simulation::state(StateArchive& a) {
  a.section("simulation");
  p_.state(a);
  nl_.state(a);
  walls_.state(a);
  wc_.state(a);
  a.section("entries");
  ContactHistory::Vectors& ft = history_.tangential();
  a(ft.x, ft.y, ft.z, fu_x_, fu_y_, fu_z_);
  // The per-entry R*, m* and sqrt(R*) caches of formats 1 to 5, derived values: written empty,
  // read and dropped.
  for (int k = 0; k < 3; ++k) {
    std::vector<double> unused;
    a(unused);
  }
  a(history_.touching, wc_.offsets, history_.kept_pairs[0], history_.kept_walls);
  a.section("clock");
  a(history_.kept, skin_);
  time_step_.state(a);
  a(forces_valid_, nl_valid_, time_, steps_);
  // The law is derived from the configuration again: only its friction can change.
  double mu = law_.params().mu;
  a(cfg_.material.friction, mu);
  law_.set_friction(mu);
  a(load_factor_, load_.sigma, load_.F_n_max, load_.nx, load_.ny, load_.nz);
  // The couple sub-model's history vector (the rolling moment; empty without one). Format 3
  // and later; older checkpoints predate rolling resistance, so their configuration has it off.
  ContactHistory::Vectors none;
  std::vector<ContactHistory::PairVector> none_kept;
  const bool couple = history_.pair.size() > 1;
  ContactHistory::Vectors& ch = couple ? history_.pair[1] : none;
  std::vector<ContactHistory::PairVector>& ch_kept = couple ? history_.kept_pairs[1] : none_kept;
  if (a.version() >= 3) {
    a.section("rolling");
    a(ch.x, ch.y, ch.z, ch_kept);
  }
  if (!a.loading()) return;
  if (couple && nl_valid_ && ch.x.size() != nl_.neighbors.size()) {
    throw RuntimeFailure("checkpoint: rolling-resistance history and neighbour list disagree");
  }
  if (nl_valid_ && nl_.num_particles() != p_.size()) {
    throw RuntimeFailure("checkpoint: neighbour list and particles disagree");
  }
  check_loaded_state();
  // The loaded list may carry the build count the pruned list was made for; the packed copies
  // are those of the state before.
  pair_loop_.pruned().invalidate();
  pair_loop_.mark_stale();
  next_drift_.reset();
  inspection_ = {};
  ++layout_version_;
}

// A loaded state is checked for what the step relies on without checking (sizes, indices, ids,
// finite values, grains within the box), beyond the file's checksum: an edited state behind a
// recomputed checksum is refused with a message, never read out of bounds.
void Simulation::check_loaded_state() const {
  const auto fail = [](const std::string& what) {
    throw RuntimeFailure("checkpoint: " + what + "; the state is damaged or was edited");
  };
  const std::size_t n = p_.size();
  const ContactHistory::Vectors& ft = history_.tangential();
  if (nl_valid_ && (ft.x.size() != nl_.neighbors.size() || ft.y.size() != ft.x.size() ||
                    ft.z.size() != ft.x.size())) {
    fail("the contact history and the neighbour list disagree");
  }
  const std::size_t nw = wc_.size();
  for (const auto* v : {&wc_.ft_x, &wc_.ft_y, &wc_.ft_z, &wc_.fx, &wc_.fy, &wc_.fz, &wc_.tx,
                        &wc_.ty, &wc_.tz, &wc_.F_n, &wc_.k_n, &wc_.delta}) {
    if (v->size() != nw) fail("the wall contacts' arrays differ in length");
  }
  if (wc_.wall.size() != nw) fail("the wall contacts' arrays differ in length");
  for (std::size_t k = 0; k < nw; ++k) {
    if (wc_.particle[k] >= n) {
      fail("wall contact " + std::to_string(k) + " names grain index " +
           std::to_string(wc_.particle[k]) + " of " + std::to_string(n));
    }
    if (wc_.wall[k] >= walls_.size()) fail("a wall contact names a body that does not exist");
  }
  if (nl_valid_) {
    // The step reads the wall contacts by grain through the offsets (CSR), and the pair
    // entries' touching flags by entry.
    const std::vector<std::uint32_t>& off = wc_.offsets;
    if (off.size() != n + 1 || off.front() != 0 || off.back() != nw) {
      fail("the wall contacts' offsets do not span the grains and their entries");
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (off[i + 1] < off[i]) fail("the wall contacts' offsets decrease");
      for (std::uint32_t k = off[i]; k < off[i + 1]; ++k) {
        if (wc_.particle[k] != i) fail("a wall contact lies outside its grain's entries");
      }
    }
    if (history_.touching.size() != nl_.neighbors.size()) {
      fail("the contacts' touching flags and the neighbour list disagree");
    }
  }
  const auto all_finite = [](const std::vector<double>& v) {
    return std::all_of(v.begin(), v.end(), [](double d) { return std::isfinite(d); });
  };
  for (const auto* v : {&wc_.ft_x, &wc_.ft_y, &wc_.ft_z, &wc_.delta, &ft.x, &ft.y, &ft.z}) {
    if (!all_finite(*v)) fail("a contact's history holds a non-finite value");
  }
  for (const auto* v : {&p_.vx, &p_.vy, &p_.vz, &p_.wx, &p_.wy, &p_.wz}) {
    if (!all_finite(*v)) fail("a grain's velocity is not finite");
  }
  std::vector<ParticleId> ids(p_.id.begin(), p_.id.end());
  std::sort(ids.begin(), ids.end());
  if (std::adjacent_find(ids.begin(), ids.end()) != ids.end()) fail("two grains share an id");
  if (!ids.empty() && ids.back() >= p_.next_id()) fail("a grain id beyond the next id");
  for (std::size_t i = 0; i < n; ++i) {
    const double r = p_.radius[i];
    const double c[3] = {p_.x[i], p_.y[i], p_.z[i]};
    if (!(r > 0.0) || !std::isfinite(r) || !std::isfinite(c[0]) || !std::isfinite(c[1]) ||
        !std::isfinite(c[2]) || !(p_.mass[i] > 0.0)) {
      fail("grain " + std::to_string(p_.id[i]) + " has a non-finite or non-positive value");
    }
    for (int a = 0; a < 3; ++a) {
      if (c[a] < walls_.position(2 * a) - r || c[a] > walls_.position(2 * a + 1) + r) {
        fail("grain " + std::to_string(p_.id[i]) + " lies outside the box");
      }
    }
  }
}

// --- time integration --------------------------------------------------------------------------

void Simulation::set_friction(double mu) {
  if (!(mu >= 0.0) || !std::isfinite(mu)) {
    throw ConfigError(bad_value("friction", show_number(mu), "a coefficient >= 0"));
  }
  cfg_.material.friction = mu;
  law_.set_friction(mu);
}

void Simulation::step(std::uint64_t n) {
  // Integration unless a rebuild or the force evaluation (their own parts) is running.
  const PartScope timed(part_clock_, Part::Integration);
  for (std::uint64_t s = 0; s < n; ++s) {
    dt();
    if (!forces_valid_ || !nl_valid_) compute_forces();
    const double h = time_step_.value();
    // The first half kick and drift, unless the last step's gather pass did it already.
    const DriftMaxima drift =
        next_drift_ ? *next_drift_ : kick_drift(p_, nl_, pair_loop_, h, law_.params().spin_scale);
    next_drift_.reset();
    pair_loop_.pruned().add_step(std::sqrt(drift.step2));
    const double d = std::sqrt(drift.since_build2);
    walls_.move(h);
    if (rebuild_due(d, walls_.max_displacement_since_build(), skin_)) rebuild_neighbors();
    // The next step's kick and drift join this step's gather pass (one pass over the grains
    // instead of two) when that step follows in this call, with the same dt: nothing outside
    // step() can change the state in between, and dt() will not recompute it.
    evaluate_forces(h, true, s + 1 < n && !time_step_.due(steps_ + 1));
    walls_.update_velocities(h);
    time_ += h;
    ++steps_;
  }
}

void Simulation::set_clock(double time, std::uint64_t steps, const TimeStep& time_step) {
  time_ = time;
  steps_ = steps;
  time_step_ = time_step;
  next_drift_.reset();
  pair_loop_.mark_stale();
  forces_valid_ = true;
}

double Simulation::rayleigh_dt() const {
  return rayleigh_time(p_, cfg_.material);
}

NormalForce Simulation::normal_force(double delta, double R_star, bool wall) const {
  return with_law(law_, [&](const auto& model) {
    return wall ? model.wall_law(delta, R_star, std::sqrt(R_star))
                : model.pair_law(delta, R_star, std::sqrt(R_star));
  });
}

double Simulation::stiffness_dt() const {
  if (!nl_valid_) return std::numeric_limits<double>::infinity();
  return stiffness_time(
      p_, nl_, wc_, walls_, law_.params().tangential_ratio,
      [this](double delta, double R_star, bool wall) { return normal_force(delta, R_star, wall); });
}

double Simulation::automatic_dt() {
  if (!nl_valid_ && p_.size() > 0) rebuild_neighbors();
  return automatic_dt_with(stiffness_dt());
}

double Simulation::automatic_dt_with(double stiffness_time) const {
  const double h = std::min(cfg_.timestep.rayleigh_fraction * rayleigh_dt(),
                            cfg_.timestep.safety * stiffness_time);
  return std::isfinite(h) ? h : 1e-6;  // no particles: any value works
}

double Simulation::dt() {
  if (time_step_.due(steps_)) time_step_.choose(automatic_dt(), steps_);
  return time_step_.value();
}

void Simulation::choose_dt(double stiffness_time) {
  if (time_step_.fixed()) return;  // a fixed step is never replaced
  time_step_.choose(automatic_dt_with(stiffness_time), steps_);
}

void Simulation::set_dt(double dt) {
  if (!(dt > 0.0) || !std::isfinite(dt)) {
    throw ConfigError(bad_value("timestep.dt", show_number(dt), "a positive time step in s"));
  }
  time_step_.fix(dt);
}

// --- measurements ------------------------------------------------------------------------------

double Simulation::kinetic_energy() const {
  return deterministic_sum(p_.size(), [&](std::size_t i) {
    const double v2 = p_.vx[i] * p_.vx[i] + p_.vy[i] * p_.vy[i] + p_.vz[i] * p_.vz[i];
    const double w2 = p_.wx[i] * p_.wx[i] + p_.wy[i] * p_.wy[i] + p_.wz[i] * p_.wz[i];
    return 0.5 * p_.mass[i] * v2 + 0.5 / p_.inv_inertia[i] * w2;
  });
}

std::size_t Simulation::memory_bytes() const {
  std::size_t b = 0;
  auto add = [&b](const auto& v) { b += v.capacity() * sizeof(v[0]); };
  for (const auto* v :
       {&p_.x, &p_.y, &p_.z, &p_.vx, &p_.vy, &p_.vz, &p_.wx, &p_.wy, &p_.wz, &p_.fx, &p_.fy, &p_.fz,
        &p_.tx, &p_.ty, &p_.tz, &p_.radius, &p_.mass, &p_.inv_mass, &p_.inv_inertia}) {
    add(*v);
  }
  add(p_.id);
  add(p_.parent);
  for (std::size_t k = 0; k < p_.field_names().size(); ++k) add(p_.field(k));
  for (const auto* v : {&nl_.offsets, &nl_.neighbors, &nl_.column_offsets, &nl_.column_members,
                        &nl_.owner, &wc_.offsets}) {
    add(*v);
  }
  b += history_.memory_bytes() + pair_loop_.memory_bytes();
  add(wc_.particle);
  add(wc_.wall);
  for (const auto* v : {&wc_.ft_x, &wc_.ft_y, &wc_.ft_z, &wc_.fx, &wc_.fy, &wc_.fz, &wc_.tx,
                        &wc_.ty, &wc_.tz, &wc_.F_n, &wc_.k_n, &wc_.delta}) {
    add(*v);
  }
  return b;
}

std::size_t Simulation::num_contacts() const {
  std::size_t n = 0;
  if (!forces_valid_) return 0;
  for (auto t : history_.touching) n += t;
  return n;
}

ContactRecord Simulation::pair_record(std::size_t e) const {
  const std::size_t i = nl_.owner[e], j = nl_.neighbors[e];
  const Vec3 dx{p_.x[j] - p_.x[i], p_.y[j] - p_.y[i], p_.z[j] - p_.z[i]};
  const double dist = norm(dx);
  ContactRecord c;
  c.id_i = p_.id[i];
  c.id_j = p_.id[j];
  c.delta = p_.radius[i] + p_.radius[j] - dist;
  c.normal = (1.0 / dist) * dx;
  c.F_n = normal_force(c.delta, pair_R_star(p_.radius[i], p_.radius[j]), false).F_n;
  const ContactHistory::Vectors& ft = history_.tangential();
  c.F_t = {ft.x[e], ft.y[e], ft.z[e]};
  if (history_.pair.size() > 1) {  // the couple's vector: the rolling moment
    const ContactHistory::Vectors& mr = history_.pair[1];
    c.M_r = {mr.x[e], mr.y[e], mr.z[e]};
  }
  return c;
}

std::vector<ContactRecord> Simulation::contacts() const {
  std::vector<ContactRecord> out;
  if (!forces_valid_) return out;
  for (std::size_t e = 0; e < nl_.neighbors.size(); ++e) {
    if (history_.touching[e]) out.push_back(pair_record(e));
  }
  for (std::size_t e = 0; e < wc_.size(); ++e) {
    if (wc_.delta[e] <= 0.0) continue;
    ContactRecord c;
    c.id_i = p_.id[wc_.particle[e]];
    c.id_j = wc_.wall[e];
    c.is_wall = true;
    c.delta = wc_.delta[e];
    const std::size_t i = wc_.particle[e];
    c.normal = walls_.surface(wc_.wall[e], {p_.x[i], p_.y[i], p_.z[i]}).n;
    c.F_n = wc_.F_n[e];
    c.F_t = {wc_.ft_x[e], wc_.ft_y[e], wc_.ft_z[e]};
    out.push_back(c);
  }
  return out;
}

std::array<double, 9> Simulation::love_weber_stress() const {
  // sigma_ab = (1/V) sum_c f_a l_b: f the contact force on j (or on the wall), l the branch
  // vector from i to j (or from the grain centre to the wall contact). Elastic contact forces;
  // viscous damping forces (zero at equilibrium) are left out.
  std::array<double, 9> s{};
  if (!forces_valid_) return s;
  const double V = walls_.volume();
  std::vector<std::array<double, 9>> per_entry(nl_.neighbors.size());
#pragma omp parallel for schedule(static) if (worth_threading(per_entry.size()))
  for (Idx ee = 0; ee < static_cast<Idx>(per_entry.size()); ++ee) {
    const auto e = static_cast<std::size_t>(ee);
    per_entry[e] = {};
    if (!history_.touching[e]) continue;
    const ContactRecord c = pair_record(e);
    const Vec3 f = c.F_n * c.normal - c.F_t;  // force on j
    const Vec3 l = (p_.radius[nl_.owner[e]] + p_.radius[nl_.neighbors[e]] - c.delta) * c.normal;
    const double fa[3] = {f.x, f.y, f.z}, lb[3] = {l.x, l.y, l.z};
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) per_entry[e][static_cast<std::size_t>(3 * a + b)] = fa[a] * lb[b];
    }
  }
  for (std::size_t k = 0; k < 9; ++k) {
    double pair =
        deterministic_sum(per_entry.size(), [&](std::size_t e) { return per_entry[e][k]; });
    double wall = 0.0;
    const int a = static_cast<int>(k / 3), b = static_cast<int>(k % 3);
    for (std::size_t e = 0; e < wc_.size(); ++e) {
      if (wc_.delta[e] <= 0.0) continue;
      const std::size_t i = wc_.particle[e];
      const Vec3 n = walls_.surface(wc_.wall[e], {p_.x[i], p_.y[i], p_.z[i]}).n;
      const double dist = p_.radius[i] - wc_.delta[e];
      const Vec3 f = wc_.F_n[e] * n - Vec3{wc_.ft_x[e], wc_.ft_y[e], wc_.ft_z[e]};  // on the wall
      const double fa[3] = {f.x, f.y, f.z}, lb[3] = {dist * n.x, dist * n.y, dist * n.z};
      wall += fa[a] * lb[b];
    }
    s[k] = (pair + wall) / V;
  }
  return s;
}

}  // namespace crushdem
