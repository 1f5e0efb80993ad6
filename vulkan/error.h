// vulkan/error.h - the one error the device layers throw: what the environment or the caller got
// wrong (no Vulkan device, a failed Vulkan call, bad input). render::RenderError names the same type,
// so that a caller catches one error whichever layer refused. No Vulkan header.
#pragma once

#include <stdexcept>

namespace displace::vulkan {

struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace displace::vulkan
