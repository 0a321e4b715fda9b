// Test helper for refused scenes: loading `text` (as file `name`) must throw one SceneError whose
// single line starts with "name:" and contains every part (the key, the value, the reason).
#pragma once

#include <gtest/gtest.h>

#include <initializer_list>
#include <string>

#include "io/scene.hpp"

namespace matep::test {

inline void expect_scene_error(const std::string& text, const std::string& name, const std::string& dir,
                               std::initializer_list<std::string> parts) {
  try {
    load_scene_string(text, name, dir, {});
    ADD_FAILURE() << "no SceneError; expected one containing " << *parts.begin();
  } catch (const SceneError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(name + ":", 0), 0u) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    for (const auto& p : parts) EXPECT_NE(msg.find(p), std::string::npos) << "'" << p << "' not in: " << msg;
  }
}

// Ten spheres in a unit box with `run_lines` added to the [run] table: a scene for tests that read
// one run key.
inline std::string small_gas_scene(const std::string& run_lines) {
  return "[run]\ndimension = 3\nend_time = 1.0\n" + run_lines +
         "[domain]\nlower = [0.0, 0.0, 0.0]\nupper = [1.0, 1.0, 1.0]\n"
         "[material.m]\ndensity = 1.0\nrestitution = 1.0\n"
         "[particles.p]\nmaterial = \"m\"\nradius = 0.05\ncount = 10\narrangement = \"random\"\n";
}

}  // namespace matep::test
