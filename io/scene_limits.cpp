#include "io/scene_limits.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>

#include <vector>

#include <fmt/format.h>

#include "io/scene.hpp"

namespace matep::scene_detail {

namespace {

// One open bracket or brace (or the top level): the dots of the key being read in it.
struct Frame {
  char open = 0;        // 0 (top level), '[' or '{'
  int key_dots = 0;
  bool in_key = true;   // before the '=' of a key (dots are key separators, not decimals)
};

}  // namespace

void check_scene_text(std::string_view text, const std::string& file) {
  if (text.size() > kMaxSceneBytes)
    throw SceneError(fmt::format("{}: the scene is {} bytes, more than the limit of {} (give particles in a CSV "
                                 "file: particles.NAME.file)",
                                 file, text.size(), show_bytes(static_cast<double>(kMaxSceneBytes))));
  enum class S { Normal, Comment, Basic, Literal, MlBasic, MlLiteral };
  S s = S::Normal;
  std::vector<Frame> frames{Frame{}};
  int header = 0, depth = 0;       // levels of the current [table] header; levels open now
  bool line_start = true, in_header = false;
  std::size_t line = 1;
  const auto deeper = [&](int by) {
    depth += by;
    if (depth > kMaxSceneNesting)
      throw SceneError(fmt::format("{}: line {}: tables, arrays and dotted keys nest more than {} levels deep "
                                   "(a scene needs about five); the file is not read",
                                   file, line, kMaxSceneNesting));
  };
  const std::size_t n = text.size();
  for (std::size_t i = 0; i < n; ++i) {
    const char c = text[i];
    if (c == '\n') {
      ++line;
      if (s == S::Comment || s == S::Basic || s == S::Literal) s = S::Normal;
    }
    switch (s) {
      case S::Comment: continue;
      case S::Basic:
        if (c == '\\') line += ++i < n && text[i] == '\n';
        else if (c == '"') s = S::Normal;
        continue;
      case S::Literal:
        if (c == '\'') s = S::Normal;
        continue;
      case S::MlBasic:
        if (c == '\\') line += ++i < n && text[i] == '\n';
        else if (text.substr(i, 3) == "\"\"\"") { s = S::Normal; i += 2; }
        continue;
      case S::MlLiteral:
        if (text.substr(i, 3) == "'''") { s = S::Normal; i += 2; }
        continue;
      case S::Normal: break;
    }
    Frame& f = frames.back();
    const bool was_line_start = line_start;
    if (c != ' ' && c != '\t' && c != '\r') line_start = c == '\n';
    switch (c) {
      case '#': s = S::Comment; break;
      case '"':
        if (text.substr(i, 3) == "\"\"\"") { s = S::MlBasic; i += 2; }
        else s = S::Basic;
        break;
      case '\'':
        if (text.substr(i, 3) == "'''") { s = S::MlLiteral; i += 2; }
        else s = S::Literal;
        break;
      case '\n':
        if (frames.size() == 1) {  // a key/value line or a header ends
          depth -= f.key_dots;
          f = Frame{};
          in_header = false;
        }
        break;
      case '.':
        if (in_header) {
          ++header;
          deeper(1);
        } else if (f.in_key) {
          ++f.key_dots;
          deeper(1);
        }
        break;
      case '=':
        f.in_key = false;
        break;
      case ',':
        if (f.open == '{') {
          depth -= f.key_dots;
          f.key_dots = 0;
          f.in_key = true;
        }
        break;
      case '[':
        if (frames.size() == 1 && (was_line_start || in_header) && f.in_key) {  // [table] or [[array]]
          if (!in_header) {
            depth -= header;
            header = 0;
            in_header = true;
          }
          ++header;
          deeper(1);
          break;
        }
        frames.push_back(Frame{'[', 0, false});
        deeper(1);
        break;
      case '{':
        frames.push_back(Frame{'{', 0, true});
        deeper(1);
        break;
      case ']':
      case '}':
        if (frames.size() > 1) {
          depth -= frames.back().key_dots + 1;
          frames.pop_back();
        }
        break;
      default: break;
    }
  }
}

double physical_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), size = ::sysconf(_SC_PAGE_SIZE);
  double mem = pages > 0 && size > 0 ? static_cast<double>(pages) * static_cast<double>(size) : 0.0;
  rlimit as{};
  if (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY)  // ulimit -v
    mem = mem > 0.0 ? std::min(mem, static_cast<double>(as.rlim_cur)) : static_cast<double>(as.rlim_cur);
  return mem;
}

std::string show_bytes(double b) {
  if (b >= 1e12) return fmt::format("{:.3g} TB", b / 1e12);
  if (b >= 1e9) return fmt::format("{:.3g} GB", b / 1e9);
  if (b >= 1e6) return fmt::format("{:.3g} MB", b / 1e6);
  if (b >= 1e3) return fmt::format("{:.3g} kB", b / 1e3);
  return fmt::format("{:.0f} bytes", b);
}

}  // namespace matep::scene_detail
