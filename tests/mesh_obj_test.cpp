// OBJ + MTL loader: group numbering per the scene-format spec, triangulation and winding,
// and errors that name file and line. Also loadMeshFile's dispatch.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include "core/mesh.h"
#include "io/file_read.h"
#include "io/mesh_load.h"
#include "tests/test_files.h"

using namespace shadowcull;
using shadowcull::testing::freshTestDir;
using shadowcull::testing::writeText;
namespace fs = std::filesystem;

namespace {

// Loads `text` written as `name` in a fresh directory (plus optional extra files).
Expected<Mesh> loadText(const std::string& text, const std::vector<std::pair<std::string, std::string>>& extra = {},
                        const std::string& name = "m.obj") {
    fs::path dir = freshTestDir();
    for (const auto& [file, content] : extra) writeText(dir / file, content);
    writeText(dir / name, text);
    return loadObj((dir / name).string());
}

glm::dvec3 normalOf(const Mesh& m, size_t t) {
    const auto& tri = m.triangles[t];
    const glm::dvec3 a = m.positions[tri[0]], b = m.positions[tri[1]], c = m.positions[tri[2]];
    return glm::normalize(glm::cross(b - a, c - a));
}

size_t trianglesIn(const Mesh& m, uint32_t group) {
    return size_t(std::count(m.triangleGroup.begin(), m.triangleGroup.end(), group));
}

const char* kCubeVertices =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
    "v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n";

}  // namespace

TEST(MeshObj, CubeWithTwoMaterialsInFirstUseOrder) {
    // "blue" is used first, then "red", then "blue" again: groups are [blue, red].
    std::string obj = std::string("mtllib cube.mtl\n") + kCubeVertices +
                      "usemtl blue\n"
                      "f 1 4 3 2\n"   // z=0 face, outward -z
                      "f 5 6 7 8\n"   // z=1 face, outward +z
                      "usemtl red\n"
                      "f 1 2 6 5\n"   // y=0
                      "f 4 8 7 3\n"   // y=1
                      "usemtl blue\n"
                      "f 1 5 8 4\n"   // x=0
                      "f 2 3 7 6\n";  // x=1
    auto m = loadText(obj, {{"cube.mtl", "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n"}});
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->groups.size(), 2u);
    EXPECT_EQ(m->groups[0].name, "blue");
    EXPECT_EQ(m->groups[1].name, "red");
    EXPECT_FALSE(m->groups[0].alphaTested);
    EXPECT_FALSE(m->groups[1].twoSided());
    EXPECT_EQ(m->positions.size(), 8u);
    ASSERT_EQ(m->triangles.size(), 12u);
    ASSERT_EQ(m->triangleGroup.size(), 12u);
    EXPECT_EQ(trianglesIn(*m, 0), 8u);
    EXPECT_EQ(trianglesIn(*m, 1), 4u);
    const std::vector<uint32_t> expected = {0, 0, 0, 0, 1, 1, 1, 1, 0, 0, 0, 0};
    EXPECT_EQ(m->triangleGroup, expected);
    // Every face is CCW seen from outside: normals point away from the cube centre.
    for (size_t t = 0; t < m->triangles.size(); ++t) {
        const auto& tri = m->triangles[t];
        glm::dvec3 centroid = (m->positions[tri[0]] + m->positions[tri[1]] + m->positions[tri[2]]) / 3.0;
        EXPECT_GT(glm::dot(normalOf(*m, t), centroid - glm::dvec3(0.5)), 0.0) << "triangle " << t;
    }
}

TEST(MeshObj, FacesBeforeFirstUsemtlGetGroupZero) {
    auto m = loadText("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nusemtl a\nf 1 2 3\nf 3 2 1\nusemtl b\n");
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->groups.size(), 3u);
    EXPECT_EQ(m->groups[0].name, "");
    EXPECT_EQ(m->groups[1].name, "a");
    EXPECT_EQ(m->groups[2].name, "b");  // declared by usemtl even without faces
    EXPECT_EQ(m->triangleGroup, (std::vector<uint32_t>{0, 1, 1}));
}

TEST(MeshObj, NoUsemtlIsGroupZeroAndEmptyFileHasOneGroup) {
    auto m = loadText("# just a triangle\nv 0 0 0\nv 1 0 0\nv 0 1 0\no thing\ng part\ns 1\nf 1 2 3\n");
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->groups.size(), 1u);  // o/g/s do not start groups
    EXPECT_EQ(m->triangleGroup, (std::vector<uint32_t>{0}));

    auto empty = loadText("");
    ASSERT_TRUE(empty) << empty.error().what();
    EXPECT_EQ(empty->groups.size(), 1u);
    EXPECT_TRUE(empty->triangles.empty());
}

TEST(MeshObj, MapDMakesMaterialAlphaTestedButDAloneDoesNot) {
    const std::string mtl =
        "newmtl leaves\nKd 0 1 0\nmap_d leaves_alpha.png\n"
        "newmtl glass\nd 0.3\n"
        "newmtl plain\n";
    auto m = loadText("mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                      "usemtl plain\nf 1 2 3\nusemtl leaves\nf 1 2 3\nusemtl glass\nf 1 2 3\n",
                      {{"lib.mtl", mtl}});
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->groups.size(), 3u);
    EXPECT_FALSE(m->groups[0].alphaTested);
    EXPECT_TRUE(m->groups[1].alphaTested);
    EXPECT_TRUE(m->groups[1].twoSided());
    EXPECT_FALSE(m->groups[2].alphaTested);
}

TEST(MeshObj, SeveralMtlLibraries) {
    auto m = loadText("mtllib a.mtl sub/b.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\nusemtl y\nf 1 2 3\n",
                      {{"a.mtl", "newmtl y\n"}, {"sub/b.mtl", "newmtl x\nmap_d a.png\n"}});
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->groups.size(), 2u);
    EXPECT_TRUE(m->groups[0].alphaTested);
    EXPECT_FALSE(m->groups[1].alphaTested);
    EXPECT_FALSE(m->groups[0].alphaUnknown || m->groups[1].alphaUnknown);
}

// Issue 11: a missing, unreadable or broken material library, or a material no library
// defines, used to bake alpha-tested leaves as opaque without a word (false culls).
TEST(MeshObj, MissingOrBrokenMaterialsAreErrorsNeverOpaqueGuesses) {
    auto missing = loadText("v 0 0 0\nv 1 0 0\nv 0 1 0\nmtllib missing.mtl\nusemtl x\nf 1 2 3\n", {});
    ASSERT_FALSE(missing);
    EXPECT_EQ(missing.error().line, 4);
    EXPECT_NE(missing.error().message.find("mtllib 'missing.mtl'"), std::string::npos) << missing.error().what();

    auto dir = loadText("mtllib lib\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n", {{"lib/x", ""}});
    ASSERT_FALSE(dir);  // a directory named like the library
    EXPECT_EQ(dir.error().line, 1);

    const std::string obj = "mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl leaves\nf 1 2 3\n";
    for (const auto& [mtl, line, words] : std::vector<std::tuple<std::string, int, std::string>>{
             {std::string("newmtl leaves\nKd 0 1 0\0\x01\x02", 25), 2, "binary data"},
             {"# lib\nnewmtl\nmap_d a.png\n", 2, "needs a material name"},
             {"map_d a.png\nnewmtl leaves\n", 1, "before any 'newmtl'"},
             {"newmtl leaves\nmap_d\n", 2, "needs a texture file"}}) {
        auto m = loadText(obj, {{"lib.mtl", mtl}});
        ASSERT_FALSE(m) << words;
        EXPECT_NE(m.error().file.find("lib.mtl"), std::string::npos) << m.error().what();
        EXPECT_EQ(m.error().line, line) << m.error().what();
        EXPECT_NE(m.error().message.find(words), std::string::npos) << m.error().what();
    }

    // A material no library defines: the group's alpha is unknown, and a model made of
    // the mesh alone cannot be loaded (the error names the usemtl line).
    auto undefined = loadText("mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl leaves\nf 1 2 3\nusemtl bark\nf 1 2 3\n",
                              {{"lib.mtl", "newmtl leaves\nmap_d a.png\n"}});
    ASSERT_TRUE(undefined) << undefined.error().what();
    EXPECT_FALSE(undefined->groups[0].alphaUnknown);
    ASSERT_TRUE(undefined->groups[1].alphaUnknown);
    EXPECT_EQ(undefined->groups[1].alphaUnknown->line, 7);
}

TEST(MeshObj, NegativeIndicesAndAllVertexForms) {
    auto m = loadText(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n"
        "f -3 -2 -1\n"
        "f 1/1 2/2 3/3\n"
        "f 1//1 2//1 3//1\n"
        "f 1/1/1 2/2/1 -1/-1/-1\n"
        "v 5 5 5\n"
        "f -4 -3 -1\n");
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->triangles.size(), 5u);
    for (size_t t = 0; t < 4; ++t) EXPECT_EQ(m->triangles[t], (std::array<uint32_t, 3>{0, 1, 2})) << t;
    EXPECT_EQ(m->triangles[4], (std::array<uint32_t, 3>{0, 1, 3}));
}

TEST(MeshObj, QuadAndPentagonAreFanTriangulatedKeepingWinding) {
    // CCW seen from +z: a quad and a convex pentagon.
    auto m = loadText(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        "v 2 0 0\nv 3 0 0\nv 3.5 1 0\nv 2.5 2 0\nv 1.5 1 0\n"
        "f 1 2 3 4\nf 5 6 7 8 9\n");
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->triangles.size(), 5u);
    EXPECT_EQ(m->triangles[0], (std::array<uint32_t, 3>{0, 1, 2}));
    EXPECT_EQ(m->triangles[1], (std::array<uint32_t, 3>{0, 2, 3}));
    EXPECT_EQ(m->triangles[2], (std::array<uint32_t, 3>{4, 5, 6}));
    EXPECT_EQ(m->triangles[4], (std::array<uint32_t, 3>{4, 7, 8}));
    for (size_t t = 0; t < 5; ++t) EXPECT_NEAR(normalOf(*m, t).z, 1.0, 1e-12) << t;

    // The same quad listed clockwise faces -z.
    auto cw = loadText("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 4 3 2 1\n");
    ASSERT_TRUE(cw) << cw.error().what();
    for (size_t t = 0; t < 2; ++t) EXPECT_NEAR(normalOf(*cw, t).z, -1.0, 1e-12) << t;
}

TEST(MeshObj, ValuesAreParsedExactly) {
    auto m = loadText("v +1.5 -2e3 0.25 1.0\nv 1 2 3 0.5 0.5 0.5\n");
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->positions.size(), 2u);
    EXPECT_EQ(m->positions[0], glm::dvec3(1.5, -2000.0, 0.25));
    EXPECT_EQ(m->positions[1], glm::dvec3(1, 2, 3));
}

TEST(MeshObj, NonFiniteVertexIsAnErrorWithLine) {
    for (const char* bad : {"nan", "inf", "-Infinity", "1e999"}) {
        auto m = loadText(std::string("v 0 0 0\n\nv 1 ") + bad + " 0\n");
        ASSERT_FALSE(m) << bad;
        EXPECT_EQ(m.error().kind, ErrorKind::BadInput);
        EXPECT_EQ(m.error().line, 3) << bad;
        EXPECT_NE(m.error().what().find("m.obj:3:"), std::string::npos) << m.error().what();
        EXPECT_NE(m.error().message.find("non-finite"), std::string::npos) << m.error().message;
    }
}

TEST(MeshObj, OutOfRangeAndZeroIndicesAreErrorsWithLine) {
    auto m = loadText("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
    ASSERT_FALSE(m);
    EXPECT_EQ(m.error().line, 4);
    EXPECT_NE(m.error().message.find("out of range"), std::string::npos) << m.error().message;

    auto neg = loadText("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n");
    ASSERT_FALSE(neg);
    EXPECT_EQ(neg.error().line, 4);

    auto zero = loadText("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
    ASSERT_FALSE(zero);
    EXPECT_EQ(zero.error().line, 4);

    // A face may only use vertices defined before it.
    auto early = loadText("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n");
    ASSERT_FALSE(early);
    EXPECT_EQ(early.error().line, 3);

    auto vt = loadText("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n");
    ASSERT_FALSE(vt);
    EXPECT_EQ(vt.error().line, 5);
}

TEST(MeshObj, TruncatedContentIsAnErrorWithLine) {
    struct Case {
        std::string tail;
        const char* expect;
    };
    for (const Case& c : std::vector<Case>{{"v 1 2 1.5e", "malformed number"},
                                           {"v 1 2", "needs x y z"},
                                           {"v 1 2 3x", "malformed number"},
                                           {"f 1 2", "at least 3"},
                                           {"f 1 2 3/", "malformed vertex reference"},
                                           {"f 1 2 3//", "malformed vertex reference"},
                                           {"f 1 2 3/1/1/1", "malformed vertex reference"},
                                           {"f 1 2 -", "malformed vertex reference"}}) {
        auto m = loadText("v 0 0 0\nv 1 0 0\nv 0 1 0\n" + c.tail);
        ASSERT_FALSE(m) << c.tail;
        EXPECT_EQ(m.error().kind, ErrorKind::BadInput);
        EXPECT_EQ(m.error().line, 4) << c.tail;
        EXPECT_NE(m.error().message.find(c.expect), std::string::npos) << c.tail << " -> " << m.error().message;
    }
}

TEST(MeshObj, MissingFileIsMissingResource) {
    fs::path dir = freshTestDir();
    auto m = loadObj((dir / "nope.obj").string());
    ASSERT_FALSE(m);
    EXPECT_EQ(m.error().kind, ErrorKind::MissingResource);
    EXPECT_NE(m.error().what().find("nope.obj"), std::string::npos);
}

TEST(MeshObj, LineContinuationCommentsAndCrLf) {
    auto m = loadText("v 0 0 0\r\nv 1 0 \\\r\n 0\r\nv 0 1 0 # top\r\nf 1 \\\n2 \\\n3\r\n# f 1 2 3\r\nv 1 1 1\nf 1 2 x\n");
    ASSERT_FALSE(m);
    // Physical lines are counted even across continuations: the bad face is on line 10.
    EXPECT_EQ(m.error().line, 10) << m.error().what();

    auto ok = loadText("v 0 0 0\r\nv 1 0 \\\r\n 0\r\nv 0 1 0 # top\r\nf 1 \\\n2 \\\n3\r\n# f 1 2 3\r\n");
    ASSERT_TRUE(ok) << ok.error().what();
    ASSERT_EQ(ok->positions.size(), 3u);
    EXPECT_EQ(ok->positions[1], glm::dvec3(1, 0, 0));
    ASSERT_EQ(ok->triangles.size(), 1u);
    EXPECT_EQ(ok->triangles[0], (std::array<uint32_t, 3>{0, 1, 2}));

    // Statements are views into the text, or into one buffer for continued ones: two
    // continued statements in a row, and a file ending on a backslash, each read whole.
    auto twice = loadText("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 \\\n2 3\nf 3 \\\n2 \\\n1 # one\nf 1 2 \\\n3 \\");
    ASSERT_TRUE(twice) << twice.error().what();
    ASSERT_EQ(twice->triangles.size(), 3u);
    EXPECT_EQ(twice->triangles[0], (std::array<uint32_t, 3>{0, 1, 2}));
    EXPECT_EQ(twice->triangles[1], (std::array<uint32_t, 3>{2, 1, 0}));
    EXPECT_EQ(twice->triangles[2], (std::array<uint32_t, 3>{0, 1, 2}));
}

TEST(MeshObj, MaterialNamesMayContainSpaces) {
    auto m = loadText("mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl my leaf  \nf 1 2 3\n",
                      {{"lib.mtl", "newmtl my leaf\nmap_d x.png\n"}});
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->groups.size(), 1u);
    EXPECT_EQ(m->groups[0].name, "my leaf");
    EXPECT_TRUE(m->groups[0].alphaTested);
}

TEST(MeshLoad, DispatchesByExtensionCaseInsensitively) {
    fs::path dir = freshTestDir();
    writeText(dir / "a.OBJ", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    auto m = loadMeshFile((dir / "a.OBJ").string());
    ASSERT_TRUE(m) << m.error().what();
    EXPECT_EQ(m->triangles.size(), 1u);

    writeText(dir / "a.stl", "solid x\n");
    auto bad = loadMeshFile((dir / "a.stl").string());
    ASSERT_FALSE(bad);
    EXPECT_EQ(bad.error().kind, ErrorKind::BadInput);
    EXPECT_NE(bad.error().message.find("unsupported mesh format"), std::string::npos);

    auto missing = loadMeshFile((dir / "gone.glb").string());
    ASSERT_FALSE(missing);
    EXPECT_EQ(missing.error().kind, ErrorKind::MissingResource);
}

// A dense mesh is read and stored at its size: the file into one buffer of its size (the
// read used to grow it by a block at the end, copying it into one twice as large), the
// vertex and triangle arrays reserved by a count of their lines (they used to grow as they
// filled, touching about twice their size in fresh pages). The content is unchanged.
TEST(MeshObj, ADenseMeshIsReadAndStoredAtItsSize) {
    const int n = 300;  // 90,601 vertices, 180,000 triangles
    std::string obj;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) obj += "v " + std::to_string(i) + " " + std::to_string((i + j) % 2) + " " + std::to_string(j) + "\n";
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const int a = j * (n + 1) + i + 1, b = a + 1, c = a + n + 1, d = c + 1;
            obj += "f " + std::to_string(a) + " " + std::to_string(c) + " " + std::to_string(b) + "\n";
            obj += "f " + std::to_string(b) + " " + std::to_string(c) + " " + std::to_string(d) + "\n";
        }
    const fs::path dir = freshTestDir();
    writeText(dir / "dense.obj", obj);
    Expected<std::string> text = readRegularFile((dir / "dense.obj").string(), "OBJ file");
    ASSERT_TRUE(text) << text.error().what();
    EXPECT_EQ(*text, obj);
    EXPECT_LT(text->capacity(), obj.size() + 4096) << "the file's buffer grew past its size";
    Expected<Mesh> m = loadObj((dir / "dense.obj").string());
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->positions.size(), size_t((n + 1) * (n + 1)));
    ASSERT_EQ(m->triangles.size(), size_t(2 * n * n));
    EXPECT_EQ(m->positions.capacity(), m->positions.size());
    EXPECT_EQ(m->triangles.capacity(), m->triangles.size());
    EXPECT_EQ(m->triangleGroup.capacity(), m->triangleGroup.size());
    EXPECT_EQ(m->positions[n + 2], glm::dvec3(1, 0, 1));
    const uint32_t b = uint32_t(n * n + n - 1), c = uint32_t(n * (n + 1) + n - 1), d = uint32_t((n + 1) * (n + 1) - 1);
    EXPECT_EQ(m->triangles.back(), (std::array<uint32_t, 3>{b, c, d}));
}

// Plain "v x y z" and "f a b c" lines are read by a fast path; every other form by the
// general one. Both give the same mesh, bit for bit: the same vertices written with a w
// (general) and the same faces by negative indices (general) against the plain forms,
// with exponents, long mantissas, negative zero, tabs and comments. A plain-looking line
// the fast path cannot take (an index out of range, a number out of range) is still the
// general path's error, with its line.
TEST(MeshObj, PlainLinesReadFastAreTheGeneralReading) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    std::string plain = "# plain\n", general = "# general\n";
    const int n = 200;
    for (int k = 0; k < n; ++k) {
        char x[64], y[64], z[64];
        std::snprintf(x, sizeof x, "%.17g", unit(rng) * 1e3);
        std::snprintf(y, sizeof y, "%.6e", unit(rng));
        std::snprintf(z, sizeof z, "%s", k % 7 == 0 ? "-0" : std::to_string(unit(rng)).c_str());
        plain += std::string(k % 3 ? "v " : "v\t") + x + " " + y + "  " + z + (k % 5 ? "\n" : " # a comment\n");
        general += std::string("v ") + x + " " + y + " " + z + " 1\n";
    }
    for (int k = 2; k < n; ++k) {
        plain += "f " + std::to_string(k - 1) + " " + std::to_string(k) + " " + std::to_string(k + 1) + "\n";
        general += "f " + std::to_string(k - 1 - (n + 1)) + " " + std::to_string(k - (n + 1)) + " " + std::to_string(k + 1 - (n + 1)) + "\n";
    }
    Expected<Mesh> a = loadText(plain), b = loadText(general);
    ASSERT_TRUE(a) << a.error().what();
    ASSERT_TRUE(b) << b.error().what();
    ASSERT_EQ(a->positions.size(), size_t(n));
    ASSERT_EQ(a->positions.size(), b->positions.size());
    for (size_t k = 0; k < a->positions.size(); ++k)
        for (int c = 0; c < 3; ++c)
            EXPECT_EQ(std::memcmp(&a->positions[k][c], &b->positions[k][c], sizeof(double)), 0) << "vertex " << k;
    EXPECT_EQ(a->triangles, b->triangles);
    EXPECT_EQ(a->triangleGroup, b->triangleGroup);
    EXPECT_TRUE(std::signbit(a->positions[0].z)) << "-0 kept";

    Expected<Mesh> far = loadText("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
    ASSERT_FALSE(far);
    EXPECT_EQ(far.error().line, 4);
    EXPECT_NE(far.error().message.find("out of range"), std::string::npos) << far.error().message;
    Expected<Mesh> huge = loadText("v 0 0 0\nv 1e9 0 0\n");
    ASSERT_FALSE(huge);
    EXPECT_EQ(huge.error().line, 2);
}
