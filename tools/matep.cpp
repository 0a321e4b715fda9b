// The matep command line: run | check | log (and --help, --version).
#include <fmt/format.h>
#include <unistd.h>

#include <boost/program_options.hpp>
#include <algorithm>
#include <chrono>
#include <deque>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "io/interrupt.hpp"
#include "io/log_tools.hpp"
#include "io/output.hpp"
#include "io/run.hpp"
#include "io/scene.hpp"

namespace po = boost::program_options;

namespace {

constexpr int kExitViolation = 1;  // matep log verify: a record breaks a conservation law
constexpr int kExitUsage = 2;     // bad command line or bad input
constexpr int kExitStopped = 3;   // the run stopped early (collapse, escape, event cap)
constexpr int kExitWrite = 4;     // an output could not be written (full disk, file-size limit, ...)
// A run stopped by a signal exits with 128 + the signal (130 SIGINT, 143 SIGTERM), as shells expect.

const char* kUsage =
    "matep: hybrid event-driven / time-driven granular dynamics\n"
    "\n"
    "usage:\n"
    "  matep run SCENE.toml [--set KEY=VALUE]... [--out DIR] [--resume CHECKPOINT] [--quiet]\n"
    "  matep check SCENE.toml [--set KEY=VALUE]... [--resume CHECKPOINT]\n"
    "  matep log stats LOG [--bins N]\n"
    "  matep log filter LOG --out FILE [--from T] [--to T] [--ids I,J,...] [--kind K]... [--csv]\n"
    "  matep log verify LOG [--scene SCENE.toml [--set KEY=VALUE]...] [--tol TOL]\n"
    "  matep log export LOG [--out FILE.csv]\n"
    "  matep --help | --version\n"
    "\n"
    "  run     runs the scene and writes thermo.csv, final_state.csv, summary.json\n"
    "          (and events.bin with output.events = true) into output.dir or --out; the\n"
    "          folder's previous outputs are replaced only once the new set is complete.\n"
    "          Ctrl-C (SIGINT) or SIGTERM stops at the next event or step and writes every\n"
    "          output (status \"interrupted\", exit 130 / 143); a second one stops at once\n"
    "  check   validates the scene and prints what will be modelled; with --resume, also\n"
    "          that the checkpoint is whole and was written for this scene\n"
    "  log     reads an event log (events.bin) record by record, checking every block's\n"
    "          checksum and every record (exit status 2 at the first bad one):\n"
    "          stats   counts by kind, time span, collision rate in N time bins (default 10),\n"
    "                  busiest particle, largest impact speed, min / max / mean e\n"
    "          filter  writes the records with from <= time <= to, i or j (pair) in --ids and\n"
    "                  a kind among --kind (pair, wall, soft, hard, outflow, inflow; repeatable) as\n"
    "                  an event log, or as CSV with --csv or a FILE ending in .csv\n"
    "          verify  replays every collision: momentum, normal velocity -e, tangential\n"
    "                  velocity and spins unchanged, energy loss (1-e^2) m* u_n^2/2, relative\n"
    "                  to --tol (default 1e-9); with --scene also e against the materials'\n"
    "                  restitution models. Exit status 1 at the first violation\n"
    "          export  every record as CSV (stdout without --out)\n"
    "          filter and export --out write a temporary file and rename it onto FILE only\n"
    "          on success; an existing FILE that is not a regular file, or is LOG, is refused\n"
    "\n"
    "  --set KEY=VALUE  overrides any scene key by its dotted path, e.g.\n"
    "                   --set run.end_time=2 --set material.glass.restitution=0.8\n"
    "  --out DIR        output folder (overrides output.dir)\n"
    "  --resume FILE    continue the run saved in FILE (a checkpoint.bin, beside the outputs\n"
    "                   it continues), bit for bit as if it had not stopped\n"
    "  --quiet          no progress line even on a terminal\n";

int fail(const std::string& msg, int code = kExitUsage) {
  std::fflush(stdout);
  fmt::print(stderr, "matep: error: {}\n", msg);
  return code;
}

struct Args {
  std::string scene;
  std::vector<std::string> sets;
  std::string out;
  std::string resume;
  bool quiet = false;
};

Args parse(const std::vector<std::string>& rest, bool allow_out) {
  po::options_description opts("options");
  opts.add_options()("set", po::value<std::vector<std::string>>()->composing(), "override")(
      "scene", po::value<std::string>(), "scene file")("resume", po::value<std::string>(), "checkpoint");
  if (allow_out) opts.add_options()("out", po::value<std::string>(), "output dir")("quiet", "no progress");
  po::positional_options_description pos;
  pos.add("scene", 1);
  po::variables_map vm;
  po::store(po::command_line_parser(rest).options(opts).positional(pos).run(), vm);
  po::notify(vm);
  Args a;
  if (!vm.count("scene")) throw po::error("missing SCENE.toml");
  a.scene = vm["scene"].as<std::string>();
  if (vm.count("set")) a.sets = vm["set"].as<std::vector<std::string>>();
  if (allow_out && vm.count("out")) a.out = vm["out"].as<std::string>();
  if (allow_out && vm.count("quiet")) a.quiet = true;
  if (vm.count("resume")) a.resume = vm["resume"].as<std::string>();
  return a;
}

int cmd_check(const std::vector<std::string>& rest) {
  const Args a = parse(rest, false);
  const matep::Scene scene = matep::load_scene(a.scene, a.sets);
  for (const auto& w : scene.warnings) fmt::print(stderr, "warning: {}\n", w);
  fmt::print("{}", matep::describe_scene(scene));
  if (!a.resume.empty()) fmt::print("{}", matep::describe_checkpoint(scene, a.resume));
  fmt::print("scene is valid{}\n", a.resume.empty() ? "" : " and the checkpoint continues it");
  return 0;
}

int cmd_run(const std::vector<std::string>& rest) {
  // From here a signal asks the run to stop and publish its outputs (io/interrupt.hpp).
  matep::install_interrupt_handlers();
  const Args a = parse(rest, true);
  const matep::Scene scene = matep::load_scene(a.scene, a.sets);
  for (const auto& w : scene.warnings) fmt::print(stderr, "warning: {}\n", w);
  const std::string dir = a.out.empty() ? scene.output.dir : a.out;
  matep::ProgressFn progress;
  const bool tty = !a.quiet && isatty(STDERR_FILENO);
  auto start = std::chrono::steady_clock::now();
  auto last = start;
  // The ETA divides what is left by the rate over the last ~10 s (a pour slows down as it lands; the
  // rate since the start would promise too little time).
  std::deque<std::pair<double, double>> recent;  // (seconds since start, fraction done)
  if (tty) {
    progress = [&](double t, double frac, std::uint64_t events) {
      const auto now = std::chrono::steady_clock::now();
      if (std::chrono::duration<double>(now - last).count() < 0.5) return;
      last = now;
      const double el = std::chrono::duration<double>(now - start).count();
      recent.emplace_back(el, frac);
      while (recent.size() > 2 && recent[1].first <= el - 10.0) recent.pop_front();
      const auto [el0, frac0] = recent.size() > 1 ? recent.front() : std::pair<double, double>{0.0, 0.0};
      const double eta = frac > frac0 ? (el - el0) * (1.0 - frac) / (frac - frac0) : 0.0;
      fmt::print(stderr, "\r  t = {:.6g} ({:5.1f}%)  {:.3g} {}/s  ETA {:.0f} s   ", t, 100.0 * frac,
                 events / std::max(el, 1e-9), scene.method == matep::Method::Tdm ? "steps" : "events", eta);
    };
  }
  const matep::RunOutcome out = matep::run_scene(scene, dir, progress, a.resume);
  if (tty) fmt::print(stderr, "\r{:78}\r", "");
  for (const auto& w : out.warnings) fmt::print(stderr, "warning: {}: {}\n", scene.path, w);
  if (scene.method == matep::Method::Edm)
    fmt::print("matep: {} collisions in {:.3f} s wall; output written to {}/\n", out.collisions,
               out.wall_seconds, out.out_dir);
  else if (scene.method == matep::Method::Hybrid)
    fmt::print("matep: {} hard collisions, {} substeps of {:.6g} ({} soft particle-steps), {} switches to soft and "
               "{} to hard, {} soft at the end{}, in {:.3f} s wall; output written to {}/\n",
               out.collisions, out.steps, out.dt, out.soft_particle_steps, out.to_soft, out.to_hard, out.soft_at_end,
               out.slept > 0 ? fmt::format(" ({} put to sleep)", out.slept) : std::string(), out.wall_seconds,
               out.out_dir);
  else
    fmt::print("matep: {} steps of {:.6g} ({} contacts begun) in {:.3f} s wall, {:.3g} particle-steps/s; "
               "output written to {}/\n",
               out.steps, out.dt, out.collisions, out.wall_seconds, out.particle_steps_per_second, out.out_dir);
  if (out.status == "interrupted") {
    const int sig = matep::stop_signal();
    return fail(fmt::format("interrupted ({}): {}", scene.path, out.message), 128 + (sig > 0 ? sig : SIGINT));
  }
  if (out.status != "ok") return fail(fmt::format("{} ({}): {}", out.status, scene.path, out.message), kExitStopped);
  return 0;
}

// ---- matep log -------------------------------------------------------------------------------

po::variables_map parse_log(const std::vector<std::string>& rest, po::options_description& opts) {
  opts.add_options()("log", po::value<std::string>(), "event log");
  po::positional_options_description pos;
  pos.add("log", 1);
  po::variables_map vm;
  po::store(po::command_line_parser(rest).options(opts).positional(pos).run(), vm);
  po::notify(vm);
  if (!vm.count("log")) throw po::error("missing LOG (an events.bin file)");
  return vm;
}

int cmd_log(const std::vector<std::string>& args) {
  if (args.empty()) return fail("matep log needs a subcommand: stats, filter, verify or export (try matep --help)");
  const std::string sub = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (sub == "stats") {
    po::options_description opts("options");
    opts.add_options()("bins", po::value<long long>()->default_value(10), "time bins");
    const po::variables_map vm = parse_log(rest, opts);
    const long long bins = vm["bins"].as<long long>();
    if (bins < 1 || bins > 1000000) return fail(fmt::format("--bins must be between 1 and 1000000 (got {})", bins));
    const matep::LogStats s = matep::compute_log_stats(vm["log"].as<std::string>(), static_cast<std::size_t>(bins));
    fmt::print("{}", matep::format_log_stats(s));
    return 0;
  }
  if (sub == "filter") {
    po::options_description opts("options");
    opts.add_options()("out", po::value<std::string>(), "output file")("from", po::value<double>(), "from time")(
        "to", po::value<double>(), "to time")("ids", po::value<std::vector<std::string>>()->composing(), "ids")(
        "kind", po::value<std::vector<std::string>>()->composing(), "kinds")("csv", "write CSV");
    const po::variables_map vm = parse_log(rest, opts);
    if (!vm.count("out")) throw po::error("matep log filter needs --out FILE");
    matep::LogFilter f;
    if (vm.count("from")) f.from = vm["from"].as<double>();
    if (vm.count("to")) f.to = vm["to"].as<double>();
    if (vm.count("ids"))
      for (const auto& list : vm["ids"].as<std::vector<std::string>>())
        for (std::uint32_t id : matep::parse_id_list(list)) f.ids.push_back(id);
    std::sort(f.ids.begin(), f.ids.end());
    f.ids.erase(std::unique(f.ids.begin(), f.ids.end()), f.ids.end());
    if (vm.count("kind"))
      for (const auto& k : vm["kind"].as<std::vector<std::string>>()) f.kinds.push_back(matep::parse_event_kind(k));
    const std::string out = vm["out"].as<std::string>();
    const bool csv = vm.count("csv") || (out.size() >= 4 && out.compare(out.size() - 4, 4, ".csv") == 0);
    const matep::FilterResult r = matep::filter_log(vm["log"].as<std::string>(), out, f, csv);
    fmt::print("matep: {} of {} records written to {}{}\n", r.written, r.read, out, csv ? " (CSV)" : "");
    return 0;
  }
  if (sub == "verify") {
    po::options_description opts("options");
    opts.add_options()("scene", po::value<std::string>(), "scene file")(
        "set", po::value<std::vector<std::string>>()->composing(), "override")(
        "tol", po::value<double>()->default_value(1e-9), "relative tolerance");
    const po::variables_map vm = parse_log(rest, opts);
    const double tol = vm["tol"].as<double>();
    if (!(tol >= 0.0)) return fail(fmt::format("--tol must be >= 0 (got {})", tol));
    if (vm.count("set") && !vm.count("scene")) return fail("--set needs --scene SCENE.toml");
    std::optional<matep::Scene> scene;
    if (vm.count("scene"))
      scene = matep::load_scene(vm["scene"].as<std::string>(),
                                vm.count("set") ? vm["set"].as<std::vector<std::string>>() : std::vector<std::string>{});
    const std::string log = vm["log"].as<std::string>();
    const matep::VerifyResult r = matep::verify_log(log, scene ? &*scene : nullptr, tol);
    if (!r.ok) {
      std::fflush(stdout);
      fmt::print(stderr, "matep: verify failed: {}\n", r.message);
      return kExitViolation;
    }
    std::string extra;
    if (r.model_checked) extra += fmt::format("; e matches the restitution models of {}", scene->path);
    if (r.rough)
      extra += fmt::format("; {} rough: angular momentum about the contact point, tangential restitution{}", r.rough,
                           r.model_checked ? " (the scene's rule), radii from the scene" : " (radii implied by the records)");
    if (r.skipped) extra += fmt::format("; {} non-collision records skipped", r.skipped);
    fmt::print("verified {} records: momentum, restitution, energy OK ({} pair, {} wall collisions, tol {:g}{})\n",
               r.pair + r.wall, r.pair, r.wall, tol, extra);
    return 0;
  }
  if (sub == "export") {
    po::options_description opts("options");
    opts.add_options()("out", po::value<std::string>(), "output CSV");
    const po::variables_map vm = parse_log(rest, opts);
    const std::string out = vm.count("out") ? vm["out"].as<std::string>() : std::string();
    const std::uint64_t n = matep::export_csv(vm["log"].as<std::string>(), out);
    if (!out.empty()) fmt::print("matep: {} records written to {}\n", n, out);
    return 0;
  }
  return fail(fmt::format("unknown log subcommand '{}' (stats, filter, verify or export; try matep --help)", sub));
}

}  // namespace

// OpenMP's threads spin at every barrier by default (libgomp reads OMP_WAIT_POLICY once, when the
// library loads). On a machine shared with other work a spinning thread whose partner has been
// descheduled costs a scheduler quantum per step (measured: 10x slower than one thread), so the
// CLI re-executes itself once with OMP_WAIT_POLICY=passive unless the user chose a policy.
void prefer_passive_openmp(char** argv) {
  if (std::getenv("OMP_WAIT_POLICY") != nullptr) return;
  if (setenv("OMP_WAIT_POLICY", "passive", 1) != 0) return;
  execv("/proc/self/exe", argv);  // returns only on failure: then run as we are
}

int main(int argc, char** argv) {
  prefer_passive_openmp(argv);
  // A file-size limit (ulimit -f) then fails the write with EFBIG, reported with the file's name
  // and exit status 4, instead of killing the process mid-row.
  std::signal(SIGXFSZ, SIG_IGN);
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty()) {
    fmt::print(stderr, "{}", kUsage);
    return kExitUsage;
  }
  const std::string cmd = args[0];
  if (cmd == "--help" || cmd == "-h" || cmd == "help") {
    fmt::print("{}", kUsage);
    return 0;
  }
  if (cmd == "--version") {
    fmt::print("matep {}\n", MATEP_VERSION);
    return 0;
  }
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  try {
    for (const auto& r : rest)
      if (r == "--help" || r == "-h") {
        fmt::print("{}", kUsage);
        return 0;
      }
    if (cmd == "run") return cmd_run(rest);
    if (cmd == "check") return cmd_check(rest);
    if (cmd == "log") return cmd_log(rest);
    return fail(fmt::format("unknown command '{}' (try matep --help)", cmd));
  } catch (const po::error& e) {
    return fail(fmt::format("{} (try matep --help)", e.what()));
  } catch (const matep::SceneError& e) {
    return fail(e.what());
  } catch (const matep::WriteError& e) {
    return fail(e.what(), kExitWrite);
  } catch (const matep::IoError& e) {
    return fail(e.what());
  } catch (const std::invalid_argument& e) {
    return fail(e.what());
  } catch (const std::exception& e) {
    return fail(e.what());
  }
}
