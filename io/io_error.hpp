// The error of a file that cannot be read or written: its message names the file (and the byte
// offset or the OS error). A WriteError is an output that could not be written (exit status 4,
// README "Exit status"); other IoErrors are bad input (exit status 2).
#pragma once

#include <stdexcept>

namespace matep {

class IoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class WriteError : public IoError {
 public:
  using IoError::IoError;
};

}  // namespace matep
