#include "cli/resume.h"

#include "core/file_read.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "cli/pipeline.h"
#include "core/chunk_writer.h"
#include "core/file_read.h"
#include "core/hash.h"

namespace fs = std::filesystem;

namespace shadowcull::cli {

namespace {

// Bumped whenever a change to the tool may change verdicts for the same input.
constexpr const char* kBakeLogicVersion = "shadowcull-bake-2";

uint64_t meshHash(const Mesh& m) {
    Hasher h;
    h.pod(uint64_t(m.positions.size()));
    for (const glm::dvec3& p : m.positions) h.vec(p);
    h.pod(uint64_t(m.triangles.size()));
    for (size_t t = 0; t < m.triangles.size(); ++t) h.pod(m.triangles[t]).pod(m.triangleGroup[t]);
    for (const PrimitiveGroup& g : m.groups) h.pod(g.alphaTested).pod(g.doubleSided);
    return h.value();
}

uint64_t heightfieldHash(const Heightfield& hf) {
    Hasher h;
    h.pod(hf.n).pod(hf.size);
    h.bytes(hf.heights.data(), hf.heights.size() * sizeof(double));
    return h.value();
}

}  // namespace

namespace {

// The settings, lights and the bake options that change verdicts.
void hashSettings(Hasher& h, const SpaceSettings& S, const BakeOptions& opt) {
    h.str(kBakeLogicVersion);
    h.pod(opt.useRaycast).pod(opt.useGeometry).pod(opt.raycast.areaSamples).pod(opt.raycast.maxFeatureSamples);
    h.pod(opt.raycast.maxHitsPerRay).pod(opt.useGpu).pod(opt.gpuBaseline).pod(opt.gpuResolution).pod(opt.gpuTerrain);
    h.pod(S.chunkSize).pod(S.terrainTolerance).pod(S.neighbours);
    for (const Light& L : S.lights) {
        h.str(L.name).pod(L.type).vec(L.direction).vec(L.position).pod(L.range).pod(L.coneHalfAngleDeg);
        h.pod(L.bias).pod(L.slopeBias).pod(L.filterRadius);
    }
}

// One chunk's objects: placement, flags, and the content of each mesh or heightfield.
void hashChunk(Hasher& h, const ChunkFile& cf, std::unordered_map<const void*, uint64_t>& cache) {
    h.pod(uint8_t(1)).pod(cf.coord);
    for (const ChunkObject& o : cf.objects) {
        h.pod(o.kind).pod(o.elementIndex).str(o.resource).str(o.uuid).pod(o.castsShadow).pod(o.skipped);
        for (const glm::dvec3& r : o.transform.rows) h.vec(r);
        const void* key = o.mesh ? static_cast<const void*>(o.mesh.get()) : static_cast<const void*>(o.heightfield.get());
        if (!key) continue;
        auto found = cache.find(key);
        if (found == cache.end()) found = cache.emplace(key, o.mesh ? meshHash(*o.mesh) : heightfieldHash(*o.heightfield)).first;
        h.pod(found->second);
    }
}

}  // namespace

uint64_t windowInputHash(const Space& space, ChunkCoord centre, const BakeOptions& opt,
                         std::unordered_map<const void*, uint64_t>& cache) {
    const SpaceSettings& S = space.settings;
    Hasher h;
    hashSettings(h, S, opt);
    h.pod(centre);
    for (int dx = -S.neighbours.left; dx <= S.neighbours.right; ++dx)
        for (int dz = -S.neighbours.bottom; dz <= S.neighbours.top; ++dz) {
            auto it = space.chunks.find({centre.x + dx, centre.z + dz});
            if (it == space.chunks.end()) {
                h.pod(uint8_t(0));
                continue;
            }
            hashChunk(h, it->second, cache);
        }
    return h.value();
}

uint64_t spaceInputHash(const Space& space, const BakeOptions& opt, std::unordered_map<const void*, uint64_t>& cache) {
    Hasher h;
    hashSettings(h, space.settings, opt);
    h.str(space.settings.spaceDir);  // the results name it
    h.pod(uint64_t(space.chunks.size()));
    for (const auto& [coord, cf] : space.chunks) {
        hashChunk(h, cf, cache);
        h.pod(cf.contentHash);  // the text each shard rewrites
    }
    return h.value();
}

std::string ResumeState::nameFor(int shardIndex, int shardCount) {
    if (shardCount <= 0) return ".shadowcull-bake-state.json";
    return ".shadowcull-bake-state.shard-" + std::to_string(shardIndex) + "-of-" + std::to_string(shardCount) + ".json";
}

std::string ResumeState::pathIn(const std::string& dir, int shardIndex, int shardCount) {
    return (fs::path(dir) / nameFor(shardIndex, shardCount)).string();
}

void ResumeState::load(const std::string& path) {
    entries_.clear();
    Expected<std::string> text = readRegularFile(path, "bake state");  // never a FIFO to wait on
    if (!text) return;
    try {
        nlohmann::json j = nlohmann::json::parse(*text);
        for (const auto& [chunk, e] : j.at("chunks").items())
            entries_[chunk] = Entry{std::stoull(e.at("input").get<std::string>(), nullptr, 16),
                                    std::stoull(e.at("output").get<std::string>(), nullptr, 16),
                                    e.contains("results") ? e["results"].get<std::string>() : std::string()};
    } catch (const std::exception&) {
        entries_.clear();  // unreadable: bake everything again
    }
}

bool ResumeState::upToDate(const std::string& chunk, uint64_t inputHash, const std::string& currentBytes,
                           bool needResults) const {
    auto it = entries_.find(chunk);
    return it != entries_.end() && it->second.input == inputHash &&
           it->second.output == Hasher().str(currentBytes).value() && (!needResults || !it->second.results.empty());
}

const std::string& ResumeState::results(const std::string& chunk) const {
    static const std::string none;
    auto it = entries_.find(chunk);
    return it == entries_.end() ? none : it->second.results;
}

void ResumeState::record(const std::string& chunk, uint64_t inputHash, const std::string& writtenBytes,
                         std::string resultsJson) {
    entries_[chunk] = Entry{inputHash, Hasher().str(writtenBytes).value(), std::move(resultsJson)};
}

Status ResumeState::save(const std::string& path) const {
    nlohmann::json j;
    j["format"] = "shadowcull-bake-state";
    j["version"] = 1;
    nlohmann::json chunks = nlohmann::json::object();
    for (const auto& [chunk, e] : entries_) {
        chunks[chunk] = {{"input", hexHash(e.input)}, {"output", hexHash(e.output)}};
        if (!e.results.empty()) chunks[chunk]["results"] = e.results;
    }
    j["chunks"] = chunks;
    return writeFileAtomic(path, j.dump(1) + "\n");
}

}  // namespace shadowcull::cli
