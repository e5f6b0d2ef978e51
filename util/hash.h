// A 64-bit content hash for change detection (bake --resume): FNV-1a over the bytes, with a
// final avalanche (SplitMix64) so nearby inputs give unrelated values. Not cryptographic.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>

#include <glm/vec3.hpp>

namespace shadowcull {

class Hasher {
public:
    Hasher& bytes(const void* data, size_t n) {
        const auto* p = static_cast<const unsigned char*>(data);
        for (size_t i = 0; i < n; ++i) {
            h_ ^= p[i];
            h_ *= 0x100000001b3ull;
        }
        return *this;
    }
    // One 64-bit word at once: xor, multiply, and a shift that brings the high bits down
    // (a multiply alone only carries bits upward, so two flipped sign bits cancelled).
    // Not bytes()' value for the same word; 8x fewer steps. For bulk data whose hash is
    // not compared with bytes()' (a mesh's arrays: hashing them byte by byte was the last
    // 15 ms of a dense world's scan).
    Hasher& word(uint64_t w) {
        h_ ^= w;
        h_ *= 0x9e3779b97f4a7c15ull;
        h_ ^= h_ >> 29;
        return *this;
    }
    template <class T>
    Hasher& pod(const T& v) {
        return bytes(&v, sizeof v);
    }
    Hasher& str(const std::string& s) { return pod(uint64_t(s.size())).bytes(s.data(), s.size()); }
    Hasher& vec(const glm::dvec3& v) { return pod(v.x).pod(v.y).pod(v.z); }
    uint64_t value() const {
        uint64_t z = h_ + 0x9e3779b97f4a7c15ull;
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    }

private:
    uint64_t h_ = 0xcbf29ce484222325ull;
};

inline std::string hexHash(uint64_t v) {
    static const char* digits = "0123456789abcdef";
    std::string s(16, '0');
    for (int i = 15; i >= 0; --i, v >>= 4) s[size_t(i)] = digits[v & 15];
    return s;
}

}  // namespace shadowcull
