#include "fuzz/fuzz_support.h"

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string_view>

#include <unistd.h>

namespace fs = std::filesystem;

namespace {

struct Scratch {
    std::string path;
    Scratch() {
        fs::path base;
        if (const char* env = std::getenv("SHADOWCULL_FUZZ_TMPDIR"); env && *env) base = env;
        else if (fs::is_directory("/dev/shm")) base = "/dev/shm";  // no disk I/O per run
        else base = fs::temp_directory_path();
        fs::create_directories(base);
        std::string templ = (base / ("shadowcull-fuzz-" + std::to_string(::getpid()) + "-XXXXXX")).string();
        if (!::mkdtemp(templ.data())) {
            std::perror("fuzz: mkdtemp");
            std::abort();  // a harness that cannot write its files would test nothing
        }
        path = templ;
    }
    ~Scratch() {
        std::error_code ec;
        fs::remove_all(path, ec);
    }
};

[[noreturn]] void broken(const char* what, size_t index) {
    std::fprintf(stderr, "fuzz: loader broke its promise: %s (element %zu)\n", what, index);
    std::abort();
}

}  // namespace

void brokenPromise(const char* what) {
    std::fprintf(stderr, "fuzz: broken promise: %s\n", what);
    std::abort();
}

namespace {

uint32_t crc32(const unsigned char* p, size_t n) {
    static const std::array<uint32_t, 256> table = [] {
        std::array<uint32_t, 256> t{};
        for (uint32_t i = 0; i < 256; ++i) {
            uint32_t c = i;
            for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
            t[i] = c;
        }
        return t;
    }();
    uint32_t c = 0xffffffffu;
    for (size_t i = 0; i < n; ++i) c = table[(c ^ p[i]) & 0xff] ^ (c >> 8);
    return c ^ 0xffffffffu;
}

}  // namespace

const std::string& scratchDir() {
    static const Scratch scratch;
    return scratch.path;
}

std::vector<std::string> splitInput(const uint8_t* data, size_t size, size_t count) {
    const std::string_view input(reinterpret_cast<const char*>(data), size), sep(kFuzzSeparator);
    std::vector<std::string> parts;
    for (size_t at = 0; parts.size() < count;) {
        const size_t end = parts.size() + 1 < count ? input.find(sep, at) : std::string_view::npos;
        parts.emplace_back(input.substr(at, end == std::string_view::npos ? std::string_view::npos : end - at));
        if (end == std::string_view::npos) break;
        at = end + sep.size();
    }
    return parts;
}

std::vector<std::string> writeFiles(const std::vector<std::string>& parts, const std::vector<std::string>& names) {
    std::vector<std::string> paths;
    for (size_t i = 0; i < names.size(); ++i) {
        paths.push_back(scratchDir() + "/" + names[i]);
        if (i < parts.size()) std::ofstream(paths.back(), std::ios::binary) << parts[i];
        else std::remove(paths.back().c_str());
    }
    return paths;
}

std::vector<std::string> writeInputFiles(const uint8_t* data, size_t size, const std::vector<std::string>& names) {
    return writeFiles(splitInput(data, size, names.size()), names);
}

std::string withPngCrcsFixed(std::string png) {
    auto* b = reinterpret_cast<unsigned char*>(png.data());
    // Signature (8 bytes), then chunks: length (4, big-endian), type (4), data, CRC (4).
    for (size_t at = 8; at + 12 <= png.size();) {
        const size_t length = size_t(b[at]) << 24 | size_t(b[at + 1]) << 16 | size_t(b[at + 2]) << 8 | b[at + 3];
        if (length > png.size() - at - 12) break;  // truncated: leave it for the reader to find
        const uint32_t crc = crc32(b + at + 4, 4 + length);
        for (int k = 0; k < 4; ++k) b[at + 8 + length + size_t(k)] = (unsigned char)(crc >> (24 - 8 * k));
        at += 12 + length;
    }
    return png;
}

void checkMesh(const shadowcull::Mesh& m) {
    if (m.triangleGroup.size() != m.triangles.size()) broken("one group per triangle", m.triangles.size());
    for (size_t v = 0; v < m.positions.size(); ++v)
        for (int k = 0; k < 3; ++k)
            if (!std::isfinite(m.positions[v][k])) broken("finite vertex positions", v);
    for (size_t t = 0; t < m.triangles.size(); ++t) {
        for (uint32_t i : m.triangles[t])
            if (i >= m.positions.size()) broken("triangle indices within the positions", t);
        if (m.triangleGroup[t] >= m.groups.size()) broken("triangle group within the groups", t);
    }
}

void checkHeightfield(const shadowcull::Heightfield& hf) {
    if (hf.n < 2 || hf.heights.size() != size_t(hf.n) * size_t(hf.n)) broken("n >= 2 and n*n heights", hf.heights.size());
    for (size_t i = 0; i < hf.heights.size(); ++i)
        if (!std::isfinite(hf.heights[i])) broken("finite terrain heights", i);
}
