#include "crushdem/run/driver.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>

#include "crushdem/io/vtk.hpp"
#include "crushdem/run/run_directory.hpp"
#include "crushdem/run/signals.hpp"

namespace crushdem {

std::string ordinal_stamp(std::size_t k) {
  char b[24];  // any size_t
  std::snprintf(b, sizeof b, "%06zu", k);
  return b;
}

std::string step_stamp(std::uint64_t step) {
  char b[24];  // any uint64
  std::snprintf(b, sizeof b, "%010llu", static_cast<unsigned long long>(step));
  return b;
}

// --- FixedLengthController ---------------------------------------------------------------------

void FixedLengthController::begin(Simulation& sim) {
  start_step_ = sim.step_count();
  start_time_ = sim.time();
}

bool FixedLengthController::update(Simulation& sim) {
  return steps_ > 0 ? sim.step_count() - start_step_ >= steps_
                    : sim.time() - start_time_ >= duration_;
}

std::uint64_t FixedLengthController::steps_to_check(Simulation& sim) {
  if (steps_ > 0) return std::max<std::uint64_t>(1, steps_ - (sim.step_count() - start_step_));
  const double left = std::ceil((start_time_ + duration_ - sim.time()) / sim.dt());
  return static_cast<std::uint64_t>(std::max(1.0, left));
}

void FixedLengthController::state(StateArchive& a) {
  a.section("run");
  a(start_step_, start_time_);
}

double FixedLengthController::fraction(const Simulation& sim) const {
  return steps_ > 0
             ? static_cast<double>(sim.step_count() - start_step_) / static_cast<double>(steps_)
             : (sim.time() - start_time_) / duration_;
}

// --- Driver ------------------------------------------------------------------------------------

Driver::Driver(Simulation& sim, Stepper& stepper, const RunConfig& cfg, const RunOptions& opt)
    : sim_(sim),
      stepper_(stepper),
      cfg_(cfg),
      opt_(opt),
      dir_(opt.out_dir),
      t0_(clock::now()),
      last_(t0_),
      last_checkpoint_(t0_) {}

CsvWriter& Driver::file(const std::string& name) {
  auto& f = files_[name];
  if (!f) {
    if (manifest) manifest->add(name);
    f = std::make_unique<CsvWriter>((dir_ / name).string());
  }
  return *f;
}

std::string Driver::resume_command() const {
  // Files that keep their columns need the option again: this build's rows still differ.
  return "crushdem-sand resume " + opt_.out_dir + (opt_.keep_columns ? " --keep-columns" : "");
}

void Driver::report_left_out_columns() {
  for (auto& [name, f] : files_) {
    const std::vector<std::string>& out = f->left_out();
    std::size_t& told = left_out_told_[name];
    if (out.size() == told) continue;
    std::string list;
    for (std::size_t k = told; k < out.size(); ++k) list += (k > told ? ", " : "") + out[k];
    say(name + " keeps the columns the run started it with (--keep-columns): this crushdem's " +
        list + " left out");
    told = out.size();
  }
}

void Driver::snapshot() {
  const PartScope timed(sim_.part_clock(), Part::Output);
  const Snapshot now{sim_.step_count(), sim_.time(), ageing_clock_};
  if (!snapshots_.empty() && snapshots_.back().step == now.step) return;  // written already
  const std::filesystem::path vtk = dir_ / "vtk";
  const std::string k = step_stamp(now.step);
  write_vtp_particles((vtk / ("particles_" + k + ".vtp")).string(), sim_.particles(),
                      sim_.resultant_force(0), sim_.resultant_force(1), sim_.resultant_force(2));
  write_vtp_contacts((vtk / ("contacts_" + k + ".vtp")).string(), sim_.particles(),
                     sim_.contacts());
  double b[6];
  for (int w = 0; w < kNumWalls; ++w) b[w] = sim_.walls().position(w);
  write_vtp_box((vtk / ("box_" + k + ".vtp")).string(), b);
  if (sim_.walls().size() > kNumWalls) {
    write_vtp_bodies((vtk / ("bodies_" + k + ".vtp")).string(), sim_.walls());
  }
  for (const std::string& kind : snapshot_kinds()) keep("vtk/" + kind + "_" + k + ".vtp");
  snapshots_.push_back(now);
  write_collections();
}

std::vector<std::string> Driver::snapshot_kinds() const {
  std::vector<std::string> kinds(std::begin(kSnapshotKinds), std::end(kSnapshotKinds));
  if (sim_.walls().size() > kNumWalls) kinds.emplace_back("bodies");
  return kinds;
}

void Driver::write_collections() const {
  for (const std::string& kind : snapshot_kinds()) {
    std::vector<PvdEntry> entries;
    for (const Snapshot& s : snapshots_) {
      entries.push_back({s.time + s.ageing, kind + "_" + step_stamp(s.step) + ".vtp"});
    }
    write_pvd((dir_ / "vtk" / (kind + ".pvd")).string(), entries);
  }
}

void Driver::attach_crusher(Crusher* crusher, bool resumed) {
  crusher_ = crusher;
  stepper_.attach_crusher(crusher,
                          [this](const std::vector<BreakageEvent>& events) { log(events); });
  if (!resumed) {
    file("breakage.csv")
        .start({"time_s", "step", "id", "diameter_m", "cause", "sigma_Pa", "sigma_lim_Pa",
                "fragments", "removed_fragments", "fragment_ids", "x_m", "y_m", "z_m"});
  }
}

void Driver::drive(Controller& c, CsvWriter& csv, const std::function<Measurement()>& row,
                   const std::string& label, const std::function<double()>& fraction, bool resumed,
                   std::uint64_t to_check, std::function<std::string()> note) {
  progress_note_ = std::move(note);
  if (!resumed) {
    c.begin(sim_);
    csv.write(row());
    to_check = c.steps_to_check(sim_);
  }
  drive_t0_ = clock::now();
  drive_step0_ = sim_.step_count();
  drive_f0_ = fraction ? fraction() : std::nan("");
  bool finished = false;
  const std::uint64_t interval = cfg_.output.interval, vtk = cfg_.output.vtk_interval;
  while (!finished) {
    const std::uint64_t s0 = sim_.step_count();
    std::uint64_t n = std::min(interval - s0 % interval, to_check);
    if (vtk > 0) n = std::min(n, vtk - s0 % vtk);
    // Chunks short enough that a stop request is answered within seconds (the chunking does
    // not change the result); the stepper checks crushing inside them.
    n = std::min(n, stepper_.max_chunk());
    const double before = stepper_.particle_steps();
    stepper_.advance(sim_, n);
    particle_steps_ += stepper_.particle_steps() - before;
    to_check -= n;
    // A device backend brings to the host what comes next reads: the clock, walls and the
    // controllers' scalars always; every grain for a check that reads grains, a row, a snapshot.
    stepper_.sync(sim_, Sync::Clock);
    sim_.walls().check_radii();  // moved on the device, where nothing throws
    if (to_check == 0 && c.reads_grains(sim_)) stepper_.sync(sim_, Sync::All);
    const std::uint64_t s = sim_.step_count();
    if (to_check == 0) {
      finished = c.update(sim_);
      if (!finished) to_check = c.steps_to_check(sim_);
    }
    const bool row_due = s % interval == 0 || finished;
    const bool snapshot_due = vtk > 0 && s % vtk == 0 && !finished;  // the final one follows
    if (row_due || snapshot_due) stepper_.sync(sim_, Sync::All);
    if (row_due) {
      const Measurement m = row();
      const PartScope timed(sim_.part_clock(), Part::Output);
      csv.write(m);
    }
    if (snapshot_due) snapshot();
    progress(label, fraction);
    if (!finished && checkpoint) {
      const int stop = stop_signal();
      const double since = std::chrono::duration<double>(clock::now() - last_checkpoint_).count();
      const double every = cfg_.output.checkpoint_seconds;
      if (checkpoint_requested_ || stop != 0 || (every > 0.0 && since >= every)) {
        stepper_.sync(sim_, Sync::All);
        checkpoint(c, to_check);
        checkpoint_requested_ = false;
      }
      if (stop != 0) {
        say("stopped by signal " + std::to_string(stop) + " at step " +
                std::to_string(sim_.step_count()) + "; continue with `" + resume_command() + "`",
            false);
        throw Interrupted(stop, opt_.out_dir, resume_command());
      }
    }
  }
}

std::vector<std::string> Driver::file_names() const {
  std::vector<std::string> names;
  for (const auto& [name, f] : files_) names.push_back(name);
  return names;
}

void Driver::keep(const std::string& path, const std::string* bytes) {
  const std::string full = (dir_ / path).string();
  KeptFile f{path, 0, 0};
  if (bytes) {
    f.size = static_cast<long long>(bytes->size());
    f.digest = fnv1a64(bytes->data(), bytes->size());
  } else {
    f.size = static_cast<long long>(std::filesystem::file_size(full));
    f.digest = file_digest(full);
  }
  const auto it =
      std::find_if(kept_.begin(), kept_.end(), [&](const KeptFile& k) { return k.path == path; });
  if (it != kept_.end()) {
    *it = f;
  } else {
    kept_.push_back(f);
  }
}

void Driver::check_kept_files() const {
  namespace fs = std::filesystem;
  for (const KeptFile& k : kept_) {
    const fs::path full = dir_ / k.path;
    std::error_code ec;
    const auto size = fs::file_size(full, ec);
    const char* what = nullptr;
    if (ec) {
      what = "is missing";
    } else if (static_cast<long long>(size) != k.size) {
      what = "has another size than the run wrote";
    } else if (file_digest(full.string()) != k.digest) {
      what = "was changed after the run wrote it";
    }
    if (what) {
      throw ConfigError("cannot go on from '" + dir_.string() + "': " + k.path + " " + what + " (" +
                        std::to_string(k.size) +
                        " bytes); restore it, or start the run again with --overwrite");
    }
  }
}

void Driver::state(StateArchive& a) {
  a.section("files");
  // Format 4 and older: a count of legacy .vtk snapshots only.
  legacy_snapshots_ = static_cast<std::size_t>(a.value<std::uint64_t>(legacy_snapshots_));
  if (a.loading()) snapshots_.clear();
  if (a.version() >= 5) {
    const auto count = a.count(snapshots_.size(), "snapshot count");
    if (a.loading()) snapshots_.resize(count);
    for (Snapshot& snap : snapshots_) {
      a(snap.step, snap.time);
      a.since(7, snap.ageing);
    }
  }
  a.since(7, ageing_clock_);
  // Each result file: its name, its length and its columns, from format 6 on its checksum.
  const auto n = a.count(files_.size(), "result file count");
  if (!a.loading()) {
    for (auto& [name, f] : files_) {
      std::string file_name = name;
      long long size = f->size();
      std::vector<std::string> columns = f->columns();
      std::uint64_t digest = f->digest();
      a(file_name, size, columns);
      a.since(6, digest);
    }
  } else {
    for (std::uint64_t k = 0; k < n; ++k) {
      std::string name;
      long long size = 0;
      std::vector<std::string> columns;
      std::uint64_t digest = 0;
      a(name, size, columns);
      a.since(6, digest);
      CsvWriter& f = file(name);
      f.keep_columns(opt_.keep_columns);
      f.resume(size, columns, a.version() >= 6 ? &digest : nullptr);
    }
  }
  if (a.version() < 6) return;
  const auto kept = a.count(kept_.size(), "kept file count");
  if (a.loading()) kept_.assign(kept, {});
  for (KeptFile& f : kept_) {
    a(f.path, f.size, f.digest);
    // A path inside the run directory: a damaged list must not point a branch's copy elsewhere.
    const std::filesystem::path p(f.path);
    if (a.loading() &&
        (f.path.empty() || p.is_absolute() || f.size < 0 ||
         std::any_of(p.begin(), p.end(), [](const auto& part) { return part == ".."; }))) {
      throw RuntimeFailure("checkpoint lists a kept file outside its run directory ('" +
                           f.path.substr(0, 80) + "'): it is damaged or from another program");
    }
  }
}

namespace {

/// "42 s", "12 min", "3.4 h" or "2.1 days".
std::string show_duration(double s) {
  char b[32];
  if (s < 120.0) {
    std::snprintf(b, sizeof b, "%.0f s", s);
  } else if (s < 7200.0) {
    std::snprintf(b, sizeof b, "%.0f min", s / 60.0);
  } else if (s < 172800.0) {
    std::snprintf(b, sizeof b, "%.1f h", s / 3600.0);
  } else {
    std::snprintf(b, sizeof b, "%.1f days", s / 86400.0);
  }
  return b;
}

}  // namespace

void Driver::progress(const std::string& label, const std::function<double()>& fraction) {
  const auto now = clock::now();
  const auto since = [&](clock::time_point t) {
    return std::chrono::duration<double>(now - t).count();
  };
  const double every = cfg_.output.progress_seconds;
  const bool to_terminal = opt_.progress && every > 0 && since(last_) >= every;
  const bool to_log = since(last_logged_) >= kLogSeconds;
  if (!to_terminal && !to_log) return;
  const Walls& w = sim_.walls();
  const double sz = w.axial_stress(), sr = w.lateral_stress();
  char b[256];
  std::snprintf(b, sizeof b,
                "%s  step %llu  t = %.4e s  sigma_z = %.4g MPa  sigma_r = %.4g MPa  q = %.4g MPa",
                label.c_str(), static_cast<unsigned long long>(sim_.step_count()), sim_.time(),
                1e-6 * sz, 1e-6 * sr, 1e-6 * (sz - sr));
  std::string line = b;
  if (progress_note_) {
    const std::string note = progress_note_();
    if (!note.empty()) line += "  " + note;
  }
  const double el = since(drive_t0_);
  if (el > 0.0) {
    std::snprintf(b, sizeof b, "  %.3g steps/s",
                  static_cast<double>(sim_.step_count() - drive_step0_) / el);
    line += b;
  }
  const double f = fraction ? fraction() : std::nan("");
  if (std::isfinite(f)) {
    // The ETA from the share done since this drive began (a resumed stage starts part done).
    const double done = f - (std::isfinite(drive_f0_) ? drive_f0_ : 0.0);
    std::snprintf(b, sizeof b, "  %.1f %% done", 100.0 * f);
    line += b;
    if (done > 0.0 && f < 1.0) line += ", ETA " + show_duration(el * (1 - f) / done);
  }
  if (to_terminal) {
    last_ = now;
    std::fprintf(stderr, "[crushdem] %s\n", line.c_str());
  }
  if (to_log) {
    last_logged_ = now;
    log_line(line);
  }
}

void Driver::say(const std::string& text, bool terminal) {
  if (terminal && opt_.progress) std::fprintf(stderr, "[crushdem] %s\n", text.c_str());
  log_line(text);
}

void Driver::log_line(const std::string& text) {
  if (!run_log_) {
    if (manifest) manifest->add("run.log");
    run_log_.reset(std::fopen((dir_ / "run.log").c_str(), "a"));
    if (!run_log_) return;  // the log is for people; a run never stops for it
  }
  write_log_line(run_log_.get(), text);
}

void write_log_line(std::FILE* log, const std::string& text) {
  const std::time_t t = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&t, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%SZ", &utc);
  std::fprintf(log, "%s  %s\n", stamp, text.c_str());
  std::fflush(log);
}

void Driver::log(const std::vector<BreakageEvent>& events) {
  CsvWriter& out = file("breakage.csv");
  // The grain's centre: in the files of runs begun by a version that wrote it.
  const std::vector<std::string>& cols = out.columns();
  const bool positions = std::find(cols.begin(), cols.end(), "x_m") != cols.end();
  for (const BreakageEvent& e : events) {
    std::string line = format_double(e.time) + "," + std::to_string(e.step) + "," +
                       std::to_string(e.id) + "," + format_double(e.diameter) + "," +
                       to_string(e.cause) + "," + format_double(e.sigma) + "," +
                       format_double(e.sigma_lim) + "," + std::to_string(e.fragments.size()) + "," +
                       std::to_string(e.removed_fragments) + ",";
    for (std::size_t k = 0; k < e.fragments.size(); ++k) {
      if (k) line += ' ';
      line += std::to_string(e.fragments[k]);
    }
    if (positions) {
      for (const double c : {e.position.x, e.position.y, e.position.z}) {
        line += ',';
        line += format_double(c);
      }
    }
    out.write_line(line);  // flushed: finished work is on disk
  }
}

}  // namespace crushdem
