// The space builder writes what scene-format.md says: names, chunk-relative transforms,
// 16-bit terrain, OBJ groups, and exact world moves for the metamorphic tests.

#include "tests/support/space_builder.h"

#include <png.h>
#include <tinyxml2.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

namespace fs = std::filesystem;
using namespace shadowcull::testing;

namespace {

// A directory unique to the running test, emptied (not created: write() creates it).
fs::path scratchDir(const std::string& suffix = "") {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    fs::path dir = fs::temp_directory_path() / "shadowcull-tests" /
                   (std::string(info->test_suite_name()) + "." + info->name() + suffix);
    fs::remove_all(dir);
    return dir;
}

std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

// Text of a child element with the surrounding spaces the writer puts in removed.
std::string childText(const tinyxml2::XMLElement* e, const char* name) {
    const tinyxml2::XMLElement* c = e ? e->FirstChildElement(name) : nullptr;
    if (!c || !c->GetText()) return "";
    std::string s = c->GetText();
    const size_t b = s.find_first_not_of(" \t\n"), en = s.find_last_not_of(" \t\n");
    return b == std::string::npos ? "" : s.substr(b, en - b + 1);
}

// The model/terrain children of a chunk's root, in document order.
std::vector<const tinyxml2::XMLElement*> objects(const tinyxml2::XMLDocument& doc) {
    std::vector<const tinyxml2::XMLElement*> out;
    for (const auto* e = doc.RootElement()->FirstChildElement(); e; e = e->NextSiblingElement()) {
        const std::string n = e->Name();
        if (n == "model" || n == "terrain") out.push_back(e);
    }
    return out;
}

struct GreyPng {
    unsigned width = 0, height = 0;
    int bitDepth = 0, colourType = -1;
    std::vector<uint16_t> samples;  // row-major
};

// Reads a PNG from memory (no FILE* to close across libpng's longjmp).
GreyPng readPng(const fs::path& p) {
    struct Source {
        std::string bytes;
        size_t at = 0;
    } src{slurp(p), 0};
    GreyPng out;
    if (src.bytes.size() < 8) return out;
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
    png_infop info = png_create_info_struct(png);
    if (setjmp(png_jmpbuf(png)) != 0) {
        png_destroy_read_struct(&png, &info, nullptr);
        return GreyPng{};
    }
    png_set_read_fn(png, &src, [](png_structp ps, png_bytep data, png_size_t n) {
        auto* s = static_cast<Source*>(png_get_io_ptr(ps));
        if (s->at + n > s->bytes.size()) png_error(ps, "truncated");
        std::copy_n(s->bytes.data() + s->at, n, data);
        s->at += n;
    });
    png_read_png(png, info, PNG_TRANSFORM_IDENTITY, nullptr);
    out.width = png_get_image_width(png, info);
    out.height = png_get_image_height(png, info);
    out.bitDepth = png_get_bit_depth(png, info);
    out.colourType = png_get_color_type(png, info);
    png_bytepp rows = png_get_rows(png, info);
    for (unsigned j = 0; j < out.height; ++j)
        for (unsigned i = 0; i < out.width; ++i)
            out.samples.push_back(out.bitDepth == 16 ? uint16_t(rows[j][2 * i] << 8 | rows[j][2 * i + 1]) : rows[j][i]);
    png_destroy_read_struct(&png, &info, nullptr);
    return out;
}

}  // namespace

TEST(SpaceBuilder, ChunkNamesUseSixteenBitTwosComplementHex) {
    EXPECT_EQ(chunkName(0, 0), "00000000o.chunk");
    EXPECT_EQ(chunkName(-1, 0), "ffff0000o.chunk");
    EXPECT_EQ(chunkName(-2, -1), "fffeffffo.chunk");
    EXPECT_EQ(chunkName(1, -1), "0001ffffo.chunk");
    EXPECT_EQ(chunkName(1000, 10), "03e8000ao.chunk");
    EXPECT_EQ(chunkName(-32768, 32767), "80007fffo.chunk");
    EXPECT_THROW(chunkName(32768, 0), std::out_of_range);
    EXPECT_EQ(SpaceBuilder::terrainKey(-1, 2), "terrain:ffff0002");

    // Chunk squares are half-open: [gx*S, (gx+1)*S).
    EXPECT_EQ(chunkContaining(0.0, -0.001, 100), (ChunkId{0, -1}));
    EXPECT_EQ(chunkContaining(-100.0, 199.999, 100), (ChunkId{-1, 1}));
    EXPECT_EQ(chunkContaining(100.0, -100.0, 100), (ChunkId{1, -1}));
}

TEST(SpaceBuilder, NumbersAreShortestRoundTripText) {
    EXPECT_EQ(formatNumber(0.3), "0.3");
    EXPECT_EQ(formatNumber(100.0), "100");
    EXPECT_EQ(formatNumber(-0.0), "0");
    EXPECT_EQ(formatNumber(100046.6), "100046.6");
    EXPECT_EQ(fixedUuid(0xA1), "00000000-00000000-00000000-000000A1");
}

TEST(SpaceBuilder, WrittenSpaceParsesAndHoldsTheExpectedElements) {
    const fs::path dir = scratchDir();
    cubeOnTerrain().write(dir.string());

    tinyxml2::XMLDocument space;
    ASSERT_EQ(space.LoadFile((dir / "space.xml").string().c_str()), tinyxml2::XML_SUCCESS);
    const tinyxml2::XMLElement* root = space.RootElement();
    ASSERT_STREQ(root->Name(), "space");
    EXPECT_EQ(childText(root, "chunkSize"), "100");
    EXPECT_EQ(childText(root, "neighbours"), "1");
    EXPECT_EQ(childText(root, "terrainTolerance"), "0.01");
    const tinyxml2::XMLElement* sun = root->FirstChildElement("light");
    ASSERT_NE(sun, nullptr);
    EXPECT_EQ(sun->NextSiblingElement("light"), nullptr);
    EXPECT_EQ(childText(sun, "name"), "sun");
    EXPECT_EQ(childText(sun, "type"), "directional");
    EXPECT_EQ(childText(sun, "direction"), "0.3 -1 0.2");
    EXPECT_EQ(childText(sun, "bias"), "0.05");
    EXPECT_EQ(sun->FirstChildElement("position"), nullptr);

    tinyxml2::XMLDocument chunk;
    ASSERT_EQ(chunk.LoadFile((dir / "00000000o.chunk").string().c_str()), tinyxml2::XML_SUCCESS);
    const auto objs = objects(chunk);
    ASSERT_EQ(objs.size(), 2u);
    EXPECT_STREQ(objs[0]->Name(), "model");
    EXPECT_EQ(childText(objs[0], "resource"), "models/cube.obj");
    EXPECT_EQ(childText(objs[0], "uuid"), fixedUuid(1));
    EXPECT_EQ(childText(objs[0]->FirstChildElement("transform"), "row3"), "50 0 50");
    EXPECT_EQ(objs[0]->FirstChildElement("castsShadow"), nullptr);  // only written when asked
    EXPECT_STREQ(objs[1]->Name(), "terrain");
    EXPECT_EQ(childText(objs[1], "resource"), "terrain/00000000.terrain");

    tinyxml2::XMLDocument terrain;
    ASSERT_EQ(terrain.LoadFile((dir / "terrain/00000000.terrain").string().c_str()), tinyxml2::XML_SUCCESS);
    EXPECT_EQ(childText(terrain.RootElement(), "heights"), "00000000.png");
    EXPECT_EQ(childText(terrain.RootElement(), "minHeight"), "0");
    EXPECT_TRUE(fs::exists(dir / "terrain/00000000.png"));
    EXPECT_TRUE(fs::exists(dir / "models/cube.obj"));
    EXPECT_FALSE(fs::exists(dir / "models/cube.mtl"));  // a single plain group needs no material

    const auto where = cubeOnTerrain().locateObjects();
    EXPECT_EQ(where.at(fixedUuid(1)).chunkFile, "00000000o.chunk");
    EXPECT_EQ(where.at(fixedUuid(1)).elementIndex, 0);
    EXPECT_EQ(where.at(SpaceBuilder::terrainKey(0, 0)).elementIndex, 1);
}

TEST(SpaceBuilder, TransformsAreRelativeToTheChunkOrigin) {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addModel("cube", Affine::scaling({2, 2, 2}).then(Affine::translation({-30.5, 2, 150.25})), "A", false);
    b.addModel("cube", Affine::translation({0, 0, -0.5}), "B");
    const fs::path dir = scratchDir();
    b.write(dir.string());

    EXPECT_EQ(b.chunkFiles(), (std::vector<std::string>{"ffff0001o.chunk", "0000ffffo.chunk"}));
    tinyxml2::XMLDocument a;
    ASSERT_EQ(a.LoadFile((dir / "ffff0001o.chunk").string().c_str()), tinyxml2::XML_SUCCESS);
    const tinyxml2::XMLElement* ta = objects(a).at(0)->FirstChildElement("transform");
    EXPECT_EQ(childText(ta, "row0"), "2 0 0");
    EXPECT_EQ(childText(ta, "row3"), "69.5 2 50.25");  // (-30.5, 150.25) - (-100, 100)
    EXPECT_EQ(childText(objects(a).at(0), "castsShadow"), "false");

    tinyxml2::XMLDocument bdoc;
    ASSERT_EQ(bdoc.LoadFile((dir / "0000ffffo.chunk").string().c_str()), tinyxml2::XML_SUCCESS);
    EXPECT_EQ(childText(objects(bdoc).at(0)->FirstChildElement("transform"), "row3"), "0 0 99.5");
}

TEST(SpaceBuilder, TerrainIsA16BitGreyPngOfQuantisedHeights) {
    SpaceBuilder b;
    // Heights vary along both axes, so a swapped row/column order would show.
    auto height = [](double x, double z) { return 0.05 * x - 0.02 * z; };  // chunk (-1,1): -5..0 - 2..4
    b.addTerrain(-1, 1, 5, height, -10.0, 10.0);
    b.addFlatTerrain(0, 0, 3.25, 3);
    const fs::path dir = scratchDir();
    b.write(dir.string());

    const GreyPng png = readPng(dir / "terrain/ffff0001.png");
    ASSERT_EQ(png.width, 5u);
    ASSERT_EQ(png.height, 5u);
    EXPECT_EQ(png.bitDepth, 16);
    EXPECT_EQ(png.colourType, PNG_COLOR_TYPE_GRAY);
    for (int j = 0; j < 5; ++j)
        for (int i = 0; i < 5; ++i) {
            // Column i at chunk-local x = i*S/(N-1), row j at z = j*S/(N-1); origin (-100, 100).
            const double x = -100.0 + i * 25.0, z = 100.0 + j * 25.0;
            const uint16_t q = png.samples[size_t(j * 5 + i)];
            EXPECT_EQ(q, quantiseHeight(height(x, z), -10, 10)) << i << "," << j;
            EXPECT_NEAR(dequantiseHeight(q, -10, 10), height(x, z), 20.0 / 65535);
        }

    // Flat terrain reads back exactly: every sample is 0 = minHeight.
    const GreyPng flat = readPng(dir / "terrain/00000000.png");
    ASSERT_EQ(flat.samples.size(), 9u);
    for (uint16_t q : flat.samples) EXPECT_EQ(q, 0);
    tinyxml2::XMLDocument t;
    ASSERT_EQ(t.LoadFile((dir / "terrain/00000000.terrain").string().c_str()), tinyxml2::XML_SUCCESS);
    EXPECT_EQ(childText(t.RootElement(), "minHeight"), "3.25");
    EXPECT_EQ(*b.terrainHeightAt(37.0, 81.5), 3.25);

    // The surface height follows the (i,j)-(i+1,j+1) split; a plane is reproduced anywhere.
    EXPECT_NEAR(*b.terrainHeightAt(-63.0, 141.0), height(-63.0, 141.0), 1e-3);
    EXPECT_FALSE(b.terrainHeightAt(150.0, 0.0).has_value());
    EXPECT_THROW(quantiseHeight(10.5, -10, 10), std::range_error);
}

TEST(SpaceBuilder, QuarterTurnMovesModelsLightsAndTerrain) {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addModel("cube", Affine::translation({10, 0, 20}), "A");
    b.addLight(LightSpec::spot("torch", {10, 6, 20}, {1, -1, 0}, 20, 30));
    auto height = [](double x, double z) { return 0.01 * x + 0.001 * z; };
    b.addTerrain(0, 0, 3, height, -5, 5);
    const WorldTransform turn = WorldTransform::turned(1);
    EXPECT_EQ(turn.apply({10, 0, 20}), glm::dvec3(20, 0, -10));
    const fs::path dir = scratchDir();
    b.write(dir.string(), turn);

    // World (10,0,20) -> (20,0,-10): chunk (0,-1), local (20, 0, 90).
    const auto where = b.locateObjects(turn);
    EXPECT_EQ(where.at("A").chunkFile, "0000ffffo.chunk");
    tinyxml2::XMLDocument c;
    ASSERT_EQ(c.LoadFile((dir / "0000ffffo.chunk").string().c_str()), tinyxml2::XML_SUCCESS);
    const auto objs = objects(c);
    ASSERT_EQ(objs.size(), 2u);  // the cube and the terrain: chunk (0,0)'s square turns into (0,-1)
    const tinyxml2::XMLElement* tr = objs[0]->FirstChildElement("transform");
    EXPECT_EQ(childText(tr, "row0"), "0 0 -1");
    EXPECT_EQ(childText(tr, "row1"), "0 1 0");
    EXPECT_EQ(childText(tr, "row2"), "1 0 0");
    EXPECT_EQ(childText(tr, "row3"), "20 0 90");
    EXPECT_EQ(where.at(SpaceBuilder::terrainKey(0, 0)).chunkFile, "0000ffffo.chunk");
    EXPECT_EQ(where.at(SpaceBuilder::terrainKey(0, 0)).elementIndex, 1);

    tinyxml2::XMLDocument space;
    ASSERT_EQ(space.LoadFile((dir / "space.xml").string().c_str()), tinyxml2::XML_SUCCESS);
    const tinyxml2::XMLElement* torch = space.RootElement()->FirstChildElement("light");
    EXPECT_EQ(childText(torch, "position"), "20 6 -10");
    EXPECT_EQ(childText(torch, "direction"), "0 -1 -1");

    // Each new sample holds the height of the world point it came from.
    const GreyPng png = readPng(dir / "terrain/0000ffff.png");
    ASSERT_EQ(png.samples.size(), 9u);
    for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 3; ++i) {
            const double xNew = i * 50.0, zNew = -100.0 + j * 50.0;
            const double xOld = -zNew, zOld = xNew;  // inverse of x' = z, z' = -x
            EXPECT_EQ(png.samples[size_t(j * 3 + i)], quantiseHeight(height(xOld, zOld), -5, 5)) << i << "," << j;
        }

    // Four turns are the identity.
    EXPECT_EQ(b.locateObjects(WorldTransform::turned(4)).at("A").chunkFile, "00000000o.chunk");
    EXPECT_EQ(mapChunk({-3, 5}, WorldTransform::turned(2), 100), (ChunkId{2, -6}));
}

TEST(SpaceBuilder, HundredKilometreMoveKeepsChunkLocalTextIdentical) {
    const SpaceBuilder b = manyChunks(2);
    const fs::path a = scratchDir("-a"), moved = scratchDir("-moved");
    const WorldTransform far = WorldTransform::moved({100000.0, 0.0, -100000.0});
    b.write(a.string());
    b.write(moved.string(), far);

    const auto before = b.locateObjects(), after = b.locateObjects(far);
    ASSERT_EQ(before.size(), after.size());
    for (const auto& [key, loc] : before) {
        EXPECT_EQ(after.at(key).chunk, (ChunkId{loc.chunk.gx + 1000, loc.chunk.gz - 1000})) << key;
        EXPECT_EQ(after.at(key).elementIndex, loc.elementIndex) << key;
    }
    for (const std::string& name : b.chunkFiles()) {
        // Same file with the chunk names inside (terrain resources) renamed: identical text.
        const std::string oldBase = name.substr(0, 8);
        int gx = int(int16_t(std::stoi(oldBase.substr(0, 4), nullptr, 16)));
        int gz = int(int16_t(std::stoi(oldBase.substr(4, 4), nullptr, 16)));
        const std::string newBase = chunkBaseName(gx + 1000, gz - 1000);
        std::string expected = slurp(a / name);
        for (size_t at; (at = expected.find(oldBase)) != std::string::npos;) expected.replace(at, 8, newBase);
        EXPECT_EQ(slurp(moved / (newBase + "o.chunk")), expected) << name;
        EXPECT_EQ(slurp(a / "terrain" / (oldBase + ".png")), slurp(moved / "terrain" / (newBase + ".png")));
    }

    // 5 km up: terrain bounds and model heights shift by exactly 5000 m, samples stay.
    const fs::path up = scratchDir("-up");
    b.write(up.string(), WorldTransform::moved({0, 5000, 0}));
    tinyxml2::XMLDocument t;
    ASSERT_EQ(t.LoadFile((up / "terrain/00000000.terrain").string().c_str()), tinyxml2::XML_SUCCESS);
    EXPECT_EQ(childText(t.RootElement(), "minHeight"), "4998");
    EXPECT_EQ(childText(t.RootElement(), "maxHeight"), "5002");
    EXPECT_EQ(slurp(a / "terrain/00000000.png"), slurp(up / "terrain/00000000.png"));

    // Moves that are not whole chunks would change chunk-local text: refused.
    EXPECT_THROW(b.write(scratchDir("-bad").string(), WorldTransform::moved({150, 0, 0})), std::invalid_argument);
}

TEST(SpaceBuilder, MeshesWriteGroupsMaterialsAndOverrides) {
    MeshSpec tree = MeshSpec::box({-0.2, 0, -0.2}, {0.2, 3, 0.2}, GroupSpec::named("bark"));
    tree.append(MeshSpec::quad({-2, 2, 0}, {2, 2, 0}, {2, 6, 0}, {-2, 6, 0}, GroupSpec::named("leaves", true)));
    GroupSpec sign = GroupSpec::named("paint");
    sign.doubleSidedOverride = true;
    SpaceBuilder b;
    EXPECT_EQ(b.addMesh("tree", tree), "models/tree.obj");
    EXPECT_EQ(b.addMesh("sign", MeshSpec::quad({0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, sign)), "models/sign.model");
    EXPECT_EQ(b.addMesh("plain", MeshSpec::box({0, 0, 0}, {1, 1, 1}), true), "models/plain.model");
    b.addModel("tree", Affine::translation({5, 0, 5}));
    const fs::path dir = scratchDir();
    b.write(dir.string());

    const std::string obj = slurp(dir / "models/tree.obj");
    EXPECT_NE(obj.find("mtllib tree.mtl"), std::string::npos);
    const size_t bark = obj.find("usemtl bark"), leaves = obj.find("usemtl leaves");
    ASSERT_NE(bark, std::string::npos);
    ASSERT_NE(leaves, std::string::npos);
    EXPECT_LT(bark, leaves);  // group 0 first
    const std::string mtl = slurp(dir / "models/tree.mtl");
    EXPECT_NE(mtl.find("newmtl leaves\nKd 0.6 0.6 0.6\nmap_d tree_alpha.png"), std::string::npos);
    EXPECT_EQ(mtl.find("map_d", mtl.find("newmtl bark")), mtl.find("map_d"));  // only once, under leaves
    EXPECT_TRUE(fs::exists(dir / "models/tree_alpha.png"));

    tinyxml2::XMLDocument model;
    ASSERT_EQ(model.LoadFile((dir / "models/sign.model").string().c_str()), tinyxml2::XML_SUCCESS);
    EXPECT_EQ(childText(model.RootElement(), "visual"), "sign.obj");
    const tinyxml2::XMLElement* pg = model.RootElement()->FirstChildElement("primitiveGroup");
    ASSERT_NE(pg, nullptr);
    EXPECT_EQ(pg->IntAttribute("index", -1), 0);
    EXPECT_TRUE(pg->BoolAttribute("doubleSided", false));
    EXPECT_EQ(pg->Attribute("alphaTest"), nullptr);

    // Groups that would not exist in OBJ, or share a material, are refused at once.
    MeshSpec unused = MeshSpec::box({0, 0, 0}, {1, 1, 1});
    unused.addGroup(GroupSpec::named("ghost"));
    EXPECT_THROW(b.addMesh("unused", unused), std::invalid_argument);
    EXPECT_THROW(b.addModel("nosuchmesh", Affine{}), std::invalid_argument);
}

TEST(SpaceBuilder, BoxesAreClosedAndFaceOutwards) {
    for (const MeshSpec& m : {MeshSpec::box({-1, 2, 3}, {4, 2.5, 3.005}), MeshSpec::rod(2.0, 0.005)}) {
        // Closed and consistently wound: every directed edge appears once, its reverse once.
        std::map<std::pair<int, int>, int> edges;
        double volume6 = 0;
        for (const auto& t : m.triangles) {
            for (int k = 0; k < 3; ++k) ++edges[{t[size_t(k)], t[size_t((k + 1) % 3)]}];
            const glm::dvec3& a = m.positions[size_t(t[0])];
            const glm::dvec3& b = m.positions[size_t(t[1])];
            const glm::dvec3& c = m.positions[size_t(t[2])];
            volume6 += a.x * (b.y * c.z - b.z * c.y) - a.y * (b.x * c.z - b.z * c.x) + a.z * (b.x * c.y - b.y * c.x);
        }
        EXPECT_EQ(m.triangles.size(), 12u);
        EXPECT_EQ(m.positions.size(), 8u);
        for (const auto& [e, n] : edges) {
            EXPECT_EQ(n, 1);
            EXPECT_EQ(edges.count({e.second, e.first}), 1u);
        }
        EXPECT_GT(volume6, 0);  // outward (counter-clockwise from outside) gives positive volume
    }
    EXPECT_EQ(MeshSpec::openBox({0, 0, 0}, {1, 1, 1}).triangles.size(), 10u);
    // Two cubes welded along an edge: that edge carries four triangles.
    const MeshSpec nm = MeshSpec::edgeSharingCubes(1.0);
    EXPECT_EQ(nm.positions.size(), 14u);
    int onEdge = 0;
    for (const auto& t : nm.triangles) {
        int hits = 0;
        for (int v : t) hits += nm.positions[size_t(v)].x == 1.0 && nm.positions[size_t(v)].y == 1.0;
        onEdge += hits == 2;
    }
    EXPECT_EQ(onEdge, 4);
}

TEST(SpaceBuilder, ChunkXmlExtrasAndForcedChunksAreWritten) {
    SpaceBuilder b;
    b.options().neighbours = {2, 0, 1, 3};  // left, right, top, bottom
    b.addChunkXml(0, 0, "<!-- keep me -->\n<editorInfo revision=\"7\"> <note> v2 </note> </editorInfo>");
    b.addChunk(-3, 4);
    EXPECT_THROW(b.addChunkXml(0, 0, "<model/>"), std::invalid_argument);
    const fs::path dir = scratchDir();
    b.write(dir.string());
    EXPECT_EQ(b.chunkFiles(), (std::vector<std::string>{"fffd0004o.chunk", "00000000o.chunk"}));
    const std::string text = slurp(dir / "00000000o.chunk");
    EXPECT_NE(text.find("<!-- keep me -->"), std::string::npos);
    tinyxml2::XMLDocument c;
    ASSERT_EQ(c.Parse(text.c_str()), tinyxml2::XML_SUCCESS);
    EXPECT_NE(c.RootElement()->FirstChildElement("editorInfo"), nullptr);
    EXPECT_NE(slurp(dir / "space.xml").find("<neighbours left=\"2\" right=\"0\" top=\"1\" bottom=\"3\"/>"),
              std::string::npos);

    // Neighbour counts turn with the world: +x (right) becomes -z (bottom), and so on.
    const fs::path turned = scratchDir("-turned");
    b.write(turned.string(), WorldTransform::turned(1));
    EXPECT_NE(slurp(turned / "space.xml").find("<neighbours left=\"3\" right=\"1\" top=\"2\" bottom=\"0\"/>"),
              std::string::npos);

    // A non-empty directory is refused (stale chunks would join the space).
    EXPECT_THROW(b.write(dir.string()), std::runtime_error);
}

TEST(SpaceBuilder, KnownAnswerScenesWriteAndLocateTheirExpectations) {
    const std::vector<std::pair<std::string, SpaceBuilder>> scenes = {
        {"cubeOnTerrain", cubeOnTerrain()},   {"twoFloatingCubes", twoFloatingCubes()},
        {"rangeAndCone", rangeAndCone()},     {"thinRod", thinRod()},
        {"twoLightsMasks", twoLightsMasks()}, {"hiddenOpaque", hiddenUnderRoof(Roof::Opaque)},
        {"hiddenAlpha", hiddenUnderRoof(Roof::AlphaTested)}};
    std::map<std::string, fs::path> written;
    for (const auto& [name, scene] : scenes) {
        EXPECT_FALSE(scene.expectations().empty()) << name;
        for (const WorldTransform& wt : {WorldTransform::identity(), WorldTransform::turned(1),
                                         WorldTransform::moved({100000, 5000, 100000})}) {
            const auto where = scene.locateObjects(wt);
            for (const KnownAnswer& k : scene.expectations()) EXPECT_EQ(where.count(k.key), 1u) << name << " " << k.key;
        }
        const fs::path dir = written[name] = scratchDir("-" + name);
        ASSERT_NO_THROW(scene.write(dir.string())) << name;
        EXPECT_TRUE(fs::exists(dir / "space.xml")) << name;
    }
    // The alpha variant goes through a .model override, the opaque one names the OBJ.
    EXPECT_NE(slurp(written["hiddenAlpha"] / "models/roof.model").find("alphaTest=\"true\""), std::string::npos);
    EXPECT_TRUE(fs::exists(written["hiddenOpaque"] / "models/roof.obj"));
    EXPECT_FALSE(fs::exists(written["hiddenOpaque"] / "models/roof.model"));
    EXPECT_EQ(twoLightsMasks().expectations().at(0).mask, 2u);
    EXPECT_EQ(twoLightsMasks().expectations().at(1).mask, 3u);

    const SpaceBuilder many = manyChunks(3);
    EXPECT_EQ(many.chunkFiles().size(), 9u);
    EXPECT_EQ(many.locateObjects().size(), 9u * 4u);  // 3 cubes + 1 terrain per chunk
}

TEST(SpaceBuilder, ResourceRootHoldsModelsAndTerrain) {
    SpaceBuilder b;
    b.options().resourceRoot = "res";
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addFile("models/extra.gltf", "{\"asset\": {\"version\": \"2.0\"}}");
    b.addModel("cube", Affine::translation({1, 0, 1}));
    b.addModel("models/extra.gltf", Affine::translation({2, 0, 2}));  // a path, used verbatim
    b.addFlatTerrain(0, 0, -4.5);
    const fs::path dir = scratchDir();
    b.write(dir.string());
    EXPECT_NE(slurp(dir / "space.xml").find("<resourceRoot> res </resourceRoot>"), std::string::npos);
    EXPECT_TRUE(fs::exists(dir / "res/models/cube.obj"));
    EXPECT_TRUE(fs::exists(dir / "res/models/extra.gltf"));
    EXPECT_TRUE(fs::exists(dir / "res/terrain/00000000.terrain"));
    EXPECT_NE(slurp(dir / "00000000o.chunk").find("<resource> models/extra.gltf </resource>"), std::string::npos);
}
