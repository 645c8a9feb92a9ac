// Strict number parsing for the readers: the whole token must be the number.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>

namespace vfe {

/// The integer spelled by all of `token` (an optional '+' or '-', then digits), or nothing
/// when the token has anything else ("1x", "2.9", "") or does not fit int64.
inline std::optional<std::int64_t> parse_int64(std::string_view token) {
  if (token.size() > 1 && token.front() == '+' && token[1] != '-') token.remove_prefix(1);
  std::int64_t v = 0;
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  if (ec != std::errc() || ptr != token.data() + token.size() || token.empty()) return std::nullopt;
  return v;
}

/// The finite double spelled by all of `token` (decimal or exponent form, optional sign),
/// or nothing when the token has anything else, overflows or is inf/nan. Values below the
/// smallest double round to 0 or a subnormal, as strtod does.
inline std::optional<double> parse_finite_double(std::string_view token) {
  if (token.size() > 1 && token.front() == '+' && token[1] != '-') token.remove_prefix(1);
  double v = 0;
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  if (token.empty() || ptr != token.data() + token.size()) return std::nullopt;
  if (ec == std::errc::result_out_of_range) {
    // from_chars reports underflow too and leaves v alone; strtod tells the two apart.
    const std::string copy(token);
    v = std::strtod(copy.c_str(), nullptr);
    return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
  }
  if (ec != std::errc() || !std::isfinite(v)) return std::nullopt;
  return v;
}

}  // namespace vfe
