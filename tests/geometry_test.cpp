// geometry/: exact shadow-volume proofs on scenes with known answers, hard cases included
// (coplanar, touching, grazing, under terrain, bias, degenerate and open meshes), and the
// same scenes moved 100 km and turned.

#include <cmath>
#include <functional>
#include <memory>

#include <CGAL/FPU.h>
#include <glm/geometric.hpp>

#include <gtest/gtest.h>

#include "cli/pipeline.h"
#include "cli/report.h"
#include "geometry/exact_frustum.h"
#include "geometry/geometry_stage.h"
#include "geometry/receiver_rules.h"
#include "tests/support/bake_lookup.h"
#include "tests/support/loaded_window.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

using geometry::ExactFrustum;
using geometry::LightGeometry;
using geometry::Triangle;

const LightGeometry kDown{true, {0, -1, 0}, {0, 0, 0}};

// --- The exact frustum test on single triangles --------------------------------------

TEST(ExactFrustum, ReceiverBelowIsReachedAndAboveIsNot) {
    const Triangle caster = {glm::dvec3(0, 1, 0), glm::dvec3(0, 1, 1), glm::dvec3(1, 1, 0)};
    const ExactFrustum f(caster, kDown, 0.0);
    ASSERT_FALSE(f.degenerate());
    const Triangle below = {glm::dvec3(-5, 0, -5), glm::dvec3(-5, 0, 5), glm::dvec3(5, 0, -5)};
    const Triangle above = {glm::dvec3(-5, 2, -5), glm::dvec3(-5, 2, 5), glm::dvec3(5, 2, -5)};
    const Triangle beside = {glm::dvec3(2, 0, 2), glm::dvec3(2, 0, 3), glm::dvec3(3, 0, 2)};
    EXPECT_TRUE(f.reaches(below, 0.0));
    EXPECT_FALSE(f.reaches(above, 0.0));
    EXPECT_FALSE(f.reaches(beside, 0.0));
    // Bias: 1 m below is reached with a bias of 0.999, not with 1.0 (strictly behind).
    EXPECT_TRUE(f.reaches(below, 0.999));
    EXPECT_FALSE(f.reaches(below, 1.0));
}

// The occluders' source places triangles in double as every stage does, so it must run in
// round-to-nearest: called inside the interval code's upward rounding, the geometry stage
// placed the caster's own triangle an ulp nearer the light, where it "shaded" the caster
// (a false cull the exact reference found, issue 34). Fails when find() runs upward.
TEST(ExactFrustum, OccluderSourceRunsInRoundToNearest) {
    const Triangle caster = {glm::dvec3(0, 1, 0), glm::dvec3(0, 1, 1), glm::dvec3(1, 1, 0)};
    const ExactFrustum f(caster, kDown, 0.0);
    int calls = 0, nearest = 0;
    const geometry::OccluderSource source([&](const std::array<glm::dvec3, 2>&, std::vector<Triangle>&) {
        ++calls;
        nearest += CGAL::FPU_get_cw() == CGAL_FE_TONEAREST;  // the mode CGAL's protection sets
    });
    // A receiver wholly inside the shadow (the interval path decides it) and one across its
    // edge (the exact path does).
    const Triangle inside = {glm::dvec3(0.1, 0, 0.1), glm::dvec3(0.1, 0, 0.3), glm::dvec3(0.3, 0, 0.1)};
    const Triangle across = {glm::dvec3(-5, 0, -5), glm::dvec3(-5, 0, 5), glm::dvec3(5, 0, -5)};
    EXPECT_TRUE(f.reaches(inside, 0.5, nullptr, nullptr, &source));
    EXPECT_TRUE(f.reaches(across, 0.0, nullptr, nullptr, &source));
    EXPECT_EQ(CGAL::FPU_get_cw(), CGAL_FE_TONEAREST);
    ASSERT_GT(calls, 0);
    EXPECT_EQ(nearest, calls);
}

TEST(ExactFrustum, CoplanarAndTouchingReceiversAreNotStrictlyBehind) {
    const Triangle caster = {glm::dvec3(0, 0, 0), glm::dvec3(0, 0, 1), glm::dvec3(1, 0, 0)};
    const ExactFrustum f(caster, kDown, 0.0);
    // The same plane, overlapping: depth equal, never strictly behind.
    const Triangle coplanar = {glm::dvec3(-5, 0, -5), glm::dvec3(-5, 0, 5), glm::dvec3(5, 0, -5)};
    EXPECT_FALSE(f.reaches(coplanar, 0.0));
    EXPECT_FALSE(f.reaches(caster, 0.0)) << "a triangle does not shadow itself";
    // A vertical wall touching the caster along its edge x = 0, going down: behind.
    const Triangle wallDown = {glm::dvec3(0, 0, 0), glm::dvec3(0, -1, 0), glm::dvec3(0, 0, 1)};
    EXPECT_TRUE(f.reaches(wallDown, 0.0));
    // The same wall going up only touches the frustum at depth 0.
    const Triangle wallUp = {glm::dvec3(0, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1)};
    EXPECT_FALSE(f.reaches(wallUp, 0.0));
    // 1e-12 m below the plane is strictly behind: exact arithmetic sees it.
    const Triangle justBelow = {glm::dvec3(0.1, -1e-12, 0.1), glm::dvec3(0.1, -1e-12, 0.2), glm::dvec3(0.2, -1e-12, 0.1)};
    EXPECT_TRUE(f.reaches(justBelow, 0.0));
}

TEST(ExactFrustum, EdgeOnCasterCastsASheetAndFacingIsExact) {
    const Triangle wall = {glm::dvec3(0, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1)};
    const ExactFrustum sheet(wall, kDown, 0.0);
    EXPECT_FALSE(sheet.degenerate());
    // The sheet hangs below the wall in its plane x = 0: a floor crossing x = 0 below it is
    // reached, so is one at the wall's foot (points of the wall lie above that line); the
    // same floor beside the plane is not, nor one level with the wall's top vertex.
    const Triangle crossing = {glm::dvec3(-1, -1, 0.2), glm::dvec3(-1, -1, 0.4), glm::dvec3(1, -1, 0.2)};
    const Triangle beside = {glm::dvec3(1, -1, 0.2), glm::dvec3(1, -1, 0.4), glm::dvec3(2, -1, 0.2)};
    const Triangle atFoot = {glm::dvec3(-1, 0, 0.2), glm::dvec3(-1, 0, 0.4), glm::dvec3(1, 0, 0.2)};
    const Triangle atTop = {glm::dvec3(-1, 1, -0.2), glm::dvec3(-1, 1, 0.4), glm::dvec3(1, 1, -0.2)};
    EXPECT_TRUE(sheet.reaches(crossing, 0.0));
    EXPECT_FALSE(sheet.reaches(beside, 0.0));
    EXPECT_TRUE(sheet.reaches(atFoot, 0.0));
    EXPECT_FALSE(sheet.reaches(atTop, 0.0));
    // A triangle with collinear vertices casts a sheet too (here in the plane z = 0).
    const Triangle sliver = {glm::dvec3(0, 0, 0), glm::dvec3(0.5, 0, 0), glm::dvec3(1, 0, 0)};
    const Triangle under = {glm::dvec3(0.2, -1, -0.1), glm::dvec3(0.2, -1, 0.1), glm::dvec3(0.8, -1, -0.1)};
    EXPECT_TRUE(ExactFrustum(sliver, kDown, 0.0).reaches(under, 0.0));
    EXPECT_FALSE(ExactFrustum(sliver, kDown, 0.0).reaches(crossing, 0.0));
    // A point light in the caster's plane: a wedge in that plane, behind the caster as seen
    // from the light (issue 18); degenerate only with the light on or inside the caster.
    const ExactFrustum wedge(wall, LightGeometry{false, {0, 0, 0}, {0, 5, 3}}, 0.0);
    EXPECT_FALSE(wedge.degenerate());
    // From (0, 5, 3) through the wall the wedge continues below y = 0 towards -z.
    const Triangle crossingBelow = {glm::dvec3(-1, -1, -0.5), glm::dvec3(-1, -1, 0.1), glm::dvec3(1, -1, -0.5)};
    const Triangle crossingBeyondCone = {glm::dvec3(-1, -1, 1.2), glm::dvec3(-1, -1, 1.4), glm::dvec3(1, -1, 1.2)};
    EXPECT_TRUE(wedge.reaches(crossingBelow, 0.0));
    EXPECT_FALSE(wedge.reaches(crossingBeyondCone, 0.0));
    EXPECT_FALSE(wedge.reaches(beside, 0.0));
    EXPECT_FALSE(wedge.reaches(atTop, 0.0));
    EXPECT_TRUE(ExactFrustum(wall, LightGeometry{false, {0, 0, 0}, {0, 0.2, 0.2}}, 0.0).degenerate());
    EXPECT_TRUE(ExactFrustum(wall, LightGeometry{false, {0, 0, 0}, {0, 0.5, 0}}, 0.0).degenerate());
    const Triangle floorUp = {glm::dvec3(0, 0, 0), glm::dvec3(0, 0, 1), glm::dvec3(1, 0, 0)};
    const Triangle floorDown = {glm::dvec3(0, 0, 0), glm::dvec3(1, 0, 0), glm::dvec3(0, 0, 1)};
    EXPECT_EQ(geometry::exactFacing(floorUp, false, kDown), 1);
    EXPECT_EQ(geometry::exactFacing(floorDown, false, kDown), -1);
    EXPECT_EQ(geometry::exactFacing(floorDown, true, kDown), 1) << "a mirroring transform swaps the sides";
    const LightGeometry grazing{true, {1, 0, 0}, {0, 0, 0}};
    EXPECT_EQ(geometry::exactFacing(floorUp, false, grazing), 0);
    const LightGeometry lamp{false, {0, 0, 0}, {0.25, 3, 0.25}};
    EXPECT_EQ(geometry::exactFacing(floorUp, false, lamp), 1);
    EXPECT_EQ(geometry::exactFacing(floorDown, false, lamp), -1);
}

// An edge-on caster's sheet is exactly {p + s d : p in t, s > beta} in its plane: the
// faces that share its edges only touch it there, what lies beside or before it is not
// reached, and what lies beyond it along the light is, unless within the bias.
TEST(ExactFrustum, SheetIsBoundedByTheEdgesTheLightEntersBy) {
    const LightGeometry diagonal{true, {1, -1, 0}, {0, 0, 0}};
    // The z = 0 face of a unit cube, edge-on to the light.
    const Triangle face = {glm::dvec3(0, 0, 0), glm::dvec3(1, 1, 0), glm::dvec3(0, 1, 0)};
    const ExactFrustum sheet(face, diagonal, 0.0);
    ASSERT_FALSE(sheet.degenerate());
    // The cube's top (y = 1) and left (x = 0) faces share the face's edges.
    const Triangle top = {glm::dvec3(0, 1, 0), glm::dvec3(1, 1, 0), glm::dvec3(1, 1, 1)};
    const Triangle left = {glm::dvec3(0, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 1, 1)};
    EXPECT_FALSE(sheet.reaches(top, 0.0));
    EXPECT_FALSE(sheet.reaches(left, 0.0));
    // In the plane: above the face (y > 1), left of it (x < 0): before the light reaches it.
    EXPECT_FALSE(sheet.reaches({glm::dvec3(0.2, 1.1, 0), glm::dvec3(0.8, 1.1, 0), glm::dvec3(0.5, 1.5, 0)}, 0.0));
    EXPECT_FALSE(sheet.reaches({glm::dvec3(-0.5, 0.2, 0), glm::dvec3(-0.1, 0.2, 0), glm::dvec3(-0.3, 0.8, 0)}, 0.0));
    // Beyond it along the light: reached, across the plane too; its farthest point lies 0.8 d
    // beyond the face, so not with a bias above that (in units of d, as the exact test takes it).
    const Triangle beyond = {glm::dvec3(1.2, 0.3, -0.5), glm::dvec3(1.4, 0.3, 0.5), glm::dvec3(1.3, 0.1, 0.5)};
    EXPECT_TRUE(sheet.reaches(beyond, 0.0));
    EXPECT_TRUE(sheet.reaches(beyond, 0.75));
    EXPECT_FALSE(sheet.reaches(beyond, 0.85));
    // A triangle whose vertices lie each on a different bounding line, none inside: the
    // polygon touches every boundary but holds points strictly inside all of them.
    EXPECT_TRUE(sheet.reaches({glm::dvec3(0.5, 1.0, 0), glm::dvec3(0.0, 0.5, 0), glm::dvec3(1.5, -0.5, 0)}, 0.0));
}

TEST(ExactFrustum, PointLightFrustumAndDilation) {
    const LightGeometry lamp{false, {0, 0, 0}, {0, 10, 0}};
    const Triangle caster = {glm::dvec3(-1, 5, -1), glm::dvec3(-1, 5, 1), glm::dvec3(1, 5, -1)};
    const ExactFrustum f(caster, lamp, 0.0);
    // The shadow spreads: at y = 0 the frustum reaches x = -2 (twice the caster's extent).
    const Triangle farLeft = {glm::dvec3(-1.95, 0, -0.1), glm::dvec3(-1.95, 0, 0.1), glm::dvec3(-1.9, 0, -0.1)};
    const Triangle outside = {glm::dvec3(-2.2, 0, -0.1), glm::dvec3(-2.2, 0, 0.1), glm::dvec3(-2.1, 0, -0.1)};
    EXPECT_TRUE(f.reaches(farLeft, 0.0));
    EXPECT_FALSE(f.reaches(outside, 0.0));
    // A filter radius of 0.5 m reaches the triangle 0.1..0.2 m outside.
    EXPECT_TRUE(ExactFrustum(caster, lamp, 0.5).reaches(outside, 0.0));
}

// The exact terrain rule: a wall standing in the ground is reached by a caster's shadow
// below and above the ground; only its part above the ground (or within the tolerance
// under it) counts.
TEST(ExactFrustum, ReachesAboveGroundCountsOnlyWhatIsNotBuried) {
    const Triangle caster = {glm::dvec3(0, 2, 0), glm::dvec3(0, 2, 1), glm::dvec3(1, 2, 0)};
    const ExactFrustum f(caster, kDown, 0.0);
    // A wall across the column from y = -1 to y = 1 (front towards the light? two-sided
    // here: the rule only asks where its points are).
    const Triangle wall = {glm::dvec3(0.2, -1, 0.3), glm::dvec3(0.4, 1, 0.3), glm::dvec3(0.6, -1, 0.3)};
    ASSERT_TRUE(f.reaches(wall, 0.0));
    // Ground: two triangles of the plane y = h over [-5, 5]^2, wound either way.
    auto ground = [](double h) {
        return std::vector<Triangle>{{glm::dvec3(-5, h, -5), glm::dvec3(-5, h, 5), glm::dvec3(5, h, 5)},
                                     {glm::dvec3(-5, h, -5), glm::dvec3(5, h, -5), glm::dvec3(5, h, 5)}};
    };
    EXPECT_TRUE(f.reachesAboveGround(wall, 0.0, ground(0.0), {}, 0.0));    // its top half is above
    EXPECT_FALSE(f.reachesAboveGround(wall, 0.0, ground(1.5), {}, 0.0));   // all buried
    EXPECT_FALSE(f.reachesAboveGround(wall, 0.0, ground(1.5), {}, 0.49));  // deeper than the tolerance
    EXPECT_TRUE(f.reachesAboveGround(wall, 0.0, ground(1.5), {}, 0.51));   // its top within it
    EXPECT_TRUE(f.reachesAboveGround(wall, 0.0, ground(1.0), {}, 0.0));    // touching the surface counts
    // The bias still applies: more than 2 m behind the caster (y = 2) is under the ground.
    EXPECT_TRUE(f.reachesAboveGround(wall, 1.9, ground(0.0), {}, 0.0));
    EXPECT_FALSE(f.reachesAboveGround(wall, 2.0, ground(0.0), {}, 0.0));
    // Ground that does not lie under the reached part decides nothing (the caller checks
    // coverage): here it is beside it, so no point is found above it.
    const std::vector<Triangle> beside = {{glm::dvec3(3, 5, 3), glm::dvec3(3, 5, 4), glm::dvec3(4, 5, 3)}};
    EXPECT_FALSE(f.reachesAboveGround(wall, 0.0, beside, {}, 0.0));
}

// A square with no terrain (the world's edge) is an opening: over it every height
// receives, and nowhere else.
TEST(ExactFrustum, ReachesAboveGroundOverAnOpeningAtAnyHeight) {
    const Triangle caster = {glm::dvec3(0, 2, 0), glm::dvec3(0, 2, 1), glm::dvec3(1, 2, 0)};
    const ExactFrustum f(caster, kDown, 0.0);
    const Triangle wall = {glm::dvec3(0.2, -1, 0.3), glm::dvec3(0.4, 1, 0.3), glm::dvec3(0.6, -1, 0.3)};
    // Ground at y = 1.5 over x <= 0.5 only: the wall is buried there.
    const std::vector<Triangle> west = {{glm::dvec3(-5, 1.5, -5), glm::dvec3(-5, 1.5, 5), glm::dvec3(0.5, 1.5, 5)},
                                        {glm::dvec3(-5, 1.5, -5), glm::dvec3(0.5, 1.5, -5), glm::dvec3(0.5, 1.5, 5)}};
    EXPECT_FALSE(f.reachesAboveGround(wall, 0.0, west, {}, 0.0));
    // The rest of the wall's column (x in [0.5, 0.7] at z = 0.3) over an opening: reached.
    EXPECT_TRUE(f.reachesAboveGround(wall, 0.0, west, {GroundOpening{0.5, -5, 5, 5}}, 0.0));
    // An opening beside the part reached decides nothing.
    EXPECT_FALSE(f.reachesAboveGround(wall, 0.0, west, {GroundOpening{0.8, -5, 5, 5}}, 0.0));
    EXPECT_FALSE(f.reachesAboveGround(wall, 0.0, west, {GroundOpening{-5, 0.5, 5, 5}}, 0.0));
}

// --- Scenes through the pipeline ----------------------------------------------------------

cli::BakeResult bake(const SpaceBuilder& b, const fs::path& dir, const WorldTransform& wt = {}, bool crossCheck = true) {
    b.write(dir.string(), wt);
    cli::BakeOptions opt;
    opt.spaceDir = dir.string();
    opt.write = false;
    opt.geometry.crossCheckWitnesses = crossCheck;
    Expected<cli::BakeResult> r = cli::runBake(opt);
    EXPECT_TRUE(r) << (r ? "" : r.error().what());
    return r ? std::move(*r) : cli::BakeResult{};
}


// One hard case: a builder and, per model uuid (group 0, light 1), the expected outcome.
struct HardCase {
    const char* name;
    std::function<SpaceBuilder(std::map<std::string, Verdict>&)> make;
};

SpaceBuilder flatWorld(const LightSpec& light, bool terrain = false) {
    SpaceBuilder b;
    if (terrain) b.addFlatTerrain(0, 0, 0.0);
    b.addLight(light);
    return b;
}

MeshSpec quadFacing(double y, bool up, double size = 1.0) {
    MeshSpec m;
    int g = m.addGroup(GroupSpec{});
    int a = m.addVertex({0, y, 0}), b = m.addVertex({0, y, size}), c = m.addVertex({size, y, size}), d = m.addVertex({size, y, 0});
    if (up) {
        m.addTriangle(a, b, c, g);
        m.addTriangle(a, c, d, g);
    } else {
        m.addTriangle(a, c, b, g);
        m.addTriangle(a, d, c, g);
    }
    return m;
}

const std::vector<HardCase>& hardCases() {
    static const std::vector<HardCase> cases = {
        {"floating cube over nothing",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {0.3, -1, 0.2}));
             b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
             want[b.addModel("cube", Affine::translation({50, 20, 50}))] = Verdict::Culled;
             return b;
         }},
        // Light along a diagonal: two side faces of each cube are edge-on (their shadow is a
        // sheet in their own plane, which only touches the neighbouring faces along their
        // shared edges), and nothing else is loaded (issue 15: stayed undecided).
        {"lone cubes lit along diagonals (side faces edge-on)",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {1, -1, 0}));
             b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
             want[b.addModel("cube", Affine::translation({50, 5, 50}))] = Verdict::Culled;
             want[b.addModel("cube", Affine::rotationY(90).then(Affine::translation({20, 5, 70})))] = Verdict::Culled;
             want[b.addModel("cube", Affine::rotationY(45).then(Affine::translation({70, 5, 20})))] = Verdict::Culled;
             return b;
         }},
        {"caster touching its receiver (cube on a floor)",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {0.3, -1, 0.2}));
             b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
             b.addMesh("floor", quadFacing(0, true, 20));
             want[b.addModel("cube", Affine::translation({50, 0, 50}))] = Verdict::Kept;
             b.addModel("floor", Affine::translation({40, 0, 40}));
             return b;
         }},
        {"receiver coplanar with the caster (a decal lying on the floor, no bias)",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {0.3, -1, 0.2}));
             b.addMesh("decal", quadFacing(0, true, 1));
             b.addMesh("floor", quadFacing(0, true, 20));
             want[b.addModel("decal", Affine::translation({50, 0, 50}))] = Verdict::Culled;
             b.addModel("floor", Affine::translation({40, 0, 40}));
             return b;
         }},
        {"decal 2 mm above a floor, bias 5 cm",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {0.3, -1, 0.2}).withBias(0.05));
             b.addMesh("decal", quadFacing(0, true, 1));
             b.addMesh("floor", quadFacing(0, true, 20));
             want[b.addModel("decal", Affine::translation({50, 0.002, 50}))] = Verdict::Culled;
             b.addModel("floor", Affine::translation({40, 0, 40}));
             return b;
         }},
        {"decal 2 mm above a floor, no bias",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {0.3, -1, 0.2}));
             b.addMesh("decal", quadFacing(0, true, 1));
             b.addMesh("floor", quadFacing(0, true, 20));
             want[b.addModel("decal", Affine::translation({50, 0.002, 50}))] = Verdict::Kept;
             b.addModel("floor", Affine::translation({40, 0, 40}));
             return b;
         }},
        {"decal 2 mm before a wall, bias 5 cm (horizontal light)",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {1, -0.2, 0.1}).withBias(0.05));
             // A wall facing -x at x = 52, and a decal 2 mm before it.
             MeshSpec wall = quadFacing(0, true, 10), decal = quadFacing(0, true, 1);
             b.addMesh("wall", wall);
             b.addMesh("decal", decal);
             // Turn the up-facing quads to face -x: rows map local y to world -x.
             const Affine toWall{glm::dvec3(0, 1, 0), glm::dvec3(-1, 0, 0), glm::dvec3(0, 0, 1), glm::dvec3(0)};
             b.addModel("wall", toWall.then(Affine::translation({52, 0, 45})));
             want[b.addModel("decal", toWall.then(Affine::translation({51.998, 4, 49})))] = Verdict::Culled;
             return b;
         }},
        {"decal 2 mm before a wall, no bias (horizontal light)",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {1, -0.2, 0.1}));
             b.addMesh("wall", quadFacing(0, true, 10));
             b.addMesh("decal", quadFacing(0, true, 1));
             const Affine toWall{glm::dvec3(0, 1, 0), glm::dvec3(-1, 0, 0), glm::dvec3(0, 0, 1), glm::dvec3(0)};
             b.addModel("wall", toWall.then(Affine::translation({52, 0, 45})));
             want[b.addModel("decal", toWall.then(Affine::translation({51.998, 4, 49})))] = Verdict::Kept;
             return b;
         }},
        {"point lamp: cube over a floor beyond the lamp's range",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::point("lamp", {50.5, 8, 50.5}, 6));
             b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
             b.addMesh("floor", quadFacing(0, true, 20));
             // The floor is 8 m under the lamp, range 6: nothing the cube shades is lit.
             want[b.addModel("cube", Affine::translation({50, 4, 50}))] = Verdict::Culled;
             b.addModel("floor", Affine::translation({40, 0, 40}));
             return b;
         }},
        // One group: a small face 7 m from the lamp facing it, whose shadow passes over the
        // floor's far edge, and a patch 20 m away (beyond range) over the floor. Only the
        // face can hold p; the patch's shadow reaches the floor, whose triangles reach into
        // range (was undecided: every caster triangle was tested, in range or not).
        {"point lamp: a group the range cuts, its part within range shading nothing",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::point("lamp", {50, 5, 50}, 10));
             b.addMesh("parts", faceAndFarPatch());
             b.addMesh("floor", quadFacing(0, true, 50));
             want[b.addModel("parts", Affine::translation({50, 0, 50}))] = Verdict::Culled;
             b.addModel("floor", Affine::translation({30, 0, 30}));
             return b;
         }},
        {"spot light: cube over a floor within range",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::spot("torch", {50.5, 8, 50.5}, {0, -1, 0}, 20, 30));
             b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
             b.addMesh("floor", quadFacing(0, true, 20));
             want[b.addModel("cube", Affine::translation({50, 4, 50}))] = Verdict::Kept;
             b.addModel("floor", Affine::translation({40, 0, 40}));
             return b;
         }},
        {"one-sided floor facing away from the light",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {0.3, -1, 0.2}));
             b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
             b.addMesh("floor", quadFacing(0, false, 20));
             want[b.addModel("cube", Affine::translation({50, 2, 50}))] = Verdict::Culled;
             b.addModel("floor", Affine::translation({40, 0, 40}));
             return b;
         }},
        {"light exactly parallel to the floor",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {1, 0, 0}));
             b.addMesh("post", MeshSpec::box({0, 0, 0}, {0.2, 2, 0.2}));
             b.addMesh("floor", quadFacing(0, true, 20));
             // The post stands on the floor; with light parallel to the floor, only the
             // post's far side could receive, and that faces away: nothing receives.
             want[b.addModel("post", Affine::translation({45, 0, 50}))] = Verdict::Culled;
             b.addModel("floor", Affine::translation({40, 0, 40}));
             return b;
         }},
        {"light one degree above the floor",
         [](auto& want) {
             const double a = 1.0 * 3.14159265358979323846 / 180.0;
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {std::cos(a), -std::sin(a), 0}));
             b.addMesh("post", MeshSpec::box({0, 0, 0}, {0.2, 2, 0.2}));
             b.addMesh("floor", quadFacing(0, true, 200));
             want[b.addModel("post", Affine::translation({45, 0, 50}))] = Verdict::Kept;
             b.addModel("floor", Affine::translation({0, 0, 0}));
             return b;
         }},
        {"receiver under terrain",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {0.3, -1, 0.2}), true);
             b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
             b.addMesh("slab", MeshSpec::box({0, 0, 0}, {10, 0.5, 10}));
             // A cube floating 5 m up over a slab buried 1 m deep: the slab does not count,
             // the terrain receives: kept. (Terrain is a receiver.)
             want[b.addModel("cube", Affine::translation({50, 5, 50}))] = Verdict::Kept;
             b.addModel("slab", Affine::translation({45, -1.5, 45}));
             return b;
         }},
        {"caster under terrain, receiver only under terrain",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {0.3, -1, 0.2}), true);
             b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
             b.addMesh("slab", MeshSpec::box({0, 0, 0}, {10, 0.5, 10}));
             // Both buried: the terrain is above the cube, the slab is deeper than the
             // tolerance: nothing can receive. (Terrain itself casts, the cube is not behind... )
             want[b.addModel("cube", Affine::translation({50, -3, 50}))] = Verdict::Culled;
             b.addModel("slab", Affine::translation({45, -6, 45}));
             return b;
         }},
        {"degenerate triangles, duplicate vertices, open and non-manifold meshes over nothing",
         [](auto& want) {
             SpaceBuilder b = flatWorld(LightSpec::directional("sun", {0.3, -1, 0.2}));
             // An open box (no top: light falls in onto inner faces, which are backs), a
             // point, a collinear sliver, duplicate vertices, and two cubes sharing an edge
             // placed apart so that neither shadows the other.
             MeshSpec messy = MeshSpec::openBox({0, 0, 0}, {1, 1, 1});
             const int g = 0;
             const int p = messy.addVertex({3.5, 0.5, 0.5});
             messy.addTriangle(p, p, p, g);
             const int q = messy.addVertex({3.7, 0.5, 0.5}), r = messy.addVertex({3.9, 0.5, 0.5});
             messy.addTriangle(p, q, r, g);
             const int dup = messy.addVertex({0, 0, 0});
             messy.addTriangle(dup, messy.addVertex({0, 0, 0}), messy.addVertex({0, 0, 0}), g);
             MeshSpec cubes = MeshSpec::edgeSharingCubes(0.5);
             for (auto& v : cubes.positions) v += glm::dvec3(-6, 0, 0);
             messy.append(cubes);
             b.addMesh("messy", messy);
             want[b.addModel("messy", Affine::translation({50, 30, 50}))] = Verdict::Culled;
             return b;
         }},
    };
    return cases;
}

}  // namespace

// Each hard case, as built, moved 100 km, and turned a quarter: the expected outcome for
// light 1 and group 0 of the named models, and no contradiction with any witness
// (crossCheckWitnesses).
TEST(GeometryStage, HardCasesHaveTheExpectedVerdictsEverywhere) {
    const std::vector<WorldTransform> moves = {WorldTransform::identity(), WorldTransform::moved({100000, 0, -100000}),
                                               WorldTransform::turned(1), WorldTransform{3, glm::dvec3(0, 5000, 0)}};
    for (const HardCase& hc : hardCases()) {
        SCOPED_TRACE(hc.name);
        std::map<std::string, Verdict> want;
        SpaceBuilder b = hc.make(want);
        for (size_t k = 0; k < moves.size(); ++k) {
            SCOPED_TRACE("transform " + std::to_string(k));
            fs::path dir = freshTestDir("-" + std::to_string(&hc - hardCases().data()) + "-" + std::to_string(k));
            cli::BakeResult r = bake(b, dir / "space", moves[k]);
            auto where = b.locateObjects(moves[k]);
            for (const auto& [uuid, v] : want) {
                const Decision* d = findDecision(r, where.at(uuid), 0, 0);
                ASSERT_NE(d, nullptr);
                EXPECT_EQ(d->verdict, v) << "got " << verdictName(d->verdict) << " by " << d->stage << ": " << d->reason()
                                         << (d->witness() ? " on " + d->witness()->receiver : "");
            }
        }
    }
}

// Known-answer scenes: every true 0 that is a "nothing receives" case is now proved, and
// the geometry stage never contradicts a witness.
TEST(GeometryStage, ProvesTheFloatingCubesAndNeverContradictsAWitness) {
    for (auto make : {twoFloatingCubes, cubeOnTerrain, thinRod, rangeAndCone, twoLightsMasks}) {
        SpaceBuilder b = make();
        fs::path dir = freshTestDir("-" + std::to_string(reinterpret_cast<uintptr_t>(make) % 100000));
        cli::BakeResult r = bake(b, dir / "space");
        auto where = b.locateObjects();
        for (const KnownAnswer& a : b.expectations())
            for (int l = 0; l < int(r.settings.lights.size()); ++l) {
                const Decision* d = findDecision(r, where.at(a.key), a.group, l);
                ASSERT_NE(d, nullptr);
                const bool trueBit = (a.mask >> l) & 1u;
                if (trueBit) EXPECT_EQ(d->verdict, Verdict::Kept) << a.key << ": " << a.why;
                else EXPECT_EQ(d->verdict, Verdict::Culled) << a.key << " light " << l + 1 << ": " << a.why;
            }
    }
}

// A window with a skipped object proves nothing (the object might have received).
TEST(GeometryStage, NoProofWhenAnObjectOfTheWindowWasSkipped) {
    SpaceBuilder b = twoFloatingCubes();
    b.addModel("models/missing.obj", Affine::translation({45, 0, 45}));
    fs::path dir = freshTestDir();
    cli::BakeResult r = bake(b, dir / "space");
    cli::BitCounts c = cli::countBits(r);
    EXPECT_EQ(c.culled, 0u);
    EXPECT_EQ(c.undecided, 2u);
}

TEST(GeometryStage, FastPathEqualsTheExhaustiveReference) {
    struct Scene {
        const char* name;
        std::function<void(SpaceBuilder&)> add;
    };
    const std::vector<Scene> scenes = {
        {"sheet on a floor", [](SpaceBuilder& b) {
             b.addMesh("floor", quadFacing(0, true, 20));
             b.addModel("floor", Affine::translation({40, 0, 40}));
             b.addModel("sheet", Affine::translation({50, 0, 50}));
         }},
        {"floating sheet", [](SpaceBuilder& b) { b.addModel("sheet", Affine::translation({50, 3, 50})); }},
        {"sheet half in a terrain", [](SpaceBuilder& b) {
             b.addFlatTerrain(0, 0, 0.015);
             b.addModel("sheet", Affine::translation({50, 0, 50}));
         }},
        // Instances whose mesh coordinates are not the window's: the broad phase queries
        // each mesh's tree in its own coordinates.
        {"turned, scaled, tilted and mirrored sheets on a floor", [](SpaceBuilder& b) {
             b.addMesh("floor", quadFacing(0, true, 20));
             b.addModel("floor", Affine::translation({40, 0, 40}));
             b.addModel("sheet", Affine::rotationY(33).then(Affine::scaling({1.3, 0.7, 0.9})).then(Affine::translation({50, 0.05, 50})));
             b.addModel("sheet", Affine::scaling({-1, 1, 1}).then(Affine::translation({47, 0.3, 46})));
             Affine tilt;  // about x by ~25 degrees, then lifted
             tilt.row1 = {0, 0.906, 0.423};
             tilt.row2 = {0, -0.423, 0.906};
             tilt.row3 = {52, 0.8, 53};
             b.addModel("sheet", tilt);
         }},
        // Buried: whole clusters of casters are decided at once (their shadows stay under
        // the terrain), beside a sheet that crosses the surface.
        {"sheets buried in a terrain", [](SpaceBuilder& b) {
             b.addFlatTerrain(0, 0, 0.5);
             b.addModel("sheet", Affine::translation({50, -0.2, 50}));
             b.addModel("sheet", Affine::rotationY(71).then(Affine::translation({46, 0.0, 44})));
             b.addModel("sheet", Affine::translation({54, 0.48, 46}));
         }},
        // Tilted across the ground (a rock's ground line): the terrain's columns reach the
        // buried side, the part above lies in front of them.
        {"tilted sheets crossing a terrain", [](SpaceBuilder& b) {
             b.addFlatTerrain(0, 0, 0.2);
             Affine tilt;  // about x by ~25 degrees, centred on the ground
             tilt.row1 = {0, 0.906, 0.423};
             tilt.row2 = {0, -0.423, 0.906};
             tilt.row3 = {50, 0.3, 49.9};
             b.addModel("sheet", tilt);
             b.addModel("sheet", Affine::rotationY(40).then(tilt).then(Affine::translation({-3, 0.05, 2})));
         }},
        // The lamp's range (5 m from (50.1, 1, 50.1)) cuts these sheets: only their
        // triangles within it may hold p.
        {"sheets the lamp's range cuts, over a floor", [](SpaceBuilder& b) {
             b.addMesh("floor", quadFacing(0, true, 20));
             b.addModel("floor", Affine::translation({40, 0, 40}));
             b.addModel("sheet", Affine::translation({54.7, 0.3, 50}));
             b.addModel("sheet", Affine::rotationY(90).then(Affine::translation({50, 1.5, 45.3})));
         }},
    };
    std::vector<LightSpec> lights = {LightSpec::directional("sun", {0.3, -1, 0.2}), LightSpec::directional("steep", {0.9, -1, 0.1}),
                                     LightSpec::point("lamp", {50.1, 1.0, 50.1}, 5.0)};
    lights[0].bias = 0.02;
    lights[1].filterRadius = 0.01;
    size_t allProved = 0, allUndecided = 0;
    for (const Scene& sc : scenes) {
        SCOPED_TRACE(sc.name);
        SpaceBuilder b;
        for (const LightSpec& L : lights) b.addLight(L);
        b.addMesh("sheet", MeshSpec::jaggedSheet(10, 0.05, 0.04));
        sc.add(b);
        const fs::path dir = freshTestDir("-" + std::to_string(&sc - scenes.data()));
        b.write((dir / "space").string());
        // The reference first, then the fast path as baked and with the terrain rule's node
        // tests on every mesh (by default only on meshes of 1,024 triangles and more).
        std::vector<cli::BakeResult> results;
        for (int run = 0; run < 3; ++run) {
            cli::BakeOptions opt;
            opt.spaceDir = (dir / "space").string();
            opt.write = false;
            opt.useRaycast = false;  // every bit goes to the geometry stage
            opt.useGpu = false;
            opt.geometry.exhaustive = run == 0;
            if (run == 2) opt.geometry.nodeTerrainRuleFrom = 0;
            Expected<cli::BakeResult> r = cli::runBake(opt);
            ASSERT_TRUE(r) << r.error().what();
            results.push_back(std::move(*r));
        }
        size_t bits = 0, proved = 0, undecided = 0;
        for (size_t run = 1; run < results.size(); ++run) {
            SCOPED_TRACE(run == 1 ? "fast path" : "fast path, node rules on every mesh");
            ASSERT_EQ(results[run].chunks.size(), results[0].chunks.size());
            for (size_t c = 0; c < results[0].chunks.size(); ++c) {
                const auto& fast = results[run].chunks[c];
                const auto& ref = results[0].chunks[c];
                ASSERT_EQ(fast.objects.size(), ref.objects.size());
                for (size_t o = 0; o < fast.objects.size(); ++o)
                    for (int g = 0; g < fast.objects[o].groupCount; ++g)
                        for (int l = 0; l < fast.lightCount; ++l) {
                            const Decision& a = fast.at(o, g, l);
                            const Decision& e = ref.at(o, g, l);
                            if (run == 1) {
                                ++bits;
                                proved += e.verdict == Verdict::Culled && e.stage == std::string("geometry");
                                undecided += e.verdict == Verdict::Undecided;
                            }
                            EXPECT_EQ(a.verdict, e.verdict) << "chunk " << c << " object " << o << " light " << l + 1;
                            EXPECT_EQ(std::string(a.stage), std::string(e.stage));
                        }
            }
        }
        EXPECT_GT(bits, 0u);
        std::printf("%s: %zu bits, %zu proved 0 by the geometry stage, %zu left undecided\n", sc.name, bits, proved, undecided);
        allProved += proved;
        allUndecided += undecided;
    }
    // Both outcomes occur: the comparison covers proofs and bits left to the next stage.
    EXPECT_GT(allProved, 0u);
    EXPECT_GT(allUndecided, 0u);
}

// --- The terrain rule, exactly (issue 19) ---------------------------------------------------

namespace {

// Gentle hills (slopes up to 0.2, cells of 4 m) with 1 m rocks half-buried on the slopes,
// under a 45-degree sun. A ray entering the ground can only leave it where the ground
// falls away faster than the light (slope 1): never here. So the terrain's shadow reaches
// only the rocks' buried sides, within a centimetre of the surface (the tolerance band)
// only within ~1.2 cm of where the ray went in: less than the bias behind p.
SpaceBuilder rocksOnHills(double bias) {
    SpaceBuilder b;
    LightSpec sun = LightSpec::directional("sun", {0.6, -1, 0.8});
    sun.bias = bias;
    b.addLight(sun);
    const auto hills = [](double x, double z) { return 1.5 * std::sin(x / 12.0) + 1.2 * std::cos(z / 9.0); };
    b.addTerrain(0, 0, 26, hills, -3.0, 3.0);
    b.addMesh("rock", MeshSpec::box({-0.5, -0.5, -0.5}, {0.5, 0.5, 0.5}));
    for (int k = 0; k < 12; ++k) {
        const double x = 12.0 + 7.0 * k, z = 20.0 + 5.5 * (k % 7);
        b.addModel("rock", Affine::rotationY(17.0 * k).then(Affine::translation({x, *b.terrainHeightAt(x, z), z})));
    }
    return b;
}

}  // namespace

// With a bias, the terrain is a true 0 that the exact rule proves (the rocks' parts in its
// shadow volume are deeper than the tolerance under the slopes); the box of such a part
// against the lowest sample of its cell could not (a 4 m cell on a 0.2 slope spans 0.8 m).
// Without bias, the band above the rocks' buried sides is a true receiver: never a 0.
TEST(GeometryStage, TerrainRuleIsExactOnSlopes) {
    for (double bias : {0.05, 0.0}) {
        SCOPED_TRACE("bias " + std::to_string(bias));
        SpaceBuilder b = rocksOnHills(bias);
        const fs::path dir = freshTestDir(bias > 0 ? "-bias" : "-nobias");
        cli::BakeResult r = bake(b, dir / "space");
        const auto where = b.locateObjects();
        const Decision* d = findDecision(r, where.at(SpaceBuilder::terrainKey(0, 0)), 0, 0);
        ASSERT_NE(d, nullptr);
        if (bias > 0) EXPECT_EQ(d->verdict, Verdict::Culled) << d->stage << ": " << d->reason();
        else EXPECT_NE(d->verdict, Verdict::Culled) << d->reason();
    }
}


// The terrain rule depends on the receiver alone: every light's receiver rules take one
// answer per receiver triangle from the window's ReceiverGround (the same part above the
// ground, not a copy per light), and agree with the rule computed on its own (underTerrain).
// Fails when a light computes its own part, or when the shared answer differs from the rule.
TEST(ReceiverGround, OneAnswerPerReceiverForEveryLight) {
    SpaceBuilder b = rocksOnHills(0.05);
    b.addLight(LightSpec::directional("high sun", {0.1, -1, 0.2}).withBias(0.05));
    const std::unique_ptr<Loaded> loaded = load(b);
    ASSERT_TRUE(loaded);
    const BakeWindow& w = loaded->window;
    ASSERT_TRUE(w.hasTerrain);
    ASSERT_EQ(w.lsLights.size(), 2u);
    const double margin = 1e-9;
    ThreadArena arena;
    const geometry::ReceiverGround ground(w, margin, true, arena);
    std::vector<LightGeometry> lg;
    std::vector<std::unique_ptr<geometry::ReceiverRules>> rules;
    for (const Light& L : w.lsLights) lg.push_back(LightGeometry{true, L.direction, L.position});
    for (size_t l = 0; l < 2; ++l) rules.push_back(std::make_unique<geometry::ReceiverRules>(w, w.lsLights[l], lg[l], ground, arena));
    size_t buried = 0, withPart = 0, shared = 0;
    for (uint32_t k = 0; k < w.objects.size(); ++k) {
        const WindowObject& o = w.objects[k];
        if (o.kind == ChunkObject::Kind::Terrain) continue;
        for (uint32_t t = 0; t < o.mesh->triangles.size(); ++t) {
            geometry::Receiver r;
            r.tri = o.lsTriangle(t);
            r.box = geometry::triangleBox(r.tri);
            r.twoSided = true;  // facing aside: every triangle reaches the terrain rule
            const geometry::ReceiverGround::Answer a = ground.of(k, t, r);
            if (geometry::underTerrain(w, {r.box.min, r.box.max}, margin)) {
                EXPECT_TRUE(a.buried);
            }
            buried += a.buried;
            withPart += a.part != nullptr;
            const geometry::GroundPart* above[2] = {nullptr, nullptr};
            for (size_t l = 0; l < 2; ++l) {
                const double beta = rules[l]->beta(k, t, [&]() -> const geometry::Receiver& { return r; }, &above[l]);
                EXPECT_EQ(beta < 0, a.buried) << "object " << k << " triangle " << t << " light " << l;
            }
            if (!a.buried) {
                EXPECT_EQ(above[0], a.part);
                EXPECT_EQ(above[1], a.part);
                shared += a.part != nullptr;
            }
        }
    }
    // Both answers occur: half-buried rocks have buried triangles and triangles above ground.
    EXPECT_GT(buried, 0u);
    EXPECT_GT(withPart, 0u);
    EXPECT_EQ(shared, withPart);
}

// BakeWindow::lsTerrainTrianglesOver with `keep` leaves out whole cells beside its x-z
// extent: the triangles it gives are those of the full list whose boxes are not wholly
// beside `keep`, plus at most others of kept cells, in the full list's order. Fails when a
// cell is dropped that holds a triangle reaching `keep` (a column or row off by one).
TEST(BakeWindow, TerrainTrianglesNearAKeepBoxAreTheFullListsInOrder) {
    const std::unique_ptr<Loaded> loaded = load(rocksOnHills(0.05));
    ASSERT_TRUE(loaded);
    const BakeWindow& w = loaded->window;
    ASSERT_TRUE(w.hasTerrain);
    size_t kept = 0, dropped = 0;
    for (int k = 0; k < 200; ++k) {
        // Boxes from a few centimetres to tens of metres, some on cell lines (4 m cells).
        const double x = 1.0 + 0.37 * k, z = 2.0 + 0.29 * k, size = k % 3 == 0 ? 0.04 : 0.5 + 0.2 * (k % 50);
        const double snap = k % 5 == 0 ? 4.0 * std::floor(x / 4.0) : x;
        const Aabb box{glm::dvec3(snap, -10, z), glm::dvec3(snap + size, 10, z + size)};
        const double margin = 1e-9;
        const Aabb keep{box.min - glm::dvec3(margin), box.max + glm::dvec3(margin)};
        std::vector<std::array<glm::dvec3, 3>> all, near;
        const bool okAll = w.lsTerrainTrianglesOver(box.min.x, box.min.z, box.max.x, box.max.z, all);
        const bool okNear = w.lsTerrainTrianglesOver(box.min.x, box.min.z, box.max.x, box.max.z, keep, near);
        ASSERT_EQ(okAll, okNear);
        if (!okAll) continue;
        auto beside = [&](const std::array<glm::dvec3, 3>& t) {
            const Aabb tb = geometry::triangleBox(t);
            return tb.max.x < keep.min.x || tb.min.x > keep.max.x || tb.max.z < keep.min.z || tb.min.z > keep.max.z;
        };
        // `near` is a subsequence of `all` holding every triangle of `all` not beside `keep`.
        size_t n = 0;
        for (const auto& t : all) {
            const bool here = n < near.size() && near[n] == t;
            if (!beside(t)) {
                ASSERT_TRUE(here) << "box " << k << ": a triangle reaching the box was left out";
            }
            if (here) ++n, ++kept;
            else ++dropped;
        }
        ASSERT_EQ(n, near.size()) << "box " << k << ": triangles out of order or not in the full list";
    }
    EXPECT_GT(kept, 0u);
    EXPECT_GT(dropped, 0u);  // the cells around the box are left out
}
