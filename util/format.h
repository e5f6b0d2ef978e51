// Numbers in messages and reports: shortest readable form, the same on every machine.
#pragma once

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <string>
#include <string_view>

namespace shadowcull {

// "%.6g": 0.01 -> "0.01", 25 -> "25", 1e-07 -> "1e-07".
inline std::string formatNumber(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

// A value the user gave, as formatNumber writes it but with as many digits as it takes to
// read back as exactly `v`: a message must not say "1e+10 is outside [-1e+10, 1e+10]" of
// 1.0000001e10. Within six significant digits the text is formatNumber's.
inline std::string formatExact(double v) {
    char shortest[32];
    const std::to_chars_result r = std::to_chars(shortest, shortest + sizeof shortest, v, std::chars_format::scientific);
    // "d.ddde+XX": the significant digits are those before the exponent, the point aside.
    const std::string_view mantissa(shortest, size_t(std::find(shortest, r.ptr, 'e') - shortest));
    const int digits = int(std::count_if(mantissa.begin(), mantissa.end(), [](char c) { return c >= '0' && c <= '9'; }));
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.*g", std::max(6, digits), v);
    return buf;
}

// An accepted interval as messages quote it, bounds exact: "[-100000, 100000]", or with
// `aboveLow` (the low bound itself refused) "(0, 100000]".
inline std::string formatInterval(double low, double high, bool aboveLow = false) {
    return (aboveLow ? "(" : "[") + formatExact(low) + ", " + formatExact(high) + "]";
}

}  // namespace shadowcull
