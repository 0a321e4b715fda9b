// Helpers for reading scene TOML: one-line error messages "<file>: <dotted.key>: <problem>
// (got <value>)", typed and range-checked getters that reject unknown keys, and --set
// overrides. Internal to io/.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <toml++/toml.h>

namespace matep::scene_detail {

// A TOML value rendered for a message: strings quoted, arrays and tables inline, long
// renderings shortened.
std::string show(const toml::node& n);
// A quoted string for a message.
std::string quote(std::string_view s);
// "a string", "an integer", ... for "expected X but found Y" messages.
std::string_view type_name(const toml::node& n);

// Throws SceneError "<file>: <key>: <problem>" and, when `got` is given, " (got <got>)".
[[noreturn]] void fail(std::string_view file, std::string_view key, std::string_view problem);
[[noreturn]] void fail(std::string_view file, std::string_view key, std::string_view problem,
                       const toml::node& got);
[[noreturn]] void fail_got(std::string_view file, std::string_view key, std::string_view problem,
                           std::string_view got);

// A closed/open interval for range checks, described in messages as "must be > 0",
// "must be in [0, 1]", ...
struct Range {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool hi_open = false;
  bool contains(double v) const;
  std::string describe() const;
};
inline constexpr Range kAny{};
inline constexpr Range kPositive{0.0, std::numeric_limits<double>::infinity(), true, false};
inline constexpr Range kNonNegative{0.0, std::numeric_limits<double>::infinity(), false, false};
inline constexpr Range kUnit{0.0, 1.0, false, false};

// Parses TOML text; a syntax error becomes a SceneError with file, line and column.
toml::table parse_toml(std::string_view text, const std::string& file);

// Applies --set overrides ("dotted.key=VALUE") to the parsed table before validation.
void apply_overrides(toml::table& root, const std::vector<std::string>& overrides,
                     const std::string& file);

// Position of a node in the file, for ordering tables as written (nodes created by --set come
// last).
std::pair<std::uint32_t, std::uint32_t> source_order(const toml::node& n);

// Typed, range-checked access to one table of the scene. `path` is the table's dotted key
// ("" for the root).
class TableReader {
 public:
  TableReader(const std::string& file, const toml::table& table, std::string path);

  const std::string& file() const { return file_; }
  const std::string& path() const { return path_; }
  const toml::table& table() const { return table_; }
  // Full dotted key of a key of this table.
  std::string key(std::string_view k) const;

  // Unknown keys are errors (with a did-you-mean hint when one allowed key is close).
  void allow(std::initializer_list<std::string_view> keys) const;

  const toml::node* find(std::string_view k) const;
  bool has(std::string_view k) const { return find(k) != nullptr; }
  // Throws "missing" when absent.
  const toml::node& need(std::string_view k) const;

  [[noreturn]] void fail(std::string_view k, std::string_view problem) const;
  [[noreturn]] void fail(std::string_view k, std::string_view problem, const toml::node& got) const;

  // Numbers (integers are accepted where a number is expected); must be finite.
  double number(std::string_view k, Range r = kAny) const;
  std::optional<double> number_opt(std::string_view k, Range r = kAny) const;
  double number_or(std::string_view k, double def, Range r = kAny) const;
  // Integers (a float is a type error).
  std::int64_t integer(std::string_view k, Range r = kAny) const;
  std::optional<std::int64_t> integer_opt(std::string_view k, Range r = kAny) const;
  std::int64_t integer_or(std::string_view k, std::int64_t def, Range r = kAny) const;
  // Strings, optionally restricted to `choices`.
  std::string string(std::string_view k, std::initializer_list<std::string_view> choices = {}) const;
  std::optional<std::string> string_opt(std::string_view k,
                                        std::initializer_list<std::string_view> choices = {}) const;
  bool boolean_or(std::string_view k, bool def) const;
  // Arrays of exactly n numbers / booleans.
  std::vector<double> numbers(std::string_view k, std::size_t n) const;
  // The array at k, which must have exactly n elements (`what` names them in messages).
  const toml::array& array_of(std::string_view k, std::size_t n, std::string_view what) const;
  std::vector<bool> booleans(std::string_view k, std::size_t n) const;
  // Sub-table (type-checked).
  TableReader sub(std::string_view k) const;

  // Checks of an already-read node (for values that may have several types).
  double as_number(const toml::node& n, std::string_view k, Range r) const;

 private:
  const std::string& file_;
  const toml::table& table_;
  std::string path_;
};

}  // namespace matep::scene_detail
