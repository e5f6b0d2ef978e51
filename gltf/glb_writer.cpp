#include "gltf/glb_writer.h"

#include <algorithm>
#include <cstring>
#include <limits>

#include <nlohmann/json.hpp>

namespace shadowcull::gltf {

namespace {

using nlohmann::json;

void appendU32(std::string& s, uint32_t v) {
    for (int k = 0; k < 4; ++k) s += char((v >> (8 * k)) & 0xff);
}

void appendF32(std::string& s, float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    appendU32(s, u);
}

constexpr uint32_t kChunkJson = 0x4E4F534A;  // "JSON"
constexpr uint32_t kChunkBin = 0x004E4942;   // "BIN\0"

}  // namespace

std::string glbContainer(const std::string& jsonText, const std::string* bin,
                         const std::vector<std::pair<uint32_t, std::string>>& otherChunks) {
    std::string body;
    auto chunk = [&](uint32_t type, const std::string& data, char pad) {
        const size_t padded = (data.size() + 3) / 4 * 4;
        appendU32(body, uint32_t(padded));
        appendU32(body, type);
        body += data;
        body.append(padded - data.size(), pad);
    };
    chunk(kChunkJson, jsonText, ' ');
    if (bin) chunk(kChunkBin, *bin, '\0');
    for (const auto& [type, data] : otherChunks) chunk(type, data, '\0');
    std::string out = "glTF";
    appendU32(out, 2);
    appendU32(out, uint32_t(12 + body.size()));
    return out + body;
}

std::string meshGlb(const std::vector<GltfPrimitive>& primitives, const std::string& meshName) {
    json doc = {{"asset", {{"version", "2.0"}, {"generator", "shadowcull import"}}},
                {"scene", 0},
                {"scenes", json::array({{{"nodes", json::array({0})}}})},
                {"nodes", json::array({{{"mesh", 0}}})}};
    std::string bin;
    json views = json::array(), accessors = json::array(), materials = json::array(), prims = json::array();
    auto addView = [&](const std::string& bytes, bool indices) {
        while (bin.size() % 4) bin += '\0';
        json v = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes.size()}};
        v["target"] = indices ? 34963 : 34962;
        bin += bytes;
        views.push_back(v);
        return views.size() - 1;
    };
    for (const GltfPrimitive& p : primitives) {
        // One point when the primitive has no triangles (points, lines, empty): it keeps
        // its group number and casts nothing.
        const bool points = p.triangles.empty();
        std::string pos;
        float lo[3] = {std::numeric_limits<float>::max(), std::numeric_limits<float>::max(), std::numeric_limits<float>::max()};
        float hi[3] = {-lo[0], -lo[1], -lo[2]};
        const size_t vertexCount = points ? 1 : p.positions.size();
        for (size_t k = 0; k < vertexCount; ++k) {
            const glm::dvec3 q = p.positions.empty() ? glm::dvec3(0.0) : p.positions[k];
            for (int c = 0; c < 3; ++c) {
                const float f = float(q[c]);
                appendF32(pos, f);
                lo[c] = std::min(lo[c], f);
                hi[c] = std::max(hi[c], f);
            }
        }
        const size_t posView = addView(pos, false);
        accessors.push_back({{"bufferView", posView},
                             {"componentType", 5126},
                             {"count", vertexCount},
                             {"type", "VEC3"},
                             {"min", {lo[0], lo[1], lo[2]}},
                             {"max", {hi[0], hi[1], hi[2]}}});
        json prim = {{"attributes", {{"POSITION", accessors.size() - 1}}}, {"material", materials.size()}};
        if (points) {
            prim["mode"] = 0;
        } else {
            std::string idx;
            for (const auto& t : p.triangles)
                for (uint32_t i : t) appendU32(idx, i);
            const size_t idxView = addView(idx, true);
            accessors.push_back({{"bufferView", idxView}, {"componentType", 5125}, {"count", p.triangles.size() * 3}, {"type", "SCALAR"}});
            prim["indices"] = accessors.size() - 1;
        }
        json material = {{"name", p.group.name}, {"doubleSided", p.group.doubleSided}};
        if (p.group.alphaTested) material["alphaMode"] = "MASK";
        materials.push_back(material);
        prims.push_back(prim);
    }
    json mesh = {{"primitives", prims}};
    if (!meshName.empty()) mesh["name"] = meshName;
    doc["meshes"] = json::array({mesh});
    doc["materials"] = materials;
    doc["accessors"] = accessors;
    doc["bufferViews"] = views;
    doc["buffers"] = json::array({{{"byteLength", bin.size()}}});
    return glbContainer(doc.dump(), &bin);
}

}  // namespace shadowcull::gltf
