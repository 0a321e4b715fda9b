#include "io/scene_toml.hpp"
#include "io/text.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <fmt/format.h>

#include "io/scene.hpp"
#include "io/scene_limits.hpp"

namespace matep::scene_detail {

namespace {

constexpr std::size_t kMaxShown = 120;

void show_into(const toml::node& n, std::string& out) {
  if (out.size() > kMaxShown) return;
  switch (n.type()) {
    case toml::node_type::string: out += quote(n.as_string()->get()); break;
    case toml::node_type::integer: out += fmt::format("{}", n.as_integer()->get()); break;
    case toml::node_type::floating_point: out += fmt::format("{}", n.as_floating_point()->get()); break;
    case toml::node_type::boolean: out += n.as_boolean()->get() ? "true" : "false"; break;
    case toml::node_type::array: {
      out += '[';
      bool first = true;
      for (const auto& e : *n.as_array()) {
        if (!first) out += ", ";
        first = false;
        show_into(e, out);
        if (out.size() > kMaxShown) return;
      }
      out += ']';
      break;
    }
    case toml::node_type::table: {
      out += '{';
      bool first = true;
      for (const auto& [k, v] : *n.as_table()) {
        out += first ? " " : ", ";
        first = false;
        out += k.str();
        out += " = ";
        show_into(v, out);
        if (out.size() > kMaxShown) return;
      }
      out += first ? "}" : " }";
      break;
    }
    default: {
      std::ostringstream s;
      n.visit([&](const auto& v) { s << v; });
      out += s.str();
      break;
    }
  }
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t sub = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string fmt_bound(double v) { return fmt::format("{}", v); }

}  // namespace

std::string quote(std::string_view s) {
  std::string out = "\"";
  for (const char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      case '\r': out += "\\r"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          out += fmt::format("\\u{:04X}", static_cast<unsigned>(c));
        } else {
          out += c;
        }
    }
    if (out.size() > kMaxShown) {
      out += "...";
      break;
    }
  }
  out += '"';
  return out;
}

std::string show(const toml::node& n) {
  std::string out;
  show_into(n, out);
  if (out.size() > kMaxShown) {
    out.resize(kMaxShown);
    out += "...";
  }
  return out;
}

std::string_view type_name(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::table: return "a table";
    case toml::node_type::array: return "an array";
    case toml::node_type::string: return "a string";
    case toml::node_type::integer: return "an integer";
    case toml::node_type::floating_point: return "a floating-point number";
    case toml::node_type::boolean: return "a boolean";
    case toml::node_type::date: return "a date";
    case toml::node_type::time: return "a time";
    case toml::node_type::date_time: return "a date-time";
    default: return "nothing";
  }
}

void fail(std::string_view file, std::string_view key, std::string_view problem) {
  throw SceneError(fmt::format("{}: {}: {}", file, key, problem));
}

void fail(std::string_view file, std::string_view key, std::string_view problem, const toml::node& got) {
  fail_got(file, key, problem, show(got));
}

void fail_got(std::string_view file, std::string_view key, std::string_view problem, std::string_view got) {
  throw SceneError(fmt::format("{}: {}: {} (got {})", file, key, problem, got));
}

bool Range::contains(double v) const {
  if (lo_open ? !(v > lo) : !(v >= lo)) return false;
  if (hi_open ? !(v < hi) : !(v <= hi)) return false;
  return true;
}

std::string Range::describe() const {
  const bool has_lo = std::isfinite(lo), has_hi = std::isfinite(hi);
  if (has_lo && has_hi) {
    return fmt::format("must be in {}{}, {}{}", lo_open ? '(' : '[', fmt_bound(lo), fmt_bound(hi),
                       hi_open ? ')' : ']');
  }
  if (has_lo) return fmt::format("must be {} {}", lo_open ? ">" : ">=", fmt_bound(lo));
  if (has_hi) return fmt::format("must be {} {}", hi_open ? "<" : "<=", fmt_bound(hi));
  return "must be a finite number";
}

toml::table parse_toml(std::string_view text, const std::string& file) {
  check_scene_text(text, file);
  try {
    return toml::parse(text, file);
  } catch (const toml::parse_error& e) {
    std::string desc(e.description());
    std::replace(desc.begin(), desc.end(), '\n', ' ');
    throw SceneError(fmt::format("{}: line {}, column {}: TOML syntax error: {}", file, e.source().begin.line,
                                 e.source().begin.column, desc));
  }
}

void apply_overrides(toml::table& root, const std::vector<std::string>& overrides, const std::string& file) {
  for (const std::string& ov : overrides) {
    const std::string shown = fmt::format("--set {}", quote(ov));
    const auto eq = ov.find('=');
    if (eq == std::string::npos) {
      fail_got(file, "--set", "malformed override, expected dotted.key=VALUE", quote(ov));
    }
    const std::string_view key = trim(std::string_view(ov).substr(0, eq));
    const std::string_view value = trim(std::string_view(ov).substr(eq + 1));
    if (key.empty()) fail_got(file, "--set", "malformed override, the key before '=' is empty", quote(ov));
    std::vector<std::string> parts;
    for (std::size_t start = 0;;) {
      const auto dot = key.find('.', start);
      const std::string_view part = trim(key.substr(start, dot == std::string_view::npos ? dot : dot - start));
      if (part.empty()) {
        fail_got(file, key, fmt::format("malformed override {}: empty component in the dotted key", shown),
                 quote(ov));
      }
      parts.emplace_back(part);
      if (parts.size() > static_cast<std::size_t>(kMaxSceneNesting))
        fail_got(file, "--set", fmt::format("the key has more than {} levels", kMaxSceneNesting), quote(ov));
      if (dot == std::string_view::npos) break;
      start = dot + 1;
    }

    // VALUE as a TOML value; anything else (a bare word such as heap) is a string.
    toml::table parsed;
    bool is_toml = false;
    try {
      const std::string doc = fmt::format("v = {}", value);
      check_scene_text(doc, fmt::format("{}: {}", file, shown));
      parsed = toml::parse(std::string_view(doc), std::string_view("--set"));
      is_toml = parsed.size() == 1 && parsed.contains("v");
    } catch (const toml::parse_error&) {
      is_toml = false;
    }

    toml::table* cur = &root;
    std::string walked;
    for (std::size_t i = 0; i + 1 < parts.size(); ++i) {
      walked += (walked.empty() ? "" : ".") + parts[i];
      toml::node* n = cur->get(parts[i]);
      if (n == nullptr) {
        cur = cur->insert(parts[i], toml::table{}).first->second.as_table();
      } else if (n->is_table()) {
        cur = n->as_table();
      } else {
        fail(file, key,
             fmt::format("cannot apply {}: {} is {}, not a table", shown, walked, type_name(*n)), *n);
      }
    }
    if (is_toml) {
      cur->insert_or_assign(parts.back(), std::move(*parsed.get("v")));
    } else {
      cur->insert_or_assign(parts.back(), std::string(value));
    }
  }
}

std::pair<std::uint32_t, std::uint32_t> source_order(const toml::node& n) {
  const auto& b = n.source().begin;
  if (b.line == 0) return {std::numeric_limits<std::uint32_t>::max(), 0};
  return {b.line, b.column};
}

// ---------------------------------------------------------------------------------------------

TableReader::TableReader(const std::string& file, const toml::table& table, std::string path)
    : file_(file), table_(table), path_(std::move(path)) {}

std::string TableReader::key(std::string_view k) const {
  return path_.empty() ? std::string(k) : fmt::format("{}.{}", path_, k);
}

void TableReader::allow(std::initializer_list<std::string_view> keys) const {
  for (const auto& [k, v] : table_) {
    const std::string_view name = k.str();
    if (std::find(keys.begin(), keys.end(), name) != keys.end()) continue;
    std::string hint;
    std::size_t best = 3;
    for (const auto cand : keys) {
      const std::size_t d = edit_distance(name, cand);
      if (d < best) {
        best = d;
        hint = fmt::format("did you mean '{}'? ", cand);
      }
    }
    std::string allowed;
    for (const auto cand : keys) allowed += (allowed.empty() ? "" : ", ") + std::string(cand);
    fail(name, fmt::format("unknown key; {}allowed keys here: {}", hint, allowed), v);
  }
}

const toml::node* TableReader::find(std::string_view k) const { return table_.get(k); }

const toml::node& TableReader::need(std::string_view k) const {
  const toml::node* n = find(k);
  if (n == nullptr) fail(k, "missing (required key)");
  return *n;
}

void TableReader::fail(std::string_view k, std::string_view problem) const {
  scene_detail::fail(file_, key(k), problem);
}

void TableReader::fail(std::string_view k, std::string_view problem, const toml::node& got) const {
  scene_detail::fail(file_, key(k), problem, got);
}

double TableReader::as_number(const toml::node& n, std::string_view k, Range r) const {
  double v = 0.0;
  if (n.is_integer()) {
    v = static_cast<double>(n.as_integer()->get());
  } else if (n.is_floating_point()) {
    v = n.as_floating_point()->get();
  } else {
    fail(k, fmt::format("expected a number but found {}", type_name(n)), n);
  }
  if (!std::isfinite(v)) fail(k, "must be a finite number", n);
  if (!r.contains(v)) fail(k, r.describe(), n);
  return v;
}

double TableReader::number(std::string_view k, Range r) const { return as_number(need(k), k, r); }

std::optional<double> TableReader::number_opt(std::string_view k, Range r) const {
  const toml::node* n = find(k);
  if (n == nullptr) return std::nullopt;
  return as_number(*n, k, r);
}

double TableReader::number_or(std::string_view k, double def, Range r) const {
  return number_opt(k, r).value_or(def);
}

std::int64_t TableReader::integer(std::string_view k, Range r) const {
  const toml::node& n = need(k);
  if (!n.is_integer()) fail(k, fmt::format("expected an integer but found {}", type_name(n)), n);
  const std::int64_t v = n.as_integer()->get();
  if (!r.contains(static_cast<double>(v))) fail(k, r.describe(), n);
  return v;
}

std::optional<std::int64_t> TableReader::integer_opt(std::string_view k, Range r) const {
  if (!has(k)) return std::nullopt;
  return integer(k, r);
}

std::int64_t TableReader::integer_or(std::string_view k, std::int64_t def, Range r) const {
  return integer_opt(k, r).value_or(def);
}

std::string TableReader::string(std::string_view k, std::initializer_list<std::string_view> choices) const {
  const toml::node& n = need(k);
  if (!n.is_string()) fail(k, fmt::format("expected a string but found {}", type_name(n)), n);
  std::string v = n.as_string()->get();
  if (choices.size() > 0 && std::find(choices.begin(), choices.end(), v) == choices.end()) {
    std::string list;
    for (const auto c : choices) list += (list.empty() ? "" : ", ") + quote(c);
    fail(k, fmt::format("must be one of {}", list), n);
  }
  return v;
}

std::optional<std::string> TableReader::string_opt(std::string_view k,
                                                   std::initializer_list<std::string_view> choices) const {
  if (!has(k)) return std::nullopt;
  return string(k, choices);
}

bool TableReader::boolean_or(std::string_view k, bool def) const {
  const toml::node* n = find(k);
  if (n == nullptr) return def;
  if (!n->is_boolean()) fail(k, fmt::format("expected a boolean but found {}", type_name(*n)), *n);
  return n->as_boolean()->get();
}

const toml::array& TableReader::array_of(std::string_view k, std::size_t n, std::string_view what) const {
  const toml::node& node = need(k);
  const toml::array* a = node.as_array();
  if (a == nullptr) {
    fail(k, fmt::format("expected an array of {} {} but found {}", n, what, type_name(node)), node);
  }
  if (a->size() != n) {
    fail(k, fmt::format("expected an array of {} {} (one per dimension) but it has {}", n, what, a->size()),
         node);
  }
  return *a;
}

std::vector<double> TableReader::numbers(std::string_view k, std::size_t n) const {
  const toml::array* a = &array_of(k, n, "numbers");
  const toml::node& node = *a;
  std::vector<double> out;
  for (std::size_t i = 0; i < n; ++i) {
    const toml::node& e = *a->get(i);
    if (!e.is_number()) {
      fail(k, fmt::format("element {} must be a number but is {}", i, type_name(e)), node);
    }
    const double v = e.value<double>().value_or(0.0);
    if (!std::isfinite(v)) fail(k, fmt::format("element {} must be a finite number", i), node);
    out.push_back(v);
  }
  return out;
}

std::vector<bool> TableReader::booleans(std::string_view k, std::size_t n) const {
  const toml::array* a = &array_of(k, n, "booleans");
  const toml::node& node = *a;
  std::vector<bool> out;
  for (std::size_t i = 0; i < n; ++i) {
    const toml::node& e = *a->get(i);
    if (!e.is_boolean()) {
      fail(k, fmt::format("element {} must be a boolean but is {}", i, type_name(e)), node);
    }
    out.push_back(e.as_boolean()->get());
  }
  return out;
}

TableReader TableReader::sub(std::string_view k) const {
  const toml::node& n = need(k);
  if (!n.is_table()) fail(k, fmt::format("expected a table but found {}", type_name(n)), n);
  return TableReader(file_, *n.as_table(), key(k));
}

}  // namespace matep::scene_detail
