#pragma once
// The one exception type of the library. Messages are single lines that name the problem.
#include <stdexcept>
#include <string>

namespace penumbra {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace penumbra
