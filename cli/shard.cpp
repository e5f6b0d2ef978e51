#include "cli/shard.h"

#include <algorithm>
#include <cctype>

#include "core/light_reach.h"

namespace shadowcull::cli {

std::optional<ShardSpec> parseShard(const std::string& text) {
    const size_t slash = text.find('/');
    if (slash == std::string::npos) return std::nullopt;
    auto number = [](const std::string& s) -> std::optional<int> {
        if (s.empty() || s.size() > 6) return std::nullopt;
        for (char ch : s)
            if (!std::isdigit(static_cast<unsigned char>(ch))) return std::nullopt;
        return std::stoi(s);
    };
    const std::optional<int> k = number(text.substr(0, slash)), n = number(text.substr(slash + 1));
    if (!k || !n || *n < 1 || *n > kMaxShards || *k < 1 || *k > *n) return std::nullopt;
    return ShardSpec{*k, *n};
}

double chunkWork(const SpaceSource& space, ChunkCoord c) {
    const ChunkEntry& e = space.chunks().at(c);
    const double objects = double(e.usableObjects) + double(e.triangles) / kTrianglesPerObject;
    // The chunk's column, any height: a light reaches it unless it surely cannot.
    const double size = space.settings().chunkSize;
    Aabb column;
    column.min = glm::dvec3(double(c.x) * size, -1e9, double(c.z) * size);
    column.max = glm::dvec3(double(c.x + 1) * size, 1e9, double(c.z + 1) * size);
    size_t lights = 0;
    for (const Light& L : space.settings().lights) lights += boxBeyondRange(L, column) ? 0 : 1;
    return objects * double(lights) + 1.0;
}

std::vector<std::vector<ChunkCoord>> partitionChunks(const SpaceSource& space, int count) {
    // Consecutive runs of the grid order, cut where the running work crosses each shard's
    // share (a chunk goes to the shard its work's midpoint falls in). A run keeps a
    // shard's windows together: the bake loads each chunk about once and holds two
    // columns of the grid, where scattered chunks would each load a whole window.
    std::vector<std::pair<ChunkCoord, double>> work;
    double total = 0;
    for (const auto& [coord, e] : space.chunks()) {
        work.emplace_back(coord, chunkWork(space, coord));
        total += work.back().second;
    }
    const size_t n = size_t(std::max(count, 1));
    std::vector<std::vector<ChunkCoord>> shards(n);
    double before = 0;
    for (const auto& [coord, w] : work) {
        const double middle = before + w / 2;
        shards[std::min(n - 1, size_t(middle / total * double(n)))].push_back(coord);
        before += w;
    }
    return shards;
}

}  // namespace shadowcull::cli
