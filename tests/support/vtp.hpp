// The numbers of one DataArray of a .vtp file written by matep, ASCII or appended raw binary
// (UInt64 byte-count headers; VTK XML file format), as doubles. An empty name: the first
// DataArray (the points). A test-side reader, independent of io/snapshots.cpp.
#pragma once

#include <cstdint>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

namespace matep::test {

inline std::string vtp_attr(const std::string& text, std::size_t tag, const std::string& attr) {
  const auto end = text.find('>', tag);
  const auto at = text.find(" " + attr + "=\"", tag);
  if (at == std::string::npos || at > end) return {};
  const auto v = at + attr.size() + 3;
  return text.substr(v, text.find('"', v) - v);
}

inline std::vector<double> vtp_array(const std::string& text, const std::string& name) {
  const auto xml_end = text.find("<AppendedData");
  const auto tag = name.empty() ? text.find("<DataArray", text.find("<Points")) : text.find("Name=\"" + name + "\"");
  if (tag == std::string::npos || tag > xml_end) return {};
  const auto open = text.rfind("<DataArray", tag);
  std::vector<double> v;
  if (vtp_attr(text, open, "format") != "appended") {
    const auto start = text.find('>', open) + 1;
    std::istringstream in(text.substr(start, text.find("</DataArray>", start) - start));
    double x;
    while (in >> x) v.push_back(x);
    return v;
  }
  const std::size_t raw = text.find('_', xml_end) + 1 + std::stoull(vtp_attr(text, open, "offset"));
  std::uint64_t bytes = 0;
  std::memcpy(&bytes, text.data() + raw, 8);
  const char* p = text.data() + raw + 8;
  const std::string type = vtp_attr(text, open, "type");
  auto take = [&](auto zero) {
    using T = decltype(zero);
    for (std::size_t k = 0; k < bytes / sizeof(T); ++k) {
      T x;
      std::memcpy(&x, p + k * sizeof(T), sizeof(T));
      v.push_back(static_cast<double>(x));
    }
  };
  if (type == "Float64") take(double{});
  else if (type == "Float32") take(float{});
  else if (type == "UInt8") take(std::uint8_t{});
  else if (type == "UInt16") take(std::uint16_t{});
  else if (type == "UInt32") take(std::uint32_t{});
  else if (type == "Int32") take(std::int32_t{});
  return v;
}

}  // namespace matep::test
