#include "io/checkpoint.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <toml++/toml.h>

#include "engine/state_archive.hpp"
#include "io/io_error.hpp"

namespace matep {

namespace {
constexpr std::uint32_t kByteOrder = 0x01020304;
constexpr std::size_t kHead = 8 + 4 + 4 + 8;
}  // namespace

template <class A>
void Checkpoint::archive(A& a) {
  a.tag("checkpoint");
  a(method);
  a(dimension);
  a(scene);
  a(time);
  a.tag("outputs");
  a(thermo);
  bool has = outflow.has_value();
  a(has);
  if (has) {
    if (!outflow) outflow.emplace();
    a(*outflow);
  }
  has = events.has_value();
  a(has);
  if (has) {
    if (!events) events.emplace();
    a(*events);
  }
  has = snapshots.has_value();
  a(has);
  if (has) {
    if (!snapshots) snapshots.emplace();
    a(*snapshots);
  }
  a.tag("engine");
  if constexpr (!A::loading) {
    if (engine_source) {  // as a(engine) writes a byte vector: its length, then the bytes
      a(engine_bytes);
      if (a.count_only) a.size += engine_bytes;  // (counted once by write_checkpoint)
      else (*engine_source)(a);
      return;
    }
  }
  a(engine);
}

void write_checkpoint(const std::string& path, const Checkpoint& c, bool durable) {
  // The body is counted first (its length is in the head), then archived straight into the file
  // with its checksum carried along: no copy of the engine's state is made here.
  Checkpoint& cc = const_cast<Checkpoint&>(c);
  if (cc.engine_source) {
    StateWriter engine;
    engine.count_only = true;
    (*cc.engine_source)(engine);
    cc.engine_bytes = engine.size;
  }
  StateWriter count;
  count.count_only = true;
  cc.archive(count);
  std::array<std::uint8_t, kHead> head{};
  std::memcpy(head.data(), kCheckpointMagic, 8);
  std::memcpy(head.data() + 8, &kCheckpointVersion, 4);
  std::memcpy(head.data() + 12, &kByteOrder, 4);
  const std::uint64_t n = count.size;
  std::memcpy(head.data() + 16, &n, 8);
  // A temporary beside it, (synced,) then renamed: the checkpoint in place is always whole.
  const std::string tmp = path + ".tmp";
  {
    CheckedFile f(tmp, "wb");
    std::uint32_t crc = crc32c(head.data(), head.size(), 0);
    f.write(head.data(), head.size());
    StateWriter body;
    body.sink = [&](const void* p, std::size_t k) {
      crc = crc32c(p, k, crc);
      f.write(p, k);
    };
    cc.archive(body);
    if (body.size != n) throw WriteError(fmt::format("{}: the checkpoint's body changed while it was written", path));
    f.write(&crc, sizeof crc);
    if (durable) f.sync();
    else f.flush();
    f.close();
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw WriteError(fmt::format("{}: cannot rename into place: {}", path, ec.message()));
}

Checkpoint parse_checkpoint(const std::vector<std::uint8_t>& bytes, const std::string& path) {
  if (bytes.size() < kHead + 4 || std::memcmp(bytes.data(), kCheckpointMagic, 8) != 0)
    throw IoError(fmt::format("{}: not a matep checkpoint (no \"MATEPCKP\" header)", path));
  std::uint32_t version = 0, order = 0;
  std::uint64_t n = 0;
  std::memcpy(&version, bytes.data() + 8, 4);
  std::memcpy(&order, bytes.data() + 12, 4);
  std::memcpy(&n, bytes.data() + 16, 8);
  if (order != kByteOrder)
    throw IoError(fmt::format("{}: written on a machine of another byte order; a checkpoint resumes on the "
                              "machine class that wrote it",
                              path));
  if (version != kCheckpointVersion)
    throw IoError(fmt::format("{}: checkpoint version {}, this matep reads version {}", path, version,
                              kCheckpointVersion));
  if (n != bytes.size() - kHead - 4)
    throw IoError(fmt::format("{}: {} bytes, the header gives {} (cut short or extended)", path, bytes.size(),
                              n + kHead + 4));
  std::uint32_t stored = 0;
  std::memcpy(&stored, bytes.data() + bytes.size() - 4, 4);
  if (crc32c(bytes.data(), bytes.size() - 4, 0) != stored)
    throw IoError(fmt::format("{}: the checksum does not match (the file is corrupt)", path));
  const std::vector<std::uint8_t> body(bytes.begin() + kHead, bytes.end() - 4);
  Checkpoint c;
  try {
    StateReader r(body);
    c.archive(r);
    if (!r.done()) throw StateError("bytes after the engine state");
  } catch (const StateError& e) {
    throw IoError(fmt::format("{}: not a readable checkpoint: {}", path, e.what()));
  }
  if (c.method > 2 || (c.dimension != 2 && c.dimension != 3))
    throw IoError(fmt::format("{}: not a readable checkpoint: method {} dimension {}", path, c.method, c.dimension));
  return c;
}

Checkpoint read_checkpoint(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw IoError(fmt::format("{}: cannot read the checkpoint: {}", path,
                              std::filesystem::exists(path, ec) ? "not a regular file" : "no such file"));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(fmt::format("{}: cannot read the checkpoint: {}", path, std::strerror(errno)));
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw IoError(fmt::format("{}: cannot read the checkpoint: read error", path));
  return parse_checkpoint(bytes, path);
}

namespace {

std::string text(const toml::node* n) {
  if (!n) return "(absent)";
  std::ostringstream s;
  n->visit([&](const auto& v) {
    if constexpr (toml::is_table<decltype(v)>) s << "a table";
    else s << toml::toml_formatter(v, toml::format_flags::none);
  });
  return s.str();
}
std::string show(const toml::node* n) {
  std::string out = text(n);
  if (out.size() > 80) out = out.substr(0, 77) + "...";
  return out;
}

std::optional<std::string> first_difference(const toml::table& a, const toml::table& b, const std::string& prefix,
                                            const std::vector<std::string>& ignore) {
  std::vector<std::string> keys;
  for (const auto& [k, v] : a) keys.emplace_back(k.str());
  for (const auto& [k, v] : b)
    if (!a.contains(k.str())) keys.emplace_back(k.str());
  for (const std::string& k : keys) {
    const std::string key = prefix.empty() ? k : prefix + "." + k;
    if (std::find(ignore.begin(), ignore.end(), key) != ignore.end()) continue;
    const toml::node* x = a.get(k);
    const toml::node* y = b.get(k);
    if (x && y && x->is_table() && y->is_table()) {
      if (auto d = first_difference(*x->as_table(), *y->as_table(), key, ignore)) return d;
      continue;
    }
    if (!x || !y || x->type() != y->type() || text(x) != text(y)) return fmt::format("{}: checkpoint {}, this scene {}", key, show(x), show(y));
  }
  return std::nullopt;
}

}  // namespace

std::optional<std::string> scene_difference(const std::string& saved, const std::string& now,
                                            const std::vector<std::string>& ignore) {
  if (saved == now) return std::nullopt;
  toml::table a, b;
  try {
    a = toml::parse(saved);
    b = toml::parse(now);
  } catch (const toml::parse_error&) {
    return std::string("the scene text differs");
  }
  return first_difference(a, b, "", ignore);
}

}  // namespace matep
