// `shadowcull preview` (gpu/preview.h): the frame shadowed as an engine does it, with every
// caster and with only the kept ones. The masks promise (docs/semantics.md, "Why the frames
// agree") zero differing pixels wherever the light's filterRadius covers the shadow map's
// sampling footprint; these tests hold the bake to it on the sample space and on a generated
// world, from cameras above the chunk centres, low over the terrain, looking along and
// against the light. Any differing pixel where the condition holds is printed with the
// caster whose removal changed it and the receiver point (a false cull or a modelling error,
// to be turned into a known-answer scene). The detector itself is checked on a deliberate
// false cull.
#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include "bench/world_gen.h"
#include "cli/pipeline.h"
#include "cli/preview_command.h"
#include "gltf/gltf_import.h"
#include "gpu/preview.h"
#include "tests/support/gl_available.h"
#include "tests/support/gltf_scenes.h"
#include "tests/support/sample_space.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

// Rewrites every light's <filterRadius> in space.xml: `directional` metres for directional
// lights, `local` for point and spot lights (the footprint of a perspective map is smaller).
void setFilterRadii(const fs::path& space, double directional, double local) {
    std::ifstream in(space / "space.xml");
    std::stringstream ss;
    ss << in.rdbuf();
    std::string xml = ss.str(), out;
    size_t at = 0;
    while (true) {
        const size_t b = xml.find("<light>", at);
        if (b == std::string::npos) break;
        const size_t e = xml.find("</light>", b);
        out += xml.substr(at, b - at);
        std::string block = xml.substr(b, e - b);
        const bool dir = block.find("directional") != std::string::npos;
        std::ostringstream value;
        value << "<filterRadius> " << (dir ? directional : local) << " </filterRadius>";
        static const std::regex old("<filterRadius>[^<]*</filterRadius>");
        if (std::regex_search(block, old)) block = std::regex_replace(block, old, value.str());
        else block += value.str() + "\n  ";
        out += block;
        at = e;
    }
    out += xml.substr(at);
    std::ofstream(space / "space.xml", std::ios::trunc) << out;
}

struct Camera {
    std::string name;
    glm::dvec3 wsEye, wsTarget;
};

// The brief's camera set for one chunk and light: above the chunk centre, low over the
// terrain, looking along the light and against it (world coordinates).
std::vector<Camera> camerasFor(const BakeWindow& w, const Light& L) {
    const double S = w.chunkSize;
    auto ground = [&](double x, double z) {
        std::optional<double> h = w.lsTerrainHeight(x, z);
        return h ? *h : (w.lsCentreBounds.empty() ? 0.0 : w.lsCentreBounds.min.y);
    };
    const glm::dvec3 centre(S / 2, ground(S / 2, S / 2), S / 2);
    // Horizontal direction of travel (for a straight-down light: +x).
    glm::dvec3 along = L.type == LightType::Point ? centre - L.position : L.direction;
    along.y = 0;
    along = glm::length(along) > 1e-6 ? glm::normalize(along) : glm::dvec3(1, 0, 0);
    std::vector<Camera> cams;
    cams.push_back({"above the centre", centre + glm::dvec3(0, 0.85 * S, 0.55 * S), centre});
    const glm::dvec3 lowEye(0.1 * S, ground(0.1 * S, 0.2 * S) + 2.0, 0.2 * S);
    cams.push_back({"low over the terrain", lowEye, glm::dvec3(0.7 * S, ground(0.7 * S, 0.6 * S), 0.6 * S)});
    const glm::dvec3 a0 = centre - along * (0.35 * S);
    cams.push_back({"along the light", a0 + glm::dvec3(0, 12, 0), centre + along * (0.2 * S)});
    const glm::dvec3 b0 = centre + along * (0.35 * S);
    cams.push_back({"against the light", b0 + glm::dvec3(0, 12, 0), centre - along * (0.2 * S)});
    for (Camera& c : cams) c.wsEye += w.wsOrigin, c.wsTarget += w.wsOrigin;
    return cams;
}

Expected<cli::ChunkBake> bake(const fs::path& space, ChunkCoord c) {
    cli::BakeOptions opt;
    opt.spaceDir = space.string();
    opt.write = false;
    return cli::bakeChunk(opt, c);
}

std::string describe(const gpu::PreviewReport& r) {
    std::ostringstream s;
    s << r.differingPixels << " differing pixels, " << r.differingCovered << " where the filter covers the footprint (of "
      << r.coveredPixels << " covered, " << r.receiverPixels << " lit); on kept surfaces " << r.differingOnKeptSurfaces
      << " (false culls), on culled casters' own surfaces " << r.differingOnOwnSurfaces << " (+" << r.falseCullsOnOwnSurfaces
      << " with a witness), in the band " << r.differingInBand << "; PCF " << r.pcfRadius << ", footprint "
      << r.worstFootprint << " m";
    for (const gpu::DifferingPixel& d : r.listed)
        s << "\n  pixel " << d.x << "," << d.y << " " << gpu::pixelClassName(d.cls) << (d.covered ? " COVERED" : "")
          << ": receiver " << d.receiver
          << " at (" << d.wsReceiver.x << ", " << d.wsReceiver.y << ", " << d.wsReceiver.z << "), caster " << d.caster
          << " [" << d.casterProof << "], footprint " << d.footprint << " m";
    return s.str();
}

struct Totals {
    uint64_t previews = 0, covered = 0, culled = 0, differing = 0, ownSurface = 0, band = 0;
};

// Every light of `chunk` from every camera: no false cull shows (no differing pixel on a kept
// surface, none where the filter covers the footprint, none on a culled caster's own surface
// with a witness). Returns what was seen, so that callers can check the run was not vacuous.
Totals checkChunk(const fs::path& space, ChunkCoord chunk, int shadowResolution, const fs::path& pictures) {
    Totals t;
    Expected<cli::ChunkBake> cb = bake(space, chunk);
    EXPECT_TRUE(cb) << (cb ? "" : cb.error().what());
    if (!cb) return t;
    for (size_t l = 0; l < cb->window.lsLights.size(); ++l) {
        const Light& L = cb->window.lsLights[l];
        const std::vector<Camera> cams = camerasFor(cb->window, L);
        for (size_t ci = 0; ci < cams.size(); ++ci) {
            const Camera& cam = cams[ci];
            gpu::PreviewRequest rq;
            rq.light = int(l);
            rq.shadowResolution = shadowResolution;
            rq.wsEye = cam.wsEye, rq.wsTarget = cam.wsTarget;
            rq.width = 320, rq.height = 240;
            rq.timingRepeats = 1;
            rq.maxListed = 5;
            const fs::path png = pictures / (chunkFileName(chunk) + "-light" + std::to_string(l + 1) + "-" + std::to_string(ci) + ".png");
            Expected<gpu::PreviewReport> r = gpu::renderShadowPreview(cb->window, cb->verdicts, rq, png.string());
            EXPECT_TRUE(r) << (r ? "" : r.error().what());
            if (!r) continue;
            ++t.previews;
            t.covered += r->coveredPixels;
            t.culled += r->culledCasters;
            t.differing += r->differingPixels;
            t.ownSurface += r->differingOnOwnSurfaces;
            t.band += r->differingInBand;
            EXPECT_EQ(r->differingPixels, r->differingOnKeptSurfaces + r->falseCullsOnOwnSurfaces +
                                              r->differingOnOwnSurfaces + r->differingInBand);
            EXPECT_EQ(r->falseCullPixels(), 0u)
                << space.filename().string() << " " << chunkFileName(chunk) << ", light " << l + 1 << " '" << L.name
                << "', camera " << cam.name << ": " << describe(*r);
            EXPECT_EQ(r->differingCovered, 0u)
                << space.filename().string() << " " << chunkFileName(chunk) << ", light " << l + 1 << " '" << L.name
                << "', camera " << cam.name << ": " << describe(*r);
            EXPECT_LE(r->differingPixels, r->receiverPixels);
            if (L.filterRadius == 0) {
                EXPECT_EQ(r->coveredPixels, 0u);
            }
        }
    }
    return t;
}

// The generated forest world (bench/world_gen's worldS), thinned to keep a test short,
// named `name`, with every filterRadius set (directional, local): chunk (0,0) checked
// from four cameras a light at 1024 px.
Totals checkThinnedForest(const std::string& name, double directional, double local) {
    const fs::path dir = freshTestDir();
    const fs::path space = dir / "world";
    bench::WorldSpec spec = bench::worldS();
    spec.name = name;
    spec.objectsPerChunk = 60;
    spec.localLights = 3;
    spec.seed = 14;
    bench::writeWorld(spec, space.string());
    setFilterRadii(space, directional, local);
    return checkChunk(space, ChunkCoord{0, 0}, 1024, dir);
}

}  // namespace

TEST(Preview, DefaultPcfRadiusKeepsTheFootprintWithinTheFilter) {
    // (R + 1/2) diagonals <= filterRadius, largest R; none fits: 0.
    EXPECT_EQ(gpu::defaultPcfRadius(0.0, 0.1), 0);
    EXPECT_EQ(gpu::defaultPcfRadius(0.04, 0.1), 0);   // half a diagonal (0.05) already exceeds
    EXPECT_EQ(gpu::defaultPcfRadius(0.05, 0.1), 0);
    EXPECT_EQ(gpu::defaultPcfRadius(0.149, 0.1), 0);
    EXPECT_EQ(gpu::defaultPcfRadius(0.15, 0.1), 1);
    EXPECT_EQ(gpu::defaultPcfRadius(0.36, 0.1), 3);
    EXPECT_EQ(gpu::defaultPcfRadius(100.0, 0.1), 8);  // capped
    for (double r : {0.07, 0.2, 0.33, 0.61})
        EXPECT_LE((gpu::defaultPcfRadius(r, 0.1) + 0.5) * 0.1, r + 1e-12) << r;
}

// The sample space with every light filtering wider than its footprint (directional 1.2 m
// against a 1024 map over ~350 m; point and spot 0.15 m at 25 m range), every chunk that
// holds a light's reach, four cameras each.
TEST(Preview, SampleSpaceFramesAgreeWhereTheFilterCoversTheFootprint) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir();
    const fs::path space = dir / "space";
    sampleSpace().write(space.string());
    setFilterRadii(space, 1.2, 0.15);
    Totals all;
    for (ChunkCoord c : {ChunkCoord{0, 0}, ChunkCoord{-1, -1}}) {
        const Totals t = checkChunk(space, c, 1024, dir);
        all.previews += t.previews, all.covered += t.covered, all.culled += t.culled;
    }
    EXPECT_EQ(all.previews, 2u * 3u * 4u);
    EXPECT_GT(all.covered, 100000u);  // the condition held on most lit pixels: the test saw something
    EXPECT_GT(all.culled, 0u);        // and casters were culled in those frames
}

// filterRadius 0 (the sample as shipped): no pixel is covered, and still no false cull shows:
// the frames differ only on culled casters' own surfaces (their acne) and in the texel-edge
// band. The counts are printed for docs/semantics.md.
TEST(Preview, SampleSpaceWithoutFilterShowsNoFalseCull) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir();
    const fs::path space = dir / "space";
    sampleSpace().write(space.string());
    const Totals t = checkChunk(space, ChunkCoord{0, 0}, 1024, dir);
    EXPECT_EQ(t.covered, 0u);
    EXPECT_GT(t.culled, 0u);
    std::cout << "sample, filterRadius 0, chunk 00000000o: " << t.differing << " differing pixels over " << t.previews
              << " previews of 320 x 240: " << t.ownSurface << " on culled casters' own surfaces, " << t.band
              << " in the texel-edge band, 0 false culls\n";
}

// A generated forest world (bench/world_gen: terrain, alpha-tested trees, buried chests,
// floating balloons, castsShadow-false grass, point and spot lights), thinned to keep the
// test short, with filters wider than the footprint.
TEST(Preview, GeneratedWorldFramesAgreeWhereTheFilterCoversTheFootprint) {
    REQUIRE_GL();
    const Totals t = checkThinnedForest("preview", 1.2, 0.3);
    EXPECT_EQ(t.previews, 6u * 4u);
    EXPECT_GT(t.covered, 100000u);
    EXPECT_GT(t.culled, 0u);
}

// The same world with every filterRadius 0: no pixel is covered, and still no
// false cull shows from any camera, for the sun, the point and the spot lights.
TEST(Preview, GeneratedWorldWithoutFilterShowsNoFalseCull) {
    REQUIRE_GL();
    const Totals t = checkThinnedForest("preview0", 0.0, 0.0);  // some of its lights have one as generated
    EXPECT_EQ(t.previews, 6u * 4u);
    EXPECT_EQ(t.covered, 0u);
    EXPECT_GT(t.culled, 0u);
}

// The glTF courtyard (tests/support/gltf_scenes: sun, lamp and torch on nodes, an
// alpha-masked bush, a mirrored shelf, a node that casts no shadow) imported as a user
// would, filterRadius 0: every chunk it covers, every light, four cameras.
TEST(Preview, CourtyardShowsNoFalseCull) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir();
    const fs::path scene = dir / "courtyard.glb";
    writeText(scene, courtyardScene().scene.glb());
    gltf::ImportOptions io;
    io.scenePath = scene.string();
    io.outDir = (dir / "space").string();
    Expected<gltf::ImportReport> imported = gltf::importScene(io);
    ASSERT_TRUE(imported) << imported.error().what();
    Totals all;
    for (ChunkCoord c : {ChunkCoord{0, 0}, ChunkCoord{-1, -1}, ChunkCoord{-1, 0}, ChunkCoord{0, -1}}) {
        const Totals t = checkChunk(dir / "space", c, 1024, dir);
        all.previews += t.previews, all.covered += t.covered, all.culled += t.culled;
    }
    EXPECT_EQ(all.previews, 4u * 3u * 4u);
    EXPECT_EQ(all.covered, 0u);
    EXPECT_GT(all.culled, 0u);
}

namespace {

// Every kept model group of the centre chunk for `light`, culled by hand (a deliberate
// false cull). Returns how many.
int cullKeptModels(ChunkVerdicts& cv, int light) {
    int flipped = 0;
    for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
        const ObjectVerdicts& ov = cv.objects[oi];
        if (ov.terrain) continue;
        for (int g = 0; g < ov.groupCount; ++g)
            if (cv.at(oi, g, light).verdict == Verdict::Kept) {
                cv.at(oi, g, light).verdict = Verdict::Culled;
                ++flipped;
            }
    }
    return flipped;
}

}  // namespace

namespace {

// The sample's chunk 00000000o baked, then every model the sun kept marked culled by hand
// (each has a witness: its shadow shows), previewed for the sun from above.
Expected<gpu::PreviewReport> previewWithKeptModelsCulled(const fs::path& space, const fs::path& png) {
    Expected<cli::ChunkBake> cb = bake(space, ChunkCoord{0, 0});
    if (!cb) return cb.error();
    EXPECT_GT(cullKeptModels(cb->verdicts, 0), 0);
    gpu::PreviewRequest rq;
    rq.light = 0;
    rq.shadowResolution = 1024;
    rq.width = 320, rq.height = 240;
    rq.timingRepeats = 1;
    return gpu::renderShadowPreview(cb->window, cb->verdicts, rq, png.string());
}

}  // namespace

// The detector: a caster that does cast a visible shadow (the sample's house, kept with a
// witness for the sun), marked culled by hand, must show as differing pixels where the
// filter covers the footprint, with that caster named.
TEST(Preview, DeliberateFalseCullIsCaughtAndNamed) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir();
    const fs::path space = dir / "space";
    sampleSpace().write(space.string());
    setFilterRadii(space, 1.2, 0.15);
    Expected<gpu::PreviewReport> r = previewWithKeptModelsCulled(space, dir / "false.png");
    ASSERT_TRUE(r) << r.error().what();
    EXPECT_GT(r->differingCovered, 50u) << describe(*r);
    ASSERT_FALSE(r->listed.empty());
    EXPECT_TRUE(r->listed[0].covered) << describe(*r);
    EXPECT_NE(r->listed[0].caster.find("00000000o.chunk"), std::string::npos) << describe(*r);
    EXPECT_FALSE(r->listed[0].receiver.empty());
    EXPECT_LT(r->kept.triangles, r->all.triangles);
}

// The same with filterRadius 0 (the sample as shipped), where every differing texel lies
// beyond the filter: the exact light rays through the receivers still catch the missing
// shadows on kept surfaces and name the casters.
TEST(Preview, DeliberateFalseCullWithoutFilterIsCaughtAndNamed) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir();
    const fs::path space = dir / "space";
    sampleSpace().write(space.string());
    Expected<gpu::PreviewReport> r = previewWithKeptModelsCulled(space, dir / "false0.png");
    ASSERT_TRUE(r) << r.error().what();
    EXPECT_EQ(r->coveredPixels, 0u);
    EXPECT_GT(r->differingOnKeptSurfaces, 50u) << describe(*r);
    ASSERT_FALSE(r->falseCulls.empty()) << describe(*r);
    EXPECT_NE(r->falseCulls[0].caster.find("00000000o.chunk model"), std::string::npos) << r->falseCulls[0].caster;
    ASSERT_FALSE(r->listed.empty());
    EXPECT_EQ(r->listed[0].cls, gpu::PixelClass::FalseCull) << describe(*r);
    EXPECT_TRUE(r->listed[0].exactWitness) << describe(*r);
}

// The command as a user runs it: the lines it promises, and the picture.
TEST(Preview, CommandPrintsDifferingPixelsAndPassCosts) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir();
    const fs::path space = dir / "space";
    sampleSpace().write(space.string());
    cli::PreviewOptions o;
    o.bake.spaceDir = space.string();
    o.chunk = "00000000o";
    o.light = 2;
    o.shadowResolution = 256;
    o.repeats = 1;
    o.outPath = (dir / "p.png").string();
    std::ostringstream out, err;
    EXPECT_EQ(cli::runPreview(o, out, err), 0) << err.str();
    EXPECT_NE(out.str().find("\ndiffering pixels: "), std::string::npos) << out.str();
    EXPECT_NE(out.str().find("\ndiffering on kept surfaces: 0\n"), std::string::npos) << out.str();
    EXPECT_NE(out.str().find("shadow pass, all casters:  "), std::string::npos) << out.str();
    EXPECT_NE(out.str().find("shadow pass, kept casters: "), std::string::npos) << out.str();
    EXPECT_TRUE(fs::exists(o.outPath));
    o.camera = "1,2,3,1,2";
    std::ostringstream out2, err2;
    EXPECT_EQ(cli::runPreview(o, out2, err2), 2);
    EXPECT_NE(err2.str().find("six numbers"), std::string::npos) << err2.str();
}

namespace {

// A known answer at texel scale: a floor with a square hole, and a plate 1 m above that
// covers all of the hole but a 2 cm margin, under a sun straight down. Every ray through the
// plate falls through the hole (into nothing): with filterRadius 0 the plate's bit is 0. The
// engine's map (256 texels over the floor's 80 m: 31 cm texels, their grid starting at the
// floor's edge x = 10, v = -90) still shadows the floor just outside the hole from the
// texels that straddle the gap with their centres over the plate (x in [48.75, 48.83]
// reads the texel centred at 48.906), so the frames differ there, at texel scale. With
// filterRadius 0.25 m (more than half a texel's diagonal, 0.22 m) the floor is within reach:
// the plate is kept and the frames agree.
fs::path writePlateOverHole(const fs::path& dir, double filterRadius) {
    SpaceBuilder b;
    auto ground = [](double x0, double z0, double x1, double z1) {
        return MeshSpec::quad({x0, 0, z0}, {x0, 0, z1}, {x1, 0, z1}, {x1, 0, z0});
    };
    const double h0 = 48.83, h1 = 51.17;  // the hole
    MeshSpec floor = ground(10, 10, 90, h0);
    floor.append(ground(10, h1, 90, 90)).append(ground(10, h0, h0, h1)).append(ground(h1, h0, 90, h1));
    b.addMesh("floor", floor.welded());
    b.addMesh("plate", MeshSpec::quad({48.85, 1, 48.85}, {48.85, 1, 51.15}, {51.15, 1, 51.15}, {51.15, 1, 48.85}));
    b.addModel("floor", Affine{});
    b.addModel("plate", Affine{});
    b.addLight(LightSpec::directional("sun", {0, -1, 0}).withBias(0.05).withFilterRadius(filterRadius));
    b.write(dir.string());
    return dir;
}

gpu::PreviewReport previewPlate(const fs::path& space, const fs::path& png) {
    Expected<cli::ChunkBake> cb = bake(space, ChunkCoord{0, 0});
    EXPECT_TRUE(cb) << (cb ? "" : cb.error().what());
    if (!cb) return {};
    gpu::PreviewRequest rq;
    rq.shadowResolution = 256;
    rq.wsEye = glm::dvec3(50, 6, 53);
    rq.wsTarget = glm::dvec3(50, 0, 50);
    rq.timingRepeats = 1;
    Expected<gpu::PreviewReport> r = gpu::renderShadowPreview(cb->window, cb->verdicts, rq, png.string());
    EXPECT_TRUE(r) << (r ? "" : r.error().what());
    return r ? *r : gpu::PreviewReport{};
}

}  // namespace

TEST(Preview, PlateOverAHoleDiffersAtTexelScaleOnlyWithoutFilter) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir();
    const gpu::PreviewReport r0 = previewPlate(writePlateOverHole(dir / "r0", 0.0), dir / "r0.png");
    EXPECT_EQ(r0.culledCasters, 5u);  // the plate, and the floor's four quads (nothing under them)
    EXPECT_GT(r0.differingPixels, 0u) << describe(r0);  // texel scale: the floor at the hole's rim
    EXPECT_EQ(r0.differingCovered, 0u);
    // No witness: the plate's texel-edge band on the floor (culled too, but another caster).
    EXPECT_EQ(r0.falseCullPixels(), 0u) << describe(r0);
    EXPECT_EQ(r0.differingInBand, r0.differingPixels) << describe(r0);
    for (const gpu::DifferingPixel& d : r0.listed) {
        EXPECT_EQ(d.cls, gpu::PixelClass::Band);
        EXPECT_NE(d.caster.find("model #1"), std::string::npos) << d.caster;  // the plate
        EXPECT_LT(std::abs(std::max(std::abs(d.wsReceiver.x - 50), std::abs(d.wsReceiver.z - 50)) - 1.17), 0.35)
            << "not at the hole's rim: " << d.wsReceiver.x << ", " << d.wsReceiver.z;
    }
    std::cout << "plate over a hole, filterRadius 0: " << r0.differingPixels << " differing pixels of "
              << r0.receiverPixels << "\n";
    const gpu::PreviewReport r2 = previewPlate(writePlateOverHole(dir / "r2", 0.25), dir / "r2.png");
    EXPECT_EQ(r2.culledCasters, 4u);  // the floor's quads only: the plate is kept
    EXPECT_EQ(r2.differingPixels, 0u) << describe(r2);
    EXPECT_GT(r2.coveredPixels, 10000u);
}
