#include "cli/shard.h"

#include <algorithm>
#include <cctype>
#include <functional>
#include <queue>

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
    const size_t objects = space.chunks().at(c).usableObjects;
    // The chunk's column, any height: a light reaches it unless it surely cannot.
    const double size = space.settings().chunkSize;
    Aabb column;
    column.min = glm::dvec3(double(c.x) * size, -1e9, double(c.z) * size);
    column.max = glm::dvec3(double(c.x + 1) * size, 1e9, double(c.z + 1) * size);
    size_t lights = 0;
    for (const Light& L : space.settings().lights) lights += boxBeyondRange(L, column) ? 0 : 1;
    return double(objects) * double(lights) + 1.0;
}

std::vector<std::vector<ChunkCoord>> partitionChunks(const SpaceSource& space, int count) {
    std::vector<std::pair<double, ChunkCoord>> work;
    for (const auto& [coord, e] : space.chunks()) work.emplace_back(chunkWork(space, coord), coord);
    // Largest first (longest-processing-time rule); stable, so equal work stays in grid order.
    std::stable_sort(work.begin(), work.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    std::vector<std::vector<ChunkCoord>> shards(size_t(std::max(count, 1)));
    // (work so far, shard): the top is the least loaded, the lowest index among equals.
    using Load = std::pair<double, size_t>;
    std::priority_queue<Load, std::vector<Load>, std::greater<Load>> least;
    for (size_t k = 0; k < shards.size(); ++k) least.push({0.0, k});
    for (const auto& [w, coord] : work) {
        Load l = least.top();
        least.pop();
        shards[l.second].push_back(coord);
        least.push({l.first + w, l.second});
    }
    for (std::vector<ChunkCoord>& s : shards) std::sort(s.begin(), s.end());
    return shards;
}

}  // namespace shadowcull::cli
