#include "io/scene_csv.hpp"
#include "io/text.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string_view>

#include <fmt/format.h>

namespace matep::scene_detail {

namespace {

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> out;
  for (std::size_t start = 0;;) {
    const auto comma = line.find(',', start);
    out.push_back(trim(line.substr(start, comma == std::string_view::npos ? comma : comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return out;
}

bool parse_double(std::string_view s, double& v) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const auto res = std::from_chars(s.data(), s.data() + s.size(), v);
  return res.ec == std::errc() && res.ptr == s.data() + s.size() && std::isfinite(v);
}

}  // namespace

CsvTable parse_csv(const std::string& text, const std::vector<std::string>& text_columns) {
  CsvTable t;
  std::vector<std::vector<std::string>*> words;  // per column: its words (text columns), else null
  bool have_header = false;
  std::size_t line_no = 0;
  std::string_view rest(text);
  while (!rest.empty()) {
    const auto nl = rest.find('\n');
    std::string_view line = rest.substr(0, nl);
    rest = (nl == std::string_view::npos) ? std::string_view{} : rest.substr(nl + 1);
    ++line_no;
    line = trim(line);
    if (line.empty() || line.front() == '#') continue;
    const auto fields = split(line);
    if (!have_header) {
      for (const auto f : fields) {
        if (f.empty()) throw CsvError(fmt::format("line {}: empty column name in the header", line_no));
        if (std::find(t.columns.begin(), t.columns.end(), f) != t.columns.end()) {
          throw CsvError(fmt::format("line {}: column '{}' appears twice in the header", line_no, f));
        }
        t.columns.emplace_back(f);
      }
      for (const auto& c : t.columns) {
        const bool is_text = std::find(text_columns.begin(), text_columns.end(), c) != text_columns.end();
        words.push_back(is_text ? &t.text[c] : nullptr);
      }
      have_header = true;
      continue;
    }
    if (fields.size() != t.columns.size()) {
      throw CsvError(fmt::format("line {}: {} fields but the header has {} columns", line_no, fields.size(),
                                 t.columns.size()));
    }
    std::vector<double> row(fields.size());
    for (std::size_t c = 0; c < fields.size(); ++c) {
      if (words[c]) {
        if (fields[c].empty()) throw CsvError(fmt::format("line {}, column '{}': empty", line_no, t.columns[c]));
        words[c]->emplace_back(fields[c]);
        row[c] = std::numeric_limits<double>::quiet_NaN();
        continue;
      }
      if (!parse_double(fields[c], row[c])) {
        throw CsvError(fmt::format("line {}, column '{}': not a finite number (got \"{}\")", line_no,
                                   t.columns[c], fields[c]));
      }
    }
    t.rows.push_back(std::move(row));
    t.lines.push_back(line_no);
  }
  if (!have_header) throw CsvError("no header line (expected column names such as x,y,vx,vy,radius)");
  return t;
}

CsvTable read_csv(const std::string& path, const std::vector<std::string>& text_columns) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw CsvError("cannot read particle file: it is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CsvError(fmt::format("cannot read particle file: {}", std::strerror(errno)));
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw CsvError("cannot read particle file: read error");
  return parse_csv(ss.str(), text_columns);
}

}  // namespace matep::scene_detail
