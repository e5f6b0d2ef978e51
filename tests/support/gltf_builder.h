// Writes glTF 2.0 test files: a document and its binary buffer built in memory (GltfBuilder),
// loaded through the mesh loader; shared by the glTF loader's tests (mesh_gltf_test.cpp,
// mesh_gltf_pipeline_test.cpp).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <meshoptimizer.h>
#include <nlohmann/json.hpp>

#include "core/mesh.h"
#include "io/mesh_load.h"
#include "tests/test_files.h"

namespace shadowcull::testing::gltf {

// What the glTF loader's tests use besides the builder: `using namespace
// shadowcull::testing::gltf` is their whole preamble.
using nlohmann::json;
using shadowcull::testing::freshTestDir;
using shadowcull::testing::readText;
using shadowcull::testing::writeText;
namespace fs = std::filesystem;

inline std::string base64(const std::vector<uint8_t>& d) {
    static const char* alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    for (size_t i = 0; i < d.size(); i += 3) {
        uint32_t v = uint32_t(d[i]) << 16;
        if (i + 1 < d.size()) v |= uint32_t(d[i + 1]) << 8;
        if (i + 2 < d.size()) v |= d[i + 2];
        out += alphabet[(v >> 18) & 63];
        out += alphabet[(v >> 12) & 63];
        out += i + 1 < d.size() ? alphabet[(v >> 6) & 63] : '=';
        out += i + 2 < d.size() ? alphabet[v & 63] : '=';
    }
    return out;
}

inline void appendU32(std::string& s, uint32_t v) {
    for (int k = 0; k < 4; ++k) s += char((v >> (8 * k)) & 0xff);
}

// Assembles a glTF document and its one binary buffer (plus, once a view is compressed,
// the EXT_meshopt_compression fallback buffer 1, which holds no data).
struct GltfBuilder {
    std::vector<uint8_t> bin;
    json doc = {{"asset", {{"version", "2.0"}}}};
    size_t fallbackLength = 0;

    json fallbackBuffer() const {
        return {{"byteLength", fallbackLength}, {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}};
    }
    void requireExtension(const std::string& name) {
        for (const char* list : {"extensionsUsed", "extensionsRequired"}) {
            json& l = doc[list];
            if (std::find(l.begin(), l.end(), name) == l.end()) l.push_back(name);
        }
    }
    // A view of `count` elements of `stride` bytes compressed with EXT_meshopt_compression by
    // libmeshoptimizer's encoder: the compressed bytes in buffer 0, the view itself on the
    // fallback buffer 1, as gltfpack writes it. Indices (TRIANGLES, INDICES) are 2 or 4
    // bytes each in `raw`.
    size_t addMeshoptView(const std::vector<uint8_t>& raw, size_t count, size_t stride, const std::string& mode,
                          const std::string& filter = "NONE") {
        std::vector<uint8_t> packed;
        if (mode == "ATTRIBUTES") {
            packed.resize(meshopt_encodeVertexBufferBound(count, stride));
            packed.resize(meshopt_encodeVertexBuffer(packed.data(), packed.size(), raw.data(), count, stride));
        } else {
            std::vector<uint32_t> ix(count);
            for (size_t k = 0; k < count; ++k)
                for (size_t b = 0; b < stride; ++b) ix[k] |= uint32_t(raw[k * stride + b]) << (8 * b);
            uint32_t vertices = 0;
            for (uint32_t i : ix) vertices = std::max(vertices, i + 1);
            if (mode == "TRIANGLES") {
                packed.resize(meshopt_encodeIndexBufferBound(count, vertices));
                packed.resize(meshopt_encodeIndexBuffer(packed.data(), packed.size(), ix.data(), count));
            } else {
                packed.resize(meshopt_encodeIndexSequenceBound(count, vertices));
                packed.resize(meshopt_encodeIndexSequence(packed.data(), packed.size(), ix.data(), count));
            }
        }
        while (bin.size() % 4) bin.push_back(0);
        json ext = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", packed.size()}, {"byteStride", stride},
                    {"count", count}, {"mode", mode}};
        if (filter != "NONE") ext["filter"] = filter;
        bin.insert(bin.end(), packed.begin(), packed.end());
        json view = {{"buffer", 1}, {"byteOffset", fallbackLength}, {"byteLength", count * stride},
                     {"extensions", {{"EXT_meshopt_compression", ext}}}};
        if (mode == "ATTRIBUTES") view["byteStride"] = stride;
        fallbackLength += (count * stride + 3) / 4 * 4;
        doc["bufferViews"].push_back(view);
        requireExtension("EXT_meshopt_compression");
        return doc["bufferViews"].size() - 1;
    }

    size_t addView(const void* data, size_t bytes, size_t stride = 0) {
        while (bin.size() % 4) bin.push_back(0);
        json view = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes}};
        if (stride) view["byteStride"] = stride;
        bin.insert(bin.end(), static_cast<const uint8_t*>(data), static_cast<const uint8_t*>(data) + bytes);
        doc["bufferViews"].push_back(view);
        return doc["bufferViews"].size() - 1;
    }
    size_t addAccessor(size_t view, int componentType, size_t count, const char* type) {
        doc["accessors"].push_back({{"bufferView", view}, {"componentType", componentType}, {"count", count}, {"type", type}});
        return doc["accessors"].size() - 1;
    }
    size_t addPositions(const std::vector<glm::vec3>& p) {
        return addAccessor(addView(p.data(), p.size() * sizeof(glm::vec3)), 5126, p.size(), "VEC3");
    }
    size_t addIndices(const std::vector<uint32_t>& ix, int componentType = 5125) {
        const size_t size = componentType == 5121 ? 1 : componentType == 5123 ? 2 : 4;
        std::vector<uint8_t> bytes;
        for (uint32_t i : ix)
            for (size_t k = 0; k < size; ++k) bytes.push_back(uint8_t(i >> (8 * k)));
        return addAccessor(addView(bytes.data(), bytes.size()), componentType, ix.size(), "SCALAR");
    }
    size_t addMesh(json primitives) {
        doc["meshes"].push_back({{"primitives", std::move(primitives)}});
        return doc["meshes"].size() - 1;
    }
    size_t addNode(json node) {
        doc["nodes"].push_back(std::move(node));
        return doc["nodes"].size() - 1;
    }

    std::string gltf() const {
        json d = doc;
        d["buffers"] = {{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}};
        if (fallbackLength) d["buffers"].push_back(fallbackBuffer());
        return d.dump(2);
    }
    std::string glb() const {
        json d = doc;
        d["buffers"] = {{{"byteLength", bin.size()}}};
        if (fallbackLength) d["buffers"].push_back(fallbackBuffer());
        std::string text = d.dump();
        while (text.size() % 4) text += ' ';
        std::string data(bin.begin(), bin.end());
        while (data.size() % 4) data += '\0';
        std::string out = "glTF";
        appendU32(out, 2);
        appendU32(out, uint32_t(12 + 8 + text.size() + 8 + data.size()));
        appendU32(out, uint32_t(text.size()));
        appendU32(out, 0x4E4F534A);  // JSON
        out += text;
        appendU32(out, uint32_t(data.size()));
        appendU32(out, 0x004E4942);  // BIN
        return out + data;
    }
};

inline Expected<Mesh> loadString(const std::string& content, const std::string& name = "m.gltf") {
    fs::path p = freshTestDir() / name;
    writeText(p, content);
    return loadGltf(p.string());
}

inline const std::vector<glm::vec3> kTriangle = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};          // CCW seen from +z
inline const std::vector<glm::vec3> kQuad = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};  // CCW seen from +z

inline glm::dvec3 normalOf(const Mesh& m, size_t t) {
    const auto& tri = m.triangles[t];
    const glm::dvec3 a = m.positions[tri[0]], b = m.positions[tri[1]], c = m.positions[tri[2]];
    return glm::normalize(glm::cross(b - a, c - a));
}

// A scene with one node drawing a one-triangle mesh, with node properties `node`.
inline GltfBuilder oneTriangle(json node = json::object()) {
    GltfBuilder b;
    b.addMesh({{{"attributes", {{"POSITION", b.addPositions(kTriangle)}}}}});
    node["mesh"] = 0;
    b.addNode(node);
    b.doc["scenes"] = {{{"nodes", {0}}}};
    return b;
}

inline void expectError(const Expected<Mesh>& m, const std::string& fragment, ErrorKind kind = ErrorKind::BadInput) {
    ASSERT_FALSE(m) << "expected an error containing '" << fragment << "'";
    EXPECT_EQ(m.error().kind, kind) << m.error().what();
    EXPECT_NE(m.error().what().find(fragment), std::string::npos) << m.error().what();
    EXPECT_NE(m.error().what().find("m.gl"), std::string::npos) << "error must name the file: " << m.error().what();
}

}  // namespace shadowcull::testing::gltf
