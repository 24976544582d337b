#include "crushdem/backend/device_stepper.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <tuple>
#include <type_traits>
#include <utility>

#include "crushdem/core/deterministic.hpp"
#include "crushdem/core/error.hpp"

namespace crushdem {

namespace {

using device::Control;
using device::Index;
using device::View;

/// A View member pointed at a buffer (the field rows' binding: the member's type, not a macro
/// argument, names the element).
template <class T>
void bind_to(T*& member, void* p) {
  member = static_cast<T*>(p);
}

/// Buffers keep spare room so that most rebuilds and splits do not reallocate (a reallocation
/// changes the view and, on a GPU, the captured graph).
std::size_t with_room(std::size_t bytes) {
  return std::max<std::size_t>(bytes + bytes / 4, 256);
}

// --- the host emulation ------------------------------------------------------------------------

/// The device step's bodies run serially on the host in the kernels' order of summation (the
/// wall totals by the same fixed tree), so the emulation has the device's bits.
class EmulatedApi : public device::Api {
 public:
  bool emulated() const override { return true; }
  void* allocate(std::size_t bytes) override {
    void* p = std::malloc(bytes);
    if (!p) throw RuntimeFailure("emulated device: out of host memory");
    return p;
  }
  void release(void* p) override { std::free(p); }
  void upload(void* dev, const void* host, std::size_t bytes) override {
    if (bytes) std::memcpy(dev, host, bytes);
  }
  void download(void* host, const void* dev, std::size_t bytes) override {
    if (bytes) std::memcpy(host, dev, bytes);
  }
  device::Laws place_laws(const ContactLaw& law) override {
    device::Laws out{law, {}};
    for (std::size_t k = 0; k < law.tables().size(); ++k) out.placed[k] = law.tables()[k].host;
    return out;
  }
  void run_steps(const View& v, const device::Laws& laws, int steps) override {
    for (int s = 0; s < steps; ++s) {
      if (v.ctrl->halt) return;
      kick_drift(v);
      if (v.ctrl->halt) return;
      forces(v, laws);
    }
  }
  void finish_step(const View& v, const device::Laws& laws) override { forces(v, laws); }
  void inspect(const View& v, const device::Laws& laws, unsigned grains) override {
    laws.visit([&](const auto& model) { inspect_with(v, model, grains); });
  }
  void stiffness_time(const View& v, const device::Laws& laws, unsigned grains) override {
    double best = std::numeric_limits<double>::infinity();
    laws.visit([&](const auto& model) {
      for (Index j = 0; j < grains; ++j) {
        best = std::min(best, device::stiffness_time_item(v, model, j));
      }
    });
    std::memcpy(&v.ctrl->stiffness_bits, &best, sizeof best);
  }
  void read_control(const View& v, Control& host) override { host = *v.ctrl; }

 private:
  static void kick_drift(const View& v) {
    double m2 = 0.0;
    for (Index i = 0; i < v.ctrl->N; ++i) m2 = std::max(m2, device::kick_drift_item(v, i));
    device::finish_drift(v, m2);
  }

  // The kernels' two passes and trees, in their order.
  template <class Model>
  static void inspect_with(const View& v, const Model& model, unsigned grains) {
    constexpr int B = device::kInspectBlock;
    const unsigned blocks = (grains + B - 1) / B;
    std::vector<device::InspectSum> part(B);
    for (unsigned b = 0; b < blocks; ++b) {
      for (int t = 0; t < B; ++t) {
        const unsigned i = b * B + static_cast<unsigned>(t);
        part[static_cast<std::size_t>(t)] =
            i < grains ? device::inspect_item(v, model, i) : device::InspectSum{0.0, 0.0, 0.0};
      }
      tree(part);
      v.inspect_partial[b] = part[0];
    }
    for (int t = 0; t < B; ++t) {
      device::InspectSum acc{0.0, 0.0, 0.0};
      for (unsigned k = static_cast<unsigned>(t); k < blocks; k += B) {
        device::add_inspect(acc, v.inspect_partial[k]);
      }
      part[static_cast<std::size_t>(t)] = acc;
    }
    tree(part);
    v.ctrl->inspect_resultant = part[0].resultant;
    v.ctrl->inspect_F_n = part[0].F_n;
    v.ctrl->inspect_pairs = part[0].pairs;
  }

  static void tree(std::vector<device::InspectSum>& part) {
    for (int s = device::kInspectBlock / 2; s > 0; s >>= 1) {
      for (int t = 0; t < s; ++t) {
        device::add_inspect(part[static_cast<std::size_t>(t)],
                            part[static_cast<std::size_t>(t + s)]);
      }
    }
  }

  static void forces(const View& v, const device::Laws& laws) {
    Control& c = *v.ctrl;
    laws.visit([&](const auto& model) {
      for (Index e = 0; e < c.M; ++e) device::pair_item(v, model, e);
      for (Index e = 0; e < c.Mw; ++e) device::wall_item(v, model, e);
    });
    std::vector<device::WallSum> part(device::kWallThreads);
    for (int k = 0; k < static_cast<int>(v.bodies); ++k) {
      for (int t = 0; t < device::kWallThreads; ++t) {
        part[static_cast<std::size_t>(t)] = device::wall_partial(v, k, t);
      }
      for (int s = device::kWallThreads / 2; s > 0; s >>= 1) {
        for (int t = 0; t < s; ++t) {
          device::add_sum(part[static_cast<std::size_t>(t)], part[static_cast<std::size_t>(t + s)]);
        }
      }
      device::wall_store_and_servo(v, k, part[0]);
    }
    for (Index j = 0; j < c.N; ++j) device::gather_item(v, j);
    device::advance_clock(v);
    if (v.fail && device::crushing_step(v)) {
      for (Index i = 0; i < c.N; ++i) {
        if (device::crushing_item(v, i)) ++c.failures;
      }
      if (c.failures > 0) c.halt = device::kFailure;
    }
  }
};

// --- the mirror: what the device holds, as one list ---------------------------------------------

using device::Count;
using device::When;

/// One array the device holds that mirrors a host array (a row of CD_DEVICE_FIELDS, or a
/// declared history vector's component): its host array, its size, the view pointer it sets,
/// and the bytes last transferred (the shadow), which tell whether host code changed it since.
struct Field {
  using HostArray = std::function<std::pair<void*, std::size_t>(Simulation&)>;
  using Bind = std::function<void(View&, void*)>;
  std::string name;
  Count count = Count::Grains;
  bool both_ways = false;  // downloaded by sync() (false: the device only reads it)
  // Per-entry data (R*, sqrt(R*), m*) derives from it: a host change needs a full upload.
  bool feeds_entries = false;
  std::size_t elem = 0;
  // The host array's data and its element count (checked against the device's count).
  HostArray host;
  Bind bind;
  void* buf = nullptr;
  std::size_t cap = 0;
  std::vector<unsigned char> shadow;
};

/// A device-only array (a row of CD_DEVICE_SCRATCH), or a buffer of the control block.
struct Scratch {
  std::string name;
  Count count = Count::Grains;
  When when = When::Always;
  std::size_t elem = 0;
  std::function<void(View&, void*)> bind;
  void* p = nullptr;
  std::size_t cap = 0;
};

/// The data pointer and element count of a host vector, whatever its constness (read-only rows
/// are never written through it).
template <class Vector>
std::pair<void*, std::size_t> host_array(Vector& v) {
  return {const_cast<void*>(static_cast<const void*>(v.data())), v.size()};
}

}  // namespace

std::unique_ptr<device::Api> device::make_emulated_api() {
  return std::make_unique<EmulatedApi>();
}

#ifndef CRUSHDEM_HAVE_CUDA
std::unique_ptr<device::Api> device::make_cuda_api() {
  throw RuntimeFailure(
      "--backend cuda: this crushdem was built without CUDA (configure with -DCRUSHDEM_CUDA=ON)");
}
bool device::cuda_available() {
  return false;
}
bool device::cuda_built() {
  return false;
}
#endif

struct DeviceStepper::Impl {
  std::unique_ptr<device::Api> api;
  std::vector<Field> fields;     // mirrors of host arrays, this run's (make_fields())
  std::vector<Scratch> scratch;  // device-only arrays, every row (held when the run needs them)
  Scratch ctrl_buf, partial;     // the control block and the inspection's partial sums
  device::Laws laws;
  View view{};
  Control ctrl{};  // the host's copy of the control block
  bool have_device = false;
  // What the host copy holds of the device's state: the fields (grain and contact arrays), and
  // the clock, walls and inspection. Both true until the device steps.
  bool fields_current = true;
  bool clock_current = true;
  std::uint64_t layout = ~std::uint64_t{0};
  const Simulation* owner = nullptr;  // the Simulation the device copy is of
  std::size_t history = 0;            // pair history vectors the law declares
  bool load = false, crushing = false;
  Crusher* crusher = nullptr;
  BreakageSink sink;
  std::size_t N = 0, M = 0, Mw = 0, bodies = 0;
  std::uint64_t full_uploads = 0, field_uploads = 0;
  double particle_steps = 0.0;
  static constexpr int kBatch = device::kBatchSteps;

  explicit Impl(std::unique_ptr<device::Api> a) : api(std::move(a)) {
#define CD_SCRATCH_ROW(name_, T, count_, when_)                            \
  scratch.push_back(Scratch{#name_, Count::count_, When::when_, sizeof(T), \
                            [](View& v, void* p) { bind_to(v.name_, p); }});
    CD_DEVICE_SCRATCH(CD_SCRATCH_ROW)
#undef CD_SCRATCH_ROW
  }

  ~Impl() {
    for (Field& f : fields) release(f.buf);
    for (Scratch& s : scratch) release(s.p);
    release(ctrl_buf.p);
    release(partial.p);
  }

  void release(void*& p) {
    if (p) api->release(p);
    p = nullptr;
  }

  /// Room for `bytes` in (p, cap); true when it moved.
  bool reserve(void*& p, std::size_t& cap, std::size_t bytes) {
    if (p && bytes <= cap) return false;
    release(p);
    cap = with_room(bytes);
    p = api->allocate(cap);
    return true;
  }

  std::size_t count(Count c) const {
    switch (c) {
      case Count::Grains: return N;
      case Count::Entries: return M;
      case Count::WallEntries: return Mw;
      case Count::GrainsPlusOne: return N + 1;
      case Count::Bodies: return bodies;
    }
    return 0;
  }
  std::size_t count(const Field& f) const {
    return count(f.count);
  }

  bool holds(When w) const {
    return w == When::Always || (w == When::Load && load) || (w == When::Crushing && crushing);
  }

  Scratch& scratch_named(const char* name) {
    for (Scratch& s : scratch) {
      if (s.name == name) return s;
    }
    throw RuntimeFailure(std::string("device: no scratch array '") + name + "'");
  }

  // --- the list of fields ----------------------------------------------------------------------

  /// The fields of this run, the one list of what the device mirrors: the rows of
  /// CD_DEVICE_FIELDS the run holds, then each component of each pair history vector the contact
  /// law declares.
  void make_fields(const Simulation& sim) {
    for (Field& f : fields) release(f.buf);
    fields.clear();
    Crusher* const run_crusher = crusher;
#define CD_FIELD_ROW(name_, T, count_, writes, when_, feeds, host_expr) \
  if (holds(When::when_)) {                                             \
    Field f;                                                            \
    f.name = #name_;                                                    \
    f.count = Count::count_;                                            \
    f.both_ways = writes;                                               \
    f.feeds_entries = feeds;                                            \
    f.elem = sizeof(T);                                                 \
    f.host = [crusher = run_crusher](Simulation& s) {                   \
      static_cast<void>(crusher);                                       \
      return host_array(host_expr);                                     \
    };                                                                  \
    f.bind = [](View& v, void* p) { bind_to(v.name_, p); };             \
    fields.push_back(std::move(f));                                     \
  }
    CD_DEVICE_FIELDS(CD_FIELD_ROW)
#undef CD_FIELD_ROW
    const std::vector<HistoryField> declared = sim.history().fields();
    history = declared.size();
    if (history > static_cast<std::size_t>(device::kMaxPairHistory)) {
      throw RuntimeFailure(
          "device: the contact law keeps more history vectors than the device step");
    }
    for (std::size_t k = 0; k < declared.size(); ++k) {
      for (int c = 0; c < 3; ++c) {
        Field f;
        f.name = std::string(declared[k].name) + "_" + "xyz"[c];
        f.count = Count::Entries;
        f.both_ways = true;
        f.elem = sizeof(double);
        f.host = [k, c](Simulation& s) {
          ContactHistory::Vectors& h = s.history().pair[k];
          return host_array(c == 0 ? h.x : (c == 1 ? h.y : h.z));
        };
        f.bind = [k, c](View& v, void* p) { v.ph[k][c] = static_cast<double*>(p); };
        fields.push_back(std::move(f));
      }
    }
  }

  // --- transfers -------------------------------------------------------------------------------

  /// Whether the run's fields or the layout changed since the last full upload.
  bool layout_changed(const Simulation& sim) const {
    return !have_device || &sim != owner || sim.layout_version() != layout ||
           history != sim.history().fields().size() || load != (sim.contact_load_factor() > 0.0) ||
           crushing != (crusher != nullptr && sim.contact_load_factor() > 0.0);
  }

  /// The host array of f, checked to hold the device's count.
  void* host_data(Field& f, Simulation& sim) const {
    const auto [data, n] = f.host(sim);
    if (n != count(f)) {
      throw RuntimeFailure(std::string("device transfer: the host's '") + f.name + "' holds " +
                           std::to_string(n) + " values, the device " + std::to_string(count(f)));
    }
    return data;
  }

  void upload_field(Field& f, Simulation& sim) {
    const std::size_t bytes = count(f) * f.elem;
    reserve(f.buf, f.cap, bytes);
    const void* src = host_data(f, sim);
    api->upload(f.buf, src, bytes);
    f.shadow.assign(static_cast<const unsigned char*>(src),
                    static_cast<const unsigned char*>(src) + bytes);
  }

  void full_upload(Simulation& sim) {
    const bool l = sim.contact_load_factor() > 0.0;
    const bool c = crusher != nullptr && l;
    if (fields.empty() || &sim != owner || history != sim.history().fields().size() || l != load ||
        c != crushing) {
      load = l;
      crushing = c;
      make_fields(sim);
    }
    if (!have_device || &sim != owner) laws = api->place_laws(sim.contact_law());
    const ParticleStore& p = sim.particles();
    const NeighborList& nl = sim.neighbors();
    const WallContacts& wc = sim.wall_contacts();
    N = p.size();
    M = nl.neighbors.size();
    Mw = wc.size();
    bodies = static_cast<std::size_t>(sim.walls().size());
    if (bodies > static_cast<std::size_t>(device::kMaxDeviceBodies)) {
      throw RuntimeFailure("device: " + std::to_string(bodies) + " bodies; the device step holds " +
                           std::to_string(device::kMaxDeviceBodies) + " at most");
    }
    if (sim.history().tangential().x.size() != M || wc.offsets.size() != N + 1) {
      throw RuntimeFailure("device upload: contact history and neighbour list disagree");
    }
    for (Field& f : fields) upload_field(f, sim);
    // Derived: the list's CSR with N + 1 offsets, its reverse (the entries where grain j is the
    // partner, in increasing order), and per-entry R*, sqrt(R*) and m* (the CPU loop computes
    // the same expressions in its lanes).
    std::vector<Index> offsets = nl.offsets;
    offsets.resize(N + 1, static_cast<Index>(M));
    std::vector<Index> r_off(N + 1, 0), r_ent(M);
    for (std::size_t e = 0; e < M; ++e) ++r_off[nl.neighbors[e] + 1];
    for (std::size_t j = 0; j < N; ++j) r_off[j + 1] += r_off[j];
    {
      std::vector<Index> fill(r_off.begin(), r_off.end() - 1);
      for (std::size_t e = 0; e < M; ++e) r_ent[fill[nl.neighbors[e]]++] = static_cast<Index>(e);
    }
    std::vector<double> rs(M), srs(M), me(M);
#pragma omp parallel for schedule(static) if (worth_threading(M))
    for (std::ptrdiff_t ee = 0; ee < static_cast<std::ptrdiff_t>(M); ++ee) {
      const auto e = static_cast<std::size_t>(ee);
      const std::size_t i = nl.owner[e], j = nl.neighbors[e];
      rs[e] = pair_R_star(p.radius[i], p.radius[j]);
      srs[e] = std::sqrt(rs[e]);
      me[e] = pair_m_eff(p.inv_mass[i], p.inv_mass[j]);
    }
    // Every scratch array the run holds gets its room; the derived ones their values. The
    // failure flags start cleared where new (the crushing check writes every grain's).
    for (Scratch& s : scratch) {
      if (!holds(s.when) || !reserve(s.p, s.cap, count(s.count) * s.elem)) continue;
      if (s.name == "fail") {
        const std::vector<std::uint8_t> none(s.cap, 0);
        api->upload(s.p, none.data(), s.cap);
      }
    }
    put("off", offsets);
    put("roff", r_off);
    put("rev", r_ent);
    put("RS", rs);
    put("SRS", srs);
    put("ME", me);
    put("woff", wc.offsets);
    reserve(ctrl_buf.p, ctrl_buf.cap, sizeof(Control));
    reserve(partial.p, partial.cap, (N / device::kInspectBlock + 1) * sizeof(device::InspectSum));
    layout = sim.layout_version();
    owner = &sim;
    have_device = true;
    ++full_uploads;
  }

  template <class T>
  void put(const char* name, const std::vector<T>& v) {
    Scratch& s = scratch_named(name);
    reserve(s.p, s.cap, v.size() * sizeof(T));
    api->upload(s.p, v.data(), v.size() * sizeof(T));
  }

  /// Uploads the fields host code changed since they were last transferred.
  void upload_changes(Simulation& sim) {
    for (Field& f : fields) {
      if (!f.feeds_entries) continue;
      const std::size_t bytes = count(f) * f.elem;
      if (std::memcmp(host_data(f, sim), f.shadow.data(), bytes) != 0) {
        full_upload(sim);
        return;
      }
    }
    for (Field& f : fields) {
      const std::size_t bytes = count(f) * f.elem;
      const void* src = host_data(f, sim);
      if (f.shadow.size() == bytes &&
          (bytes == 0 || std::memcmp(src, f.shadow.data(), bytes) == 0)) {
        continue;
      }
      upload_field(f, sim);
      ++field_uploads;
    }
  }

  /// Downloads every field the device writes into the host copy.
  void download_all(Simulation& sim) {
    for (Field& f : fields) {
      if (!f.both_ways) continue;
      const std::size_t bytes = count(f) * f.elem;
      void* dst = host_data(f, sim);
      api->download(dst, f.buf, bytes);
      f.shadow.assign(static_cast<unsigned char*>(dst), static_cast<unsigned char*>(dst) + bytes);
    }
  }

  // --- the view and the control block ----------------------------------------------------------

  /// The view of the current buffers and the host's parameters (zeroed first, so that two views
  /// compare by their bytes).
  View make_view(const Simulation& sim) {
    View u;
    std::memset(static_cast<void*>(&u), 0, sizeof u);
    for (Field& f : fields) f.bind(u, f.buf);
    for (Scratch& s : scratch) {
      if (holds(s.when)) s.bind(u, s.p);
    }
    if (load) {
      u.load_factor = sim.contact_load_factor();
      u.inv_pi_k = 1.0 / (kPi * sim.contact_load_factor());
    }
    if (crushing) {
      const CrushingConfig& c = crusher->config();
      u.d_c = crusher->d_c();
      u.v0 = c.v0;
      u.n_charles = c.n;
      u.crack_growth = c.crack_growth;
      u.crush_interval = c.interval;
    }
    u.ctrl = static_cast<Control*>(ctrl_buf.p);
    u.inspect_partial = static_cast<device::InspectSum*>(partial.p);
    std::size_t room[5] = {~std::size_t{0}, ~std::size_t{0}, ~std::size_t{0}, ~std::size_t{0},
                           ~std::size_t{0}};
    for (const Field& f : fields) {
      std::size_t& r = room[static_cast<int>(f.count)];
      r = std::min(r, f.cap / f.elem);
    }
    u.grain_capacity = static_cast<unsigned>(room[0]);
    u.entry_capacity = static_cast<unsigned>(room[1]);
    u.wall_entry_capacity = static_cast<unsigned>(room[2]);
    u.alpha = sim.config().damping.local_alpha;
    u.skin = sim.skin();
    u.gravity = sim.config().gravity.g;
    u.has_gravity = sim.config().gravity.on();
    u.bodies = static_cast<unsigned>(sim.walls().size());
    for (int k = 0; k < sim.walls().size(); ++k) {
      const WallConfig& w = sim.walls().config(k);
      device::WallCfgDev& d = u.wcfg[k];
      d.mode = w.mode == WallMode::Fixed ? 0 : (w.mode == WallMode::Velocity ? 1 : 2);
      d.velocity = w.velocity;
      d.target_stress = w.target_stress;
      d.servo_alpha = w.servo_alpha;
      d.max_speed = w.max_speed;
    }
    u.cp = sim.contact_params();
    return u;
  }

  /// The control block as the host's state sets it.
  Control host_control(const Simulation& sim) const {
    Control c;
    std::memset(static_cast<void*>(&c), 0, sizeof c);
    c.N = static_cast<unsigned>(N);
    c.M = static_cast<unsigned>(M);
    c.Mw = static_cast<unsigned>(Mw);
    c.time = sim.time();
    c.steps = sim.step_count();
    c.h = sim.current_dt();
    c.hh = 0.5 * c.h;
    c.last_check_time = crusher ? crusher->last_check_time() : 0.0;
    for (int k = 0; k < sim.walls().size(); ++k) {
      const WallState& s = sim.walls().state(k);
      c.walls[k] = {s.position, s.velocity, s.normal_force, s.force.x,
                    s.force.y,  s.force.z,  s.stiffness,    s.displacement_since_build};
    }
    return c;
  }

  void write_control(const Control& c) {
    api->upload(ctrl_buf.p, &c, sizeof c);
    ctrl = c;
  }

  /// Puts the device's clock, walls and crushing time into the host copy.
  void control_to_host(Simulation& sim) {
    for (int k = 0; k < sim.walls().size(); ++k) {
      const device::WallDev& d = ctrl.walls[k];
      WallState& s = sim.walls().state(k);
      s.position = d.position;
      s.velocity = d.velocity;
      s.normal_force = d.normal_force;
      s.force = {d.fx, d.fy, d.fz};
      s.stiffness = d.stiffness;
      s.displacement_since_build = d.displacement;
    }
    sim.set_clock(ctrl.time, ctrl.steps, sim.time_step());
    if (crusher) crusher->set_last_check_time(ctrl.last_check_time);
  }

  // --- stepping --------------------------------------------------------------------------------

  /// The host copy's changes on the device, and a view and control block that match it. With
  /// the fields not brought to the host since the device stepped, the host's arrays are older
  /// than the device's and are left alone (a controller that changes grains asks for
  /// Sync::All first); the walls, friction and clock go over either way.
  void prepare(Simulation& sim) {
    if (!clock_current) sync(sim, Sync::Clock);
    if (fields_current) {
      if (!sim.forces_current()) sim.compute_forces();  // first forces, or after a change
      sim.dt();  // the automatic step, chosen now if due (as the CPU step does first)
      if (layout_changed(sim)) {
        full_upload(sim);
      } else {
        upload_changes(sim);
      }
    } else if (layout_changed(sim)) {
      throw RuntimeFailure(
          "device: the grains changed on the host without a sync of the device's copy first");
    }
    const View u = make_view(sim);
    if (std::memcmp(static_cast<const void*>(&u), static_cast<const void*>(&view), sizeof u) != 0) {
      view = u;
      api->view_changed();
    }
    write_control(host_control(sim));
  }

  /// Steps until the automatic time step is chosen again (the batch ends there).
  std::uint64_t steps_to_dt(const Simulation& sim) const {
    const TimeStep& ts = sim.time_step();
    if (ts.fixed()) return ~std::uint64_t{0};
    const std::uint64_t since = ctrl.steps - ts.computed_at();
    const std::uint64_t every = sim.config().timestep.update_interval;
    return since >= every ? 0 : every - since;
  }

  void advance(Simulation& sim, std::uint64_t n) {
    if (n == 0) return;
    prepare(sim);
    std::uint64_t left = n;
    while (left > 0) {
      if (steps_to_dt(sim) == 0) choose_time_step(sim);
      const auto batch = static_cast<int>(
          std::min<std::uint64_t>({left, static_cast<std::uint64_t>(kBatch), steps_to_dt(sim)}));
      fields_current = clock_current = false;
      {
        // The device's whole step (its transfers stay "other").
        const PartScope timed(sim.part_clock(), Part::ContactForces);
        api->run_steps(view, laws, batch);
        api->read_control(view, ctrl);
      }
      left -= ctrl.steps_done;
      particle_steps += static_cast<double>(ctrl.steps_done) * static_cast<double>(N);
      if (ctrl.halt == device::kRebuild) {
        finish_with_rebuild(sim);
        --left;
      } else if (ctrl.halt == device::kRunning && ctrl.steps_done != static_cast<unsigned>(batch)) {
        throw RuntimeFailure("device: " + std::to_string(ctrl.steps_done) + " of " +
                             std::to_string(batch) + " steps completed");
      }
      if (ctrl.halt == device::kFailure) {
        split_failed(sim);
      } else {
        restart_counters();
      }
    }
  }

  /// The device's counters restart for the next batch (its clock and walls go on).
  void restart_counters() {
    Control c = ctrl;
    c.halt = device::kRunning;
    c.steps_done = 0;
    c.failures = 0;
    write_control(c);
  }

  /// The step the device stopped after its drift: the list rebuilt on the host (history carried
  /// over) and uploaded, then the step finished on the device.
  void finish_with_rebuild(Simulation& sim) {
    download_all(sim);  // mid-step: no inspection of it
    control_to_host(sim);
    fields_current = true;
    sim.rebuild_neighbors();
    full_upload(sim);
    const View u = make_view(sim);
    if (std::memcmp(static_cast<const void*>(&u), static_cast<const void*>(&view), sizeof u) != 0) {
      view = u;
      api->view_changed();
    }
    write_control(host_control(sim));
    fields_current = clock_current = false;
    api->finish_step(view, laws);
    api->read_control(view, ctrl);
    if (ctrl.steps_done != 1) throw RuntimeFailure("device: the rebuilt step did not finish");
    particle_steps += static_cast<double>(N);
  }

  /// The device's stiffness time (reduced there, the bits of the host's stiffness_time() on
  /// the same state).
  double stiffness_time() {
    api->stiffness_time(view, laws, static_cast<unsigned>(N));
    api->read_control(view, ctrl);
    double t = 0.0;
    std::memcpy(&t, &ctrl.stiffness_bits, sizeof t);
    return t;
  }

  /// The automatic time step, chosen as the CPU step chooses it, from the device's contacts
  /// (no grain comes to the host).
  void choose_time_step(Simulation& sim) {
    control_to_host(sim);
    sim.choose_dt(stiffness_time());
    Control c = ctrl;
    c.h = sim.current_dt();
    c.hh = 0.5 * c.h;
    write_control(c);
  }

  /// The grains the device's crushing check found failing, split on the host in one topology
  /// phase (as Crusher::apply does on the CPU), then the forces of the new state.
  void split_failed(Simulation& sim) {
    sync_all(sim);
    std::vector<std::uint8_t> flags(N);
    api->download(flags.data(), scratch_named("fail").p, N);
    std::vector<std::pair<std::size_t, BreakCause>> grains;
    for (std::size_t i = 0; i < N; ++i) {
      if (flags[i] == static_cast<std::uint8_t>(GrainFailure::None)) continue;
      grains.emplace_back(i, flags[i] == static_cast<std::uint8_t>(GrainFailure::Instant)
                                 ? BreakCause::Instant
                                 : BreakCause::Crack);
    }
    const std::vector<BreakageEvent> events = [&] {
      const PartScope timed(sim.part_clock(), Part::Crushing);
      return crusher->split(sim, std::move(grains));
    }();
    if (sink && !events.empty()) sink(events);
    sim.compute_forces();
    prepare(sim);
    clock_current = false;  // the next sync inspects the state after the split
  }

  void sync_all(Simulation& sim) {
    sync(sim, Sync::All);
  }

  void sync(Simulation& sim, Sync what) {
    if (!have_device) return;
    if (!clock_current) {
      control_to_host(sim);
      // Host code after a sync may ask for the time step (a duration's steps to its check): at
      // a step where the automatic step is due, choose it now from the device's positions, as
      // the next batch would.
      if (steps_to_dt(sim) == 0) choose_time_step(sim);
      // The controllers' scalars of this state, reduced on the device (deterministic trees).
      api->inspect(view, laws, static_cast<unsigned>(N));
      api->read_control(view, ctrl);
      Simulation::Inspection i;
      i.step = ctrl.steps;
      i.resultant_sum = ctrl.inspect_resultant;
      i.pair_F_n_sum = ctrl.inspect_F_n;
      i.pairs = ctrl.inspect_pairs;
      sim.set_inspection(i);
      clock_current = true;
    }
    if (what == Sync::All && !fields_current) {
      download_all(sim);
      fields_current = true;
    }
  }
};

DeviceStepper::DeviceStepper(std::unique_ptr<device::Api> api)
    : impl_(std::make_unique<Impl>(std::move(api))) {}

DeviceStepper::~DeviceStepper() = default;

std::string DeviceStepper::name() const {
  return impl_->api->emulated() ? "emulated" : "cuda";
}

void DeviceStepper::attach_crusher(Crusher* crusher, BreakageSink sink) {
  Stepper::attach_crusher(crusher, sink);
  impl_->crusher = crusher;
  impl_->sink = std::move(sink);
}

void DeviceStepper::advance(Simulation& sim, std::uint64_t n) {
  impl_->advance(sim, n);
  particle_steps_ = impl_->particle_steps;
}

void DeviceStepper::sync(Simulation& sim, Sync what) {
  impl_->sync(sim, what);
}

std::size_t DeviceStepper::device_bytes() const {
  std::size_t b = 0;
  for (const Field& f : impl_->fields) b += f.cap;
  for (const Scratch& s : impl_->scratch) b += s.cap;
  b += impl_->ctrl_buf.cap + impl_->partial.cap;
  return b;
}

std::uint64_t DeviceStepper::full_uploads() const {
  return impl_->full_uploads;
}

std::uint64_t DeviceStepper::field_uploads() const {
  return impl_->field_uploads;
}

double DeviceStepper::stiffness_time() {
  if (!impl_->have_device) throw RuntimeFailure("device: no state to reduce before advance()");
  return impl_->stiffness_time();
}

}  // namespace crushdem
