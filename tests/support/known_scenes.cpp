// The known-answer scenes (space_builder.h gives their geometry; the reasoning is below),
// written with SpaceBuilder.

#include <cmath>
#include <string>

#include "tests/support/space_builder.h"

namespace shadowcull::testing {


namespace {

const glm::dvec3 kTiltedSun{0.3, -1.0, 0.2};

SpaceBuilder flatWorldWithCube() {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addFlatTerrain(0, 0, 0.0);
    return b;
}

}  // namespace

SpaceBuilder cubeOnTerrain() {
    SpaceBuilder b = flatWorldWithCube();
    b.addLight(LightSpec::directional("sun", kTiltedSun).withBias(0.05));
    const std::string cube = b.addModel("cube", Affine::translation({50, 0, 50}), fixedUuid(1));
    // The sun ray through the lit top at (50.9,1,50.9) lands beyond the cube at
    // (51.2,0,51.1), about 1 m deeper (> bias 0.05), on terrain facing up to the sun.
    b.expect(cube, 0, 1, "cube's shadow falls on the terrain");
    // Nothing lies under the terrain; the cube's bottom face touches it but faces away.
    b.expect(SpaceBuilder::terrainKey(0, 0), 0, 0, "nothing below the flat terrain");
    return b;
}

SpaceBuilder twoFloatingCubes() {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addLight(LightSpec::directional("sun", {0.05, -1.0, 0.02}));
    b.addChunk(0, 0);
    // Rays drift 0.05 m sideways per metre down, so from one cube they would have to fall
    // ~180 m to reach the other, which is at the same height. Behind a lit point of a
    // convex one-sided cube there are only its own back faces, which do not receive.
    const std::string a = b.addModel("cube", Affine::translation({40, 20, 50}), fixedUuid(1));
    const std::string c = b.addModel("cube", Affine::translation({50, 20, 50}), fixedUuid(2));
    b.expect(a, 0, 0, "floating, nothing below");
    b.expect(c, 0, 0, "floating, nothing below");
    return b;
}

SpaceBuilder rangeAndCone() {
    SpaceBuilder b = flatWorldWithCube();
    b.addLight(LightSpec::point("lamp", {20, 5, 20}, 10));
    b.addLight(LightSpec::spot("torch", {20, 8, 20}, {0, -1, 0}, 20, 30));
    const std::string a = b.addModel("cube", Affine::translation({22, 0, 20}), fixedUuid(1));
    const std::string far = b.addModel("cube", Affine::translation({80, 0, 80}), fixedUuid(2));
    const std::string c = b.addModel("cube", Affine::translation({26, 0, 20}), fixedUuid(3));
    // A: the lamp ray over A's top through (22.9,1,20.5) lands beyond A at (23.6,0,20.6),
    // 6.2 m from the lamp; the torch ray through the same point is 22.8 degrees off axis
    // and lands beyond A at (23.3,0,20.6), 8.7 m away. Both within range and cone.
    b.expect(a, 0, 3, "inside the lamp's range and the torch's cone");
    // B: > 80 m from both lights (ranges 10 and 20).
    b.expect(far, 0, 0, "out of both lights' range");
    // C: the lamp ray through (26.2,1,20.5) passes 2 m over A and lands beyond C at
    // (27.75,0,20.6), 9.2 m away (< 10). From the torch every point of C is atan(6/8) =
    // 36.9 degrees or more off axis (cone 30).
    b.expect(c, 0, 1, "in the lamp's range, outside the torch's cone");
    b.expect(SpaceBuilder::terrainKey(0, 0), 0, 0, "nothing below the flat terrain");
    return b;
}

SpaceBuilder thinRod() {
    SpaceBuilder b;
    b.addMesh("rod", MeshSpec::rod(2.0, 0.005));
    b.addFlatTerrain(0, 0, 0.0);
    b.addLight(LightSpec::directional("sun", kTiltedSun));
    // Lit top face 5 mm wide; its rays meet the terrain ~2 m further on.
    const std::string rod = b.addModel("rod", Affine::translation({50, 2, 50}), fixedUuid(1));
    b.expect(rod, 0, 1, "thin, but its shadow falls on the terrain 2 m below");
    b.expect(SpaceBuilder::terrainKey(0, 0), 0, 0, "nothing below the flat terrain");
    return b;
}

SpaceBuilder twoLightsMasks() {
    SpaceBuilder b;
    MeshSpec twoCubes = MeshSpec::box({0, 0, 0}, {1, 1, 1}, GroupSpec::named("stone"));
    twoCubes.append(MeshSpec::box({6, 0, 0}, {7, 1, 1}, GroupSpec::named("metal")));
    b.addMesh("twocubes", twoCubes);
    b.addFlatTerrain(0, 0, 0.0);
    b.addLight(LightSpec::point("lamp", {48, 3, 50.5}, 5));  // light 1: bit 0
    b.addLight(LightSpec::directional("sun", kTiltedSun));   // light 2: bit 1
    const std::string m = b.addModel("twocubes", Affine::translation({40, 0, 50}), fixedUuid(1));
    // Group 0 (x 40..41): its nearest point is 7.3 m from the lamp (range 5): sun only.
    b.expect(m, 0, 2, "group 0: out of the lamp's range, under the sun");
    // Group 1 (x 46..47): the lamp ray over its top through (46.2,1,50.5) lands beyond it
    // at (45.3,0,50.5), 4.04 m from the lamp; the sun's shadow lands as well.
    b.expect(m, 1, 3, "group 1: lamp and sun");
    b.expect(SpaceBuilder::terrainKey(0, 0), 0, 0, "nothing below the flat terrain");
    return b;
}

SpaceBuilder manyChunks(int n) {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({-0.5, 0, -0.5}, {0.5, 1, 0.5}));
    b.addLight(LightSpec::directional("sun", kTiltedSun).withBias(0.05));
    // Gentle swell (< 1 m, slope < 0.05): cubes sunk 0.2 m stay grounded across their base.
    auto height = [](double x, double z) { return 0.6 * std::sin(x * 0.045) + 0.4 * std::cos(z * 0.06); };
    DeterministicRng rng(0xC0FFEE);
    for (int gx = 0; gx < n; ++gx)
        for (int gz = 0; gz < n; ++gz) {
            b.addTerrain(gx, gz, 9, height, -2.0, 2.0);
            for (int k = 0; k < 3; ++k) {
                const double x = gx * 100.0 + rng.uniform(5, 95), z = gz * 100.0 + rng.uniform(5, 95);
                b.addModel("cube", Affine::translation({x, *b.terrainHeightAt(x, z) - 0.2, z}));
            }
        }
    return b;
}

MeshSpec faceAndFarPatch() {
    MeshSpec parts;
    const int g = parts.addGroup(GroupSpec{});
    parts.addQuad({7, 4, -0.5}, {7, 4, 0.5}, {7, 4.9, 0.5}, {7, 4.9, -0.5}, g);  // faces -x, the lamp
    parts.addQuad({20, 1, 0}, {20, 1, 1}, {21, 1, 1}, {21, 1, 0}, g);              // faces up
    return parts;
}

SpaceBuilder cubeBesideLamp(double range) {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addFlatTerrain(0, 0, 0.0);
    b.addLight(LightSpec::point("lamp", {20, 5, 20}, range));
    b.addModel("cube", Affine::translation({26, 0, 20}), fixedUuid(1));
    return b;
}

SpaceBuilder hiddenUnderRoof(Roof roof) {
    SpaceBuilder b = flatWorldWithCube();
    GroupSpec roofGroup = GroupSpec::named("roof");
    if (roof == Roof::AlphaTested) roofGroup.alphaTestOverride = true;  // exercises the .model override path
    b.addMesh("roof", MeshSpec::box({-10, 0, -10}, {10, 0.2, 10}, roofGroup));
    b.addLight(LightSpec::directional("sun", kTiltedSun));
    const std::string cube = b.addModel("cube", Affine::translation({50, 0, 50}), fixedUuid(1));
    const std::string roofKey = b.addModel("roof", Affine::translation({50, 3, 50}), fixedUuid(2),
                                           roof == Roof::CastsNoShadow ? std::optional<bool>(false) : std::nullopt);
    // Traced back towards the sun, every point of the cube (x 50..51, z 50..51, y 0..1)
    // crosses y = 3 within x 49.1..50.4, z 49.4..50.6: inside the roof (40..60).
    switch (roof) {
        case Roof::Opaque:
            b.expect(cube, 0, 0, "fully hidden under the roof");
            b.expect(roofKey, 0, 1, "roof's shadow falls on the cube and the terrain");
            break;
        case Roof::AlphaTested:
            b.expect(cube, 0, 1, "light passes the alpha-tested roof; shadow on terrain");
            b.expect(roofKey, 0, 1, "roof's shadow falls on the cube and the terrain");
            break;
        case Roof::CastsNoShadow:
            b.expect(cube, 0, 1, "the roof is not in the shadow map: light passes it; shadow on terrain");
            b.expect(roofKey, 0, 0, "castsShadow false: never a caster");
            break;
    }
    b.expect(SpaceBuilder::terrainKey(0, 0), 0, 0, "nothing below the flat terrain");
    return b;
}

SpaceBuilder cubeBesideWall(double normalBias) {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    // Facing -x: (b - a) x (c - a) = (0,0,3) x (0,1.5,3) = (-4.5, 0, 0).
    b.addMesh("wall", MeshSpec::quad({0, 0, 0}, {0, 0, 3}, {0, 1.5, 3}, {0, 1.5, 0}, GroupSpec::named("wall")));
    b.addLight(LightSpec::directional("sun", {1, -1, 0}).withNormalBias(normalBias));
    b.addChunk(0, 0);
    const std::string cube = b.addModel("cube", Affine::translation({50, 2, 50}), fixedUuid(1));
    const std::string wall = b.addModel("wall", Affine::translation({54.02, 0, 49}), fixedUuid(2));
    // A ray through cube point (x, y) meets the plane x = w at height x + y - w: at most
    // 54 - 54.02 = -0.02 on the wall's plane, 54 - 53.92 = 0.08 on the plane 0.1 m in front.
    b.expect(cube, 0, normalBias >= 0.05 ? 1u : 0u,
             normalBias >= 0.05 ? "the normal bias looks the wall's foot up inside the cube's shadow"
                                : "its shadow passes 2 cm under the wall: nothing receives it");
    b.expect(wall, 0, 0, "nothing behind the wall");
    return b;
}

SpaceBuilder cubeOverNonCastingFloor() {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addMesh("floor", MeshSpec::box({-10, 0, -10}, {10, 0.2, 10}, GroupSpec::named("floor")));
    b.addLight(LightSpec::directional("sun", kTiltedSun));
    b.addChunk(0, 0);
    const std::string cube = b.addModel("cube", Affine::translation({50, 2, 50}), fixedUuid(1));
    const std::string floor = b.addModel("floor", Affine::translation({50, 0, 50}), fixedUuid(2), false);
    // The sun ray through the cube's lit top (y 3) reaches the floor's top (y 0.2) 2.8 m
    // lower and at most 0.84 m sideways in x, 0.56 m in z: on the floor (40..60).
    b.expect(cube, 0, 1, "its shadow falls on the floor, which casts no shadow but receives");
    b.expect(floor, 0, 0, "castsShadow false: never a caster");
    return b;
}

namespace {

// A ground quad facing up at y = 0 over chunk (gx, 0) of 100 m.
void addGroundQuad(SpaceBuilder& b, int gx, uint32_t uuid) {
    const double x0 = 100.0 * gx;
    b.addModel("ground", Affine::translation({x0, 0, 0}), fixedUuid(uuid));
}

}  // namespace

SpaceBuilder longShadowOverChunks(LongShadow ending) {
    SpaceBuilder b;
    // About 10 degrees above the horizon (tan = 0.18): 5.56 m of shadow per metre of height.
    b.addLight(LightSpec::directional("sun_low", {1, -0.18, 0}).withBias(0.05));
    b.addMesh("plateau", MeshSpec::box({0, 0, 0}, {50, 46, 100}, GroupSpec::named("rock")));
    b.addMesh("tower", MeshSpec::box({50, 46, 49}, {52, 60, 51}, GroupSpec::named("stone")));
    b.addMesh("ground", MeshSpec::quad({0, 0, 0}, {0, 0, 100}, {100, 0, 100}, {100, 0, 0}, GroupSpec::named("ground")));
    const std::string plateau = b.addModel("plateau", Affine::translation({0, 0, 0}), fixedUuid(1));
    const std::string tower = b.addModel("tower", Affine::translation({0, 0, 0}), fixedUuid(2));
    addGroundQuad(b, 1, 11);
    addGroundQuad(b, 2, 12);
    if (ending == LongShadow::LandsThreeChunksAway) addGroundQuad(b, 3, 13);
    if (ending == LongShadow::FallsInAGap) {
        b.addChunk(3, 0);
        addGroundQuad(b, 4, 14);
    }
    // The plateau's lit top (x 0..50, y 46) sends its shadow 255.6 m on: x 255.6..305.6.
    b.expect(plateau, 0, 1, "the cliff's shadow lands 2 and 3 chunks away, on the ground of chunk 2");
    // The tower's lit points (x 50..52, y 46..60) land at x 305.6..385.3, in chunk 3: three
    // chunks from the tower, past a neighbours-1 window.
    b.expect(tower, 0, ending == LongShadow::LandsThreeChunksAway ? 1u : 0u,
             ending == LongShadow::LandsThreeChunksAway ? "its shadow lands on the ground three chunks away"
             : ending == LongShadow::FallsInAGap        ? "its shadow falls where chunk 3 holds nothing (chunk 4's ground is above it)"
                                                        : "its shadow leaves the space at its edge (x = 300)");
    for (uint32_t g : {11u, 12u}) b.expect(fixedUuid(g), 0, 0, "flat ground with nothing below");
    return b;
}

SpaceBuilder lampTwoChunksOver() {
    SpaceBuilder b;
    b.addLight(LightSpec::point("lamp", {50, 30, 50}, 250));
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addMesh("ground", MeshSpec::quad({0, 0, 0}, {0, 0, 100}, {100, 0, 100}, {100, 0, 0}, GroupSpec::named("ground")));
    const std::string cube = b.addModel("cube", Affine::translation({80, 24.5, 49.5}), fixedUuid(1));
    b.addChunk(1, 0);
    addGroundQuad(b, 2, 12);
    // Lines from the lamp through the cube's lit faces (-x and top) reach y = 0 at x 212..262,
    // 214 m or less from the lamp: within range, two chunks over.
    b.expect(cube, 0, 1, "the lamp's range carries its shadow onto the ground two chunks over");
    b.expect(fixedUuid(12), 0, 0, "flat ground with nothing below");
    return b;
}

}  // namespace shadowcull::testing

