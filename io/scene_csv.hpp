// Minimal numeric CSV reader for particle files: a header line of column names, then one row of
// numbers per line. Blank lines and lines starting with '#' are skipped. Internal to io/.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace matep::scene_detail {

// What went wrong, without the file name (the caller adds file and key).
class CsvError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct CsvTable {
  std::vector<std::string> columns;         // trimmed header names, in file order
  std::vector<std::vector<double>> rows;    // rows[i][c]: value of column c
  std::vector<std::size_t> lines;           // 1-based line number of each row
};

// Throws CsvError when the file cannot be read, has no header, a row has the wrong number of
// fields, a field is not a finite number, or a column name is empty or repeated.
CsvTable read_csv(const std::string& path);
// Same from text (tests).
CsvTable parse_csv(const std::string& text);

}  // namespace matep::scene_detail
