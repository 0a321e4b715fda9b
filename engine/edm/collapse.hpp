// Inelastic-collapse watch: one particle's collision intervals, judged against its own recent
// intervals rather than an absolute window.
//
// Inelastic collapse (McNamara & Young, Phys. Fluids A 4, 496 (1992)): a group of hard inelastic
// grains collides infinitely often in a finite time; each grain's intervals between collisions
// shrink geometrically (three grains in a line at restitution r = 0.06: by about 0.45 a collision)
// until round-off ends the cascade with a wrong outcome. An elastic or mildly inelastic dense gas
// also has short intervals, but they go up and down about a level set by its density and
// temperature. The watch therefore follows the logarithm of the intervals:
//  * fast: an exponential average of log2(interval) with weight 1/8 (kShift). It averages over the
//    ups and downs of a many-grain collapse (a grain's intervals scatter by about a decade about
//    the decay) and of a gas;
//  * each sample is held to at most kClamp (1 decade) below fast, so that fast falls by at most
//    1/8 decade a collision: a very short or zero interval (three grains meeting at once, a
//    recollision after a grazing collision), or a brief dip of a few collisions (three grains
//    rattling in a cluster), cannot carry it deep; only a decay sustained over 32 collisions or
//    more can (a collapse goes on until round-off ends it, for about 80 collisions of three grains);
//  * high: the highest recent level of fast, leaking downwards by kLeak a collision, so that a slow
//    drift of the level (a gas being compressed or heated over many collisions) is followed, while
//    a decay faster than kLeak a collision builds up depth;
//  * a collapse is a depth (high - fast) of `depth` (default 4 decades) or more.
// Thresholds and the measurements behind them: README "Inelastic collapse".
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>

namespace matep::edm {

struct CollapseWatch {
  // Levels in 1/256 octave; kUnset = no interval yet.
  std::int32_t fast = kUnset;
  std::int32_t high = kUnset;

  static constexpr std::int32_t kUnset = INT32_MIN;
  static constexpr int kShift = 3;                  // average weight 1/8
  static constexpr std::int32_t kClamp = 850;       // 1 decade = 3.32 octaves
  static constexpr std::int32_t kLeak = 8;          // 8/256 octave = 0.0094 decades a collision

  // floor(256 log2 x) for x > 0, piecewise linear between powers of two (error < 0.09 octave): the
  // exponent and the top 8 mantissa bits of the IEEE double, read as one integer. Zero maps to
  // about -1023 octaves; +infinity to +1024.
  static std::int32_t level(double x) {
    const auto bits = std::bit_cast<std::uint64_t>(x);
    return static_cast<std::int32_t>((bits >> 44) & 0x7FFFF) - 1023 * 256;
  }
  // Depth in the units of level() from decades.
  static std::int32_t depth_units(double decades) {
    return static_cast<std::int32_t>(std::lround(decades * 256.0 / std::log10(2.0)));
  }
  static double decades(std::int32_t units) { return units * std::log10(2.0) / 256.0; }

  // The particle's collision dt after its previous one (+infinity for its first collision): true
  // when the intervals have now fallen `depth` below their recent level.
  bool note(double dt, std::int32_t depth) {
    if (!(dt < INFINITY)) return false;  // the first collision: no interval yet
    std::int32_t x = level(dt);
    if (fast == kUnset) {
      fast = high = x;
      return false;
    }
    if (x < fast - kClamp) x = fast - kClamp;
    fast += (x - fast) >> kShift;  // arithmetic shift: floor
    high -= kLeak;
    if (fast > high) high = fast;
    return depth > 0 && high - fast >= depth;
  }
  // The smoothed interval and its recent level, in seconds (for messages).
  double fast_seconds() const { return std::exp2(fast / 256.0); }
  double high_seconds() const { return std::exp2(high / 256.0); }
};

}  // namespace matep::edm
