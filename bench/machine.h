// What the benchmarks say about the machine and the process they run in (Linux /proc).
#pragma once

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

namespace shadowcull::bench {

// The CPU's model name as /proc/cpuinfo gives it.
inline std::string cpuModel() {
    std::ifstream in("/proc/cpuinfo");
    for (std::string line; std::getline(in, line);)
        if (line.rfind("model name", 0) == 0) {
            const size_t c = line.find(':');
            return c == std::string::npos ? line : line.substr(c + 2);
        }
    return "unknown CPU";
}

// A /proc/self/status field in KiB (VmRSS, VmHWM), 0 when unavailable.
inline long procStatusKiB(const char* field) {
    std::ifstream in("/proc/self/status");
    for (std::string line; std::getline(in, line);)
        if (line.rfind(field, 0) == 0) return std::atol(line.c_str() + std::strlen(field) + 1);
    return 0;
}

}  // namespace shadowcull::bench
