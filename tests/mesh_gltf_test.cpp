// glTF 2.0 loader: groups per primitive in document order, materials, node transforms
// (including mirroring), primitive modes, index types, .glb and external buffers, and
// errors for truncated or inconsistent files. Test files are written by the tests.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>

#include <gtest/gtest.h>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>

#include "core/mesh.h"
#include "io/gltf_document.h"
#include "io/mesh_load.h"
#include "tests/support/gltf_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing::gltf;  // the builder, json, fs and the test-file helpers

namespace {

// Two meshes, three primitives; node 0 draws mesh 1 so that node order differs from mesh order.
GltfBuilder threePrimitives() {
    GltfBuilder b;
    const size_t tri = b.addPositions(kTriangle), quad = b.addPositions(kQuad);
    b.addMesh({{{"attributes", {{"POSITION", tri}}}, {"indices", b.addIndices({0, 1, 2})}},
               {{"attributes", {{"POSITION", quad}}}, {"indices", b.addIndices({0, 1, 2, 0, 2, 3}, 5123)}}});
    b.addMesh({{{"attributes", {{"POSITION", tri}}}}});
    b.addNode({{"mesh", 1}});
    b.addNode({{"mesh", 0}});
    b.doc["scenes"] = {{{"nodes", {0, 1}}}};
    b.doc["scene"] = 0;
    return b;
}

void expectThreePrimitives(const Mesh& m) {
    ASSERT_EQ(m.groups.size(), 3u);
    EXPECT_EQ(m.groups[0].name, "mesh0/primitive0");
    EXPECT_EQ(m.groups[1].name, "mesh0/primitive1");
    EXPECT_EQ(m.groups[2].name, "mesh1/primitive0");
    EXPECT_EQ(m.triangleGroup, (std::vector<uint32_t>{2, 0, 1, 1}));
    ASSERT_EQ(m.triangles.size(), 4u);
    for (size_t t = 0; t < 4; ++t) EXPECT_NEAR(normalOf(m, t).z, 1.0, 1e-12) << t;
    for (const PrimitiveGroup& g : m.groups) EXPECT_FALSE(g.twoSided());
}

}  // namespace

TEST(MeshGltf, GroupsArePrimitivesInDocumentOrder) {
    auto m = loadString(threePrimitives().gltf());
    ASSERT_TRUE(m) << m.error().what();
    expectThreePrimitives(*m);
}

TEST(MeshGltf, GlbGivesTheSameMesh) {
    auto m = loadString(threePrimitives().glb(), "m.glb");
    ASSERT_TRUE(m) << m.error().what();
    expectThreePrimitives(*m);
}

TEST(MeshGltf, ExternalBufferRelativeToTheFile) {
    GltfBuilder b = threePrimitives();
    fs::path dir = freshTestDir();
    writeText(dir / "data" / "my buf.bin", std::string(b.bin.begin(), b.bin.end()));
    b.doc["buffers"] = {{{"byteLength", b.bin.size()}, {"uri", "data/my%20buf.bin"}}};
    writeText(dir / "m.gltf", b.doc.dump());
    auto m = loadGltf((dir / "m.gltf").string());
    ASSERT_TRUE(m) << m.error().what();
    expectThreePrimitives(*m);

    fs::remove(dir / "data" / "my buf.bin");
    expectError(loadGltf((dir / "m.gltf").string()), "my buf.bin", ErrorKind::MissingResource);
}

// Issue 35: a buffer uri that is absolute or climbs out of the scene's directory was read
// (/etc/passwd as a buffer). Refused at its JSON path, whether the file exists or not; a
// uri that goes down and back up inside the directory is fine.
TEST(MeshGltf, BufferFilesOutsideTheScenesDirectoryAreRefused) {
    GltfBuilder b = threePrimitives();
    const fs::path dir = freshTestDir();
    const std::string bytes(b.bin.begin(), b.bin.end());
    writeText(dir / "outside.bin", bytes);
    writeText(dir / "scene" / "data" / "in.bin", bytes);
    for (const std::string& uri : std::vector<std::string>{"../outside.bin", "data/../../outside.bin", (dir / "outside.bin").string(), "%2E%2E/outside.bin"}) {
        SCOPED_TRACE(uri);
        b.doc["buffers"] = {{{"byteLength", b.bin.size()}, {"uri", uri}}};
        writeText(dir / "scene" / "m.gltf", b.doc.dump());
        expectError(loadGltf((dir / "scene" / "m.gltf").string()), "buffers[0].uri: '" + uri + "' lies outside the scene's directory");
    }
    b.doc["buffers"] = {{{"byteLength", b.bin.size()}, {"uri", "data/../data/in.bin"}}};
    writeText(dir / "scene" / "m.gltf", b.doc.dump());
    auto m = loadGltf((dir / "scene" / "m.gltf").string());
    ASSERT_TRUE(m) << m.error().what();
    expectThreePrimitives(*m);
}

TEST(MeshGltf, MaterialsGiveAlphaTestAndDoubleSided) {
    GltfBuilder b;
    const size_t p = b.addPositions(kTriangle);
    b.doc["materials"] = {{{"alphaMode", "MASK"}, {"alphaCutoff", 0.5}},
                          {{"alphaMode", "BLEND"}},
                          {{"alphaMode", "OPAQUE"}, {"doubleSided", true}},
                          json::object()};
    json prims = json::array();
    for (int mat = 0; mat < 4; ++mat) prims.push_back({{"attributes", {{"POSITION", p}}}, {"material", mat}});
    prims.push_back({{"attributes", {{"POSITION", p}}}});  // no material
    b.addMesh(prims);
    auto m = loadString(b.gltf());  // no nodes: groups exist, no triangles
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->groups.size(), 5u);
    EXPECT_TRUE(m->triangles.empty());
    EXPECT_TRUE(m->groups[0].alphaTested);
    EXPECT_TRUE(m->groups[1].alphaTested);
    EXPECT_FALSE(m->groups[2].alphaTested);
    EXPECT_TRUE(m->groups[2].doubleSided);
    EXPECT_FALSE(m->groups[3].twoSided());
    EXPECT_FALSE(m->groups[4].twoSided());
    EXPECT_FALSE(m->groups[0].doubleSided);

    b.doc["materials"][0]["alphaMode"] = "CLIP";
    expectError(loadString(b.gltf()), "materials[0].alphaMode");
}

TEST(MeshGltf, NodeTransformsAreApplied) {
    GltfBuilder b;
    b.addMesh({{{"attributes", {{"POSITION", b.addPositions(kTriangle)}}}}});
    // Parent translation, child scale: world = T * S.
    b.addNode({{"translation", {10, 0, 0}}, {"children", {1}}});
    b.addNode({{"scale", {2, 3, 4}}, {"mesh", 0}});
    // TRS on one node: scale, then rotate 90 degrees about +y, then translate.
    const double h = std::sqrt(0.5);
    b.addNode({{"translation", {0, 5, 0}}, {"rotation", {0, h, 0, h}}, {"scale", {2, 2, 2}}, {"mesh", 0}});
    // Column-major matrix: translation in elements 12..14.
    b.addNode({{"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 7, 8, 9, 1}}, {"mesh", 0}});
    b.doc["scenes"] = {{{"nodes", {0, 2, 3}}}};
    auto m = loadString(b.gltf());
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->positions.size(), 9u);
    ASSERT_EQ(m->triangles.size(), 3u);
    auto at = [&](size_t tri, int corner) { return m->positions[m->triangles[tri][size_t(corner)]]; };
    auto near = [](glm::dvec3 a, glm::dvec3 b) { return glm::length(a - b) < 1e-6; };
    EXPECT_TRUE(near(at(0, 1), {12, 0, 0}));
    EXPECT_TRUE(near(at(0, 2), {10, 3, 0}));
    EXPECT_TRUE(near(at(1, 0), {0, 5, 0}));
    EXPECT_TRUE(near(at(1, 1), {0, 5, -2}));  // +x rotated 90 degrees about +y is -z
    EXPECT_TRUE(near(at(1, 2), {0, 7, 0}));
    EXPECT_TRUE(near(at(2, 1), {8, 8, 9}));
    for (size_t t = 0; t < 3; ++t) EXPECT_EQ(m->triangleGroup[t], 0u);
}

TEST(MeshGltf, MirroringNodeKeepsFrontFacesFront) {
    // The triangle faces +z; mirrored in x it still faces +z (normals transform by the
    // inverse transpose), which needs the winding flipped.
    for (json node : {json{{"scale", {-1, 1, 1}}}, json{{"matrix", {-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}}}) {
        auto m = loadString(oneTriangle(node).gltf());
        ASSERT_TRUE(m) << m.error().what();
        ASSERT_EQ(m->triangles.size(), 1u);
        EXPECT_NEAR(m->positions[1].x, -1.0, 1e-12);
        EXPECT_NEAR(normalOf(*m, 0).z, 1.0, 1e-12) << node.dump();
    }
    // Mirroring in z turns the front towards -z; two mirrors cancel.
    auto z = loadString(oneTriangle({{"scale", {1, 1, -1}}}).gltf());
    ASSERT_TRUE(z) << z.error().what();
    EXPECT_NEAR(normalOf(*z, 0).z, -1.0, 1e-12);
    auto twice = loadString(oneTriangle({{"scale", {-1, -1, 1}}}).gltf());
    ASSERT_TRUE(twice) << twice.error().what();
    EXPECT_EQ(twice->triangles[0], (std::array<uint32_t, 3>{0, 1, 2}));
    EXPECT_NEAR(normalOf(*twice, 0).z, 1.0, 1e-12);
}

TEST(MeshGltf, PrimitiveDrawnByTwoNodesFillsOneGroup) {
    GltfBuilder b = oneTriangle();
    b.addNode({{"mesh", 0}, {"translation", {0, 0, 5}}});
    b.doc["scenes"][0]["nodes"] = {0, 1};
    auto m = loadString(b.gltf());
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->groups.size(), 1u);
    ASSERT_EQ(m->triangles.size(), 2u);
    EXPECT_EQ(m->triangleGroup, (std::vector<uint32_t>{0, 0}));
    EXPECT_EQ(m->positions[m->triangles[1][0]], glm::dvec3(0, 0, 5));
}

TEST(MeshGltf, SceneSelection) {
    GltfBuilder b;
    b.addMesh({{{"attributes", {{"POSITION", b.addPositions(kTriangle)}}}}});
    b.addNode({{"mesh", 0}, {"children", {1}}});
    b.addNode({{"mesh", 0}, {"translation", {1, 0, 0}}});
    b.addNode({{"mesh", 0}, {"translation", {2, 0, 0}}});
    // No scenes: every root node (0 with its child 1, and 2).
    auto all = loadString(b.gltf());
    ASSERT_TRUE(all) << all.error().what();
    EXPECT_EQ(all->triangles.size(), 3u);
    // `scene` picks the default scene; without it scenes[0].
    b.doc["scenes"] = {{{"nodes", {2}}}, {{"nodes", {0}}}};
    auto first = loadString(b.gltf());
    ASSERT_TRUE(first) << first.error().what();
    ASSERT_EQ(first->triangles.size(), 1u);
    EXPECT_EQ(first->positions[0], glm::dvec3(2, 0, 0));
    b.doc["scene"] = 1;
    auto second = loadString(b.gltf());
    ASSERT_TRUE(second) << second.error().what();
    EXPECT_EQ(second->triangles.size(), 2u);
    b.doc["scene"] = 2;
    expectError(loadString(b.gltf()), "scenes[2] does not exist");
    // Node 1 with two parents is not a tree.
    b.doc.erase("scene");
    b.doc["nodes"][2]["children"] = {1};
    expectError(loadString(b.gltf()), "nodes[1] has more than one parent");
}

TEST(MeshGltf, StripAndFanKeepWinding) {
    GltfBuilder b;
    const size_t strip = b.addPositions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0, 2, 0}});
    const size_t fan = b.addPositions({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {-1, 1, 0}});
    b.addMesh({{{"attributes", {{"POSITION", strip}}}, {"mode", 5}},
               {{"attributes", {{"POSITION", fan}}}, {"mode", 6}},
               {{"attributes", {{"POSITION", fan}}}, {"mode", 5}, {"indices", b.addIndices({1, 2, 0, 3}, 5121)}}});
    b.addNode({{"mesh", 0}});
    auto m = loadString(b.gltf());
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->triangles.size(), 3u + 3u + 2u);
    EXPECT_EQ(m->triangleGroup, (std::vector<uint32_t>{0, 0, 0, 1, 1, 1, 2, 2}));
    for (size_t t = 0; t < m->triangles.size(); ++t) EXPECT_NEAR(normalOf(*m, t).z, 1.0, 1e-12) << t;
    EXPECT_EQ(m->triangles[1], (std::array<uint32_t, 3>{1, 3, 2}));   // odd strip triangle swaps
    EXPECT_EQ(m->triangles[3], (std::array<uint32_t, 3>{6, 7, 5}));   // fan around vertex 0 (5 here)
    EXPECT_EQ(m->triangles[7], (std::array<uint32_t, 3>{12, 13, 10}));  // indexed strip; own copy of positions
}

TEST(MeshGltf, NonIndexedPointsAndLines) {
    GltfBuilder b;
    const size_t six = b.addPositions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {0, 1, 1}});
    b.addMesh({{{"attributes", {{"POSITION", six}}}},
               {{"attributes", {{"POSITION", six}}}, {"mode", 0}},
               {{"attributes", {{"POSITION", six}}}, {"mode", 1}},
               {{"attributes", {{"POSITION", six}}}, {"mode", 3}}});
    b.addNode({{"mesh", 0}});
    auto m = loadString(b.gltf());
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->groups.size(), 4u);
    ASSERT_EQ(m->triangles.size(), 2u);
    EXPECT_EQ(m->triangles[0], (std::array<uint32_t, 3>{0, 1, 2}));
    EXPECT_EQ(m->triangles[1], (std::array<uint32_t, 3>{3, 4, 5}));
    EXPECT_EQ(m->positions.size(), 6u);  // points and lines add no vertices either
}

TEST(MeshGltf, AllIndexTypesAndByteStride) {
    for (int componentType : {5121, 5123, 5125}) {
        GltfBuilder b;
        // Interleaved positions: 12 bytes of position + 4 bytes of something else.
        std::vector<float> interleaved;
        for (const glm::vec3& p : kQuad) interleaved.insert(interleaved.end(), {p.x, p.y, p.z, 99.0f});
        const size_t view = b.addView(interleaved.data(), interleaved.size() * 4, 16);
        const size_t pos = b.addAccessor(view, 5126, 4, "VEC3");
        b.addMesh({{{"attributes", {{"POSITION", pos}}}, {"indices", b.addIndices({3, 0, 1, 3, 1, 2}, componentType)}}});
        b.addNode({{"mesh", 0}});
        auto m = loadString(b.gltf());
        ASSERT_TRUE(m) << componentType << ": " << m.error().what();
        ASSERT_EQ(m->triangles.size(), 2u);
        EXPECT_EQ(m->triangles[0], (std::array<uint32_t, 3>{3, 0, 1}));
        EXPECT_EQ(m->triangles[1], (std::array<uint32_t, 3>{3, 1, 2}));
        EXPECT_EQ(m->positions[2], glm::dvec3(1, 1, 0));
    }
}

TEST(MeshGltf, TruncatedDataIsAnError) {
    {  // accessor needs more bytes than its buffer view has
        GltfBuilder b = oneTriangle();
        b.doc["accessors"][0]["count"] = 4;
        expectError(loadString(b.gltf()), "accessors[0]: 4 elements");
    }
    {  // buffer shorter than its byteLength
        GltfBuilder b = oneTriangle();
        json d = json::parse(b.gltf());
        d["buffers"][0]["byteLength"] = b.bin.size() + 4;
        expectError(loadString(d.dump()), "buffers[0]: byteLength is 40 but only 36 bytes");
    }
    {  // buffer view outside the buffer
        GltfBuilder b = oneTriangle();
        b.doc["bufferViews"][0]["byteOffset"] = 8;
        expectError(loadString(b.gltf()), "bufferViews[0]: bytes 8..44");
    }
    {  // .glb cut short
        std::string glb = oneTriangle().glb();
        expectError(loadString(glb.substr(0, glb.size() - 10), "m.glb"), "truncated");
        expectError(loadString(glb.substr(0, 10), "m.glb"), "truncated");
        expectError(loadString(glb.substr(0, 3), "m.glb"), "not a GLB file");
        // Header length made consistent with the cut file: now the BIN chunk runs past the end.
        std::string cut = glb.substr(0, glb.size() - 8), length;
        appendU32(length, uint32_t(cut.size()));
        cut.replace(8, 4, length);
        expectError(loadString(cut, "m.glb"), "GLB chunk of 36 bytes runs past the end");
    }
    {  // triangle list whose index count is not a multiple of 3
        GltfBuilder b;
        b.addMesh({{{"attributes", {{"POSITION", b.addPositions(kQuad)}}}, {"indices", b.addIndices({0, 1, 2, 0})}}});
        b.addNode({{"mesh", 0}});
        expectError(loadString(b.gltf()), "do not make whole triangles");
    }
}

TEST(MeshGltf, BadJsonGivesLineNumber) {
    const std::string text = "{\n  \"asset\": {\"version\": \"2.0\"},\n  \"meshes\": [\n    {\"primitives\": [}]\n  ]\n}\n";
    auto m = loadString(text);
    ASSERT_FALSE(m);
    EXPECT_EQ(m.error().kind, ErrorKind::BadInput);
    EXPECT_EQ(m.error().line, 4) << m.error().what();
    EXPECT_NE(m.error().what().find("m.gltf:4:"), std::string::npos) << m.error().what();

    auto eof = loadString("{\n  \"asset\": {\n");  // cut off: error at the end, line 3
    ASSERT_FALSE(eof);
    EXPECT_EQ(eof.error().line, 3) << eof.error().what();

    auto newline = loadString("{\n  \"asset\": \"abc\n}\n");  // unterminated string on line 2
    ASSERT_FALSE(newline);
    EXPECT_EQ(newline.error().line, 2) << newline.error().what();
    EXPECT_EQ(newline.error().what().find("line 3"), std::string::npos) << newline.error().what();
}

TEST(MeshGltf, InvalidContentIsAnError) {
    {
        GltfBuilder b;
        b.addMesh({{{"attributes", {{"POSITION", b.addPositions(kTriangle)}}}, {"indices", b.addIndices({0, 1, 3})}}});
        b.addNode({{"mesh", 0}});
        expectError(loadString(b.gltf()), "accessors[1]: index 3 at element 2 is out of range");
    }
    {
        GltfBuilder b = oneTriangle();
        b.doc["accessors"][0]["sparse"] = {{"count", 1}};
        expectError(loadString(b.gltf()), "accessors[0].sparse.indices: object expected");
    }
    {
        GltfBuilder b;
        b.addMesh({{{"attributes", {{"POSITION", b.addPositions({{0, 0, 0}, {1, NAN, 0}, {0, 1, 0}})}}}}});
        b.addNode({{"mesh", 0}});
        expectError(loadString(b.gltf()), "POSITION 1 is not finite");
    }
    {  // FLOAT cannot be normalized; UNSIGNED_INT is no position type, even with KHR_mesh_quantization
        GltfBuilder b = oneTriangle();
        b.doc["accessors"][0]["normalized"] = true;
        expectError(loadString(b.gltf()), "accessors[0].normalized: only BYTE, UNSIGNED_BYTE, SHORT and UNSIGNED_SHORT");
        b.doc["accessors"][0]["normalized"] = false;
        b.doc["accessors"][0]["componentType"] = 5125;
        expectError(loadString(b.gltf()), "accessors[0]: POSITION componentType 5125 (UNSIGNED_INT) is not allowed");
        b.doc["accessors"][0]["normalized"] = "yes";
        expectError(loadString(b.gltf()), "accessors[0].normalized: true or false expected");
    }
    {
        GltfBuilder b = oneTriangle();
        b.doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 7;
        expectError(loadString(b.gltf()), "meshes[0].primitives[0]: accessors[7] does not exist");
    }
    {  // the geometry extensions are read, so requiring them is no error
        GltfBuilder b = oneTriangle();
        b.doc["extensionsRequired"] = {"KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_mesh_quantization"};
        EXPECT_TRUE(loadString(b.gltf()));
    }
    {
        GltfBuilder b = oneTriangle();
        b.doc["accessors"][0]["count"] = -3;
        expectError(loadString(b.gltf()), "accessors[0].count: non-negative integer expected");
    }
    expectError(loadString("[1, 2]"), "top level");
    fs::path dir = freshTestDir();
    auto missing = loadGltf((dir / "m.gltf").string());
    ASSERT_FALSE(missing);
    EXPECT_EQ(missing.error().kind, ErrorKind::MissingResource);
}

// Issue 11: a node scale of 1e20 (finite) used to reach Embree as 1e20-metre triangles and
// abort the process; a mesh whose primitives are empty stopped the whole bake with an
// Embree error naming a chunk. Both are errors of the file now.
TEST(MeshGltf, HugePlacementsAndEmptyMeshesAreErrorsOfTheFile) {
    for (const json& node : {json{{"scale", {1e20, 1, 1}}}, json{{"translation", {0, 2e18, 0}}},
                             json{{"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -1e308, 0, 0, 1}}}}) {
        SCOPED_TRACE(node.dump());
        expectError(loadString(oneTriangle(node).gltf()), "beyond the accepted 100000 m");
    }
    // 1e5 m exactly is accepted: the bound is inclusive.
    EXPECT_TRUE(loadString(oneTriangle({{"translation", {99999, 0, 0}}}).gltf()));

    GltfBuilder none;
    none.addMesh(json::array());
    none.addNode({{"mesh", 0}});
    const fs::path p = freshTestDir() / "m.gltf";
    writeText(p, none.gltf());
    ASSERT_TRUE(loadGltf(p.string()));  // a valid glTF document...
    const Expected<Mesh> m = loadMeshFile(p.string());
    expectError(m, "no triangles");  // ...that no model can be baked from
}

// Issue 35: what the file states but the reader cannot honour is refused at its JSON path,
// never read as something else (a required extension ignored, a matrix's last row
// dropped, TRS dropped beside a matrix, bytes read as positions without the extension that
// makes them positions, a root placed twice).
struct Unhonoured {
    const char* name;
    std::function<void(GltfBuilder&)> edit;
    std::string message;
};

TEST(MeshGltf, WhatTheReaderCannotHonourIsRefusedAtItsJsonPath) {
    const std::vector<uint8_t> bytes = {0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0};  // kTriangle as UNSIGNED_BYTE VEC3, stride 4
    const std::vector<Unhonoured> cases = {
        {"unknown required extension",
         [](GltfBuilder& b) { b.doc["extensionsRequired"] = {"KHR_mesh_quantization", "KHR_frobnicate"}; },
         "extensionsRequired[1]: 'KHR_frobnicate' is required, and this reader does not implement it"},
        {"required instancing", [](GltfBuilder& b) { b.doc["extensionsRequired"] = {"EXT_mesh_gpu_instancing"}; },
         "extensionsRequired[0]: 'EXT_mesh_gpu_instancing' is required"},
        {"extensionsRequired not strings", [](GltfBuilder& b) { b.doc["extensionsRequired"] = {7}; },
         "extensionsRequired[0]: string expected"},
        {"matrix with a projective last row",
         [](GltfBuilder& b) { b.doc["nodes"][0]["matrix"] = {1, 0, 0, 0.5, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}; },
         "nodes[0].matrix: elements 3, 7, 11 and 15 (the last row) are 0.5 0 0 1, not 0 0 0 1"},
        {"matrix with w 2", [](GltfBuilder& b) { b.doc["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 2}; },
         "nodes[0].matrix: elements 3, 7, 11 and 15 (the last row) are 0 0 0 2"},
        {"matrix and translation",
         [](GltfBuilder& b) {
             b.doc["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
             b.doc["nodes"][0]["translation"] = {1, 2, 3};
         },
         "nodes[0]: both matrix and translation"},
        {"matrix and scale",
         [](GltfBuilder& b) {
             b.doc["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
             b.doc["nodes"][0]["scale"] = {2, 2, 2};
         },
         "nodes[0]: both matrix and scale"},
        {"byte positions without KHR_mesh_quantization",
         [&](GltfBuilder& b) {
             b.doc["accessors"][0] = {{"bufferView", b.addView(bytes.data(), bytes.size(), 4)}, {"componentType", 5121},
                                      {"count", 3}, {"type", "VEC3"}};
         },
         "accessors[0]: POSITION componentType 5121 (UNSIGNED_BYTE) needs KHR_mesh_quantization in extensionsUsed"},
        {"a root listed twice", [](GltfBuilder& b) { b.doc["scenes"][0]["nodes"] = {0, 0}; },
         "scenes[0].nodes: nodes[0] is listed twice"},
        {"a child listed twice",
         [](GltfBuilder& b) {
             b.addNode({{"mesh", 0}});
             b.doc["nodes"][0]["children"] = {1, 1};
         },
         "nodes[0].children: nodes[1] is listed twice"},
    };
    for (const Unhonoured& c : cases) {
        SCOPED_TRACE(c.name);
        GltfBuilder b = oneTriangle();
        c.edit(b);
        expectError(loadString(b.gltf()), c.message);
    }

    // What it does honour: the extensions it implements, and the texture formats (no image
    // is read), required or not; quantized positions named in extensionsUsed alone.
    GltfBuilder b = oneTriangle();
    b.doc["extensionsRequired"] = {"KHR_mesh_quantization", "EXT_meshopt_compression", "KHR_draco_mesh_compression",
                                   "KHR_lights_punctual", "KHR_texture_basisu", "EXT_texture_webp"};
    EXPECT_TRUE(loadString(b.gltf()));
    b.doc.erase("extensionsRequired");
    b.doc["accessors"][0] = {{"bufferView", b.addView(bytes.data(), bytes.size(), 4)}, {"componentType", 5121},
                             {"count", 3}, {"type", "VEC3"}};
    b.doc["extensionsUsed"] = {"KHR_mesh_quantization"};
    const Expected<Mesh> quantized = loadString(b.gltf());
    ASSERT_TRUE(quantized) << quantized.error().what();
    EXPECT_EQ(quantized->positions[1], glm::dvec3(1, 0, 0));
}
