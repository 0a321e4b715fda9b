#include "io/run.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

#include "engine/edm/neighbours.hpp"
#include "engine/grid.hpp"
#include "engine/hybrid.hpp"
#include "engine/rough_rules.hpp"
#include "engine/tdm.hpp"
#include "io/checkpoint.hpp"
#include "io/interrupt.hpp"
#include "io/output.hpp"
#include "io/run_folder.hpp"
#include "io/scene_limits.hpp"

namespace matep {

namespace fs = std::filesystem;

namespace {

EdmSettings edm_settings(const Scene& s) {
  EdmSettings e;
  e.start_time = s.start_time;
  e.end_time = s.end_time;
  e.tc = s.tc;
  e.thermo_interval = s.output.thermo_interval;
  e.snapshot_interval = s.output.snapshot_interval;
  if (s.max_events > 0) e.max_events = s.max_events;
  e.collapse_decades = s.collapse_decades;
  e.lists = s.neighbours == "lists";
  e.lists_auto = s.neighbours == "auto";
  e.shell = s.shell;
  e.resort = s.resort;
  e.stop = &stop_flag();
  return e;
}

TdmSettings tdm_settings(const Scene& s) {
  TdmSettings t;
  t.start_time = s.start_time;
  t.end_time = s.end_time;
  t.dt = s.dt.value_or(0.0);
  t.threads = s.threads.value_or(0);
  t.thermo_interval = s.output.thermo_interval;
  t.snapshot_interval = s.output.snapshot_interval;
  t.stop = &stop_flag();
  return t;
}

}  // namespace

HybridSettings hybrid_settings(const Scene& s) {
  HybridSettings h;
  h.dt = s.dt.value_or(0.0);
  const HybridSpec& y = s.hybrid;
  if (y.stability) h.stability = *y.stability;
  if (y.repeats) h.repeats = *y.repeats;
  if (y.speed_fall) h.speed_fall = *y.speed_fall;
  if (y.lookahead) h.lookahead = *y.lookahead;
  if (y.hysteresis) h.hysteresis = *y.hysteresis;
  if (y.skin) h.skin = *y.skin;
  if (y.cost_ratio) h.cost_ratio = *y.cost_ratio;
  h.cost_measured = y.cost_measured;
  if (y.rest_speed) h.rest_speed = *y.rest_speed;
  if (y.rest_time) h.rest_time = *y.rest_time;
  h.coast = y.coast;
  h.threads = s.threads.value_or(0);
  return h;
}

namespace {

// The soft-sphere checks of the engine, reported as scene errors (file: key: message). A hybrid
// run names its substep run.dt like a TDM run.
template <int D>
SoftPlan soft_preflight(const Scene& scene, const System<D>& sys) {
  try {
    if (scene.method == Method::Hybrid) return hybrid_preflight<D>(sys, hybrid_settings(scene));
    return tdm_preflight<D>(sys, tdm_settings(scene));
  } catch (const std::invalid_argument& e) {
    throw SceneError(fmt::format("{}: {}", scene.path, e.what()));
  }
}

// The rough-sphere rules of an event-driven run (engine/rough_rules.hpp), reported as scene errors.
template <int D>
RoughRules rough_preflight(const Scene& scene, const System<D>& sys) {
  try {
    return make_rough_rules(sys.materials);
  } catch (const std::invalid_argument& e) {
    throw SceneError(fmt::format("{}: {}", scene.path, e.what()));
  }
}

const char* tangential_text(TangentialLaw l) {
  switch (l) {
    case TangentialLaw::Walton: return "Walton";
    case TangentialLaw::Constant: return "constant beta";
    case TangentialLaw::FemFit: return "FEM fit (seed eq. 3.30)";
  }
  return "?";
}

class ProgressObserver final : public Observer<2>, public Observer<3> {
 public:
  ProgressObserver(const ProgressFn& fn, double end_time) : fn_(fn), end_(end_time) {}
  void on_progress(double t, std::uint64_t events) override {
    fn_(t, end_ > 0.0 ? t / end_ : 1.0, events);
  }

 private:
  ProgressFn fn_;
  double end_;
};

// Contact value of the pair distribution: Carnahan-Starling (3D), Henderson (2D)
// (docs/references.md §2.2).
double contact_g(int d, double phi) {
  if (d == 3) return (1.0 - phi / 2.0) / std::pow(1.0 - phi, 3);
  return (1.0 - 7.0 * phi / 16.0) / std::pow(1.0 - phi, 2);
}

// Enskog's collision rate of the initial state (docs/references.md §2.1), when it applies (a moving
// gas below close packing); the packing fraction and temperature with it.
template <int D>
struct Enskog {
  double phi = 0.0, T = 0.0;
  std::optional<double> rate;  // collisions per unit time
};
template <int D>
Enskog<D> enskog(const System<D>& sys) {
  double vol = 0.0, mv2 = 0.0, msum = 0.0, dsum = 0.0;
  for (std::size_t i = 0; i < sys.size(); ++i) {
    vol += ball_volume<D>(sys.radius[i]);
    const double m = sys.mass(i);
    mv2 += m * sys.v[i].squaredNorm();
    msum += m;
    dsum += 2.0 * sys.radius[i];
  }
  const double n = static_cast<double>(sys.size());
  Enskog<D> e;
  e.phi = vol / sys.volume();
  if (n > 1 && mv2 > 0.0 && e.phi < 0.7) {
    const double m = msum / n, sigma = dsum / n;
    e.T = mv2 / (D * n);
    const double omega = (D == 3 ? 24.0 : 8.0) * e.phi * contact_g(D, e.phi) / (std::sqrt(std::numbers::pi) * sigma) *
                         std::sqrt(e.T / m);
    e.rate = 0.5 * n * omega;
  }
  return e;
}

// The outputs a run plans to write, estimated generously (README.md, "Limits"): thermo.csv rows of
// 24 bytes a column, snapshots of the bytes a grain of their formats (io/snapshots.hpp), events.bin records for max_events or for
// Enskog's rate. A plan above output.max_bytes is refused, naming the largest part's key.
template <int D>
void check_output_plan(const Scene& scene, const System<D>& sys) {
  const OutputSpec& o = scene.output;
  const double grains = static_cast<double>(sys.size() + inlet_slots(sys.inlets, scene.end_time));
  const double columns = 9.0 + (sys.inlets.empty() && sys.outlets.empty() ? 0.0 : 4.0) +
                         (o.wall_loads ? 6.0 * static_cast<double>(sys.walls.size()) : 0.0);
  struct Part {
    const char* key;
    double value, bytes;
    std::string what;
  };
  std::vector<Part> parts;
  const double rows = o.thermo_interval > 0.0 ? scene.end_time / o.thermo_interval + 2.0 : 2.0;
  parts.push_back({"thermo_interval", o.thermo_interval, rows * columns * 24.0,
                   fmt::format("thermo.csv: {:.3g} rows", rows)});
  if (o.snapshot_interval > 0.0) {
    const double snaps = scene.end_time / o.snapshot_interval + 2.0;
    parts.push_back({"snapshot_interval", o.snapshot_interval, snaps * grains * snapshot_bytes_per_grain(o.formats),
                     fmt::format("{:.3g} snapshots of {:.0f} grains", snaps, grains)});
  }
  if (o.events && scene.method != Method::Tdm) {
    std::optional<double> n;
    if (scene.max_events > 0) n = static_cast<double>(scene.max_events);
    if (const auto rate = enskog<D>(sys).rate) n = std::min(n.value_or(*rate * scene.end_time), *rate * scene.end_time);
    if (n)
      parts.push_back({"events", 1.0, *n * static_cast<double>(kEventRecordSize),
                       fmt::format("events.bin: about {:.3g} collisions{}", *n,
                                   scene.max_events > 0 ? " (run.max_events or Enskog's rate)" : " (Enskog's rate)")});
  }
  // checkpoint.bin, at the end (and replaced at each interval): about 250 (EDM), 400 (TDM) and
  // 1200 (hybrid) bytes a grain slot were measured on the shipped cases; planned at twice that.
  const double per_grain = scene.method == Method::Edm ? 500.0 : scene.method == Method::Tdm ? 800.0 : 2400.0;
  parts.push_back({"checkpoint_interval", o.checkpoint_interval, grains * per_grain,
                   fmt::format("checkpoint.bin: {:.0f} grain slots", grains)});
  double total = 0.0;
  const Part* big = &parts.front();
  for (const Part& p : parts) {
    total += p.bytes;
    if (p.bytes > big->bytes) big = &p;
  }
  if (!(total <= o.max_bytes))
    throw SceneError(fmt::format("{}: output.{}: the outputs would take about {} ({}), more than output.max_bytes = "
                                 "{}; raise the interval, shorten run.end_time or raise output.max_bytes (got {})",
                                 scene.path, big->key, scene_detail::show_bytes(total), big->what,
                                 scene_detail::show_bytes(o.max_bytes),
                                 std::string(big->key) == "events" ? std::string("true") : fmt::format("{}", big->value)));
}

// Checks what the scene reader cannot know about the engine: the periodic-axis rule of the cell
// grid (engine/grid.hpp), here with no list skin (the soft preflights check it again with theirs),
// and the size of the output plan. Called by run before anything is written, and by check.
template <int D>
void check_runnable(const Scene& scene, const System<D>& sys) {
  double dmax = 0.0;
  for (double r : sys.radius) dmax = std::max(dmax, 2.0 * r);
  try {
    check_periodic_axes<D>(sys.lower, sys.upper, sys.periodic, dmax, 0.0);
  } catch (const std::invalid_argument& e) {
    throw SceneError(fmt::format("{}: {}", scene.path, e.what()));
  }
  check_output_plan<D>(scene, sys);
}

// The scene keys a resumed run may change: where its outputs go, and how long it runs.
const std::vector<std::string> kResumeMayDiffer = {"output.dir", "run.end_time"};

// Refuses a checkpoint written for another method, dimension or scene, naming what differs.
void check_resumable(const Scene& scene, int D, const Checkpoint& c, const std::string& path) {
  if (c.method != static_cast<std::uint32_t>(scene.method) || c.dimension != static_cast<std::uint32_t>(D))
    throw IoError(fmt::format("{}: written by a \"{}\" run in {}D; {} is a \"{}\" scene in {}D", path,
                              method_name(static_cast<Method>(c.method)), c.dimension, scene.path,
                              method_name(scene.method), D));
  if (const auto d = scene_difference(c.scene, scene.canonical, kResumeMayDiffer))
    throw IoError(fmt::format("{}: written for another scene than {}: {}", path, scene.path, *d));
}

// Copies the first mark.bytes bytes of `from` (an output of the run that wrote the checkpoint) to
// `to`, checking them against the mark's checksum.
void copy_prefix(const fs::path& from, const fs::path& to, const FileMark& mark, const std::string& ckpt) {
  std::ifstream in(from, std::ios::binary);
  if (!in)
    throw IoError(fmt::format("{}: cannot continue {}: it is missing (resume needs the outputs of the run that "
                              "wrote {}, in the folder that holds it)",
                              from.string(), from.filename().string(), ckpt));
  CheckedFile out(to.string(), "wb", 1 << 20);
  std::vector<char> buf(1 << 20);
  std::uint64_t left = mark.bytes;
  std::uint32_t crc = 0;
  while (left > 0) {
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(left, buf.size()));
    in.read(buf.data(), static_cast<std::streamsize>(n));
    if (static_cast<std::size_t>(in.gcount()) != n) break;
    crc = crc32c(buf.data(), n, crc);
    out.write(buf.data(), n);
    left -= n;
  }
  if (left > 0 || crc != mark.crc)
    throw IoError(fmt::format("{}: does not begin with the {} bytes that {} continues ({}); resume needs the outputs "
                              "of the run that wrote it",
                              from.string(), mark.bytes, ckpt, left > 0 ? "it is shorter" : "their checksum differs"));
  out.close();
}

template <int D>
RunOutcome run_system(const Scene& scene, const System<D>& sys, const std::string& dir,
                      const ProgressFn& progress, const std::string& resume) {
  check_runnable(scene, sys);
  // A checkpoint to continue: read and checked against the scene before anything is written.
  std::optional<Checkpoint> from;
  fs::path from_dir;
  if (!resume.empty()) {
    from = read_checkpoint(resume);
    check_resumable(scene, D, *from, resume);
    std::error_code ec;
    from_dir = fs::weakly_canonical(fs::absolute(fs::path(resume), ec).parent_path(), ec);
  }
  const bool soft = scene.method == Method::Tdm;
  const bool hybrid = scene.method == Method::Hybrid;
  // The checks run once; their plans go to the engine.
  std::optional<SoftPlan> plan;
  std::optional<RoughRules> rough;
  if (soft || hybrid) plan = soft_preflight(scene, sys);
  if (!soft) rough = rough_preflight(scene, sys);
  if (soft) {
    if (scene.output.events)
      throw SceneError(fmt::format("{}: output.events: true, but the event log records instantaneous collisions "
                                   "and a \"tdm\" run has none; set output.events = false",
                                   scene.path));
  }
  // The outputs go to a staging folder and replace the folder's previous set only when complete.
  RunFolder folder(dir);
  const std::string out = folder.staging();
  if (from) {
    // A checkpoint in a killed run's staging folder: the run folder has just kept it as DIR.killed.
    std::error_code ec;
    if (!folder.killed().empty() && from_dir == fs::weakly_canonical(fs::absolute(folder.staging(), ec), ec))
      from_dir = folder.killed();
    copy_prefix(from_dir / "thermo.csv", fs::path(out) / "thermo.csv", from->thermo, resume);
    if (from->outflow) copy_prefix(from_dir / "outflow.csv", fs::path(out) / "outflow.csv", *from->outflow, resume);
    if (from->events) copy_prefix(from_dir / "events.bin", fs::path(out) / "events.bin", from->events->file, resume);
    if (from->snapshots) {
      fs::create_directories(fs::path(out) / "snapshots", ec);
      for (const auto& files : from->snapshots->files)
        for (const std::string& rel : files) {
          if (fs::exists(fs::path(out) / rel, ec)) continue;  // a wall at rest: one file for all
          if (rel.find("..") != std::string::npos || !fs::copy_file(from_dir / rel, fs::path(out) / rel, ec) || ec)
            throw IoError(fmt::format("{}: cannot continue the snapshot series: {} is missing or unreadable",
                                      resume, (from_dir / rel).string()));
        }
    }
  }
  const EdmSettings settings = edm_settings(scene);
  std::vector<std::string> wall_names;
  if (scene.output.wall_loads)
    for (const auto& w : sys.walls) wall_names.push_back(w.name);
  const bool flows = !sys.outlets.empty() || !sys.inlets.empty();
  // Every output names each grain's group and material; an inlet's grains (the ids after the
  // initial ones, inlet by inlet) form the group "inlet.NAME".
  StateLabels labels;
  labels.group_names = scene.group_names;
  labels.group = scene.group;
  labels.material = sys.material;
  for (const Inlet<D>& in : sys.inlets) {
    const std::uint64_t n = in.slots(scene.end_time);
    labels.group.insert(labels.group.end(), n, static_cast<int>(labels.group_names.size()));
    labels.material.insert(labels.material.end(), n, in.material);
    labels.group_names.push_back("inlet." + in.name);
  }
  for (const Material& m : sys.materials) labels.materials.push_back(m.name);
  ThermoCsvWriter thermo(out + "/thermo.csv", wall_names, D, flows, from ? &from->thermo : nullptr);
  std::unique_ptr<EventLogWriter<D>> log;
  std::vector<Observer<D>*> observers{static_cast<Observer<D>*>(&thermo)};
  std::unique_ptr<OutflowCsvWriter<D>> outflow;
  if (!sys.outlets.empty()) {
    std::vector<std::string> names;
    for (const auto& o : sys.outlets) names.push_back(o.name);
    outflow = std::make_unique<OutflowCsvWriter<D>>(out + "/outflow.csv", names,
                                                    from && from->outflow ? &*from->outflow : nullptr);
    observers.push_back(outflow.get());
  }
  if (scene.output.events) {
    if (from && from->events) {
      log = std::make_unique<EventLogWriter<D>>(out + "/events.bin", *from->events);
    } else {  // version 4: each id's group and material
      EventLogIdentity id;
      id.groups = labels.group_names;
      id.materials = labels.materials;
      id.group.assign(labels.group.begin(), labels.group.end());
      id.material.assign(labels.material.begin(), labels.material.end());
      log = std::make_unique<EventLogWriter<D>>(out + "/events.bin", sys.size() + inlet_slots(sys.inlets, scene.end_time),
                                                !sys.fixed.empty(), &id);
    }
    observers.push_back(log.get());
  }
  std::unique_ptr<SnapshotWriter<D>> snaps;
  if (scene.output.snapshot_interval > 0.0) {
    // A pure EDM run of smooth grains without initial spins has none to show.
    bool spins = scene.method != Method::Edm || (rough && rough->any);
    for (const Spin<D>& w : sys.w) spins = spins || !w.isZero();
    snaps = std::make_unique<SnapshotWriter<D>>(out, scene.output.formats, labels, sys.walls, sys.lower, sys.upper,
                                                sys.periodic, spins);
    if (from && from->snapshots) snaps->resume(*from->snapshots);
    observers.push_back(snaps.get());
  }
  // Checkpoints: the engine's state with what every output held at that moment, written whole
  // into the staging folder (published with the set; a killed run's is kept as DIR.killed).
  CheckpointHooks hooks;
  hooks.interval = scene.output.checkpoint_interval;
  hooks.save = [&](double t, const std::function<void(StateWriter&)>& state) {
    Checkpoint c;
    c.method = static_cast<std::uint32_t>(scene.method);
    c.dimension = D;
    c.scene = scene.canonical;
    c.time = t;
    c.thermo = thermo.mark();
    if (outflow) c.outflow = outflow->mark();
    if (log) c.events = log->mark();
    if (snaps) c.snapshots = snaps->mark();
    c.engine_source = &state;
    // Synced to the disk only in a run that keeps checkpoints every interval: those are there to
    // survive a crash of the machine mid-run, each replacing the one before. Without an interval
    // the checkpoint is written once, at the end or at a signal, just before the run's folder is
    // published, and stands with the other outputs, which are not synced either (the sync took
    // 20 ms of a 0.07 s hybrid run of 10 000 disks, cooling_clusters.toml cut short; its
    // checksum tells a torn one from a whole one when it is read).
    write_checkpoint(out + "/" + kCheckpointName, c, scene.output.checkpoint_interval > 0.0);
  };
  if (from) hooks.resume = &from->engine;
  std::unique_ptr<ProgressObserver> prog;
  if (progress) {
    prog = std::make_unique<ProgressObserver>(progress, scene.end_time);
    observers.push_back(static_cast<Observer<D>*>(prog.get()));
  }
  const QueueKind q = scene.queue == "heap" ? QueueKind::Heap : QueueKind::Calendar;
  EdmSettings edm = settings;
  edm.checkpoint = &hooks;
  TdmSettings tdm = tdm_settings(scene);
  tdm.checkpoint = &hooks;
  RunResult<D> res;
  try {
    res = soft     ? run_tdm<D>(sys, tdm, observers, &*plan)
          : hybrid ? run_hybrid<D>(sys, edm, hybrid_settings(scene), observers, &*plan)
                   : run_edm<D>(sys, edm, q, observers, &*rough);
  } catch (const StateError& e) {
    throw IoError(fmt::format("{}: cannot continue it with {}: {}", resume, scene.path, e.what()));
  }
  if (log) log->close();
  if (outflow) outflow->close();
  thermo.close();
  write_final_state<D>(out + "/final_state.csv", res, labels);
  SummaryInfo info;
  info.scene = scene.path;
  info.method = method_name(scene.method);
  info.queue = scene.queue;
  info.dimension = D;
  info.particles = sys.size();
  info.seed = scene.seed;
  info.end_time = scene.end_time;
  info.flows = flows;
  info.groups = labels.group_names;
  info.materials = labels.materials;
  if (res.status == "interrupted")
    res.message = fmt::format("stopped by {} at t = {:.17g}", stop_signal_name(), res.time);
  write_summary<D>(out + "/summary.json", info, res);
  folder.publish();
  RunOutcome outcome;
  outcome.status = res.status;
  outcome.message = res.message;
  outcome.out_dir = dir;
  outcome.wall_seconds = res.wall_seconds;
  outcome.collisions = res.counts.collisions();
  outcome.steps = res.soft.steps;
  outcome.dt = res.soft.dt;
  outcome.particle_steps_per_second = res.soft.particle_steps_per_second;
  outcome.soft_particle_steps = res.hybrid.soft_particle_steps;
  outcome.to_soft = res.hybrid.to_soft;
  outcome.to_hard = res.hybrid.to_hard;
  outcome.soft_at_end = res.hybrid.soft_at_end;
  outcome.slept = res.hybrid.slept;
  for (const InletReport& r : res.inlets)
    if (r.missed > 0)
      outcome.warnings.push_back(fmt::format(
          "inlet.{}: {} of the {} grains due found no free place in the region and were not inserted (the rate "
          "could not be met: {} inserted)",
          r.name, r.missed, r.due, r.inserted));
  return outcome;
}

std::string restitution_text(const Restitution& r) {
  switch (r.model) {
    case Restitution::Model::Constant: return fmt::format("constant e = {}", r.e);
    case Restitution::Model::Power: return fmt::format("power law e = {} u^-{} (capped at 1)", r.B, r.b);
    case Restitution::Model::Schwager:
      return fmt::format("Schwager-Poschel e = 1 - (1 - {})(u/{})^{}", r.e0, r.u0, r.n);
    case Restitution::Model::Exponential: return fmt::format("exponential e = {} exp(-{} u)", r.C, r.a);
  }
  return "?";
}

template <int D>
std::string describe(const Scene& scene, const System<D>& sys) {
  check_runnable(scene, sys);
  std::string s;
  s += fmt::format("scene        {}\n", scene.path);
  s += fmt::format("dimension    {} ({})\n", D, D == 3 ? "spheres" : "disks");
  s += fmt::format("particles    {}\n", sys.size());
  std::vector<std::size_t> per_group(scene.group_names.size(), 0);
  for (int g : scene.group) ++per_group[g];
  for (std::size_t g = 0; g < per_group.size(); ++g)
    s += fmt::format("  [particles.{}] {}\n", scene.group_names[g], per_group[g]);
  if (const std::size_t nf = sys.fixed_count(); nf > 0)
    s += fmt::format("fixed        {} of {} grains are fixed (immovable spheres)\n", nf, sys.size());
  s += fmt::format("method       {}", method_name(scene.method));
  if (scene.method == Method::Edm) {
    s += fmt::format(" (event-driven hard {}, {} queue)\n", D == 3 ? "spheres" : "disks", scene.queue);
    const RoughRules rough = rough_preflight(scene, sys);
    s += rough.any ? "contact      rough instantaneous collisions where a material pair has friction or a tangential "
                     "rule (spins modelled), smooth elsewhere\n"
                   : "contact      smooth instantaneous collisions (no friction, no rotation modelled)\n";
    for (std::size_t a = 0; a < sys.materials.size(); ++a) {
      const auto& m = sys.materials[a];
      s += fmt::format("  [material.{}] density {}, restitution {}\n", m.name, m.density,
                       restitution_text(m.restitution));
      if (rough.is_rough(static_cast<int>(a), static_cast<int>(a))) {
        const TangentialModel& t = rough.rule(static_cast<int>(a), static_cast<int>(a));
        s += fmt::format("    rough: tangential {}", tangential_text(t.law));
        if (t.law != TangentialLaw::Constant) s += fmt::format(", friction {}", t.friction);
        if (t.law != TangentialLaw::FemFit) s += fmt::format(", {} {}", t.law == TangentialLaw::Constant ? "beta" : "beta0", t.beta0);
        s += "\n";
      }
    }
  } else {  // "tdm" or "hybrid" (the scene reader accepts no other method)
    if (scene.method == Method::Tdm)
      s += fmt::format(" (time-driven soft {}, velocity Verlet)\n", D == 3 ? "spheres" : "disks");
    else
      s += fmt::format(" (hard {0} in EDM, dense clusters as soft {0} in TDM substeps)\n", D == 3 ? "spheres" : "disks");
    const SoftPlan plan = soft_preflight(scene, sys);
    for (std::size_t a = 0; a < sys.materials.size(); ++a) {
      const auto& m = sys.materials[a];
      s += fmt::format("  [material.{}] density {}, restitution {}\n", m.name, m.density,
                       restitution_text(m.restitution));
      const SoftLaw& l = plan.laws.empty() ? SoftLaw{} : plan.laws[a * plan.materials + a];
      if (!plan.laws.empty() && l.zeta >= 0.0 && (l.normal != NormalLaw::Hertz || l.restitution > 0.0)) {
        const char* name = l.normal == NormalLaw::Linear ? "linear spring-dashpot"
                           : l.normal == NormalLaw::Hertz ? "Hertz-Mindlin, damping exact for e"
                                                          : "viscoelastic (Brilliantov et al.)";
        s += fmt::format("    contact {}, friction {}, damping ratio {:.4g}\n", name, l.friction, l.zeta);
      }
    }
    const TdmSettings ts = tdm_settings(scene);
    const double dt = ts.dt > 0.0 ? ts.dt : plan.default_dt;
    s += fmt::format("time step    {:.6g}{} (stability limit {:.6g}, set by {})\n", dt,
                     ts.dt > 0.0 ? " (run.dt)" : " (default)", plan.max_stable_dt, plan.limiting);
    s += fmt::format("             contact time {:.6g} at impact speed {:.4g}, Rayleigh time {:.6g}; about {:.3g} steps\n",
                     plan.contact_time, plan.impact_speed, plan.rayleigh_time,
                     dt > 0.0 ? std::ceil(scene.end_time / dt) : 0.0);
    if (scene.method == Method::Hybrid) {
      const HybridSettings h = hybrid_settings(scene);
      s += fmt::format("hybrid rule  soft when {} collisions in a row each follow the previous one within {} t_c and their\n"
                       "             impact speed falls by {} over them (e > 0.3), when a strongly inelastic one would send a grain\n"
                       "             back to its earlier partner within {} t_c, or when a\n"
                       "             grain and its neighbours collide more often than once per {} substeps (cost); capture just before the touch (at least\n"
                       "             {} of the smallest diameter); release after {:.6g} s without contact{}\n",
                       h.repeats, h.stability, h.speed_fall, h.lookahead,
                       h.cost_measured ? fmt::format("N (N: the measured cost ratio, from {})", h.cost_ratio)
                                       : fmt::format("{}", h.cost_ratio),
                       least_capture(sys, h),
                       h.hysteresis > 0.0 ? h.hysteresis : 10.0 * h.stability * plan.contact_time,
                       h.rest_speed > 0.0 ? fmt::format("; quiet grains (speed < {} m/s) sleep", h.rest_speed)
                                          : std::string());
    }
  }
  std::string per;
  for (int k = 0; k < D; ++k) per += sys.periodic[k] ? "yes " : "no ";
  s += fmt::format("domain       lower {}  upper {}  periodic {}\n", fmt::join(sys.lower, ", "),
                   fmt::join(sys.upper, ", "), per);
  for (const auto& w : sys.walls) {
    s += fmt::format("  [wall.{}] {}\n", w.name, w.geometry().describe());
  }
  for (const auto& o : sys.outlets)
    s += fmt::format("  [outlet.{}] {}{}\n", o.name, o.face >= 0 ? "open face: " : "", o.region.describe());
  for (const auto& in : sys.inlets)
    s += fmt::format("  [inlet.{}] {:.6g} grains/s of material.{} (radius {}{}) from t = {}{}{}: {} grains due by end_time\n",
                     in.name, in.rate, sys.materials[static_cast<std::size_t>(in.material)].name, in.rmin,
                     in.rmax > in.rmin ? fmt::format(" .. {}", in.rmax) : std::string(), in.start,
                     std::isfinite(in.stop) ? fmt::format(" to {}", in.stop) : std::string(),
                     in.count < std::numeric_limits<std::uint64_t>::max() ? fmt::format(", at most {}", in.count)
                                                                          : std::string(),
                     in.slots(scene.end_time));
  if (sys.gravity.squaredNorm() > 0.0)
    s += fmt::format("gravity      ({})\n", fmt::join(sys.gravity, ", "));
  if (scene.tc > 0.0) s += fmt::format("TC model     collisions within {} of a previous one are elastic\n", scene.tc);
  // Predicted collision rate from Enskog theory (docs/references.md §2.1).
  const Enskog<D> en = enskog<D>(sys);
  s += fmt::format("packing      {:.4f}\n", en.phi);
  if (scene.method != Method::Tdm) {
    // How the hard grains find their pair candidates and whether their storage is re-sorted, by the
    // rules the engine applies (engine/edm/neighbours.hpp): the moving grains' packing decides "auto".
    const double phi = sys.moving_packing();
    const bool automatic = scene.neighbours == "auto";
    const bool lists =
        edm::lists_chosen(scene.neighbours == "lists", automatic, phi, sys.gravity.squaredNorm() > 0.0, sys.size());
    s += fmt::format("pair search  {}{}\n",
                     lists ? fmt::format("neighbour lists, shells of {} largest diameters", scene.shell)
                           : std::string("cells"),
                     automatic ? fmt::format(" (auto: lists where the moving grains fill at least {} of the domain, "
                                             "without gravity)",
                                             edm::kListsFromPacking)
                               : std::string());
    const bool hybrid = scene.method == Method::Hybrid;
    const double every =
        edm::resort_interval(hybrid ? edm::hybrid_resort(scene.resort) : scene.resort, sys.size(), phi);
    s += fmt::format("storage      {}\n",
                     every > 0.0 ? fmt::format("re-sorted in space every {} particle events per particle{}", every,
                                               hybrid ? " while no grain is soft" : "")
                                 : std::string("in its first order, not re-sorted (run.resort)"));
  }
  if (en.rate)
    s += fmt::format("predicted    {:.4g} collisions per unit time (Enskog, elastic, initial T = {:.4g}); "
                     "about {:.3g} collisions to end_time = {}\n",
                     *en.rate, en.T, *en.rate * scene.end_time, scene.end_time);
  s += fmt::format("outputs      {}/ thermo.csv{} final_state.csv summary.json{}\n", scene.output.dir,
                   scene.output.thermo_interval > 0.0
                       ? fmt::format(" (every {})", scene.output.thermo_interval)
                       : std::string(" (t = 0 and end)"),
                   std::string(sys.outlets.empty() ? "" : " outflow.csv") + (scene.output.events ? " events.bin" : "")) +
       (scene.output.snapshot_interval > 0.0
            ? fmt::format("             snapshots.pvd + snapshots/*.vtp every {}\n", scene.output.snapshot_interval)
            : std::string());
  return s;
}

}  // namespace

RunOutcome run_scene(const Scene& scene, const std::string& out_dir, const ProgressFn& progress,
                     const std::string& resume) {
  return std::visit([&](const auto& sys) { return run_system(scene, sys, out_dir, progress, resume); },
                    scene.system);
}

std::string describe_checkpoint(const Scene& scene, const std::string& path) {
  const Checkpoint c = read_checkpoint(path);
  check_resumable(scene, scene.dimension, c, path);
  std::string s = fmt::format("checkpoint   {}: a \"{}\" run at t = {:.17g}; continues thermo.csv ({} bytes)", path,
                              method_name(static_cast<Method>(c.method)), c.time, c.thermo.bytes);
  if (c.events) s += fmt::format(", events.bin ({} records)", c.events->total);
  if (c.outflow) s += fmt::format(", outflow.csv ({} bytes)", c.outflow->bytes);
  if (c.snapshots) s += fmt::format(", {} snapshots", c.snapshots->times.size());
  return s + "\n";
}

std::string describe_scene(const Scene& scene) {
  return std::visit([&](const auto& sys) { return describe(scene, sys); }, scene.system);
}

}  // namespace matep
