// Integers read from JSON files (nlohmann/json). get<int>() is no check: of 2.5 it truncates,
// of 1e20 it is undefined behaviour (a float out of the integer's range), and -1 read into
// a size_t is a count of 1.8e19. A reader of files a person may have edited takes its
// integers through integerIn instead.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>

#include <nlohmann/json.hpp>

namespace shadowcull {

// `v` as a T when it is a JSON integer (not 2.0 nor 2e3: the tool writes integers as
// such) within T's range; nothing otherwise.
template <class T>
std::optional<T> integerIn(const nlohmann::json& v) {
    using Limits = std::numeric_limits<T>;
    if (v.is_number_unsigned()) {
        const uint64_t u = v.get<uint64_t>();
        if (u > uint64_t(Limits::max())) return std::nullopt;
        return T(u);
    }
    if (!v.is_number_integer()) return std::nullopt;
    const int64_t s = v.get<int64_t>();
    if (s < int64_t(Limits::min()) || (s > 0 && uint64_t(s) > uint64_t(Limits::max()))) return std::nullopt;
    return T(s);
}

}  // namespace shadowcull
