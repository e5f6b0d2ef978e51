// Numbers in messages and reports: shortest readable form, the same on every machine.
#pragma once

#include <cstdio>
#include <string>

namespace shadowcull {

// "%.6g": 0.01 -> "0.01", 25 -> "25", 1e-07 -> "1e-07".
inline std::string formatNumber(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

}  // namespace shadowcull
