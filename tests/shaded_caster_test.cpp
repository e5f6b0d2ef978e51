// Condition 1 of semantics.md in the geometry stage (issue 19): a reached part of a
// receiver whose caster points one opaque triangle shades wholly gives no candidate, so a
// caster lit nowhere its shadow could land is proved 0 without the GPU stage; where the
// shade covers only part of it, the bit stays a 1.

#include <gtest/gtest.h>

#include "cli/pipeline.h"
#include "geometry/exact_frustum.h"
#include "tests/support/bake_lookup.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
using geometry::ExactFrustum;
using geometry::LightGeometry;
using geometry::OccluderSource;
using geometry::Triangle;
namespace fs = std::filesystem;

namespace {

// A 1 m plate 1 m over flat ground, under a roof quad at y = 3 spanning x from 40 to
// `roofEnd` (z 40..60), a sun nearly overhead. The plate's column meets y = 3 within
// x 51.8..52.8, z 44.9..45.9: inside the roof's triangle x - 50 >= z - 50 when the roof
// reaches x = 60; half of it outside when the roof stops at 52.5.
SpaceBuilder plateUnderRoof(double roofEnd, std::string* plate, std::string* roof) {
    SpaceBuilder b;
    b.addLight(LightSpec::directional("sun", {0.1, -1.0, 0.05}));
    b.addFlatTerrain(0, 0, 0.0);
    b.addMesh("plate", MeshSpec::quad({-0.5, 0, -0.5}, {-0.5, 0, 0.5}, {0.5, 0, 0.5}, {0.5, 0, -0.5}));
    const double e = roofEnd - 50.0;
    b.addMesh("roof", MeshSpec::quad({-10, 0, -10}, {-10, 0, 10}, {e, 0, 10}, {e, 0, -10}));
    *plate = b.addModel("plate", Affine::translation({52.5, 1.0, 45.5}));
    *roof = b.addModel("roof", Affine::translation({50.0, 3.0, 50.0}));
    return b;
}

cli::BakeResult bakeWithoutGpu(const SpaceBuilder& b, const fs::path& dir) {
    b.write(dir.string());
    cli::BakeOptions opt;
    opt.spaceDir = dir.string();
    opt.write = false;
    opt.useGpu = false;  // the GPU stage proves "hidden by others" on its own
    opt.geometry.crossCheckWitnesses = true;  // a witness and a proof of 0 must never meet
    Expected<cli::BakeResult> r = cli::runBake(opt);
    EXPECT_TRUE(r) << (r ? "" : r.error().what());
    return r ? std::move(*r) : cli::BakeResult{};
}

}  // namespace

TEST(ShadedCaster, PlateUnderARoofIsProvedZeroByTheGeometryStage) {
    std::string plate, roof;
    const SpaceBuilder b = plateUnderRoof(60.0, &plate, &roof);
    const cli::BakeResult r = bakeWithoutGpu(b, freshTestDir() / "space");
    const auto objects = b.locateObjects();
    const Decision* d = findDecision(r, objects.at(plate), 0, 0);
    ASSERT_NE(d, nullptr);
    EXPECT_EQ(d->verdict, Verdict::Culled) << d->stage << ": " << d->reason();
    EXPECT_EQ(d->stage, std::string("geometry"));
    EXPECT_NE(d->reason().find("p not lit"), std::string_view::npos) << d->reason();  // the proof says how
    const Decision* dr = findDecision(r, objects.at(roof), 0, 0);
    ASSERT_NE(dr, nullptr);
    EXPECT_EQ(dr->verdict, Verdict::Kept) << "the roof's shadow falls on the plate and the ground";
}

TEST(ShadedCaster, PlateHalfUnderARoofKeepsItsShadow) {
    std::string plate, roof;
    const SpaceBuilder b = plateUnderRoof(52.5, &plate, &roof);
    const cli::BakeResult r = bakeWithoutGpu(b, freshTestDir() / "space");
    const Decision* d = findDecision(r, b.locateObjects().at(plate), 0, 0);
    ASSERT_NE(d, nullptr);
    EXPECT_EQ(d->verdict, Verdict::Kept) << d->stage << ": " << d->reason();
}

// The exact test itself: a caster at y = 2 over a floor triangle, light straight down.
TEST(ShadedCaster, ExactTestDropsOnlyWhatOneOccluderShadesWholly) {
    const LightGeometry down{true, {0, -1, 0}, {0, 0, 0}};
    const Triangle caster = {glm::dvec3(0, 2, 0), glm::dvec3(0, 2, 1), glm::dvec3(1, 2, 0)};
    const ExactFrustum f(caster, down, 0.0);
    const Triangle floor = {glm::dvec3(-5, 0, -5), glm::dvec3(-5, 0, 5), glm::dvec3(5, 0, 5)};  // holds x <= z
    const Triangle floor2 = {glm::dvec3(-5, 0, -5), glm::dvec3(5, 0, 5), glm::dvec3(5, 0, -5)};
    ASSERT_TRUE(f.reaches(floor, 0.0) || f.reaches(floor2, 0.0));
    auto source = [](std::vector<Triangle> tris) {
        return OccluderSource([tris](const std::array<glm::dvec3, 2>&, std::vector<Triangle>& out) {
            out.insert(out.end(), tris.begin(), tris.end());
        });
    };
    // Over x + z <= 20: the whole column. halfAbove: x <= 0.3 there, a part of it.
    const Triangle bigAbove = {glm::dvec3(-10, 3, -10), glm::dvec3(-10, 3, 30), glm::dvec3(30, 3, -10)};
    const Triangle bigBelow = {glm::dvec3(-10, 1, -10), glm::dvec3(-10, 1, 30), glm::dvec3(30, 1, -10)};  // between caster and floor
    const Triangle halfAbove = {glm::dvec3(0.3, 3, -100), glm::dvec3(0.3, 3, 100), glm::dvec3(-100, 3, 0)};
    const Triangle touching = {glm::dvec3(-10, 2, -10), glm::dvec3(-10, 2, 30), glm::dvec3(30, 2, -10)};  // the caster's plane
    for (const Triangle& r : {floor, floor2}) {
        const bool reached = f.reaches(r, 0.0);
        const OccluderSource above = source({bigAbove}), below = source({bigBelow}), half = source({halfAbove}),
                             plane = source({touching}), both = source({bigBelow, bigAbove});
        EXPECT_FALSE(f.reaches(r, 0.0, nullptr, nullptr, &above));
        EXPECT_EQ(f.reaches(r, 0.0, nullptr, nullptr, &below), reached) << "behind the caster: shades nothing";
        EXPECT_EQ(f.reaches(r, 0.0, nullptr, nullptr, &half), reached) << "covers part of it only";
        EXPECT_EQ(f.reaches(r, 0.0, nullptr, nullptr, &plane), reached) << "in the caster's plane: not strictly in front";
        EXPECT_FALSE(f.reaches(r, 0.0, nullptr, nullptr, &both));
        // The terrain rule's test takes the same occluders.
        EXPECT_FALSE(f.reachesAboveGround(r, 0.0, {floor, floor2}, {}, 0.01, nullptr, &above));
        EXPECT_EQ(f.reachesAboveGround(r, 0.0, {floor, floor2}, {}, 0.01, nullptr, &half), reached);
    }
    // A point light: not modelled, the occluders are not used.
    const LightGeometry lamp{false, {0, 0, 0}, {0.3, 10, 0.3}};
    const ExactFrustum fl(caster, lamp, 0.0);
    const OccluderSource above = source({bigAbove});
    EXPECT_EQ(fl.reaches(floor, 0.0, nullptr, nullptr, &above), fl.reaches(floor, 0.0));
}

// The occluders are offered one by one and the walk ends at the first that shades the part:
// the rest of a long column towards the light is never walked. Until one shades, every
// triangle is offered, in the walk's order.
TEST(ShadedCaster, OccluderWalkEndsAtTheFirstThatShades) {
    const LightGeometry down{true, {0, -1, 0}, {0, 0, 0}};
    const Triangle caster = {glm::dvec3(0, 2, 0), glm::dvec3(0, 2, 1), glm::dvec3(1, 2, 0)};
    const ExactFrustum f(caster, down, 0.0);
    const Triangle floor = {glm::dvec3(-5, 0, -5), glm::dvec3(-5, 0, 5), glm::dvec3(5, 0, 5)};
    ASSERT_TRUE(f.reaches(floor, 0.0));
    const Triangle below = {glm::dvec3(-10, 1, -10), glm::dvec3(-10, 1, 30), glm::dvec3(30, 1, -10)};  // behind the caster
    const Triangle above = {glm::dvec3(-10, 3, -10), glm::dvec3(-10, 3, 30), glm::dvec3(30, 3, -10)};  // shades it wholly
    // Offered per walk (the exact path, should the interval one restart, walks again).
    auto walkOf = [](std::vector<Triangle> tris, std::vector<size_t>& offered) {
        return OccluderSource(OccluderSource::Walk([tris, &offered](const std::array<glm::dvec3, 2>&, const OccluderSource::Visit& visit) {
            offered.push_back(0);
            for (const Triangle& t : tris) {
                ++offered.back();
                if (visit(t)) return;
            }
        }));
    };
    std::vector<size_t> offered;
    const OccluderSource shading = walkOf({below, below, above, above, below}, offered);
    EXPECT_FALSE(f.reaches(floor, 0.0, nullptr, nullptr, &shading));
    EXPECT_TRUE(shading.shadedSome.load());
    ASSERT_FALSE(offered.empty());
    for (size_t n : offered) EXPECT_EQ(n, 3u);
    offered.clear();
    const OccluderSource none = walkOf({below, below, below}, offered);
    EXPECT_TRUE(f.reaches(floor, 0.0, nullptr, nullptr, &none));
    EXPECT_FALSE(none.shadedSome.load());
    ASSERT_FALSE(offered.empty());
    for (size_t n : offered) EXPECT_EQ(n, 3u);
}
