// The one exception type of vfe's C++ API: a status for the C API and a message that says
// what was wrong and how to fix it.
#pragma once

#include <vfe/vfe.h>

#include <stdexcept>
#include <string>

namespace vfe {

class VFE_API Error : public std::runtime_error {
 public:
  Error(vfe_status status, const std::string& message) : std::runtime_error(message), status_(status) {}
  vfe_status status() const noexcept { return status_; }

 private:
  vfe_status status_;
};

}  // namespace vfe
