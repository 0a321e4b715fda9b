// matep's Python module, native part (matep._native; the package is tools/python/matep): loading and
// checking scenes, running them, and reading checkpoints, through the same io layer as the CLI.
// A scene error raises ValueError, a file error OSError, both with the CLI's one-line message. A run
// releases the GIL and takes SIGINT / SIGTERM like `matep run` (io/interrupt.hpp) for its duration:
// Ctrl-C stops it at the next event or step, its outputs are written and published, and
// KeyboardInterrupt is raised once they are.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>
#include <vector>

#include "io/checkpoint.hpp"
#include "io/interrupt.hpp"
#include "io/run.hpp"
#include "io/scene.hpp"

namespace py = pybind11;

namespace {

matep::Scene load(const std::string& path, const std::string& text, const std::string& base_dir,
                  const std::vector<std::string>& overrides) {
  return text.empty() ? matep::load_scene(path, overrides) : matep::load_scene_string(text, path, base_dir, overrides);
}

py::dict check(const std::string& path, const std::string& text, const std::string& base_dir,
               const std::vector<std::string>& overrides, const std::string& resume) {
  const matep::Scene scene = load(path, text, base_dir, overrides);
  py::dict d;
  d["description"] = matep::describe_scene(scene) + (resume.empty() ? "" : matep::describe_checkpoint(scene, resume));
  d["warnings"] = scene.warnings;
  d["method"] = std::string(matep::method_name(scene.method));
  d["dimension"] = scene.dimension;
  d["end_time"] = scene.end_time;
  d["out_dir"] = scene.output.dir;
  return d;
}

py::dict run(const std::string& path, const std::string& text, const std::string& base_dir,
             const std::vector<std::string>& overrides, const std::string& out, const std::string& resume) {
  const matep::Scene scene = load(path, text, base_dir, overrides);
  const std::string dir = out.empty() ? scene.output.dir : out;
  matep::RunOutcome o;
  {
    py::gil_scoped_release free;
    matep::InterruptScope signals;
    o = matep::run_scene(scene, dir, {}, resume);
  }
  py::dict d;
  d["status"] = o.status;
  d["message"] = o.message;
  d["out_dir"] = o.out_dir;
  d["wall_seconds"] = o.wall_seconds;
  d["collisions"] = o.collisions;
  d["steps"] = o.steps;
  d["dt"] = o.dt;
  d["particle_steps_per_second"] = o.particle_steps_per_second;
  d["soft_particle_steps"] = o.soft_particle_steps;
  d["to_soft"] = o.to_soft;
  d["to_hard"] = o.to_hard;
  d["soft_at_end"] = o.soft_at_end;
  d["warnings"] = o.warnings;
  d["scene_warnings"] = scene.warnings;
  return d;
}

py::dict checkpoint(const std::string& path) {
  const matep::Checkpoint c = matep::read_checkpoint(path);
  py::dict d;
  d["version"] = matep::kCheckpointVersion;
  d["method"] = std::string(matep::method_name(static_cast<matep::Method>(c.method)));
  d["dimension"] = c.dimension;
  d["time"] = c.time;
  d["scene"] = c.scene;
  d["thermo_bytes"] = c.thermo.bytes;
  d["events"] = c.events.has_value();
  d["snapshots"] = c.snapshots ? c.snapshots->times.size() : 0;
  d["engine_bytes"] = c.engine.size();
  return d;
}

}  // namespace

PYBIND11_MODULE(_native, m) {
  m.doc() = "matep's native part: scenes, runs and checkpoints (see the matep package)";
  m.attr("version") = MATEP_VERSION;
  py::register_exception<matep::SceneError>(m, "SceneError", PyExc_ValueError);
  py::register_exception<matep::IoError>(m, "FileError", PyExc_OSError);
  py::register_exception<matep::StateError>(m, "StateError", PyExc_OSError);
  m.def("check", &check, py::arg("path"), py::arg("text") = "", py::arg("base_dir") = "",
        py::arg("overrides") = std::vector<std::string>{}, py::arg("resume") = "");
  m.def("run", &run, py::arg("path"), py::arg("text") = "", py::arg("base_dir") = "",
        py::arg("overrides") = std::vector<std::string>{}, py::arg("out") = "", py::arg("resume") = "");
  m.def("read_checkpoint", &checkpoint, py::arg("path"));
}
