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

}  // namespace matep::test
