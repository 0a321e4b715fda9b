// Minimal CSV reader for particle files: a header line of column names, then one row of numbers
// per line (text in the columns the caller names, e.g. final_state.csv's group and material). Blank lines and lines starting with '#' are skipped. Internal to io/.
#pragma once

#include <cstddef>
#include <map>
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
  // The text columns asked for that the header has: name -> one word per row (rows[i][c] is NaN).
  std::map<std::string, std::vector<std::string>> text;
};

// Throws CsvError when the file cannot be read, has no header, a row has the wrong number of
// fields, a field is not a finite number (an empty word in a text column), or a column name is
// empty or repeated. Columns named in text_columns hold words, not numbers.
CsvTable read_csv(const std::string& path, const std::vector<std::string>& text_columns = {});
// Same from text (tests).
CsvTable parse_csv(const std::string& text, const std::vector<std::string>& text_columns = {});

}  // namespace matep::scene_detail
