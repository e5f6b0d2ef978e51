// The scene model's own functions: names of lights and chunk files, a transform's checks,
// the heightfield's surface. The readers are in io/.

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <glm/geometric.hpp>

#include "core/limits.h"
#include "core/scene.h"
#include "util/format.h"

namespace fs = std::filesystem;

namespace shadowcull {

const char* lightTypeName(LightType type) {
    switch (type) {
        case LightType::Directional: return "directional";
        case LightType::Point: return "point";
        case LightType::Spot: return "spot";
    }
    return "?";
}

double RowTransform::determinant() const {
    const glm::dvec3& a = rows[0];
    const glm::dvec3& b = rows[1];
    const glm::dvec3& c = rows[2];
    return a.x * (b.y * c.z - b.z * c.y) - a.y * (b.x * c.z - b.z * c.x) + a.z * (b.x * c.y - b.y * c.x);
}

std::string RowTransform::singularReason() const {
    // Scale-invariant: |det| divided by the product of the row lengths is 1 for orthogonal
    // rows of any length and 0 for dependent ones (Hadamard's inequality). An absolute
    // threshold on the determinant would refuse gltfpack's dequantization scales (1e-4 per
    // axis, determinant 1e-13), which are valid and well conditioned.
    const double lengths = glm::length(rows[0]) * glm::length(rows[1]) * glm::length(rows[2]);
    const double det = determinant();
    // Formatted only for a refusal: every placed model is checked.
    auto shape = [&] {
        return "determinant " + formatNumber(det) + ", rows of lengths " + formatNumber(glm::length(rows[0])) + ", " +
               formatNumber(glm::length(rows[1])) + ", " + formatNumber(glm::length(rows[2]));
    };
    if (!(std::isfinite(det) && lengths > 0.0 && std::abs(det) > 1e-9 * lengths))
        return "singular transform (" + shape() + ")";
    // The inverse's entries are cofactors over det; compare without dividing (no overflow).
    const glm::dvec3 &a = rows[0], &b = rows[1], &c = rows[2];
    const glm::dvec3 cofactors[3] = {glm::cross(b, c), glm::cross(c, a), glm::cross(a, b)};
    double largest = 0.0;
    for (const glm::dvec3& k : cofactors) largest = std::max({largest, std::abs(k.x), std::abs(k.y), std::abs(k.z)});
    if (!(largest <= limits::kMaxInverseEntry * std::abs(det)))
        return "transform too thin to place in float geometry (" + shape() + "; its inverse has an entry of " +
               formatNumber(largest / std::abs(det)) + ", above " + formatNumber(limits::kMaxInverseEntry) +
               ": an axis shorter than 1e-10 m per model unit)";
    return "";
}

std::optional<ChunkCoord> parseChunkName(const std::string& fileName) {
    // Exactly 8 hex digits, 'o', ".chunk".
    if (fileName.size() != 15 || fileName.compare(8, 7, "o.chunk") != 0) return std::nullopt;
    auto hex4 = [&](size_t at, int32_t& out) {
        unsigned v = 0;
        for (size_t k = at; k < at + 4; ++k) {
            int c = std::tolower(static_cast<unsigned char>(fileName[k]));
            int d = (c >= '0' && c <= '9') ? c - '0' : (c >= 'a' && c <= 'f') ? c - 'a' + 10 : -1;
            if (d < 0) return false;
            v = v * 16 + unsigned(d);
        }
        out = static_cast<int16_t>(static_cast<uint16_t>(v));  // two's complement
        return true;
    };
    ChunkCoord c;
    if (!hex4(0, c.x) || !hex4(4, c.z)) return std::nullopt;
    return c;
}

std::optional<ChunkCoord> parseChunkArgument(const std::string& argument) {
    std::string file = fs::path(argument).filename().string();
    if (file.size() == 9) file += ".chunk";
    return parseChunkName(file);
}

std::string chunkFileName(ChunkCoord c) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%04x%04xo.chunk", unsigned(uint16_t(c.x)), unsigned(uint16_t(c.z)));
    return buf;
}

int Heightfield::cellOf(double v, double& fraction) const {
    // The estimate (two roundings) can be one cell off next to a sample: the positions decide.
    const double f = std::clamp(v * double(n - 1) / size, 0.0, double(n - 1));
    int i = std::min(int(f), n - 2);
    if (i < n - 2 && sampleAt(i + 1) <= v) ++i;
    else if (i > 0 && v < sampleAt(i)) --i;
    const double x0 = sampleAt(i);
    fraction = std::clamp((v - x0) / (sampleAt(i + 1) - x0), 0.0, 1.0);
    return i;
}

double Heightfield::heightAt(double x, double z) const {
    // The surface is two triangles per cell split along (i,j)-(i+1,j+1), as toMesh() places them.
    double u = 0, v = 0;
    const int i = cellOf(x, u), j = cellOf(z, v);
    double h00 = at(i, j), h10 = at(i + 1, j), h01 = at(i, j + 1), h11 = at(i + 1, j + 1);
    // Triangle (i,j),(i+1,j),(i+1,j+1) holds u >= v; (i,j),(i+1,j+1),(i,j+1) holds v >= u.
    if (u >= v) return h00 + u * (h10 - h00) + v * (h11 - h10);
    return h00 + v * (h01 - h00) + u * (h11 - h01);
}

Mesh Heightfield::toMesh() const {
    Mesh m;
    m.positions.reserve(size_t(n) * size_t(n));
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) m.positions.emplace_back(sampleAt(i), at(i, j), sampleAt(j));
    auto idx = [&](int i, int j) { return uint32_t(j * n + i); };
    for (int j = 0; j + 1 < n; ++j)
        for (int i = 0; i + 1 < n; ++i) {
            // Counter-clockwise seen from +Y: (i,j) -> (i,j+1) -> (i+1,j+1) has normal +Y.
            m.triangles.push_back({idx(i, j), idx(i, j + 1), idx(i + 1, j + 1)});
            m.triangles.push_back({idx(i, j), idx(i + 1, j + 1), idx(i + 1, j)});
        }
    m.triangleGroup.assign(m.triangles.size(), 0);
    m.groups.push_back(PrimitiveGroup{"terrain", false, false, std::nullopt});
    return m;
}

}  // namespace shadowcull
