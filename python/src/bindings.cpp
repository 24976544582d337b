// crushdem_sand._core: the nanobind module behind the Python package.
//
// The Python side builds a Simulation from a nested dict that mirrors the TOML configuration file
// (same sections, same keys, SI units); the dict is converted to a toml::Table and read by the one
// configuration reader the command line uses, so validation and error messages are identical.
// Particle state is returned as NumPy copies (float64, ids uint64).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "crushdem/backend/stepper.hpp"
#include "crushdem/cli/cli.hpp"
#include "crushdem/core/build_info.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/integrate/simulation.hpp"
#include "crushdem/io/config.hpp"
#include "crushdem/io/toml.hpp"
#include "crushdem/particles/generate.hpp"
#include "crushdem/run/runner.hpp"
#include "crushdem/walls/body_probe.hpp"

#ifdef CRUSHDEM_HAVE_OPENMP
#include <omp.h>
#endif

namespace nb = nanobind;
using namespace nb::literals;

namespace crushdem::python {
namespace {

// --- dict -> toml::Table ---------------------------------------------------------------------

std::string join_key(const std::string& prefix, const std::string& key) {
  return prefix.empty() ? key : prefix + "." + key;
}

std::string type_name_of(nb::handle obj) {
  return nb::cast<std::string>(
      nb::str(nb::handle(reinterpret_cast<PyObject*>(Py_TYPE(obj.ptr()))).attr("__name__")));
}

toml::Table to_table(nb::handle dict, const std::string& prefix, int depth = 0);

// The TOML reader's bound: a dict nested 10^5 deep (or a list that holds itself) is an error,
// not a stack overflow.

toml::Value to_value(nb::handle obj, const std::string& key, int depth = 0) {
  if (depth > toml::kMaxNesting) {
    throw ConfigError("<python>: key '" + key.substr(0, 60) +
                      "...': dicts and lists nested more than " +
                      std::to_string(toml::kMaxNesting) + " deep (no configuration goes beyond 4)");
  }
  // bool first: Python's bool is a subclass of int.
  if (PyBool_Check(obj.ptr())) return toml::Value::make_bool(obj.ptr() == Py_True);
  if (PyLong_Check(obj.ptr())) {
    int overflow = 0;
    const long long v = PyLong_AsLongLongAndOverflow(obj.ptr(), &overflow);
    if (overflow != 0) {
      throw ConfigError(
          bad_value(key, nb::cast<std::string>(nb::str(obj)), "an integer that fits in 64 bits"));
    }
    if (v == -1 && PyErr_Occurred()) throw nb::python_error();
    return toml::Value::make_integer(static_cast<std::int64_t>(v));
  }
  if (PyFloat_Check(obj.ptr())) return toml::Value::make_float(PyFloat_AsDouble(obj.ptr()));
  if (PyUnicode_Check(obj.ptr())) return toml::Value::make_string(nb::cast<std::string>(obj));
  if (PyDict_Check(obj.ptr())) return toml::Value::make_table(to_table(obj, key, depth + 1));
  if (PyList_Check(obj.ptr()) || PyTuple_Check(obj.ptr())) {
    std::vector<toml::Value> elements;
    std::size_t k = 0;
    for (nb::handle item : obj) {
      elements.push_back(to_value(item, key + "[" + std::to_string(k) + "]", depth + 1));
      ++k;
    }
    return toml::Value::make_array(std::move(elements));
  }
  // NumPy scalars and arrays (and anything else array-like with tolist()): convert to plain
  // Python objects first; numpy.bool_ becomes bool, integer dtypes int, float dtypes float.
  if (nb::hasattr(obj, "dtype") && nb::hasattr(obj, "tolist")) {
    nb::object plain = obj.attr("tolist")();
    if (!nb::hasattr(plain, "dtype")) return to_value(plain, key, depth + 1);
  }
  if (obj.is_none()) {
    throw ConfigError("<python>: key '" + key +
                      "' = None: expected a value (leave the key out for the default)");
  }
  throw ConfigError(
      "<python>: key '" + key + "': a Python " + type_name_of(obj) +
      " cannot be a configuration value (expected bool, int, float, str, list or dict)");
}

toml::Table to_table(nb::handle dict, const std::string& prefix, int depth) {
  if (!PyDict_Check(dict.ptr())) {
    throw ConfigError((prefix.empty() ? std::string("configuration") : "key '" + prefix + "'") +
                      ": expected a dict, got a " + type_name_of(dict));
  }
  toml::Table t;
  for (auto [k, v] : nb::borrow<nb::dict>(dict)) {
    if (!PyUnicode_Check(k.ptr())) {
      throw ConfigError("configuration keys must be strings; got " +
                        nb::cast<std::string>(nb::repr(k)) +
                        (prefix.empty() ? std::string() : " in '" + prefix + "'"));
    }
    const std::string key = nb::cast<std::string>(k);
    t[key] = to_value(v, join_key(prefix, key), depth);
  }
  return t;
}

// The API refuses what the sample reader refuses: a new grain at another's centre or deep
// inside it (checked against the grains present and the other new ones, before any is added).
void check_new_overlaps(const Simulation& sim, const std::vector<NewParticle>& grains) {
  const ParticleStore& p = sim.particles();
  std::vector<PlacedSphere> all;
  all.reserve(p.size() + grains.size());
  for (std::size_t i = 0; i < p.size(); ++i) all.push_back({{p.x[i], p.y[i], p.z[i]}, p.radius[i]});
  for (const NewParticle& g : grains) {
    if (!(g.radius > 0.0) || !std::isfinite(g.radius)) return;  // refused by add_particles itself
    all.push_back({g.position, g.radius});
  }
  const auto deep = find_deep_overlap(all, kMaxInputOverlapShare, p.size());
  if (!deep) return;
  const auto name = [&](std::size_t k) {
    return k < p.size() ? "grain id " + std::to_string(p.id[k])
                        : "new grain " + std::to_string(k - p.size());
  };
  char share[32];
  std::snprintf(share, sizeof share, "%.0f %%", 100.0 * deep->share);
  throw ConfigError("add_particles: " + name(deep->a) + " and " + name(deep->b) + " overlap by " +
                    share + " of the smaller radius (coincident centres give " +
                    "200 %): expected distinct grains overlapping by at most " +
                    std::to_string(static_cast<int>(100.0 * kMaxInputOverlapShare)) +
                    " % of a radius");
}

SimulationConfig config_from_dict(nb::handle dict) {
  return simulation_config_from_toml(to_table(dict, ""), "<python>");
}

// --- NumPy output ------------------------------------------------------------------------------

template <class T>
using NpArray = nb::ndarray<nb::numpy, T>;

/// A new C-contiguous NumPy array owning its memory.
template <class T>
NpArray<T> new_array(std::initializer_list<std::size_t> shape, T** data) {
  std::size_t n = 1;
  for (std::size_t s : shape) n *= s;
  T* buf = new T[n > 0 ? n : 1]();
  nb::capsule owner(buf, [](void* p) noexcept { delete[] static_cast<T*>(p); });
  *data = buf;
  return NpArray<T>(buf, shape, owner);
}

NpArray<double> column(const std::vector<double>& v) {
  double* d = nullptr;
  auto a = new_array<double>({v.size()}, &d);
  std::copy(v.begin(), v.end(), d);
  return a;
}

NpArray<std::uint64_t> id_column(const std::vector<ParticleId>& v) {
  std::uint64_t* d = nullptr;
  auto a = new_array<std::uint64_t>({v.size()}, &d);
  std::copy(v.begin(), v.end(), d);
  return a;
}

NpArray<double> triple(const std::vector<double>& x, const std::vector<double>& y,
                       const std::vector<double>& z) {
  double* d = nullptr;
  auto a = new_array<double>({x.size(), 3}, &d);
  for (std::size_t i = 0; i < x.size(); ++i) {
    d[3 * i] = x[i];
    d[3 * i + 1] = y[i];
    d[3 * i + 2] = z[i];
  }
  return a;
}

// --- NumPy input -------------------------------------------------------------------------------

using InArray = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;

void check_shape(const InArray& a, const char* name, std::size_t n, bool vec3) {
  const bool ok = vec3 ? (a.ndim() == 2 && a.shape(1) == 3 && a.shape(0) == n)
                       : (a.ndim() == 1 && a.shape(0) == n);
  if (!ok) {
    std::string got = "(";
    for (std::size_t d = 0; d < a.ndim(); ++d) {
      got += (d ? ", " : "") + std::to_string(a.shape(d));
    }
    got += a.ndim() == 1 ? ",)" : ")";
    throw nb::value_error(
        (std::string(name) + ": expected shape " +
         (vec3 ? "(" + std::to_string(n) + ", 3)" : "(" + std::to_string(n) + ",)") + ", got " +
         got)
            .c_str());
  }
}

// --- walls -------------------------------------------------------------------------------------

// A box wall (xmin ... zmax) or a [[body]] by name: its index in Walls.
int wall_index(const Simulation& sim, const std::string& name) {
  const Walls& w = sim.walls();
  std::string bodies;
  for (int k = 0; k < w.size(); ++k) {
    if (name == w.name(k)) return k;
    if (k >= kNumWalls) bodies += ", " + w.name(k);
  }
  throw ConfigError(bad_value(
      "wall", "'" + name + "'",
      "one of xmin, xmax, ymin, ymax, zmin, zmax" +
          (bodies.empty() ? std::string(" (no [[body]] is configured)") : " or a body" + bodies)));
}

// The configuration key prefix of wall or body k, as the messages name it.
std::string wall_prefix(const Walls& w, int k) {
  return k < kNumWalls ? "walls." + w.name(k) : "body[" + std::to_string(k - kNumWalls) + "]";
}

void set_wall(Simulation& sim, const std::string& name, std::optional<std::string> mode,
              std::optional<double> velocity, std::optional<double> target_stress,
              std::optional<double> servo_alpha, std::optional<double> max_speed) {
  const int k = wall_index(sim, name);
  const std::string prefix = wall_prefix(sim.walls(), k);
  WallConfig c = sim.walls().config(k);
  if (mode) c.mode = parse_wall_mode(*mode, prefix + ".mode");
  if (velocity) c.velocity = *velocity;
  if (target_stress) c.target_stress = *target_stress;
  if (servo_alpha) c.servo_alpha = *servo_alpha;
  if (max_speed) c.max_speed = *max_speed;
  sim.walls().drive(k, c, prefix);
}

// Every body beyond the box as columns: its name, index (a wall contact's id_j), degree of
// freedom, how it moves, the grains' force and moment on it and its stress.
nb::dict body_columns(const Simulation& sim) {
  const Walls& w = sim.walls();
  const auto n = static_cast<std::size_t>(w.size() - kNumWalls);
  // Not current (grains added or moved since the last evaluation): the wall entries may not
  // match the grains, so the moment is unknown, not zero.
  const double unknown = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Vec3> M =
      sim.forces_current()
          ? body_moments(w, sim.wall_contacts(), sim.particles())
          : std::vector<Vec3>(static_cast<std::size_t>(w.size()), Vec3{unknown, unknown, unknown});
  nb::list names, modes;
  std::int64_t* index;
  double *q, *v, *stress, *force, *moment;
  nb::dict out;
  auto index_array = new_array<std::int64_t>({n}, &index);
  auto q_array = new_array<double>({n}, &q);
  auto v_array = new_array<double>({n}, &v);
  auto force_array = new_array<double>({n, 3}, &force);
  auto moment_array = new_array<double>({n, 3}, &moment);
  auto stress_array = new_array<double>({n}, &stress);
  for (std::size_t b = 0; b < n; ++b) {
    const int k = kNumWalls + static_cast<int>(b);
    const WallState& st = w.state(k);
    const Vec3& m = M[static_cast<std::size_t>(k)];
    names.append(w.name(k));
    modes.append(to_string(w.config(k).mode));
    index[b] = k;
    q[b] = st.position;
    v[b] = st.velocity;
    const double f3[3] = {st.force.x, st.force.y, st.force.z}, m3[3] = {m.x, m.y, m.z};
    std::copy(f3, f3 + 3, force + 3 * b);
    std::copy(m3, m3 + 3, moment + 3 * b);
    stress[b] = w.stress(k);
  }
  out["name"] = names;
  out["index"] = index_array;
  out["mode"] = modes;
  out["position"] = q_array;
  out["velocity"] = v_array;
  out["force"] = force_array;
  out["moment"] = moment_array;
  out["stress"] = stress_array;
  return out;
}

// The penetration probe of body `name` (walls/body_probe.hpp) as a dict.
nb::dict probe_columns(const Simulation& sim, const std::string& name, double sleeve_length,
                       std::int64_t bins) {
  const Walls& w = sim.walls();
  int k = -1;
  std::string probed;  // the bodies probe_body takes, for the message
  for (int j = kNumWalls; j < w.size(); ++j) {
    if (!probe_supports(w.shape(j))) continue;
    if (w.name(j) == name) k = j;
    probed += (probed.empty() ? "" : ", ") + w.name(j);
  }
  if (k < 0) {
    throw ConfigError(bad_value(
        "name", "'" + name + "'",
        "a body that translates with a tip or a shaft (a pile, a cone, a disk or the outside of "
        "a cylinder): " +
            (probed.empty() ? std::string("this simulation has none") : "one of " + probed)));
  }
  if (!(sleeve_length >= 0.0) || !std::isfinite(sleeve_length)) {
    throw ConfigError(bad_value("sleeve_length", show_number(sleeve_length),
                                "a length >= 0 in m (0: the standard sleeve, 3.75 diameters)"));
  }
  if (bins < 1 || bins > 100000) {
    throw ConfigError(bad_value("bins", std::to_string(bins), "a number of bins in [1, 100000]"));
  }
  if (!sim.forces_current()) {
    throw RuntimeFailure(
        "probe_body: the forces are not current (grains added or moved since "
        "the last evaluation): call compute_forces() or step() first");
  }
  const BodyProbe p =
      probe_body(w, k, sim.wall_contacts(), sim.particles(), sleeve_length, static_cast<int>(bins));
  nb::dict out;
  double* tip;
  out["tip"] = new_array<double>({3}, &tip);
  tip[0] = p.tip.x;
  tip[1] = p.tip.y;
  tip[2] = p.tip.z;
  out["radius"] = p.radius;
  out["sector"] = p.sector;
  out["q_c"] = p.q_c();
  out["f_s"] = p.f_s();
  out["tip_load"] = p.tip_load;
  out["shaft_load"] = p.shaft_load;
  out["sleeve_load"] = p.sleeve_load;
  out["sleeve_length"] = p.sleeve_length;
  out["tip_contacts"] = p.tip_contacts;
  out["shaft_contacts"] = p.shaft_contacts;
  out["bin_height"] = p.bin_height;
  out["sigma_r"] = column(p.sigma_r);
  out["tau"] = column(p.tau);
  out["bin_contacts"] = id_column(p.bin_contacts);
  return out;
}

// --- the module --------------------------------------------------------------------------------

int run_cli(const std::vector<std::string>& args,
            const std::vector<cli::FrontEndCommand>& commands) {
  int rc;
  {
    nb::gil_scoped_release release;
    rc = cli::cli_main(args, commands);
    std::fflush(stdout);
    std::fflush(stderr);
  }
  return rc;
}

/// What run() and resume() return to Python.
nb::dict summary_dict(const RunSummary& s) {
  nb::dict d;
  d["steps"] = s.steps;
  d["time"] = s.time;
  d["wall_seconds"] = s.wall_seconds;
  d["particles"] = s.particles;
  return d;
}

/// A parameter table's rows as dicts (the keyword arguments of crushdem_sand.lab come from them).
nb::list rows_list(const std::vector<param_io::ParamRow>& rows) {
  nb::list out;
  for (const param_io::ParamRow& r : rows) {
    nb::dict d;
    d["key"] = r.key;
    d["type"] = r.type;
    d["default"] = std::visit([](const auto& v) { return nb::cast(v); }, r.default_value);
    d["required"] = r.default_doc == "-";
    d["default_doc"] = r.default_doc;
    d["unit"] = r.unit;
    d["doc"] = r.doc;
    d["choices"] = r.choices;
    d["expected"] = r.expected;
    out.append(d);
  }
  return out;
}

/// sim.step(n) in chunks of about 0.1 s of wall-clock time, so that Ctrl-C (the Python signal
/// handlers, run with the GIL) is seen within a second and a progress callback can be called;
/// n steps in chunks give the bits of one step(n) call (tests/test_step_fusion.cpp).
void step_interruptibly(Simulation& sim, std::uint64_t n, const nb::object& progress) {
  using clock = std::chrono::steady_clock;
  std::uint64_t done = 0, chunk = 16;
  auto last_report = clock::now();
  while (done < n) {
    const std::uint64_t k = std::min(chunk, n - done);
    const auto t0 = clock::now();
    {
      nb::gil_scoped_release release;  // a long run must not block other Python threads
      sim.step(k);
    }
    done += k;
    const double seconds = std::chrono::duration<double>(clock::now() - t0).count();
    if (seconds < 0.05 && chunk < (std::uint64_t{1} << 30)) chunk *= 2;
    if (seconds > 0.2 && chunk > 1) chunk /= 2;
    if (PyErr_CheckSignals() != 0) throw nb::python_error();
    if (!progress.is_none() &&
        (done == n || std::chrono::duration<double>(clock::now() - last_report).count() > 0.5)) {
      progress(done, n);
      last_report = clock::now();
    }
  }
}

/// crushdem_sand._core.Interrupted, a KeyboardInterrupt (so that `except Exception` does not
/// swallow it): a run stopped by SIGINT or SIGTERM after saving its checkpoint.
PyObject* interrupted_type = nullptr;

/// Runs `go` (a whole run) without the GIL and with SIGINT / SIGTERM asking it to checkpoint and
/// stop, as in the CLI; a stopped run raises Interrupted with `signal` and `out_dir` set.
nb::dict run_interruptible(const std::function<RunSummary()>& go) {
  std::optional<Interrupted> stopped;
  RunSummary s;
  {
    nb::gil_scoped_release release;  // a long run must not block other Python threads
    const StopOnSignals handlers;
    try {
      s = go();
    } catch (const Interrupted& e) {
      stopped = e;  // raised below, with the GIL held again
    }
  }
  if (stopped) {
    nb::object exc = nb::borrow(interrupted_type)(stopped->what());
    exc.attr("signal") = stopped->signal();
    exc.attr("out_dir") = stopped->out_dir();
    PyErr_SetObject(interrupted_type, exc.ptr());
    throw nb::python_error();
  }
  return summary_dict(s);
}

}  // namespace
}  // namespace crushdem::python

NB_MODULE(_core, m) {
  using namespace crushdem;
  using namespace crushdem::python;

  m.doc() =
      "crushdem C++ engine (nanobind bindings). Use the crushdem_sand package, not this module.";
  m.attr("__version__") = CRUSHDEM_VERSION;
  m.attr("__commit__") = build_commit();

  m.def("parameter_reference", &parameter_reference,
        "The configuration keys with a parameter table, as (section, Markdown table) pairs: "
        "key, default, unit and meaning of each (the tables of docs/configuration.md; for "
        "\"stage\", each kind's heading and table).");
  m.def(
      "parameter_tables",
      [] {
        nb::dict out;
        for (const auto& [section, rows] : parameter_tables())
          out[section.c_str()] = rows_list(rows);
        return out;
      },
      "The rows of every parameter table, {section: [row]}; a stage kind's section is "
      "\"stage.KIND\". A row is a dict: key, type (\"float\", \"int\", \"bool\" or \"str\"), "
      "default (the value in a default configuration), required (no default: the key must be "
      "given where it applies), default_doc (what the docs show instead of the value), unit, doc, "
      "choices (a choice's values), expected (the range, when checked).");
  m.def(
      "stage_kinds",
      [] {
        nb::list out;
        for (const StageKind* k : stage_kinds()) {
          nb::dict d;
          d["name"] = std::string(k->name);
          d["description"] = std::string(k->description);
          d["needs_crack_growth"] = k->needs_crack_growth;
          out.append(d);
        }
        return out;
      },
      "The kinds of [[stage]], in order, as dicts: name (the `type`), description, "
      "needs_crack_growth (needs [crushing] with crack_growth = true). Their keys: "
      "parameter_tables()[\"stage.\" + name].");
  m.def(
      "set_threads",
      [](long n) {
        if (n < 1) throw ConfigError(bad_value("threads", std::to_string(n), "a count >= 1"));
        cli::set_threads(n, "threads");
        return cli::current_threads();
      },
      nb::arg("n"),
      "Sets the number of OpenMP threads of every later step and run (results do not depend "
      "on it); returns the count in force (1 in a build without OpenMP).");
  m.def(
      "threads",
      [] {
#ifdef CRUSHDEM_HAVE_OPENMP
        return omp_get_max_threads();
#else
        return 1;
#endif
      },
      "The number of OpenMP threads the next step or run uses.");

  nb::exception<ConfigError>(m, "ConfigError", PyExc_ValueError);
  nb::exception<RuntimeFailure>(m, "RuntimeFailure", PyExc_RuntimeError);
  interrupted_type = PyErr_NewExceptionWithDoc(
      "crushdem_sand._core.Interrupted",
      "A run stopped by SIGINT or SIGTERM after saving its checkpoint; `signal` and `out_dir` "
      "say which signal and where (continue with crushdem_sand.resume(out_dir)).",
      PyExc_KeyboardInterrupt, nullptr);
  m.attr("Interrupted") = nb::handle(interrupted_type);

  nb::class_<Simulation>(m, "Simulation",
                         "The time-stepping engine. Build it from a nested dict with the sections "
                         "of a TOML configuration file (SI units).")
      .def(
          "__init__",
          [](Simulation* self, nb::dict config) {
            new (self) Simulation(config_from_dict(config));
          },
          "config"_a = nb::dict(),
          "Validates the configuration; bad or unknown keys raise ValueError naming the key.")

      .def(
          "add_particles",
          [](Simulation& sim, InArray positions, InArray radii, std::optional<InArray> velocities) {
            const std::size_t n = radii.ndim() == 1 ? radii.shape(0) : 0;
            check_shape(radii, "radii", n, false);
            check_shape(positions, "positions", n, true);
            if (velocities) check_shape(*velocities, "velocities", n, true);
            const double* x = positions.data();
            const double* r = radii.data();
            const double* v = velocities ? velocities->data() : nullptr;
            std::vector<NewParticle> grains(n);
            for (std::size_t i = 0; i < n; ++i) {
              grains[i].position = {x[3 * i], x[3 * i + 1], x[3 * i + 2]};
              if (v) grains[i].velocity = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
              grains[i].radius = r[i];
            }
            check_new_overlaps(sim, grains);
            return id_column(sim.add_particles(std::move(grains)));
          },
          "positions"_a, "radii"_a, "velocities"_a = nb::none(),
          "Adds grains: positions (N,3) [m], radii (N,) [m], velocities (N,3) [m/s] or None. "
          "Returns their ids (uint64).")

      .def(
          "step",
          [](Simulation& sim, std::int64_t n, nb::object progress) {
            if (n < 0) throw nb::value_error("step: n must be >= 0");
            step_interruptibly(sim, static_cast<std::uint64_t>(n), progress);
          },
          "n"_a = 1, "progress"_a = nb::none(),
          "Advances n time steps, the GIL released while stepping. Between chunks of about a "
          "tenth of a second it checks for Ctrl-C (KeyboardInterrupt, raised between two steps: "
          "the state stays consistent and step_count says how far it got) and calls "
          "progress(done, n), when given, about twice a second and at the end. Chunking changes "
          "no result.")
      .def("compute_forces", &Simulation::compute_forces,
           "Computes forces and torques for the current state without moving anything.")
      .def("invalidate", &Simulation::invalidate,
           "Forces and neighbour list are recomputed before the next step.")

      .def_prop_ro("time", &Simulation::time, "Simulated time [s].")
      .def_prop_ro("step_count", &Simulation::step_count, "Steps taken.")
      .def_prop_ro(
          "dt", [](Simulation& sim) { return sim.dt(); },
          "The time step the next step uses [s] (computed if automatic).")
      .def("set_dt", &Simulation::set_dt, "dt"_a, "Fixes the time step [s] (overrides automatic).")
      .def("rayleigh_dt", &Simulation::rayleigh_dt, "Rayleigh time-step estimate [s].")
      .def("stiffness_dt", &Simulation::stiffness_dt, "Stiffness time-step estimate [s].")
      .def("automatic_dt", &Simulation::automatic_dt,
           "The step the automatic choice would take now [s], fixed step or not.")
      .def_prop_ro("num_particles", [](const Simulation& sim) { return sim.particles().size(); })

      // Particle arrays (copies).
      .def(
          "positions",
          [](const Simulation& s) {
            const auto& p = s.particles();
            return triple(p.x, p.y, p.z);
          },
          "Positions (N,3) [m].")
      .def(
          "velocities",
          [](const Simulation& s) {
            const auto& p = s.particles();
            return triple(p.vx, p.vy, p.vz);
          },
          "Velocities (N,3) [m/s].")
      .def(
          "angular_velocities",
          [](const Simulation& s) {
            const auto& p = s.particles();
            return triple(p.wx, p.wy, p.wz);
          },
          "Angular velocities (N,3) [rad/s].")
      .def(
          "forces",
          [](const Simulation& s) {
            const auto& p = s.particles();
            return triple(p.fx, p.fy, p.fz);
          },
          "Forces (N,3) [N] of the last evaluation (after local damping).")
      .def(
          "torques",
          [](const Simulation& s) {
            const auto& p = s.particles();
            return triple(p.tx, p.ty, p.tz);
          },
          "Torques (N,3) [N m].")
      .def(
          "radii", [](const Simulation& s) { return column(s.particles().radius); },
          "Radii (N,) [m].")
      .def(
          "masses", [](const Simulation& s) { return column(s.particles().mass); },
          "Masses (N,) [kg].")
      .def(
          "ids", [](const Simulation& s) { return id_column(s.particles().id); },
          "Ids (N,) uint64.")
      .def(
          "parent_ids", [](const Simulation& s) { return id_column(s.particles().parent); },
          "Parent ids (N,) uint64; 2**64-1 for no parent.")

      .def(
          "contacts",
          [](const Simulation& sim) {
            const std::vector<ContactRecord> cs = sim.contacts();
            const std::size_t n = cs.size();
            std::uint64_t *ii, *jj;
            bool* wall;
            double *delta, *fn, *normal, *ft, *mr;
            nb::dict out;
            out["id_i"] = new_array<std::uint64_t>({n}, &ii);
            out["id_j"] = new_array<std::uint64_t>({n}, &jj);
            out["is_wall"] = new_array<bool>({n}, &wall);
            out["overlap"] = new_array<double>({n}, &delta);
            out["normal_force"] = new_array<double>({n}, &fn);
            out["normal"] = new_array<double>({n, 3}, &normal);
            out["tangential_force"] = new_array<double>({n, 3}, &ft);
            out["rolling_moment"] = new_array<double>({n, 3}, &mr);
            for (std::size_t c = 0; c < n; ++c) {
              const ContactRecord& r = cs[c];
              ii[c] = r.id_i;
              jj[c] = r.id_j;
              wall[c] = r.is_wall;
              delta[c] = r.delta;
              fn[c] = r.F_n;
              normal[3 * c] = r.normal.x;
              normal[3 * c + 1] = r.normal.y;
              normal[3 * c + 2] = r.normal.z;
              ft[3 * c] = r.F_t.x;
              ft[3 * c + 1] = r.F_t.y;
              ft[3 * c + 2] = r.F_t.z;
              mr[3 * c] = r.M_r.x;
              mr[3 * c + 1] = r.M_r.y;
              mr[3 * c + 2] = r.M_r.z;
            }
            return out;
          },
          "Touching contacts: dict of arrays id_i, id_j (uint64; wall index 0..5 when is_wall), "
          "is_wall (bool), overlap [m], normal_force [N], normal (N,3) unit vector from i to j "
          "(or into the wall), tangential_force (N,3) [N] on i, rolling_moment (N,3) [N m] on i "
          "(zero without rolling resistance and at walls).")
      .def("num_contacts", &Simulation::num_contacts, "Grain-grain contacts with positive overlap.")

      .def(
          "wall_positions",
          [](const Simulation& sim) {
            double* d;
            auto a = new_array<double>({kNumWalls}, &d);
            for (int k = 0; k < kNumWalls; ++k) d[k] = sim.walls().position(k);
            return a;
          },
          "Wall plane coordinates (6,) [m], order xmin xmax ymin ymax zmin zmax.")
      .def(
          "wall_velocities",
          [](const Simulation& sim) {
            double* d;
            auto a = new_array<double>({kNumWalls}, &d);
            for (int k = 0; k < kNumWalls; ++k) d[k] = sim.walls().state(k).velocity;
            return a;
          },
          "Wall velocities along their axes (6,) [m/s].")
      .def(
          "wall_stresses",
          [](const Simulation& sim) {
            double* d;
            auto a = new_array<double>({kNumWalls}, &d);
            for (int k = 0; k < kNumWalls; ++k) d[k] = sim.walls().stress(k);
            return a;
          },
          "Compressive normal stress on each wall (6,) [Pa].")
      .def(
          "wall_forces",
          [](const Simulation& sim) {
            double* d;
            auto a = new_array<double>({kNumWalls, 3}, &d);
            for (int k = 0; k < kNumWalls; ++k) {
              const Vec3 f = sim.walls().state(k).force;
              d[3 * k] = f.x;
              d[3 * k + 1] = f.y;
              d[3 * k + 2] = f.z;
            }
            return a;
          },
          "Total force of the grains on each wall (6,3) [N].")
      .def("set_wall", &set_wall, "name"_a, "mode"_a = nb::none(), "velocity"_a = nb::none(),
           "target_stress"_a = nb::none(), "servo_alpha"_a = nb::none(), "max_speed"_a = nb::none(),
           "Changes the control of wall or body `name` (xmin..zmax or a [[body]]'s name): mode "
           "'fixed'|'velocity'|'servo', "
           "velocity [m/s] along the axis, target_stress [Pa], servo_alpha [-], max_speed [m/s].")
      .def(
          "wall_config",
          [](const Simulation& sim, const std::string& name) {
            const WallConfig& c = sim.walls().config(wall_index(sim, name));
            nb::dict d;
            d["mode"] = to_string(c.mode);
            d["velocity"] = c.velocity;
            d["target_stress"] = c.target_stress;
            d["servo_alpha"] = c.servo_alpha;
            d["max_speed"] = c.max_speed;
            return d;
          },
          "name"_a, "The current control settings of one wall or body as a dict.")
      .def("bodies", &body_columns,
           "The bodies beyond the box as columns: name, index (a wall contact's id_j), mode, "
           "position (their degree of freedom q) [m], velocity (dq/dt) [m/s], force (n,3) and "
           "moment (n,3) of the grains on each (the moment about its reference point) [N, N m], "
           "stress [Pa]; as the last force evaluation left them.")
      .def("probe_body", &probe_columns, "name"_a, "sleeve_length"_a = 0.0, "bins"_a = 1,
           "The penetration probe of a pile, cone or shaft (docs/chamber.md): tip, radius, "
           "sector, q_c, f_s, tip_load, shaft_load, sleeve_load, sleeve_length, tip_contacts, "
           "shaft_contacts, bin_height, sigma_r, tau and bin_contacts by bin along the shaft.")

      .def(
          "love_weber_stress",
          [](const Simulation& sim) {
            const std::array<double, 9> s = sim.love_weber_stress();
            double* d;
            auto a = new_array<double>({3, 3}, &d);
            std::copy(s.begin(), s.end(), d);
            return a;
          },
          "Love-Weber stress tensor (3,3) over the box volume [Pa], compression positive.")
      .def("kinetic_energy", &Simulation::kinetic_energy, "Translational + rotational [J].")
      .def("memory_bytes", &Simulation::memory_bytes)
      .def(
          "config_toml",
          [](const Simulation& sim) { return toml::serialize(to_toml(sim.config())); },
          "The configuration the simulation was built with, every key resolved, as TOML.");

  m.def("cli_main", &run_cli, "args"_a, "commands"_a = std::vector<cli::FrontEndCommand>{},
        "Runs the command-line front end (`crushdem-sand run|check|bench ...`); returns the exit "
        "code. "
        "`commands`: (name, description) of the caller's own commands, listed in the help.");
  m.def(
      "run",
      [](nb::dict config, const std::string& out, const std::string& base_dir, bool progress,
         bool overwrite, const std::string& branch_dir, const std::string& branch_stage,
         const std::string& backend, bool keep_columns) {
        check_backend_name(backend, "backend");
        const RunConfig cfg = run_config_from_toml(to_table(config, ""), "<python>", base_dir);
        RunOptions opt;
        opt.out_dir = out;
        opt.progress = progress;
        opt.overwrite = overwrite;
        opt.branch_dir = branch_dir;
        opt.branch_stage = branch_stage;
        opt.backend = backend;
        opt.keep_columns = keep_columns;
        return run_interruptible([&] { return run_to_directory(cfg, opt); });
      },
      "config"_a, "out"_a, "base_dir"_a = ".", "progress"_a = true, "overwrite"_a = false,
      "branch_dir"_a = "", "branch_stage"_a = "", "backend"_a = "cpu", "keep_columns"_a = false,
      "Runs a whole configuration (the sections of a run file: [sample] or [particles], [[stage]] "
      "as a list of dicts, [output], ...) into the directory `out`, like `crushdem-sand run`. "
      "SIGINT or "
      "SIGTERM saves a checkpoint and raises Interrupted (continue with resume(out)). A directory "
      "that holds files is refused unless overwrite (then the entries its manifest.json lists are "
      "removed, nothing else). "
      "branch_dir (and branch_stage, index or name): start from that run's state at the start of "
      "the stage, as `crushdem-sand run --from DIR:STAGE`. backend: \"cpu\", \"cuda\" (a GPU, in a "
      "build with CUDA) or \"emulated\" (the GPU's step run on the host), as `--backend`.");
  m.def(
      "resume",
      [](const std::string& out, bool progress, const std::string& backend, bool keep_columns) {
        check_backend_name(backend, "backend");
        RunOptions opt;
        opt.progress = progress;
        opt.backend = backend;
        opt.keep_columns = keep_columns;
        return run_interruptible([&] { return resume_directory(out, opt); });
      },
      "out"_a, "progress"_a = true, "backend"_a = "cpu", "keep_columns"_a = false,
      "Continues the interrupted run in `out` from its checkpoint.bin, like `crushdem-sand "
      "resume`; "
      "the files come out as those of an uninterrupted run on the same backend. Stops on SIGINT / "
      "SIGTERM as run() does. keep_columns: as `--keep-columns`, continue a run started by a "
      "crushdem that wrote other columns (the files keep theirs).");
  m.def("backends", &stepper_names,
        "The backends this build can run: \"cpu or emulated\", or \"cpu, emulated or cuda\".");
  m.def(
      "parameter_sets",
      [] {
        nb::list out;
        for (const ParameterSet& set : parameter_sets()) {
          out.append(nb::make_tuple(std::string(set.name), std::string(set.doc),
                                    toml::serialize(set.values)));
        }
        return out;
      },
      "The named parameter sets (the top-level key `parameters`), the default first, as "
      "(name, description, TOML of the [contact] and [crushing] values) tuples.");
  m.def(
      "resolved_run_config",
      [](nb::dict config, const std::string& base_dir) {
        return toml::serialize(
            to_toml(run_config_from_toml(to_table(config, ""), "<python>", base_dir)));
      },
      "config"_a, "base_dir"_a = ".",
      "Validates a whole run configuration dict; returns it resolved, as TOML.");
  m.def(
      "resolved_config",
      [](nb::dict config) { return toml::serialize(to_toml(config_from_dict(config))); },
      "config"_a,
      "Validates a configuration dict and returns it with every default filled in, as TOML.");
}
