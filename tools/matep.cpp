// The matep command line: run | check (and --help, --version).
#include <fmt/format.h>
#include <unistd.h>

#include <boost/program_options.hpp>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "io/output.hpp"
#include "io/run.hpp"
#include "io/scene.hpp"

namespace po = boost::program_options;

namespace {

constexpr int kExitUsage = 2;     // bad command line or bad input
constexpr int kExitStopped = 3;   // the run stopped early (collapse, escape, event cap)

const char* kUsage =
    "matep: hybrid event-driven / time-driven granular dynamics\n"
    "\n"
    "usage:\n"
    "  matep run SCENE.toml [--set KEY=VALUE]... [--out DIR] [--quiet]\n"
    "  matep check SCENE.toml [--set KEY=VALUE]...\n"
    "  matep --help | --version\n"
    "\n"
    "  run     runs the scene and writes thermo.csv, final_state.csv, summary.json\n"
    "          (and events.bin with output.events = true) into output.dir or --out\n"
    "  check   validates the scene and prints what will be modelled\n"
    "\n"
    "  --set KEY=VALUE  overrides any scene key by its dotted path, e.g.\n"
    "                   --set run.end_time=2 --set material.glass.restitution=0.8\n"
    "  --out DIR        output folder (overrides output.dir)\n"
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
  bool quiet = false;
};

Args parse(const std::vector<std::string>& rest, bool allow_out) {
  po::options_description opts("options");
  opts.add_options()("set", po::value<std::vector<std::string>>()->composing(), "override")(
      "scene", po::value<std::string>(), "scene file");
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
  return a;
}

int cmd_check(const std::vector<std::string>& rest) {
  const Args a = parse(rest, false);
  const matep::Scene scene = matep::load_scene(a.scene, a.sets);
  fmt::print("{}", matep::describe_scene(scene));
  fmt::print("scene is valid\n");
  return 0;
}

int cmd_run(const std::vector<std::string>& rest) {
  const Args a = parse(rest, true);
  const matep::Scene scene = matep::load_scene(a.scene, a.sets);
  const std::string dir = a.out.empty() ? scene.output.dir : a.out;
  matep::ProgressFn progress;
  const bool tty = !a.quiet && isatty(STDERR_FILENO);
  auto start = std::chrono::steady_clock::now();
  auto last = start;
  if (tty) {
    progress = [&](double t, double frac, std::uint64_t events) {
      const auto now = std::chrono::steady_clock::now();
      if (std::chrono::duration<double>(now - last).count() < 0.5) return;
      last = now;
      const double el = std::chrono::duration<double>(now - start).count();
      const double eta = frac > 0.0 ? el * (1.0 - frac) / frac : 0.0;
      fmt::print(stderr, "\r  t = {:.6g} ({:5.1f}%)  {:.3g} events/s  ETA {:.0f} s   ", t, 100.0 * frac,
                 events / std::max(el, 1e-9), eta);
    };
  }
  const matep::RunOutcome out = matep::run_scene(scene, dir, progress);
  if (tty) fmt::print(stderr, "\r{:78}\r", "");
  fmt::print("matep: {} collisions in {:.3f} s wall; output written to {}/\n", out.collisions,
             out.wall_seconds, out.out_dir);
  if (out.status != "ok") return fail(fmt::format("{} ({}): {}", out.status, scene.path, out.message), kExitStopped);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
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
    return fail(fmt::format("unknown command '{}' (try matep --help)", cmd));
  } catch (const po::error& e) {
    return fail(fmt::format("{} (try matep --help)", e.what()));
  } catch (const matep::SceneError& e) {
    return fail(e.what());
  } catch (const matep::IoError& e) {
    return fail(e.what());
  } catch (const std::invalid_argument& e) {
    return fail(e.what());
  } catch (const std::exception& e) {
    return fail(e.what());
  }
}
