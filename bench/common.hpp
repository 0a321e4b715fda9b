// Helpers shared by the whole-run benchmark drivers (bench/run_*.cpp): resident-memory probes
// (KiB, Linux) and the median row of repeated measurements.
#pragma once

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <vector>

namespace matep::bench {

inline long peak_rss_kb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;
}

inline long current_rss_kb() {
  long pages = 0, resident = 0;
  if (std::FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
    std::fclose(f);
  }
  return resident * (sysconf(_SC_PAGESIZE) / 1024);
}

// The median of repeated measurements: the row of median rate, carrying the median of the bytes
// per particle (the two medians may come from different repeats).
template <class Row>
Row median_row(std::vector<Row> rows) {
  std::sort(rows.begin(), rows.end(), [](const Row& a, const Row& b) { return a.rate < b.rate; });
  Row med = rows[rows.size() / 2];
  std::sort(rows.begin(), rows.end(), [](const Row& a, const Row& b) { return a.bytes < b.bytes; });
  med.bytes = rows[rows.size() / 2].bytes;
  return med;
}

}  // namespace matep::bench
