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

uint64_t windowInputHash(const Space& space, ChunkCoord centre, const BakeOptions& opt,
                         std::unordered_map<const void*, uint64_t>& cache) {
    const SpaceSettings& S = space.settings;
    Hasher h;
    h.str(kBakeLogicVersion);
    h.pod(opt.useRaycast).pod(opt.useGeometry).pod(opt.raycast.areaSamples).pod(opt.raycast.maxFeatureSamples);
    h.pod(opt.raycast.maxHitsPerRay).pod(opt.useGpu).pod(opt.gpuBaseline).pod(opt.gpuResolution).pod(opt.gpuTerrain);
    h.pod(S.chunkSize).pod(S.terrainTolerance).pod(S.neighbours);
    for (const Light& L : S.lights) {
        h.str(L.name).pod(L.type).vec(L.direction).vec(L.position).pod(L.range).pod(L.coneHalfAngleDeg);
        h.pod(L.bias).pod(L.slopeBias).pod(L.filterRadius);
    }
    h.pod(centre);
    for (int dx = -S.neighbours.left; dx <= S.neighbours.right; ++dx)
        for (int dz = -S.neighbours.bottom; dz <= S.neighbours.top; ++dz) {
            auto it = space.chunks.find({centre.x + dx, centre.z + dz});
            if (it == space.chunks.end()) {
                h.pod(uint8_t(0));
                continue;
            }
            h.pod(uint8_t(1)).pod(it->second.coord);
            for (const ChunkObject& o : it->second.objects) {
                h.pod(o.kind).pod(o.elementIndex).str(o.resource).str(o.uuid).pod(o.castsShadow).pod(o.skipped);
                for (const glm::dvec3& r : o.transform.rows) h.vec(r);
                const void* key = o.mesh ? static_cast<const void*>(o.mesh.get()) : static_cast<const void*>(o.heightfield.get());
                if (!key) continue;
                auto found = cache.find(key);
                if (found == cache.end())
                    found = cache.emplace(key, o.mesh ? meshHash(*o.mesh) : heightfieldHash(*o.heightfield)).first;
                h.pod(found->second);
            }
        }
    return h.value();
}

std::string ResumeState::pathIn(const std::string& dir) { return (fs::path(dir) / ".shadowcull-bake-state.json").string(); }

void ResumeState::load(const std::string& path) {
    entries_.clear();
    Expected<std::string> text = readRegularFile(path, "bake state");  // never a FIFO to wait on
    if (!text) return;
    try {
        nlohmann::json j = nlohmann::json::parse(*text);
        for (const auto& [chunk, e] : j.at("chunks").items())
            entries_[chunk] = Entry{std::stoull(e.at("input").get<std::string>(), nullptr, 16),
                                    std::stoull(e.at("output").get<std::string>(), nullptr, 16)};
    } catch (const std::exception&) {
        entries_.clear();  // unreadable: bake everything again
    }
}

bool ResumeState::upToDate(const std::string& chunk, uint64_t inputHash, const std::string& currentBytes) const {
    auto it = entries_.find(chunk);
    return it != entries_.end() && it->second.input == inputHash &&
           it->second.output == Hasher().str(currentBytes).value();
}

void ResumeState::record(const std::string& chunk, uint64_t inputHash, const std::string& writtenBytes) {
    entries_[chunk] = Entry{inputHash, Hasher().str(writtenBytes).value()};
}

Status ResumeState::save(const std::string& path) const {
    nlohmann::json j;
    j["format"] = "shadowcull-bake-state";
    j["version"] = 1;
    nlohmann::json chunks = nlohmann::json::object();
    for (const auto& [chunk, e] : entries_) chunks[chunk] = {{"input", hexHash(e.input)}, {"output", hexHash(e.output)}};
    j["chunks"] = chunks;
    return writeFileAtomic(path, j.dump(1) + "\n");
}

}  // namespace shadowcull::cli
