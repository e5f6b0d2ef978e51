// glTF 2.0 loader on what asset pipelines write: KHR_mesh_quantization, sparse accessors,
// EXT_meshopt_compression (streams made with libmeshoptimizer's encoder, and whole files
// made by gltfpack when it is installed) and KHR_draco_mesh_compression (libdraco's encoder).

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>

#include <gtest/gtest.h>

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <meshoptimizer.h>
#include <nlohmann/json.hpp>

#include "core/mesh.h"
#include "io/gltf_document.h"
#include "io/mesh_load.h"
#include "tests/support/gltf_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing::gltf;  // the builder, json, fs and the test-file helpers

namespace {

template <class T>
std::vector<uint8_t> bytesOf(const std::vector<T>& v) {
    std::vector<uint8_t> out(v.size() * sizeof(T));
    std::memcpy(out.data(), v.data(), out.size());
    return out;
}

std::vector<uint8_t> indexBytes(const std::vector<uint32_t>& ix, size_t size) {
    std::vector<uint8_t> out;
    for (uint32_t i : ix)
        for (size_t k = 0; k < size; ++k) out.push_back(uint8_t(i >> (8 * k)));
    return out;
}

using Triangle = std::array<glm::dvec3, 3>;

std::vector<Triangle> trianglesOf(const Mesh& m) {
    std::vector<Triangle> out;
    for (const auto& t : m.triangles) out.push_back({m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]});
    return out;
}

double extentOf(const std::vector<Triangle>& tris) {
    glm::dvec3 lo(1e300), hi(-1e300);
    for (const Triangle& t : tris)
        for (const glm::dvec3& p : t) lo = glm::min(lo, p), hi = glm::max(hi, p);
    return std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
}

// The same set of triangles in space, each within `tol` per corner, in any order and any
// cyclic rotation of its corners (so with the same winding).
void expectSameTriangles(const std::vector<Triangle>& expected, const std::vector<Triangle>& actual, double tol) {
    ASSERT_EQ(actual.size(), expected.size());
    std::vector<bool> used(actual.size(), false);
    size_t unmatched = 0;
    for (size_t e = 0; e < expected.size(); ++e) {
        bool found = false;
        for (size_t a = 0; a < actual.size() && !found; ++a) {
            if (used[a]) continue;
            for (int r = 0; r < 3 && !found; ++r) {
                bool same = true;
                for (int c = 0; c < 3 && same; ++c)
                    same = glm::length(expected[e][size_t(c)] - actual[a][size_t((c + r) % 3)]) <= tol;
                if (same) found = used[a] = true;
            }
        }
        if (!found && ++unmatched <= 3) ADD_FAILURE() << "triangle " << e << " has no counterpart within " << tol;
    }
    EXPECT_EQ(unmatched, 0u);
}

// A wavy 9 x 7 grid (96 triangles, no two alike) facing +z, with 16-bit indices.
void addWavyGrid(GltfBuilder& b, size_t& positions, size_t& indices) {
    std::vector<glm::vec3> p;
    const int nx = 9, ny = 7;
    for (int y = 0; y < ny; ++y)
        for (int x = 0; x < nx; ++x)
            p.push_back({float(x) * 0.5f, float(y) * 0.4f, 0.3f * std::sin(float(x)) * std::cos(0.7f * float(y))});
    std::vector<uint32_t> ix;
    for (int y = 0; y + 1 < ny; ++y)
        for (int x = 0; x + 1 < nx; ++x) {
            const uint32_t a = uint32_t(y * nx + x), c = a + uint32_t(nx);
            ix.insert(ix.end(), {a, a + 1, c + 1, a, c + 1, c});
        }
    positions = b.addPositions(p);
    indices = b.addIndices(ix, 5123);
}

// The scene the gltfpack and Draco tests start from: the grid drawn by three nodes (one
// rotated and scaled, one mirrored) and a box with 32-bit indices.
GltfBuilder pipelineScene() {
    GltfBuilder b;
    size_t grid, gridIx;
    addWavyGrid(b, grid, gridIx);
    const std::vector<glm::vec3> box = {{0, 0, 0}, {1, 0, 0}, {1, 2, 0}, {0, 2, 0}, {0, 0, 3}, {1, 0, 3}, {1, 2, 3}, {0, 2, 3}};
    const size_t boxPos = b.addPositions(box);
    const size_t boxIx = b.addIndices({0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                       1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7});
    b.doc["materials"] = {{{"name", "ground"}}, {{"name", "box"}, {"doubleSided", true}}};
    b.addMesh({{{"attributes", {{"POSITION", grid}}}, {"indices", gridIx}, {"material", 0}}});
    b.addMesh({{{"attributes", {{"POSITION", boxPos}}}, {"indices", boxIx}, {"material", 1}}});
    const double h = std::sqrt(0.5);
    b.addNode({{"mesh", 0}, {"translation", {1, 2, 3}}, {"rotation", {h, 0, 0, h}}, {"scale", {2, 2, 2}}});
    b.addNode({{"mesh", 0}, {"scale", {-1, 1, 1}}, {"translation", {-1, 0, 0}}});
    b.addNode({{"mesh", 1}, {"translation", {4, 0, -2}}});
    b.doc["scenes"] = {{{"nodes", {0, 1, 2}}}};
    return b;
}

bool haveGltfpack() { return std::system("command -v gltfpack > /dev/null 2>&1") == 0; }

}  // namespace

TEST(MeshGltf, QuantizedPositionsOfEveryComponentType) {
    // Components c as stored, and what they mean unnormalized and normalized.
    struct Case {
        int componentType;
        std::vector<int> c;
        std::vector<double> normalized;
    };
    const std::vector<Case> cases = {
        {5120, {-128, -127, 0, 1, 64, 127, -5, 3, 100}, {-1.0, -1.0, 0, 1 / 127.0, 64 / 127.0, 1.0, -5 / 127.0, 3 / 127.0, 100 / 127.0}},
        {5121, {0, 255, 1, 128, 7, 200, 10, 20, 30}, {0, 1.0, 1 / 255.0, 128 / 255.0, 7 / 255.0, 200 / 255.0, 10 / 255.0, 20 / 255.0, 30 / 255.0}},
        {5122, {-32768, -32767, 0, 1, 32767, 1000, -7, 300, 9}, {-1.0, -1.0, 0, 1 / 32767.0, 1.0, 1000 / 32767.0, -7 / 32767.0, 300 / 32767.0, 9 / 32767.0}},
        {5123, {0, 65535, 1, 40000, 2, 3, 500, 600, 700}, {0, 1.0, 1 / 65535.0, 40000 / 65535.0, 2 / 65535.0, 3 / 65535.0, 500 / 65535.0, 600 / 65535.0, 700 / 65535.0}},
    };
    for (const Case& k : cases) {
        for (bool normalized : {false, true}) {
            SCOPED_TRACE(std::to_string(k.componentType) + (normalized ? " normalized" : ""));
            // Three VEC3 elements, each padded to 4-byte alignment as gltfpack writes them.
            const size_t size = k.componentType <= 5121 ? 1 : 2, stride = size == 1 ? 4 : 8;
            std::vector<uint8_t> bytes(3 * stride, 0xEE);
            for (size_t e = 0; e < 3; ++e)
                for (size_t c = 0; c < 3; ++c)
                    for (size_t byte = 0; byte < size; ++byte)
                        bytes[e * stride + c * size + byte] = uint8_t(uint32_t(k.c[e * 3 + c]) >> (8 * byte));
            GltfBuilder b;
            const size_t pos = b.addAccessor(b.addView(bytes.data(), bytes.size(), stride), k.componentType, 3, "VEC3");
            if (normalized) b.doc["accessors"][pos]["normalized"] = true;
            b.addMesh({{{"attributes", {{"POSITION", pos}}}}});
            b.addNode({{"mesh", 0}});
            b.requireExtension("KHR_mesh_quantization");
            auto m = loadString(b.gltf());
            ASSERT_TRUE(m) << m.error().what();
            ASSERT_EQ(m->positions.size(), 3u);
            for (size_t e = 0; e < 3; ++e)
                for (int c = 0; c < 3; ++c) {
                    const size_t i = e * 3 + size_t(c);
                    EXPECT_DOUBLE_EQ(m->positions[e][c], normalized ? k.normalized[i] : double(k.c[i])) << e << "," << c;
                }
        }
    }
}

TEST(MeshGltf, GltfpackStyleDequantizationInTheNodeTransform) {
    // Unnormalized 14-bit UNSIGNED_SHORT positions; the node scales them back to metres.
    const std::vector<uint16_t> q = {0, 0, 0, 0, 16383, 0, 0, 0, 0, 16383, 0, 0};
    GltfBuilder b;
    const size_t pos = b.addAccessor(b.addView(q.data(), q.size() * 2, 8), 5123, 3, "VEC3");
    b.addMesh({{{"attributes", {{"POSITION", pos}}}}});
    const double s = 2.0 / 16383;
    b.addNode({{"mesh", 0}, {"translation", {-1, 5, 0}}, {"scale", {s, s, s}}});
    b.requireExtension("KHR_mesh_quantization");
    auto m = loadString(b.glb(), "m.glb");
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->triangles.size(), 1u);
    const std::vector<Triangle> want = {{glm::dvec3(-1, 5, 0), glm::dvec3(1, 5, 0), glm::dvec3(-1, 7, 0)}};
    expectSameTriangles(want, trianglesOf(*m), 1e-12);
}

TEST(MeshGltf, SparseAccessorOverridesPositionsAndIndices) {
    for (int indexType : {5121, 5123, 5125}) {
        SCOPED_TRACE(indexType);
        GltfBuilder b;
        const size_t pos = b.addPositions(kQuad);
        // Elements 1 and 3 moved up by 10 in z.
        const std::vector<glm::vec3> moved = {{1, 0, 10}, {0, 1, 10}};
        const std::vector<uint8_t> which = indexBytes({1, 3}, indexType == 5121 ? 1 : indexType == 5123 ? 2 : 4);
        const size_t ixView = b.addView(which.data(), which.size());
        const size_t valView = b.addView(moved.data(), moved.size() * sizeof(glm::vec3));
        b.doc["accessors"][pos]["sparse"] = {{"count", 2},
                                             {"indices", {{"bufferView", ixView}, {"componentType", indexType}}},
                                             {"values", {{"bufferView", valView}}}};
        // Indices {0, 1, 2, 0, 2, 2} with the last one made 3 by a sparse substitution.
        const size_t ix = b.addIndices({0, 1, 2, 0, 2, 2}, 5123);
        const std::vector<uint8_t> last = {5}, three = {3, 0};
        b.doc["accessors"][ix]["sparse"] = {{"count", 1},
                                            {"indices", {{"bufferView", b.addView(last.data(), 1)}, {"componentType", 5121}}},
                                            {"values", {{"bufferView", b.addView(three.data(), 2)}}}};
        b.addMesh({{{"attributes", {{"POSITION", pos}}}, {"indices", ix}}});
        b.addNode({{"mesh", 0}});
        auto m = loadString(b.gltf());
        ASSERT_TRUE(m) << m.error().what();
        ASSERT_EQ(m->positions.size(), 4u);
        EXPECT_EQ(m->positions[0], glm::dvec3(0, 0, 0));
        EXPECT_EQ(m->positions[1], glm::dvec3(1, 0, 10));
        EXPECT_EQ(m->positions[2], glm::dvec3(1, 1, 0));
        EXPECT_EQ(m->positions[3], glm::dvec3(0, 1, 10));
        ASSERT_EQ(m->triangles.size(), 2u);
        EXPECT_EQ(m->triangles[1], (std::array<uint32_t, 3>{0, 2, 3}));
    }
    {  // Without a bufferView: zeros, then the substitutions (byteOffset honoured).
        GltfBuilder b;
        const std::vector<uint8_t> which = {0xAA, 1, 2};
        const std::vector<glm::vec3> values = {{9, 9, 9}, {1, 0, 0}, {0, 1, 0}};
        const size_t ixView = b.addView(which.data(), which.size());
        const size_t valView = b.addView(values.data(), values.size() * sizeof(glm::vec3));
        b.doc["accessors"].push_back({{"componentType", 5126}, {"count", 3}, {"type", "VEC3"},
                                      {"sparse", {{"count", 2},
                                                  {"indices", {{"bufferView", ixView}, {"byteOffset", 1}, {"componentType", 5121}}},
                                                  {"values", {{"bufferView", valView}, {"byteOffset", 12}}}}}});
        b.addMesh({{{"attributes", {{"POSITION", 0}}}}});
        b.addNode({{"mesh", 0}});
        auto m = loadString(b.gltf());
        ASSERT_TRUE(m) << m.error().what();
        ASSERT_EQ(m->positions.size(), 3u);
        EXPECT_EQ(m->positions[0], glm::dvec3(0, 0, 0));
        EXPECT_EQ(m->positions[1], glm::dvec3(1, 0, 0));
        EXPECT_EQ(m->positions[2], glm::dvec3(0, 1, 0));
    }
}

TEST(MeshGltf, SparseAccessorErrorsNameThePath) {
    // A sparse accessor over the triangle: indices {i0, i1} (UNSIGNED_BYTE), 2 values.
    auto sparse = [](std::vector<uint8_t> which, json changes = json::object()) {
        GltfBuilder b = oneTriangle();
        const std::vector<glm::vec3> values = {{5, 5, 5}, {6, 6, 6}};
        const size_t ixView = b.addView(which.data(), which.size());
        const size_t valView = b.addView(values.data(), values.size() * sizeof(glm::vec3));
        json sp = {{"count", 2}, {"indices", {{"bufferView", ixView}, {"componentType", 5121}}}, {"values", {{"bufferView", valView}}}};
        sp.merge_patch(changes);
        b.doc["accessors"][0]["sparse"] = sp;
        return loadString(b.gltf());
    };
    ASSERT_TRUE(sparse({0, 2}));
    expectError(sparse({0, 3}), "accessors[0].sparse.indices: index 3 at element 1 is out of range (accessors[0] has 3 elements)");
    expectError(sparse({2, 1}), "accessors[0].sparse.indices: index 1 at element 1 does not follow 2");
    expectError(sparse({1, 1}), "accessors[0].sparse.indices: index 1 at element 1 does not follow 1");
    expectError(sparse({0, 1}, {{"count", 4}}), "accessors[0].sparse.count: 4 substitutions for 3 elements");
    expectError(sparse({0, 1}, {{"count", 0}}), "accessors[0].sparse.count: at least 1 expected");
    expectError(sparse({0, 1}, {{"indices", {{"componentType", 5126}}}}), "accessors[0].sparse.indices.componentType: 5126");
    expectError(sparse({0, 1}, {{"indices", {{"byteOffset", 1}}}}),
                "accessors[0].sparse.indices: 2 elements of 1 bytes from byte offset 37 of buffers[0] run past the end of bufferViews[1]");
    expectError(sparse({0, 1}, {{"values", {{"byteOffset", 4}}}}), "accessors[0].sparse.values: 2 elements of 12 bytes");
    expectError(sparse({0, 1}, {{"values", {{"bufferView", 9}}}}), "accessors[0].sparse.values: bufferViews[9] does not exist");
}

TEST(MeshGltf, MeshoptCompressedVertexAndIndexViews) {
    // The wavy grid, its positions and indices compressed, against the same file plain.
    GltfBuilder plain;
    size_t pos, ix;
    addWavyGrid(plain, pos, ix);
    plain.addMesh({{{"attributes", {{"POSITION", pos}}}, {"indices", ix}}});
    plain.addNode({{"mesh", 0}});
    auto want = loadString(plain.gltf());
    ASSERT_TRUE(want) << want.error().what();

    for (int indexSize : {2, 4}) {
        for (const char* indexMode : {"TRIANGLES", "INDICES"}) {
            SCOPED_TRACE(std::string(indexMode) + " " + std::to_string(indexSize));
            GltfBuilder b;
            const json& views = plain.doc["bufferViews"];
            auto viewBytes = [&](size_t v) {
                const size_t off = views[v]["byteOffset"], len = views[v]["byteLength"];
                return std::vector<uint8_t>(plain.bin.begin() + long(off), plain.bin.begin() + long(off + len));
            };
            const size_t count = plain.doc["accessors"][pos]["count"];
            const size_t pv = b.addMeshoptView(viewBytes(0), count, 12, "ATTRIBUTES");
            std::vector<uint32_t> indices;
            const std::vector<uint8_t> ib = viewBytes(1);
            for (size_t k = 0; k + 1 < ib.size(); k += 2) indices.push_back(uint32_t(ib[k] | ib[k + 1] << 8));
            const size_t iv = b.addMeshoptView(indexBytes(indices, size_t(indexSize)), indices.size(), size_t(indexSize), indexMode);
            const size_t pa = b.addAccessor(pv, 5126, count, "VEC3");
            const size_t ia = b.addAccessor(iv, indexSize == 2 ? 5123 : 5125, indices.size(), "SCALAR");
            b.addMesh({{{"attributes", {{"POSITION", pa}}}, {"indices", ia}}});
            b.addNode({{"mesh", 0}});
            // Lossless: the same positions, and the same triangles in the same order (the
            // triangle codec may rotate a triangle's corners, keeping its winding).
            auto expectSame = [&](const Mesh& m) {
                EXPECT_EQ(m.positions, want->positions);
                ASSERT_EQ(m.triangles.size(), want->triangles.size());
                for (size_t t = 0; t < m.triangles.size(); ++t) {
                    const auto& a = m.triangles[t];
                    const auto& e = want->triangles[t];
                    bool same = false;
                    for (size_t r = 0; r < 3; ++r) same = same || (a[r] == e[0] && a[(r + 1) % 3] == e[1] && a[(r + 2) % 3] == e[2]);
                    EXPECT_TRUE(same) << "triangle " << t;
                }
            };
            for (bool glb : {false, true}) {
                auto m = glb ? loadString(b.glb(), "m.glb") : loadString(b.gltf());
                ASSERT_TRUE(m) << m.error().what();
                expectSame(*m);
            }
            // The fallback buffer is never read, even when it names a file that is not there.
            json d = json::parse(b.gltf());
            d["buffers"][1]["uri"] = "missing.bin";
            auto withUri = loadString(d.dump());
            ASSERT_TRUE(withUri) << withUri.error().what();
            expectSame(*withUri);
        }
    }
}

TEST(MeshGltf, MeshoptFiltersDecode) {
    const std::vector<float> unit = {1, 0, 0, 0, 0, 1, 0, 0, 0.6f, 0.8f, 0, 0};  // 3 unit vectors + w
    {  // EXPONENTIAL: float positions with 15-bit mantissas.
        // The filter shares one exponent per element, so the precision is relative to the
        // element's largest component.
        const std::vector<float> p = {0.1f, -2.5f, 3.0f, 1, 0, 0, 0, 100, 1e-3f};
        std::vector<uint8_t> encoded(p.size() * 4);
        meshopt_encodeFilterExp(encoded.data(), 3, 12, 15, p.data());
        std::vector<uint8_t> expected = encoded;
        meshopt_decodeFilterExp(expected.data(), 3, 12);
        GltfBuilder b;
        const size_t pos = b.addAccessor(b.addMeshoptView(encoded, 3, 12, "ATTRIBUTES", "EXPONENTIAL"), 5126, 3, "VEC3");
        b.addMesh({{{"attributes", {{"POSITION", pos}}}}});
        b.addNode({{"mesh", 0}});
        auto m = loadString(b.gltf());
        ASSERT_TRUE(m) << m.error().what();
        ASSERT_EQ(m->positions.size(), 3u);
        for (size_t k = 0; k < 9; ++k) {
            float f;
            std::memcpy(&f, expected.data() + 4 * k, 4);
            EXPECT_EQ(m->positions[k / 3][int(k % 3)], double(f)) << k;
            const float largest = std::max({std::abs(p[k / 3 * 3]), std::abs(p[k / 3 * 3 + 1]), std::abs(p[k / 3 * 3 + 2])});
            EXPECT_NEAR(m->positions[k / 3][int(k % 3)], p[k], 1e-3 * largest) << k;
        }
    }
    {  // OCTAHEDRAL: unit vectors as normalized BYTE, 4-byte stride.
        std::vector<uint8_t> encoded(3 * 4);
        meshopt_encodeFilterOct(encoded.data(), 3, 4, 8, unit.data());
        GltfBuilder b;
        const size_t pos = b.addAccessor(b.addMeshoptView(encoded, 3, 4, "ATTRIBUTES", "OCTAHEDRAL"), 5120, 3, "VEC3");
        b.doc["accessors"][pos]["normalized"] = true;
        b.requireExtension("KHR_mesh_quantization");  // BYTE positions
        b.addMesh({{{"attributes", {{"POSITION", pos}}}}});
        b.addNode({{"mesh", 0}});
        auto m = loadString(b.gltf());
        ASSERT_TRUE(m) << m.error().what();
        ASSERT_EQ(m->positions.size(), 3u);
        for (size_t k = 0; k < 3; ++k)
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(m->positions[k][c], unit[k * 4 + size_t(c)], 0.02) << k << "," << c;
    }
}

TEST(MeshGltf, MeshoptErrorsNameThePath) {
    // One compressed position view (view 0) under the triangle.
    auto compressed = [](const std::function<void(json& doc)>& edit, bool badHeader = false) {
        GltfBuilder b;
        const size_t pos = b.addAccessor(b.addMeshoptView(bytesOf(kTriangle), 3, 12, "ATTRIBUTES"), 5126, 3, "VEC3");
        b.addMesh({{{"attributes", {{"POSITION", pos}}}}});
        b.addNode({{"mesh", 0}});
        edit(b.doc);
        if (badHeader) b.bin[0] = 0x42;  // the stream's first byte: 0xa0 for this codec
        return loadString(b.gltf());
    };
    const std::string ext = "bufferViews[0].extensions.EXT_meshopt_compression";
    ASSERT_TRUE(compressed([](json&) {}));
    // A truncated compressed stream: the decoder runs out of input.
    expectError(compressed([&](json& d) { d["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["byteLength"] = 20; }),
                ext + ": the compressed ATTRIBUTES data (20 bytes at byte offset 0 of buffers[0]) does not decode (meshoptimizer error");
    // Bytes that are not a meshopt stream (bad header byte).
    expectError(compressed([](json&) {}, true), ext + ": the compressed ATTRIBUTES data");
    expectError(compressed([&](json& d) { d["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["filter"] = "SHARPEN"; }),
                ext + ".filter: 'SHARPEN' is not NONE, OCTAHEDRAL, QUATERNION or EXPONENTIAL");
    expectError(compressed([&](json& d) { d["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["filter"] = "QUATERNION"; }),
                ext + ".byteStride: 12 does not suit filter QUATERNION (8 expected)");
    expectError(compressed([&](json& d) { d["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["mode"] = "VERTICES"; }),
                ext + ".mode: 'VERTICES' is not ATTRIBUTES, TRIANGLES or INDICES");
    expectError(compressed([&](json& d) { d["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["mode"] = "TRIANGLES"; }),
                ext + ".byteStride: 12 (TRIANGLES needs 2 or 4)");
    expectError(compressed([&](json& d) { d["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["byteStride"] = 16; }),
                "bufferViews[0].byteStride: 12 differs from the extension's byteStride 16");
    expectError(compressed([&](json& d) { d["bufferViews"][0]["byteLength"] = 40; }),
                ext + ": count 3 x byteStride 12 is not bufferViews[0].byteLength 40");
    expectError(compressed([&](json& d) { d["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["byteLength"] = 4000; }),
                ext + ": bytes 0..4000 lie outside buffers[0]");
    // A decoded-size bomb: 2^28 elements claimed from a few dozen compressed bytes.
    expectError(compressed([&](json& d) {
                    const uint64_t count = uint64_t(1) << 28;
                    d["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["count"] = count;
                    d["bufferViews"][0]["byteLength"] = count * 12;
                    d["accessors"][0]["count"] = count;
                }),
                ext + ": 268435456 elements of 12 bytes (3221225472 bytes) cannot come from");
    // A plain view may not name the fallback buffer.
    expectError(compressed([&](json& d) { d["bufferViews"][0].erase("extensions"); }),
                "bufferViews[0]: buffers[1] is an EXT_meshopt_compression fallback buffer");
    // The draft name of the extension.
    expectError(compressed([&](json& d) {
                    d["bufferViews"][0]["extensions"]["MESHOPT_compression"] = d["bufferViews"][0]["extensions"]["EXT_meshopt_compression"];
                    d["bufferViews"][0]["extensions"].erase("EXT_meshopt_compression");
                }),
                "bufferViews[0]: MESHOPT_compression (the draft of EXT_meshopt_compression) is not supported");
}

TEST(MeshGltf, MeshoptViewsSharingCompressedBytesCannotAddUp) {
    // 40 views each claim (within 64:1 of it) the same ~2 KB of compressed zeros: one by one
    // each is plausible, together they would be 64 times more than the file holds.
    GltfBuilder b;
    const size_t count = 2048;
    const size_t first = b.addMeshoptView(std::vector<uint8_t>(count * 12, 0), count, 12, "ATTRIBUTES");
    json prims = json::array();
    for (int k = 0; k < 40; ++k) {
        if (k > 0) b.doc["bufferViews"].push_back(b.doc["bufferViews"][first]);
        const size_t pos = b.addAccessor(b.doc["bufferViews"].size() - 1, 5126, count - 2, "VEC3");
        prims.push_back({{"attributes", {{"POSITION", pos}}}});
    }
    b.addMesh(prims);
    b.addNode({{"mesh", 0}});
    expectError(loadString(b.glb(), "m.glb"), "bufferViews[1].extensions.EXT_meshopt_compression: with its 24576 bytes the decoded views would hold 49152 bytes, more than 64 times");
}

TEST(MeshGltf, GltfpackOutputGivesTheSameTriangles) {
    if (!haveGltfpack()) GTEST_SKIP() << "gltfpack is not installed (Debian package gltfpack; scripts/install-deps.sh installs it)";
    const fs::path dir = freshTestDir();
    GltfBuilder b = pipelineScene();
    writeText(dir / "in.bin", std::string(b.bin.begin(), b.bin.end()));
    json d = b.doc;
    d["buffers"] = {{{"byteLength", b.bin.size()}, {"uri", "in.bin"}}};
    writeText(dir / "in.gltf", d.dump(1));
    auto want = loadGltf((dir / "in.gltf").string());
    ASSERT_TRUE(want) << want.error().what();
    const std::vector<Triangle> wantTris = trianglesOf(*want);
    const double tol = 1e-3 * extentOf(wantTris);

    struct Variant {
        std::string flags;
        std::vector<std::string> required;  // extensionsRequired of the output
    };
    const std::vector<Variant> variants = {
        {"-c", {"EXT_meshopt_compression", "KHR_mesh_quantization"}},
        {"-cc", {"EXT_meshopt_compression", "KHR_mesh_quantization"}},
        {"-c -noq", {"EXT_meshopt_compression"}},
        {"-c -vpn", {"EXT_meshopt_compression", "KHR_mesh_quantization"}},
        {"-c -vp 16", {"EXT_meshopt_compression", "KHR_mesh_quantization"}},
        {"-cf", {"KHR_mesh_quantization"}},  // compressed, with an uncompressed fallback
        {"", {"KHR_mesh_quantization"}},     // quantized only
    };
    int n = 0;
    for (const Variant& v : variants) {
        SCOPED_TRACE("gltfpack " + v.flags);
        const fs::path out = dir / ("out" + std::to_string(n++) + ".glb");
        const std::string cmd = "gltfpack -i '" + (dir / "in.gltf").string() + "' -o '" + out.string() + "' " + v.flags +
                                " > '" + (dir / "gltfpack.log").string() + "' 2>&1";
        ASSERT_EQ(std::system(cmd.c_str()), 0) << readText(dir / "gltfpack.log");
        auto doc = GltfDocument::open(out.string());
        ASSERT_TRUE(doc) << doc.error().what();
        for (const std::string& e : v.required) {
            const json& required = doc->json().value("extensionsRequired", json::array());
            EXPECT_NE(std::find(required.begin(), required.end(), e), required.end()) << e << " in " << required.dump();
        }
        auto got = loadGltf(out.string());
        ASSERT_TRUE(got) << got.error().what();
        expectSameTriangles(wantTris, trianglesOf(*got), tol);
    }
}

namespace {

// The wavy grid's triangles as one Draco mesh (positions quantized to 16 bits), and what
// it decodes to: glTF accessors must state the decoded counts.
struct DracoGrid {
    std::vector<char> bytes;
    uint32_t positionId = 0;
    uint32_t points = 0, faces = 0;
};

DracoGrid encodeDracoGrid(const Mesh& plain) {
    draco::TriangleSoupMeshBuilder builder;
    builder.Start(int(plain.triangles.size()));
    const int att = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
    for (size_t f = 0; f < plain.triangles.size(); ++f) {
        glm::vec3 c[3];
        for (int k = 0; k < 3; ++k) c[k] = glm::vec3(plain.positions[plain.triangles[f][size_t(k)]]);
        builder.SetAttributeValuesForFace(att, draco::FaceIndex(uint32_t(f)), &c[0].x, &c[1].x, &c[2].x);
    }
    std::unique_ptr<draco::Mesh> mesh = builder.Finalize();
    draco::Encoder encoder;
    encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, 16);
    draco::EncoderBuffer buffer;
    EXPECT_TRUE(encoder.EncodeMeshToBuffer(*mesh, &buffer).ok());
    DracoGrid out;
    out.bytes.assign(buffer.data(), buffer.data() + buffer.size());
    out.positionId = mesh->attribute(att)->unique_id();
    draco::DecoderBuffer in;
    in.Init(out.bytes.data(), out.bytes.size());
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&in);
    EXPECT_TRUE(decoded.ok());
    out.points = decoded.value()->num_points();
    out.faces = decoded.value()->num_faces();
    return out;
}

// A file whose one primitive is the Draco grid (accessors without bufferViews).
GltfBuilder dracoFile(const DracoGrid& g) {
    GltfBuilder b;
    const size_t view = b.addView(g.bytes.data(), g.bytes.size());
    b.doc["accessors"].push_back({{"componentType", 5126}, {"count", g.points}, {"type", "VEC3"}});
    b.doc["accessors"].push_back({{"componentType", 5125}, {"count", 3 * g.faces}, {"type", "SCALAR"}});
    b.addMesh({{{"attributes", {{"POSITION", 0}}},
                {"indices", 1},
                {"extensions", {{"KHR_draco_mesh_compression", {{"bufferView", view}, {"attributes", {{"POSITION", g.positionId}}}}}}}}});
    b.addNode({{"mesh", 0}, {"translation", {1, 2, 3}}});
    b.requireExtension("KHR_draco_mesh_compression");
    return b;
}

}  // namespace

TEST(MeshGltf, DracoCompressedPrimitive) {
    GltfBuilder plain;
    size_t pos, ix;
    addWavyGrid(plain, pos, ix);
    plain.addMesh({{{"attributes", {{"POSITION", pos}}}, {"indices", ix}}});
    plain.addNode({{"mesh", 0}});
    auto local = loadString(plain.gltf());
    ASSERT_TRUE(local) << local.error().what();
    std::vector<Triangle> wantTris = trianglesOf(*local);
    for (Triangle& t : wantTris)
        for (glm::dvec3& p : t) p += glm::dvec3(1, 2, 3);  // dracoFile's node translation

    const DracoGrid g = encodeDracoGrid(*local);
    auto m = loadString(dracoFile(g).glb(), "m.glb");
    ASSERT_TRUE(m) << m.error().what();
    EXPECT_EQ(m->positions.size(), g.points);
    expectSameTriangles(wantTris, trianglesOf(*m), 1e-3 * extentOf(wantTris));

    const std::string ext = "meshes[0].primitives[0].extensions.KHR_draco_mesh_compression";
    {  // corrupt: cut short
        GltfBuilder b = dracoFile(g);
        b.doc["bufferViews"][0]["byteLength"] = g.bytes.size() / 2;
        expectError(loadString(b.gltf()), ext + ": the Draco data of bufferViews[0] does not decode");
    }
    {  // not Draco data at all
        GltfBuilder b = dracoFile(g);
        std::fill(b.bin.begin(), b.bin.begin() + 8, uint8_t('x'));
        expectError(loadString(b.gltf()), ext + ": the Draco data of bufferViews[0] does not decode");
    }
    {
        GltfBuilder b = dracoFile(g);
        b.doc["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"]["POSITION"] = 7;
        expectError(loadString(b.gltf()), ext + ": the Draco data of bufferViews[0] has no attribute with unique id 7 (attributes.POSITION)");
    }
    {
        GltfBuilder b = dracoFile(g);
        b.doc["accessors"][0]["count"] = g.points + 1;
        expectError(loadString(b.gltf()), "accessors[0].count: " + std::to_string(g.points + 1) + ", but the Draco data");
        b = dracoFile(g);
        b.doc["accessors"][1]["count"] = 3;
        expectError(loadString(b.gltf()), "accessors[1].count: 3, but the Draco data");
    }
    {
        GltfBuilder b = dracoFile(g);
        b.doc["meshes"][0]["primitives"][0]["mode"] = 5;
        expectError(loadString(b.gltf()), "meshes[0].primitives[0].mode: 5 with KHR_draco_mesh_compression is not supported");
    }
}

// A few kilobytes whose primitives all name one big accessor (here one of zeros, without
// bufferView) must not make the loader decode a copy per primitive until memory runs out:
// decoding stops at 64 elements per byte of input, with the JSON path.
TEST(MeshGltf, AccessorsSharedByManyPrimitivesCannotExhaustMemory) {
    json doc = {{"asset", {{"version", "2.0"}}},
                {"accessors", json::array({{{"componentType", 5126}, {"count", 999999}, {"type", "VEC3"}}})},
                {"nodes", json::array({{{"mesh", 0}}})},
                {"scenes", json::array({{{"nodes", json::array({0})}}})}};
    json prims = json::array();
    for (int k = 0; k < 1000; ++k) prims.push_back({{"attributes", {{"POSITION", 0}}}});
    doc["meshes"] = json::array({{{"primitives", prims}}});
    const fs::path dir = freshTestDir();
    writeText(dir / "bomb.gltf", doc.dump());
    Expected<Mesh> mesh = loadGltf((dir / "bomb.gltf").string());
    ASSERT_FALSE(mesh);
    EXPECT_NE(mesh.error().message.find("more than 64 per byte"), std::string::npos) << mesh.error().what();
    EXPECT_NE(mesh.error().message.find("accessors[0]"), std::string::npos) << mesh.error().what();
}
