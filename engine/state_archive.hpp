// The dynamic state of an engine as bytes, for checkpoints (io/checkpoint.hpp). Each engine lists
// what its future depends on in one member template `template <class A> void archive(A& a)` that
// both saves and loads: a(x) for a value or a vector of plain values, a.tag("name") between parts
// (a loaded state whose tags differ is refused), a.same(v, "what") for an array whose length the
// scene fixes (a state for another scene is refused naming it), a.check(v, "what") for a setting
// the run must share with the one that saved it. Values are the bytes in memory:
// a checkpoint resumes on the machine class that wrote it (io/ checks the byte order and version).
#pragma once

#include <fmt/format.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <functional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace matep {

// A state that cannot be loaded into this engine (another scene, another layout, cut short).
struct StateError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// How the engine hands its state to the run (io/) and takes one back. The engines call save at a
// checkpoint moment (every interval, on a stop request, at the end) with the time and their state;
// resume, when set, is a state saved by the same engine for the same scene to continue from.
class StateWriter;
struct CheckpointHooks {
  double interval = 0.0;  // 0: only at a stop request and at the end
  // state(w) archives the engine's state into w (io/ streams it into the checkpoint file, with
  // a counting pass for its length first; archive_bytes(state) gives the bytes)
  std::function<void(double t, const std::function<void(StateWriter&)>& state)> save;
  const std::vector<std::uint8_t>* resume = nullptr;
};

namespace archive_detail {
template <class T>
struct is_vector : std::false_type {};
template <class T, class A>
struct is_vector<std::vector<T, A>> : std::true_type {};
template <class T, class A>
concept HasArchive = requires(T& t, A& a) { t.archive(a); };
// Saved as its bytes: a value that owns no resources (trivially destructible: numbers, enums,
// plain structs, Eigen's fixed-size vectors) and lists no parts of its own.
template <class T, class A>
concept Plain = std::is_trivially_destructible_v<T> && !std::is_pointer_v<T> && !is_vector<T>::value &&
                !HasArchive<T, A>;
}  // namespace archive_detail

// Arrays of equal elements: the length's top bit marks one saved element for all of them (the
// hybrid's state is mostly such arrays while few grains are soft: cooling_clusters.toml's end
// checkpoint 3.3 instead of 3.8 MB). A filled array longer than kMaxFill is a corrupt state.
inline constexpr std::uint64_t kFill = std::uint64_t{1} << 63;
inline constexpr std::uint64_t kMaxFill = std::uint64_t{1} << 40;
// Every element equals the next one exactly when the bytes equal those one element further on:
// one comparison of the array with itself shifted (a call per element cost a 500-grain hybrid run
// 0.1 ms at its end checkpoint, three passes over some sixty arrays).
inline bool uniform(const void* p, std::size_t n, std::size_t size) {
  const auto* b = static_cast<const std::uint8_t*>(p);
  return n < 2 || std::memcmp(b, b + size, (n - 1) * size) == 0;
}

class StateWriter {
 public:
  static constexpr bool loading = false;
  std::vector<std::uint8_t> bytes;
  std::size_t size = 0;     // the bytes written (or counted)
  bool count_only = false;  // count them, write nothing (archive_bytes' first pass)
  // When set, the bytes go to it as they come instead of into `bytes` (a file being written).
  std::function<void(const void*, std::size_t)> sink;

  void tag(const char* name) {
    const std::uint32_t n = static_cast<std::uint32_t>(std::strlen(name));
    raw(&n, sizeof n);
    raw(name, n);
  }
  template <class T>
  void operator()(const T& v) {
    using namespace archive_detail;
    if constexpr (HasArchive<T, StateWriter>) {
      const_cast<T&>(v).archive(*this);
    } else if constexpr (Plain<T, StateWriter>) {
      raw(&v, sizeof v);
    } else if constexpr (is_vector<T>::value) {
      using E = typename T::value_type;
      const std::uint64_t n = v.size();
      if constexpr (Plain<E, StateWriter>) {
        // An array whose elements are all the same bytes (a flag nobody has set, a mode every
        // grain shares, one grain size) is saved as its length with kFill and one element.
        if (n > 1 && uniform(v.data(), n, sizeof(E))) {
          const std::uint64_t m = n | kFill;
          raw(&m, sizeof m);
          raw(v.data(), sizeof(E));
          return;
        }
        raw(&n, sizeof n);
        if (n > 0) raw(v.data(), n * sizeof(E));
      } else {
        raw(&n, sizeof n);
        for (const auto& e : v) (*this)(e);
      }
    } else if constexpr (std::is_same_v<T, std::string>) {
      const std::uint64_t n = v.size();
      raw(&n, sizeof n);
      raw(v.data(), n);
    } else {
      static_assert(sizeof(T) == 0, "no archive rule for this type");
    }
  }
  template <class V>
  void same(const V& v, const char*) {
    (*this)(v);
  }
  template <class T>
  void check(const T& v, const char*) {
    (*this)(v);
  }

 private:
  void raw(const void* p, std::size_t n) {
    size += n;
    if (count_only) return;
    if (sink) return sink(p, n);
    append(static_cast<const std::uint8_t*>(p), n);
  }
  // (Out of line: inlined into a caller that writes into a fresh writer, GCC 12 warned of an
  // overflow of the empty vector that the insert grows first, -Wstringop-overflow.)
  [[gnu::noinline]] void append(const std::uint8_t* b, std::size_t n) { bytes.insert(bytes.end(), b, b + n); }
};

// What archive(a) writes, as bytes in a buffer allocated once at its size (a first pass counts
// them; a buffer grown by doubling has each page faulted in two or three times). For a caller that
// keeps states in memory (tests); the run streams the state into the checkpoint file instead
// (io/checkpoint.cpp): copies of a 3.7 MB hybrid state took 40 ms of a 70 ms run.
template <class F>
std::vector<std::uint8_t> archive_bytes(F&& archive) {
  StateWriter count;
  count.count_only = true;
  archive(count);
  StateWriter w;
  w.bytes.reserve(count.size);
  archive(w);
  return std::move(w.bytes);
}

class StateReader {
 public:
  static constexpr bool loading = true;
  explicit StateReader(const std::vector<std::uint8_t>& bytes) : p_(bytes.data()), end_(bytes.data() + bytes.size()) {}

  void tag(const char* name) {
    std::uint32_t n = 0;
    raw(&n, sizeof n, name);
    const std::size_t want = std::strlen(name);
    if (n != want || left() < n || std::memcmp(p_, name, n) != 0)
      throw StateError(fmt::format("the engine state has no part \"{}\" where it is expected (a checkpoint of "
                                   "another method or version)",
                                   name));
    p_ += n;
    last_ = name;
  }
  template <class T>
  void operator()(T& v) {
    using namespace archive_detail;
    if constexpr (HasArchive<T, StateReader>) {
      v.archive(*this);
    } else if constexpr (std::is_same_v<T, bool>) {
      // A flag is one byte, 0 or 1: any other value is a corrupt state (and not a bool to load).
      std::uint8_t b = 0;
      raw(&b, 1, last_);
      static_assert(sizeof(bool) == 1, "the writer saves a flag as its one byte");
      if (b > 1)
        throw StateError(fmt::format("the engine state has a flag of value {} in \"{}\" (0 or 1 expected)", b, last_));
      v = b != 0;
    } else if constexpr (Plain<T, StateReader>) {
      raw(&v, sizeof v, last_);
    } else if constexpr (is_vector<T>::value) {
      using E = typename T::value_type;
      std::uint64_t n = 0;
      raw(&n, sizeof n, last_);
      if constexpr (Plain<E, StateReader>) {
        if (n & kFill) {  // n copies of one element
          n &= ~kFill;
          E e;
          raw(&e, sizeof e, last_);
          if (n > kMaxFill)
            throw StateError(fmt::format("the engine state has an array of {} elements in \"{}\"", n, last_));
          v.assign(static_cast<std::size_t>(n), e);
          return;
        }
      }
      // Bounded by the bytes left before anything is allocated.
      if (n > left() / (Plain<E, StateReader> ? sizeof(E) : 1))
        throw StateError(fmt::format("the engine state is cut short in \"{}\"", last_));
      if constexpr (Plain<E, StateReader>) {
        v.resize(static_cast<std::size_t>(n));
        if (n > 0) raw(v.data(), n * sizeof(E), last_);
      } else {
        if constexpr (std::is_default_constructible_v<E>) {
          v.resize(static_cast<std::size_t>(n));
        } else if (n != v.size()) {
          throw StateError(fmt::format("the checkpoint holds {} entries in \"{}\", this scene {}", n, last_, v.size()));
        }
        for (auto& e : v) (*this)(e);
      }
    } else if constexpr (std::is_same_v<T, std::string>) {
      std::uint64_t n = 0;
      raw(&n, sizeof n, last_);
      if (n > left()) throw StateError(fmt::format("the engine state is cut short in \"{}\"", last_));
      v.assign(reinterpret_cast<const char*>(p_), n);
      p_ += n;
    } else {
      static_assert(sizeof(T) == 0, "no archive rule for this type");
    }
  }
  // An array whose length the scene fixes (one entry per particle slot, wall, material ...).
  template <class V>
  void same(V& v, const char* what) {
    const std::size_t had = v.size();
    (*this)(v);
    if (v.size() != had)
      throw StateError(fmt::format("the checkpoint holds {} {}, this scene {}", v.size(), what, had));
  }
  // A setting the state was made with, which this run must share (the time step, the threads).
  template <class T>
  void check(const T& v, const char* what) {
    T had{};
    (*this)(had);
    if (!(had == v)) throw StateError(fmt::format("the checkpoint was written with {} = {}, this run has {}", what, had, v));
  }
  bool done() const { return p_ == end_; }

 private:
  std::size_t left() const { return static_cast<std::size_t>(end_ - p_); }
  void raw(void* dst, std::size_t n, const char* where) {
    if (left() < n) throw StateError(fmt::format("the engine state is cut short in \"{}\"", where));
    std::memcpy(dst, p_, n);
    p_ += n;
  }
  const std::uint8_t* p_;
  const std::uint8_t* end_;
  const char* last_ = "header";
};

}  // namespace matep
