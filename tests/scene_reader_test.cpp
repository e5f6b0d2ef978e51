// Readers of space.xml, chunk files, .model and .terrain resources, including bad input.

#include <png.h>

#include <cmath>
#include <cstdio>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "core/scene.h"
#include "io/chunk_writer.h"
#include "io/scene_reader.h"
#include "tests/test_files.h"

using namespace shadowcull;
using shadowcull::testing::freshTestDir;
using shadowcull::testing::writeText;
namespace fs = std::filesystem;

namespace {

// Writes a grey PNG of the given bit depth (8 or 16) with `w` x `h` samples.
void writePng(const fs::path& p, int w, int h, int depth, const std::vector<unsigned>& samples) {
    fs::create_directories(p.parent_path());
    std::FILE* f = std::fopen(p.string().c_str(), "wb");
    ASSERT_NE(f, nullptr);
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
    png_infop info = png_create_info_struct(png);
    png_init_io(png, f);
    png_set_IHDR(png, info, png_uint_32(w), png_uint_32(h), depth, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    std::vector<png_byte> row(size_t(w) * size_t(depth / 8));
    for (int j = 0; j < h; ++j) {
        for (int i = 0; i < w; ++i) {
            unsigned v = samples[size_t(j * w + i)];
            if (depth == 16) {
                row[size_t(2 * i)] = png_byte(v >> 8);
                row[size_t(2 * i + 1)] = png_byte(v & 0xff);
            } else {
                row[size_t(i)] = png_byte(v);
            }
        }
        png_write_row(png, row.data());
    }
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
    std::fclose(f);
}

const char* kSpaceXml = R"(<space>
  <chunkSize> 100 </chunkSize>
  <neighbours> 1 </neighbours>
  <terrainTolerance> 0.02 </terrainTolerance>
  <light>
    <name> sun </name>
    <type> directional </type>
    <direction> 0.3 -1 0.2 </direction>
    <bias> 0.05 </bias>
  </light>
  <light>
    <name> lamp </name> <type> point </type>
    <position> 10 4 -3 </position>
    <range> 25 </range>
  </light>
  <light>
    <name> torch </name> <type> spot </type>
    <position> 0 6 0 </position> <direction> 0 -2 0 </direction>
    <range> 20 </range> <coneAngle> 30 </coneAngle>
  </light>
</space>
)";

std::string spaceWithLight(const std::string& lightBody) {
    return "<space>\n  <light>\n" + lightBody + "\n  </light>\n</space>\n";
}

// Writes `text` as the chunk file 00000000o.chunk in `dir` and reads it as chunk (0,0).
Expected<ChunkFile> readChunkText(const fs::path& dir, const std::string& text, std::vector<Diagnostic>& diags) {
    writeText(dir / "00000000o.chunk", text);
    return readChunkFile((dir / "00000000o.chunk").string(), {0, 0}, diags);
}

// A model of a.obj placed by the four rows of its transform, on four lines as a chunk file
// has it: <model> first, its <transform> third.
std::string modelWithRows(const char* row0, const char* row1, const char* row2, const char* row3) {
    return std::string("  <model>\n    <resource> a.obj </resource>\n    <transform> <row0> ") + row0 + " </row0> <row1> " + row1 +
           " </row1> <row2> " + row2 + " </row2> <row3> " + row3 + " </row3> </transform>\n  </model>\n";
}

}  // namespace

TEST(ChunkName, ParsesTwosComplementHex) {
    auto c = parseChunkName("0000ffffo.chunk");
    ASSERT_TRUE(c);
    EXPECT_EQ(c->x, 0);
    EXPECT_EQ(c->z, -1);
    c = parseChunkName("FFFE0001o.chunk");
    ASSERT_TRUE(c);
    EXPECT_EQ(c->x, -2);
    EXPECT_EQ(c->z, 1);
    c = parseChunkName("80007fffo.chunk");
    ASSERT_TRUE(c);
    EXPECT_EQ(c->x, -32768);
    EXPECT_EQ(c->z, 32767);
}

TEST(ChunkName, RejectsOtherNames) {
    for (const char* n : {"0000ffff.chunk", "0000fffgo.chunk", "00000ffffo.chunk", "0000ffffi.chunk", "0000ffffo.chunkx",
                          "0000ffffo.xml", ""})
        EXPECT_FALSE(parseChunkName(n)) << n;
}

TEST(ChunkName, CommandLineArgumentsTakeShortNamesFileNamesAndPaths) {
    for (const char* a : {"0000ffffo", "0000ffffo.chunk", "some/dir/0000ffffo.chunk", "/abs/0000FFFFo"}) {
        auto c = parseChunkArgument(a);
        ASSERT_TRUE(c) << a;
        EXPECT_EQ(c->x, 0);
        EXPECT_EQ(c->z, -1);
    }
    for (const char* a : {"0000fff", "0000ffffo.chk", "dir/", ""}) EXPECT_FALSE(parseChunkArgument(a)) << a;
}

TEST(ChunkName, RoundTrips) {
    for (int x : {-32768, -2, -1, 0, 1, 255, 32767})
        for (int z : {-1, 0, 7}) {
            auto c = parseChunkName(chunkFileName({x, z}));
            ASSERT_TRUE(c);
            EXPECT_EQ(c->x, x);
            EXPECT_EQ(c->z, z);
        }
    EXPECT_EQ(chunkFileName({0, -1}), "0000ffffo.chunk");
}

TEST(SpaceReader, ReadsTheSpecExample) {
    fs::path dir = freshTestDir();
    writeText(dir / "space.xml", kSpaceXml);
    Expected<SpaceSettings> s = readSpaceSettings(dir.string(), "");
    ASSERT_TRUE(s) << s.error().what();
    EXPECT_EQ(s->chunkSize, 100);
    EXPECT_EQ(s->neighbours.left, 1);
    EXPECT_EQ(s->neighbours.top, 1);
    EXPECT_DOUBLE_EQ(s->terrainTolerance, 0.02);
    ASSERT_EQ(s->lights.size(), 3u);
    EXPECT_EQ(s->lights[0].name, "sun");
    EXPECT_EQ(s->lights[0].type, LightType::Directional);
    EXPECT_NEAR(glm::length(s->lights[0].direction), 1.0, 1e-15);
    EXPECT_NEAR(s->lights[0].direction.x / s->lights[0].direction.y, -0.3, 1e-15);
    EXPECT_DOUBLE_EQ(s->lights[0].bias, 0.05);
    EXPECT_EQ(s->lights[1].type, LightType::Point);
    EXPECT_EQ(s->lights[1].position, glm::dvec3(10, 4, -3));
    EXPECT_EQ(s->lights[1].range, 25);
    EXPECT_EQ(s->lights[2].type, LightType::Spot);
    EXPECT_EQ(s->lights[2].direction, glm::dvec3(0, -1, 0));
    EXPECT_EQ(s->lights[2].coneHalfAngleDeg, 30);
    EXPECT_EQ(s->lights[2].line, 16);
    EXPECT_EQ(s->resourceRoot, dir.string());
}

TEST(SpaceReader, NeighboursPerSideAndResourceRoot) {
    fs::path dir = freshTestDir();
    writeText(dir / "space.xml",
              "<space><neighbours left=\"2\" right=\"0\" top=\"3\" bottom=\"1\"/><resourceRoot> res </resourceRoot></space>");
    fs::create_directories(dir / "res");
    auto s = readSpaceSettings(dir.string(), "");
    ASSERT_TRUE(s) << s.error().what();
    EXPECT_EQ(s->neighbours.left, 2);
    EXPECT_EQ(s->neighbours.right, 0);
    EXPECT_EQ(s->neighbours.top, 3);
    EXPECT_EQ(s->neighbours.bottom, 1);
    EXPECT_EQ(fs::path(s->resourceRoot), dir / "res");
    EXPECT_EQ(s->chunkSize, 100);  // default
    fs::create_directories(dir / "elsewhere");
    auto o = readSpaceSettings(dir.string(), (dir / "elsewhere").string());
    ASSERT_TRUE(o) << o.error().what();
    EXPECT_EQ(o->resourceRoot, (dir / "elsewhere").string());
    // A resource root that is not a directory is one error up front (it was a warning for
    // every object that names a resource).
    auto missing = readSpaceSettings(dir.string(), "/nonexistent-shadowcull-root");
    ASSERT_FALSE(missing);
    EXPECT_EQ(missing.error().kind, ErrorKind::MissingResource);
}

// Each bad space.xml is an error that names the file and the line of the offending element.
struct BadSpaceCase {
    const char* name;
    std::string xml;
    int line;
    const char* words;
};

TEST(SpaceReader, BadInputNamesFileAndLine) {
    std::string many = "<space>\n";
    for (int i = 0; i < 33; ++i) many += "<light><type>directional</type><direction>0 -1 0</direction></light>\n";
    many += "</space>\n";
    const BadSpaceCase cases[] = {
        {"unknown type", spaceWithLight("    <type> area </type>"), 3, "unknown light type 'area'"},
        {"nan direction", spaceWithLight("    <type> directional </type>\n    <direction> nan -1 0 </direction>"), 4,
         "value 'nan' is not a decimal number"},
        {"zero direction", spaceWithLight("    <type> directional </type>\n    <direction> 0 0 0 </direction>"), 4,
         "<direction> '0 0 0' has no length"},
        {"direction beyond a double", spaceWithLight("    <type> directional </type>\n    <direction> 1e308 -1e309 0 </direction>"), 4,
         "<direction> value -1e309 is too large to be a number here"},
        {"point without range", spaceWithLight("    <type> point </type>\n    <position> 0 0 0 </position>"), 2,
         "<range>"},
        {"spot cone too wide",
         spaceWithLight("    <type> spot </type><position>0 0 0</position><direction>0 -1 0</direction>\n"
                        "    <range>5</range><coneAngle>120</coneAngle>"),
         4, "<coneAngle> is 120; the half-angle must be more than 0 and at most 90 degrees"},
        {"bad number", "<space>\n<chunkSize> 1O0 </chunkSize>\n</space>", 2, "value '1O0' is not a decimal number"},
        {"negative chunk", "<space>\n<chunkSize> -5 </chunkSize>\n</space>", 2, "outside the accepted range [1, 100000]"},
        {"malformed", "<space>\n<chunkSize> 100 </chunkSize>\n<light>\n</space>", 3,
         "not well-formed XML: the element <light> that starts here is closed by an end tag of another name"},
        {"33 lights", many, 34, "more than 32 lights"},
    };
    for (const BadSpaceCase& c : cases) {
        fs::path dir = freshTestDir(std::string("-") + std::to_string(&c - cases));
        writeText(dir / "space.xml", c.xml);
        auto s = readSpaceSettings(dir.string(), "");
        ASSERT_FALSE(s) << c.name;
        EXPECT_EQ(s.error().kind, ErrorKind::BadInput) << c.name;
        EXPECT_EQ(s.error().line, c.line) << c.name << ": " << s.error().what();
        EXPECT_NE(s.error().what().find(c.words), std::string::npos) << c.name << ": " << s.error().what();
        EXPECT_NE(s.error().what().find("space.xml"), std::string::npos) << c.name;
    }
}

// Components near the largest double are a direction like any other (issue 15: it was
// reported as a zero direction): scaled by the largest component before normalising.
TEST(SpaceReader, HugeDirectionComponentsAreADirection) {
    fs::path dir = freshTestDir();
    writeText(dir / "space.xml", spaceWithLight("    <type> directional </type>\n    <direction> 1e308 -1e308 1e308 </direction>"));
    auto s = readSpaceSettings(dir.string(), "");
    ASSERT_TRUE(s) << s.error().what();
    const double k = 1.0 / std::sqrt(3.0);
    EXPECT_NEAR(s->lights[0].direction.x, k, 1e-15);
    EXPECT_NEAR(s->lights[0].direction.y, -k, 1e-15);
    EXPECT_NEAR(s->lights[0].direction.z, k, 1e-15);
}

TEST(SpaceReader, ThirtyTwoLightsAreFine) {
    fs::path dir = freshTestDir();
    std::string xml = "<space>\n";
    for (int i = 0; i < 32; ++i) xml += "<light><type>directional</type><direction>0 -1 0</direction></light>\n";
    writeText(dir / "space.xml", xml + "</space>");
    auto s = readSpaceSettings(dir.string(), "");
    ASSERT_TRUE(s) << s.error().what();
    EXPECT_EQ(s->lights.size(), 32u);
}

TEST(ChunkReader, ReadsModelsTerrainAndTransforms) {
    fs::path dir = freshTestDir();
    writeText(dir / "00010002o.chunk", R"(<?xml version="1.0"?>
<chunk>
  <!-- a comment -->
  <model>
    <resource> models/rock.model </resource>
    <uuid> 6055E290-4CC63BB3-1E14A3AE-0DFBE9A0 </uuid>
    <transform>
      <row0> 0 0 -2 </row0> <row1> 0 2 0 </row1> <row2> 2 0 0 </row2>
      <row3> 46.6 0 12.0 </row3>
    </transform>
    <castsShadow> false </castsShadow>
  </model>
  <unknown><model><resource>nested/is/ignored.obj</resource></model></unknown>
  <terrain>
    <resource> terrain/00010002.terrain </resource>
  </terrain>
</chunk>
)");
    std::vector<Diagnostic> diags;
    auto cf = readChunkFile((dir / "00010002o.chunk").string(), {1, 2}, diags);
    ASSERT_TRUE(cf) << cf.error().what();
    EXPECT_TRUE(diags.empty());
    ASSERT_EQ(cf->objects.size(), 2u);
    const ChunkObject& m = cf->objects[0];
    EXPECT_EQ(m.kind, ChunkObject::Kind::Model);
    EXPECT_EQ(m.elementIndex, 0);
    EXPECT_EQ(m.line, 4);
    EXPECT_EQ(m.resource, "models/rock.model");
    EXPECT_EQ(m.uuid, "6055E290-4CC63BB3-1E14A3AE-0DFBE9A0");
    EXPECT_FALSE(m.castsShadow);
    EXPECT_FALSE(m.skipped);
    // Row-vector convention: (1,0,0) maps to row0 + row3.
    EXPECT_EQ(m.transform.apply({1, 0, 0}), glm::dvec3(46.6, 0, 10.0));
    EXPECT_EQ(m.transform.apply({0, 0, 1}), glm::dvec3(48.6, 0, 12.0));
    EXPECT_LT(m.transform.determinant(), 0.0 + 1e300);  // finite
    EXPECT_EQ(cf->objects[1].kind, ChunkObject::Kind::Terrain);
    EXPECT_EQ(cf->objects[1].elementIndex, 1);
}

TEST(ChunkReader, BadObjectsAreSkippedWithLine) {
    fs::path dir = freshTestDir();
    std::vector<Diagnostic> diags;
    auto cf = readChunkText(dir,
                            "<chunk>\n" + modelWithRows("1 0 0", "0 1 0", "0 0 1", "inf 0 0") +
                                modelWithRows("1 0 0", "2 0 0", "0 0 1", "0 0 0") + R"(  <model>
    <uuid> x </uuid>
  </model>
  <model>
    <resource> a.obj </resource>
    <castsShadow> maybe </castsShadow>
  </model>
</chunk>
)",
                            diags);
    ASSERT_TRUE(cf) << cf.error().what();
    ASSERT_EQ(cf->objects.size(), 4u);
    for (const ChunkObject& o : cf->objects) EXPECT_TRUE(o.skipped);
    ASSERT_EQ(diags.size(), 4u);
    EXPECT_EQ(diags[0].line, 4);
    EXPECT_NE(diags[0].message.find("value 'inf' is not a decimal number"), std::string::npos) << diags[0].what();
    EXPECT_NE(diags[1].message.find("singular"), std::string::npos) << diags[1].what();
    EXPECT_EQ(diags[2].line, 10);
    EXPECT_NE(diags[2].message.find("no <resource>"), std::string::npos);
    EXPECT_EQ(diags[3].line, 15);
    for (const Diagnostic& d : diags) EXPECT_NE(d.message.find("skipped"), std::string::npos);
}

// The singularity test is scale-invariant: gltfpack's dequantization scale (about 4e-5 per
// axis, determinant 6e-14) is a valid transform; rows that are nearly dependent at any
// scale are not.
TEST(ChunkReader, SingularTransformTestIsScaleInvariant) {
    fs::path dir = freshTestDir();
    std::vector<Diagnostic> diags;
    auto cf = readChunkText(dir,
                            "<chunk>\n" + modelWithRows("3.9e-5 0 0", "0 3.9e-5 0", "0 0 3.9e-5", "1 2 3") +
                                modelWithRows("1000 0 0", "1000 0.0000001 0", "0 0 1000", "0 0 0") +
                                modelWithRows("0 0 0", "0 1 0", "0 0 1", "0 0 0") + "</chunk>\n",
                            diags);
    ASSERT_TRUE(cf) << cf.error().what();
    ASSERT_EQ(cf->objects.size(), 3u);
    EXPECT_FALSE(cf->objects[0].skipped) << cf->objects[0].skipReason;
    EXPECT_TRUE(cf->objects[1].skipped);
    EXPECT_TRUE(cf->objects[2].skipped);
    ASSERT_EQ(diags.size(), 2u);
    for (const Diagnostic& d : diags) EXPECT_NE(d.message.find("singular"), std::string::npos) << d.what();
}

// A transform whose inverse float geometry cannot hold: an axis of 1e-45 (a float denormal,
// flushed to zero inside Embree, whose instance then had an infinite inverse and aborted the
// bake: fuzz/regressions/bake/embree-assert-in-rtcIntersect1-e77f2b53) or an anisotropic
// 1e-12 is refused with its line; an axis of 1e-8 per model unit (gltfpack's dequantization
// of a millimetre part) is kept.
TEST(ChunkReader, TransformTooThinForFloatGeometryIsRefused) {
    fs::path dir = freshTestDir();
    std::vector<Diagnostic> diags;
    auto cf = readChunkText(dir,
                            "<chunk>\n" + modelWithRows("1e-45 1e-45 0", "0 1 0", "0 0 1", "50 0.2 50") +
                                modelWithRows("1 0 0", "0 1e-12 0", "0 0 1", "0 0 0") +
                                modelWithRows("1e-8 0 0", "0 1e-8 0", "0 0 1e-8", "0 0 0") + "</chunk>\n",
                            diags);
    ASSERT_TRUE(cf) << cf.error().what();
    ASSERT_EQ(cf->objects.size(), 3u);
    EXPECT_TRUE(cf->objects[0].skipped);
    EXPECT_TRUE(cf->objects[1].skipped);
    EXPECT_FALSE(cf->objects[2].skipped) << cf->objects[2].skipReason;
    ASSERT_EQ(diags.size(), 2u);
    EXPECT_EQ(diags[0].line, 4);
    EXPECT_EQ(diags[1].line, 8);
    for (const Diagnostic& d : diags)
        EXPECT_NE(d.message.find("too thin to place in float geometry"), std::string::npos) << d.what();
}

TEST(ChunkReader, MalformedXmlStopsWithLine) {
    fs::path dir = freshTestDir();
    std::vector<Diagnostic> diags;
    auto cf = readChunkText(dir, "<chunk>\n  <model>\n    <resource> a.obj </resourc>\n  </model>\n</chunk>\n", diags);
    ASSERT_FALSE(cf);
    EXPECT_EQ(cf.error().kind, ErrorKind::BadInput);
    EXPECT_EQ(cf.error().line, 3) << cf.error().what();
}

TEST(TerrainReader, Reads16BitHeights) {
    fs::path dir = freshTestDir();
    writePng(dir / "t.png", 3, 3, 16, {0, 65535, 0, 32768, 0, 0, 0, 0, 65535});
    writeText(dir / "t.terrain",
              "<terrain>\n<heights> t.png </heights>\n<minHeight> -20 </minHeight>\n<maxHeight> 80 </maxHeight>\n</terrain>");
    auto hf = loadTerrainResource((dir / "t.terrain").string(), 100.0);
    ASSERT_TRUE(hf) << hf.error().what();
    EXPECT_EQ(hf->n, 3);
    EXPECT_DOUBLE_EQ(hf->at(0, 0), -20);
    EXPECT_DOUBLE_EQ(hf->at(1, 0), 80);  // column 1, row 0
    EXPECT_NEAR(hf->at(0, 1), -20 + 100 * 32768.0 / 65535.0, 1e-12);
    EXPECT_DOUBLE_EQ(hf->at(2, 2), 80);
    // Row 0 is z = 0; sample (1, 0) lies at x = 50, z = 0.
    EXPECT_DOUBLE_EQ(hf->heightAt(50, 0), 80);
}

TEST(TerrainReader, SurfaceSplitsAlongTheMainDiagonal) {
    Heightfield hf;
    hf.n = 2;
    hf.size = 10;
    hf.heights = {0, 0, 0, 0};
    hf.heights[1] = 1;  // (i=1, j=0): x = 10, z = 0
    // On the diagonal from (0,0) to (10,10) the height is the mean of the two diagonal
    // corners (0), not of the others: the split is (i,j)-(i+1,j+1).
    EXPECT_DOUBLE_EQ(hf.heightAt(5, 5), 0.0);
    EXPECT_DOUBLE_EQ(hf.heightAt(10, 0), 1.0);
    EXPECT_DOUBLE_EQ(hf.heightAt(7.5, 2.5), 0.5);  // triangle (0,0),(10,0),(10,10)
    EXPECT_DOUBLE_EQ(hf.heightAt(2.5, 7.5), 0.0);  // triangle (0,0),(10,10),(0,10)
    Mesh m = hf.toMesh();
    ASSERT_EQ(m.triangles.size(), 2u);
    for (const auto& t : m.triangles) {
        glm::dvec3 n = glm::cross(m.positions[t[1]] - m.positions[t[0]], m.positions[t[2]] - m.positions[t[0]]);
        EXPECT_GT(n.y, 0) << "terrain fronts face up";
    }
}

// Issue 34: terrain seams. Sample i lies at (i S) / (N - 1): the last column and row land on
// exactly S, where the next chunk's first lie once placed (whole chunks apart, exact in
// double), so neighbouring terrains meet without a gap. S / (N - 1) first, then times i, put
// the last one an ulp short for S = 100, N = 98 (99.99999999999999), and for many more.
TEST(TerrainReader, LastSampleLandsOnTheChunkEdgeAndSeamsAreWatertight) {
    int pairs = 0;
    for (double S : {1.0, 3.0, 10.0, 64.0, 100.0, 128.0, 250.0, 333.0, 1000.0, 4096.0, 1e5, 0.1 * 1000, 7.3, 99.5}) {
        for (int n = 2; n <= 300; n += (n < 40 ? 1 : 17)) {
            Heightfield hf;
            hf.n = n;
            hf.size = S;
            hf.heights.assign(size_t(n) * size_t(n), 0.0);
            const Mesh m = hf.toMesh();
            ++pairs;
            for (int k = 0; k < n; ++k) {
                // Column n - 1 of row k, and row n - 1 of column k.
                const glm::dvec3& right = m.positions[size_t(k) * size_t(n) + size_t(n - 1)];
                const glm::dvec3& top = m.positions[size_t(n - 1) * size_t(n) + size_t(k)];
                const glm::dvec3& left = m.positions[size_t(k) * size_t(n)];
                const glm::dvec3& bottom = m.positions[size_t(k)];
                ASSERT_EQ(right.x, S) << "S " << S << " n " << n;
                ASSERT_EQ(top.z, S) << "S " << S << " n " << n;
                ASSERT_EQ(left.x, 0.0);
                ASSERT_EQ(bottom.z, 0.0);
                // Placed in a window, whole chunks from its origin (core/window.cpp): this
                // chunk's last column on the next chunk's first, for the chunks left of,
                // at and right of the origin; the rows' z agree across the seam.
                for (double dx : {-1.0, 0.0})
                    ASSERT_EQ(dx * S + right.x, (dx + 1) * S + left.x) << "S " << S << " n " << n << " dx " << dx;
                ASSERT_EQ(right.z, left.z);
            }
        }
    }
    EXPECT_GT(pairs, 500);  // (S, N) pairs
}

// The terrain's cell lookup agrees with its mesh: at every sample the mesh places, the
// height is that sample's (exactly, but for the last column and row: interpolated from
// the cell before, within rounding), and a point just past a sample lies on the next cell.
TEST(TerrainReader, HeightLookupAgreesWithTheMeshAtEverySample) {
    for (double S : {7.3, 100.0, 333.0, 1e5}) {
        for (int n : {2, 3, 17, 98, 129, 257}) {
            Heightfield hf;
            hf.n = n;
            hf.size = S;
            for (int k = 0; k < n * n; ++k) hf.heights.push_back(std::fmod(k * 7.77, 13.0) - 5);
            const Mesh m = hf.toMesh();
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i) {
                    const glm::dvec3& p = m.positions[size_t(j) * size_t(n) + size_t(i)];
                    const double h = hf.heightAt(p.x, p.z);
                    if (i < n - 1 && j < n - 1) ASSERT_EQ(h, p.y) << "S " << S << " n " << n << " i " << i << " j " << j;
                    else ASSERT_NEAR(h, p.y, 1e-13) << "S " << S << " n " << n << " i " << i << " j " << j;
                }
            // Just past column i (i < n - 1) the surface is cell i's: raising sample
            // (i + 1, 0) moves the height there, raising (i - 1, 0) does not.
            for (int i = 1; i + 1 < n; ++i) {
                const double x = std::nextafter(m.positions[size_t(i)].x, S);
                Heightfield up = hf;
                up.heights[size_t(i - 1)] += 1;
                ASSERT_EQ(up.heightAt(x, 0), hf.heightAt(x, 0)) << "S " << S << " n " << n << " i " << i;
            }
        }
    }
}

TEST(TerrainReader, RejectsBadHeightmaps) {
    fs::path dir = freshTestDir();
    writePng(dir / "8bit.png", 3, 3, 8, std::vector<unsigned>(9, 0));
    writePng(dir / "odd.png", 3, 2, 16, std::vector<unsigned>(6, 0));
    writePng(dir / "one.png", 1, 1, 16, std::vector<unsigned>(1, 0));
    writeText(dir / "trunc.png", "\x89PNG\r\n\x1a\n\0\0\0\rIHDR");
    for (const char* png : {"8bit.png", "odd.png", "one.png", "trunc.png", "missing.png"}) {
        writeText(dir / "t.terrain", std::string("<terrain><heights>") + png +
                                         "</heights><minHeight>0</minHeight><maxHeight>1</maxHeight></terrain>");
        auto hf = loadTerrainResource((dir / "t.terrain").string(), 100.0);
        ASSERT_FALSE(hf) << png;
        EXPECT_NE(hf.error().what().find(png), std::string::npos) << hf.error().what();
    }
    writeText(dir / "t.terrain", "<terrain>\n<heights>x.png</heights>\n<minHeight>0</minHeight>\n</terrain>");
    auto hf = loadTerrainResource((dir / "t.terrain").string(), 100.0);
    ASSERT_FALSE(hf);
    EXPECT_EQ(hf.error().line, 1);
}

TEST(ModelReader, AppliesGroupOverrides) {
    fs::path dir = freshTestDir();
    writeText(dir / "m.obj",
              "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl bark\nf 1 2 3\nusemtl leaves\nf 1 3 2\n");
    // The OBJ names no material library: alpha of 'bark' and 'leaves' is unknown until the
    // .model states it for both groups.
    writeText(dir / "half.model",
              "<model>\n <visual> m.obj </visual>\n <primitiveGroup index=\"1\" alphaTest=\"true\" doubleSided=\"true\"/>\n</model>");
    auto half = loadModelResource((dir / "half.model").string());
    ASSERT_FALSE(half);
    EXPECT_EQ(half.error().file, (dir / "m.obj").string());
    EXPECT_EQ(half.error().line, 4);
    EXPECT_NE(half.error().message.find("'bark' is not defined"), std::string::npos) << half.error().what();
    writeText(dir / "m.model",
              "<model>\n <visual> m.obj </visual>\n <primitiveGroup index=\"1\" alphaTest=\"true\" doubleSided=\"true\"/>\n"
              " <primitiveGroup index=\"0\" alphaTest=\"false\"/>\n</model>");
    auto m = loadModelResource((dir / "m.model").string());
    ASSERT_TRUE(m) << m.error().what();
    ASSERT_EQ(m->groups.size(), 2u);
    EXPECT_FALSE(m->groups[0].alphaTested);
    EXPECT_TRUE(m->groups[1].alphaTested);
    EXPECT_TRUE(m->groups[1].doubleSided);

    writeText(dir / "bad.model", "<model>\n <visual> m.obj </visual>\n <primitiveGroup index=\"2\" alphaTest=\"true\"/>\n</model>");
    auto b = loadModelResource((dir / "bad.model").string());
    ASSERT_FALSE(b);
    EXPECT_EQ(b.error().line, 3);
    writeText(dir / "novisual.model", "<model>\n</model>");
    EXPECT_FALSE(loadModelResource((dir / "novisual.model").string()));
    auto missing = loadModelResource((dir / "gone.model").string());
    ASSERT_FALSE(missing);
    EXPECT_EQ(missing.error().kind, ErrorKind::MissingResource);
}

TEST(SpaceLoader, MissingResourcesSkipObjectsAndBadNamesAreIgnored) {
    fs::path dir = freshTestDir();
    writeText(dir / "space.xml", "<space><light><type>directional</type><direction>0 -1 0</direction></light></space>");
    writeText(dir / "models/a.obj", "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 3 2\n");
    writeText(dir / "00000000o.chunk",
              "<chunk>\n<model><resource>models/a.obj</resource></model>\n<model><resource>models/gone.obj</resource></model>\n"
              "<model><resource>models/gone.obj</resource></model>\n</chunk>\n");
    writeText(dir / "notachunk.chunk", "<chunk/>");
    auto s = loadSpace(dir.string(), "");
    ASSERT_TRUE(s) << s.error().what();
    ASSERT_EQ(s->chunks.size(), 1u);
    const ChunkFile& cf = s->chunks.begin()->second;
    ASSERT_EQ(cf.objects.size(), 3u);
    EXPECT_FALSE(cf.objects[0].skipped);
    ASSERT_TRUE(cf.objects[0].mesh);
    EXPECT_EQ(cf.objects[0].mesh->triangles.size(), 1u);
    EXPECT_TRUE(cf.objects[1].skipped);
    EXPECT_TRUE(cf.objects[2].skipped);
    // One message for the file name, one for the missing resource, one per object using it.
    ASSERT_EQ(s->diagnostics.size(), 4u);
    int lines = 0;
    for (const Diagnostic& d : s->diagnostics) lines += d.line;
    EXPECT_EQ(lines, 3 + 4) << "the objects' lines are named";
}

// The inputs hash of sharded bakes (ChunkFile::contentWithoutShadowsHash) must not see the
// masks a bake writes, in any of the writer's layouts (a model on many lines, one on one
// line, a self-closing element, a mask replaced, a second <shadow> removed), and must see
// every other edit.
TEST(ChunkFile, HashWithoutShadowsIgnoresTheMasksAndSeesEveryOtherEdit) {
    const fs::path dir = freshTestDir();
    const std::string original = R"(<chunk>
  <!-- keep me -->
  <editorInfo author="a"><note> n </note></editorInfo>
  <model>
    <resource> a.obj </resource>
    <uuid> 1 </uuid>
  </model>
  <model><resource> b.obj </resource></model>
  <model>
    <resource> c.obj </resource>
    <shadow> 7 </shadow>
    <shadow> 9 </shadow>
  </model>
  <terrain/>
</chunk>
)";
    auto hashOf = [&](const std::string& text) {
        std::vector<Diagnostic> diags;
        Expected<ChunkFile> cf = readChunkText(dir, text, diags);
        EXPECT_TRUE(cf) << cf.error().what();
        return cf ? cf->contentWithoutShadowsHash : 0;
    };
    const uint64_t h0 = hashOf(original);
    auto masks = [](uint32_t m) {
        std::vector<ShadowWrite> w(4);
        for (int k = 0; k < 3; ++k) w[k].mask = m, w[k].groupMasks = {m, m + 1};
        w[3].terrain = true, w[3].mask = m;
        return w;
    };
    Expected<std::string> once = rewriteChunkShadows(original, "test", masks(1));
    ASSERT_TRUE(once) << once.error().what();
    ASSERT_NE(*once, original);
    EXPECT_EQ(hashOf(*once), h0) << *once;
    Expected<std::string> twice = rewriteChunkShadows(*once, "test", masks(6));
    ASSERT_TRUE(twice);
    EXPECT_EQ(hashOf(*twice), h0) << *twice;
    EXPECT_NE(hashOf(*once), 0u);

    auto edited = [&](const std::string& from, const std::string& to) {
        std::string text = original;
        const size_t at = text.find(from);
        EXPECT_NE(at, std::string::npos) << from;
        return hashOf(text.replace(at, from.size(), to));
    };
    EXPECT_NE(edited("keep me", "keep it"), h0) << "a comment";
    EXPECT_NE(edited("author=\"a\"", "author=\"b\""), h0) << "an attribute";
    EXPECT_NE(edited("<note> n </note>", "<note> n </note><shadow> 1 </shadow>"), h0) << "a <shadow> the bake does not write";
    EXPECT_NE(edited("<uuid> 1 </uuid>", "<uuid> 2 </uuid>"), h0) << "an object's text";
    EXPECT_NE(edited("<terrain/>", "<terrain><x/></terrain>"), h0) << "a child";
    EXPECT_EQ(edited("<terrain/>", "<terrain></terrain>"), h0) << "the same element";
}
