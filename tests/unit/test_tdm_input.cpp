// Bad input for a time-driven ("tdm") run: every problem the soft-sphere engine cannot run with is
// refused before anything is written, with a message naming the scene key; a run that blows up
// stops with status "unstable" (exit 3) and keeps its outputs.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "io/run.hpp"
#include "io/scene.hpp"
#include "tests/support/cli.hpp"

namespace fs = std::filesystem;
using namespace matep;

namespace {

// Two unit-mass spheres (R = 0.5, density 1/(4/3 pi 0.5^3)) approaching head-on at v_rel, in a
// closed box without walls. `material` is the body of [material.glass].
std::string pair_scene(const std::string& material, double v_rel = 2.0, const std::string& extra = "") {
  return "[run]\ndimension = 3\nmethod = \"tdm\"\nend_time = 0.05\n" + extra +
         "[domain]\nlower = [-5.0, -5.0, -5.0]\nupper = [5.0, 5.0, 5.0]\n"
         "[material.glass]\ndensity = 1.909859317102744\n" +
         material +
         "[particles.a]\nmaterial = \"glass\"\nradius = 0.5\ncount = 1\n"
         "region = {lower = [-2.0, -0.5, -0.5], upper = [-0.6, 0.5, 0.5]}\nvelocity = [" +
         std::to_string(0.5 * v_rel) +
         ", 0.0, 0.0]\n"
         "[particles.b]\nmaterial = \"glass\"\nradius = 0.5\ncount = 1\n"
         "region = {lower = [0.6, -0.5, -0.5], upper = [2.0, 0.5, 0.5]}\nvelocity = [" +
         std::to_string(-0.5 * v_rel) + ", 0.0, 0.0]\n";
}

const std::string kLinear = "restitution = 1.0\ncontact = \"linear\"\nstiffness = 1.0e4\n";
const std::string kHertz = "restitution = 0.9\ncontact = \"hertz\"\nyoung = 1.0e7\npoisson = 0.3\n";

// The message of the SceneError (or invalid_argument) thrown while loading or running `text`;
// "" if it loaded and ran. Nothing may be written to the output folder when it throws.
std::string refusal(const std::string& text) {
  const fs::path out = test::fresh_dir("tdm_input") / "out";
  std::string msg;
  try {
    const Scene s = load_scene_string(text, "bad.toml", fs::temp_directory_path().string());
    run_scene(s, out.string());
  } catch (const SceneError& e) {
    msg = e.what();
  } catch (const std::invalid_argument& e) {
    msg = e.what();
  }
  EXPECT_TRUE(msg.empty() || !fs::exists(out)) << "output written before the refusal: " << msg;
  fs::remove_all(out.parent_path());
  return msg;
}

bool has(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

}  // namespace

TEST(TdmInput, GoodSceneRuns) {
  // The base scenes used below are valid: the refusals come from the one key each test changes.
  EXPECT_EQ(refusal(pair_scene(kLinear)), "");
  EXPECT_EQ(refusal(pair_scene(kHertz)), "");
}

TEST(TdmInput, HertzWithoutYoungNamesTheKey) {
  const std::string m = refusal(pair_scene("restitution = 0.9\ncontact = \"hertz\"\npoisson = 0.3\n"));
  EXPECT_TRUE(has(m, "material.glass.young")) << m;
  EXPECT_TRUE(has(m, "bad.toml")) << m;
}

TEST(TdmInput, NegativeFrictionNamesTheKey) {
  const std::string m = refusal(pair_scene(kHertz + "friction = -0.1\n"));
  EXPECT_TRUE(has(m, "material.glass.friction")) << m;
  EXPECT_TRUE(has(m, "-0.1")) << m;
}

TEST(TdmInput, LinearLawWithoutStiffnessNamesTheKey) {
  const std::string m = refusal(pair_scene("restitution = 0.9\ncontact = \"linear\"\n"));
  EXPECT_TRUE(has(m, "material.glass.stiffness")) << m;
}

TEST(TdmInput, VelocityDependentRestitutionWithHertzNamesTheKey) {
  const std::string m = refusal(pair_scene(
      "restitution = {model = \"power\", B = 0.9, b = 0.1}\ncontact = \"hertz\"\nyoung = 1.0e7\npoisson = 0.3\n"));
  EXPECT_TRUE(has(m, "material.glass.restitution")) << m;
}

TEST(TdmInput, RollingResistanceKeysAreCheckedAndNamed) {
  // Accepted: each model with a coefficient (epsd with its damping ratio).
  EXPECT_EQ(refusal(pair_scene(kHertz + "friction = 0.5\nrolling_friction = 0.1\nrolling = \"constant\"\n")), "");
  EXPECT_EQ(refusal(pair_scene(kHertz + "rolling_friction = 0.1\nrolling_damping = 0.5\n")), "");
  std::string m = refusal(pair_scene(kHertz + "rolling_friction = -0.1\n"));
  EXPECT_TRUE(has(m, "material.glass.rolling_friction") && has(m, "-0.1")) << m;
  m = refusal(pair_scene(kHertz + "rolling_friction = 0.1\nrolling = \"viscous\"\n"));
  EXPECT_TRUE(has(m, "material.glass.rolling") && has(m, "viscous")) << m;
  m = refusal(pair_scene(kHertz + "rolling_friction = 0.1\nrolling_damping = 1.5\n"));
  EXPECT_TRUE(has(m, "material.glass.rolling_damping") && has(m, "1.5")) << m;
  m = refusal(pair_scene(kHertz + "rolling = \"epsd\"\n"));
  EXPECT_TRUE(has(m, "material.glass.rolling_friction") && has(m, "missing")) << m;
  m = refusal(pair_scene(kHertz + "rolling_friction = 0.1\nrolling = \"constant\"\nrolling_damping = 0.3\n"));
  EXPECT_TRUE(has(m, "material.glass.rolling_damping") && has(m, "constant")) << m;
  // Two materials with different models.
  m = refusal(pair_scene(kHertz + "rolling_friction = 0.1\nrolling = \"constant\"\n") +
              "[material.steel]\ndensity = 2.0\nrestitution = 0.9\ncontact = \"hertz\"\nyoung = 1.0e7\n"
              "poisson = 0.3\nrolling_friction = 0.2\nrolling = \"epsd\"\n"
              "[particles.c]\nmaterial = \"steel\"\nradius = 0.5\ncount = 1\n"
              "region = {lower = [-1.0, 2.0, -1.0], upper = [1.0, 4.0, 1.0]}\n");
  EXPECT_TRUE(has(m, "rolling") && has(m, "constant") && has(m, "epsd")) << m;
}

TEST(TdmInput, TwoContactLawsAreRefused) {
  // Particles of two materials, one Hertz and one linear.
  std::string text = pair_scene(kHertz) +
                     "[material.steel]\ndensity = 2.0\nrestitution = 0.9\ncontact = \"linear\"\nstiffness = 1.0e4\n"
                     "[particles.c]\nmaterial = \"steel\"\nradius = 0.5\ncount = 1\n"
                     "region = {lower = [-1.0, 2.0, -1.0], upper = [1.0, 4.0, 1.0]}\n";
  const std::string m = refusal(text);
  EXPECT_TRUE(has(m, "material.steel.contact") || has(m, "material.glass.contact")) << m;
  EXPECT_TRUE(has(m, "linear") && has(m, "hertz")) << m;
}

TEST(TdmInput, EventLogIsRefused) {
  const std::string m = refusal(pair_scene(kLinear) + "[output]\nevents = true\n");
  EXPECT_TRUE(has(m, "output.events")) << m;
}

TEST(TdmInput, TimeStepAboveTheStabilityLimit) {
  // Linear law, e = 1, no friction: the Verlet limit of the pair spring is 2/omega0 =
  // 2 sqrt(m*/k) = 2 sqrt(0.5/1e4) = 0.0141421 (m x'' = -k x, leapfrog stable for h omega0 < 2).
  const double limit = 2.0 * std::sqrt(0.5 / 1.0e4);
  const std::string m = refusal(pair_scene(kLinear, 2.0, "dt = 0.02\n"));
  ASSERT_TRUE(has(m, "run.dt")) << m;
  ASSERT_TRUE(has(m, "stability limit ")) << m;
  const double printed = std::stod(m.substr(m.find("stability limit ") + 16));
  EXPECT_NEAR(printed, limit, 1e-5 * limit) << m;
  // Just below the limit it runs.
  EXPECT_EQ(refusal(pair_scene(kLinear, 2.0, "dt = 0.014\n")), "");
}

TEST(TdmInput, CliRefusesAnUnstableTimeStepWithExitStatus2) {
  const fs::path d = test::fresh_dir("tdm_cli_dt");
  {
    std::ofstream f(d / "scene.toml");
    f << pair_scene(kLinear, 2.0, "dt = 0.02\n");
  }
  const test::CliResult r = test::run_cli("run " + (d / "scene.toml").string() + " --out " + (d / "o").string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_TRUE(has(r.out, "scene.toml")) << r.out;
  EXPECT_TRUE(has(r.out, "stability limit 0.0141421")) << r.out;
  EXPECT_FALSE(fs::exists(d / "o"));  // nothing written
  // `check` refuses it the same way, and --set can repair it.
  EXPECT_EQ(test::run_cli("check " + (d / "scene.toml").string()).code, 2);
  const test::CliResult ok =
      test::run_cli("run " + (d / "scene.toml").string() + " --set run.dt=0.001 --out " + (d / "o").string());
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_TRUE(fs::exists(d / "o" / "summary.json"));
  fs::remove_all(d);
}

TEST(TdmInput, BlowUpStopsWithStatusUnstable) {
  // The step is legal, but the spring is far too soft for the impact: an elastic linear contact
  // at v_rel = 100 would overlap by v_rel sqrt(m*/k) = 0.71 of the contact distance, past the
  // engine's 0.5 limit (TdmSettings::unstable_overlap). The run stops early (exit 3) and keeps
  // its outputs, with the status in summary.json.
  const fs::path d = test::fresh_dir("tdm_cli_unstable");
  {
    std::ofstream f(d / "scene.toml");
    f << pair_scene(kLinear, 100.0);
  }
  const test::CliResult r = test::run_cli("run " + (d / "scene.toml").string() + " --out " + (d / "o").string());
  EXPECT_EQ(r.code, 3) << r.out;
  EXPECT_TRUE(has(r.out, "unstable")) << r.out;
  EXPECT_TRUE(has(test::slurp(d / "o" / "summary.json"), "\"status\": \"unstable\""));
  EXPECT_TRUE(fs::exists(d / "o" / "final_state.csv"));
  EXPECT_TRUE(fs::exists(d / "o" / "thermo.csv"));
  fs::remove_all(d);
}

// A soft-sphere state (e.g. a settled bed written by an earlier run) overlaps: particle files may
// overlap by up to kSoftFileOverlap of the contact distance with run.method = "tdm", not beyond,
// and not at all (beyond round-off) for hard spheres. Two touching unit spheres overlapping by
// delta repel: at rest and without damping, they separate with equal and opposite velocities.
TEST(TdmInput, ParticleFilesMayOverlapSlightlyForSoftSpheres) {
  const fs::path dir = fs::temp_directory_path() / "matep_tdm_file_overlap";
  fs::create_directories(dir);
  auto scene = [&](const std::string& method, double overlap) {
    // The layout of final_state.csv (its id column is accepted and ignored), so a run restarts
    // from an earlier run's output.
    std::ofstream(dir / "pair.csv") << "id,x,y,z,vx,vy,vz,wx,wy,wz,radius\n"
                                    << "0," << -0.5 + 0.5 * overlap << ",0,0,0,0,0,0,0,0,0.5\n"
                                    << "1," << 0.5 - 0.5 * overlap << ",0,0,0,0,0,0,0,0,0.5\n";
    return "[run]\ndimension = 3\nmethod = \"" + method +
           "\"\nend_time = 0.05\n[domain]\nlower = [-5.0, -5.0, -5.0]\nupper = [5.0, 5.0, 5.0]\n"
           "[material.glass]\ndensity = 1.909859317102744\n" +
           kLinear + "[particles.p]\nmaterial = \"glass\"\nfile = \"pair.csv\"\n";
  };
  // 2 % of the contact distance: accepted by tdm, refused by edm.
  const Scene soft = load_scene_string(scene("tdm", 0.02), "soft.toml", dir.string());
  EXPECT_EQ(std::get<System<3>>(soft.system).size(), 2u);
  EXPECT_THROW(load_scene_string(scene("edm", 0.02), "hard.toml", dir.string()), SceneError);
  // 8 % is beyond what a soft state may hold.
  try {
    load_scene_string(scene("tdm", 0.08), "deep.toml", dir.string());
    ADD_FAILURE() << "an 8 % overlap was accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("overlaps"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("particles.p"), std::string::npos) << e.what();
  }
  // The accepted state runs: the spring (k = 1e4, delta = 0.02) pushes the pair apart; elastic,
  // so the stored energy k delta^2/2 = 2 becomes kinetic: 2 (m v^2/2) = 2 with m = 1, v = sqrt 2.
  const fs::path out = dir / "out";
  fs::remove_all(out);
  const RunOutcome r = run_scene(soft, out.string());
  ASSERT_EQ(r.status, "ok") << r.message;
  std::ifstream f(out / "final_state.csv");
  std::string header, a, b;
  std::getline(f, header);
  std::getline(f, a);
  std::getline(f, b);
  auto vx = [](const std::string& line) {
    std::size_t p = 0;
    for (int k = 0; k < 4; ++k) p = line.find(',', p) + 1;  // id,x,y,z, -> vx
    return std::stod(line.substr(p));
  };
  EXPECT_NEAR(vx(a), -std::sqrt(2.0), 0.01);
  EXPECT_NEAR(vx(b), std::sqrt(2.0), 0.01);
  fs::remove_all(dir);
}

TEST(TdmInput, AStepThatGivesMoreStepsThanACounterHoldsIsRefused) {
  const std::string m = refusal(pair_scene(kLinear, 2.0, "dt = 1e-300\n"));
  EXPECT_TRUE(has(m, "run.dt: 1e-300 gives 5e+298 steps to run.end_time = 0.05; at most 1e15")) << m;
}
