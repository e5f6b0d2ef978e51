// The GPU stages' tests (gpu_test.cpp, gpu_random_test.cpp): a written space loaded into
// chunk (0, 0)'s bake window, the stages run on it, and the tiny scenes with known answers.
#pragma once

#include <cstdlib>
#include <cstdio>
#include <functional>
#include <map>
#include <set>
#include <tuple>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>
#include <png.h>

#include "core/scene.h"
#include "core/stage.h"
#include "core/window.h"
#include "core/window_plan.h"
#include "gpu/baseline.h"
#include "gpu/confirm_stage.h"
#include "gpu/gl_context.h"
#include "gpu/light_view.h"
#include "gpu/render.h"
#include "io/scene_reader.h"
#include "io/space_source.h"
#include "raycast/raycast_stage.h"
#include "tests/support/bake_lookup.h"
#include "tests/support/gl_available.h"
#include "tests/support/loaded_window.h"
#include "tests/support/sample_space.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

namespace shadowcull::testing {

namespace fs = std::filesystem;

inline std::string keyOf(const KnownAnswer& a) { return a.key.rfind("terrain:", 0) == 0 ? "terrain" : a.key; }

template <class StageT>
inline void runStage(StageT& stage, Loaded& l) {
    StageStats st;
    Status s = stage.run(l.window, l.verdicts, st);
    ASSERT_TRUE(s) << s.error().what();
}

inline const gpu::GroupPixels* findPixels(const gpu::GpuConfirmStage& stage, size_t object, int group, int light) {
    for (const gpu::GroupPixels& g : stage.passedPixels())
        if (g.object == object && g.group == group && g.light == light) return &g;
    return nullptr;
}

inline const glm::dvec3 kDown{0, -1, 0};
inline const glm::dvec3 kTiltedSun{0.3, -1.0, 0.2};

// --- Scenes ----------------------------------------------------------------------------

// Straight-down light over the 100 m chunk (0,0): a ground quad over the whole chunk at
// y = 0 and a quad over x, z in [0, 50] at y = 1, both facing up. At 64 px the small quad
// covers exactly the 32 x 32 pixels of one quarter of the view.
inline SpaceBuilder quarterQuad() {
    SpaceBuilder b;
    b.addMesh("ground", MeshSpec::quad({0, 0, 0}, {0, 0, 100}, {100, 0, 100}, {100, 0, 0}));
    b.addMesh("small", MeshSpec::quad({0, 1, 0}, {0, 1, 50}, {50, 1, 50}, {50, 1, 0}));
    b.addLight(LightSpec::directional("down", kDown).withBias(0.05));
    b.addModel("ground", Affine::translation({0, 0, 0}), fixedUuid(1));
    b.addModel("small", Affine::translation({0, 0, 0}), fixedUuid(2));
    return b;
}

// Flat terrain at 0 and a two-sided quad over x, z in [0, 50] at `depth` below it; light
// straight down with a 1 mm bias (a surface is never behind itself by more than that).
inline SpaceBuilder quadUnderTerrain(double depth) {
    SpaceBuilder b;
    GroupSpec twoSided = GroupSpec::named("sheet");
    twoSided.doubleSidedOverride = true;
    b.addMesh("sheet", MeshSpec::quad({0, 0, 0}, {0, 0, 50}, {50, 0, 50}, {50, 0, 0}, twoSided), true);
    b.addFlatTerrain(0, 0, 0.0);
    b.addLight(LightSpec::directional("down", kDown).withBias(0.001));
    b.addModel("sheet", Affine::translation({0, -depth, 0}), fixedUuid(1));
    return b;
}

// A tree: a 0.5 m trunk (group 0) from the ground up to an opaque 6 x 1 x 6 m canopy
// (group 1), on flat terrain, under the tilted sun. Traced back to the sun, every point of
// the trunk crosses the canopy's bottom (y = 4) within 1.5 m of the trunk: trunk 0,
// canopy 1 (its shadow lands on the terrain), terrain 0.
inline SpaceBuilder trunkUnderCanopy() {
    SpaceBuilder b;
    MeshSpec tree = MeshSpec::box({-0.25, 0, -0.25}, {0.25, 4, 0.25}, GroupSpec::named("bark"));
    tree.append(MeshSpec::box({-3, 4, -3}, {3, 5, 3}, GroupSpec::named("leaves")));
    b.addMesh("tree", tree);
    b.addFlatTerrain(0, 0, 0.0);
    b.addLight(LightSpec::directional("sun", kTiltedSun).withBias(0.05));
    const std::string t = b.addModel("tree", Affine::translation({50, 0, 50}), fixedUuid(1));
    b.expect(t, 0, 0, "the trunk is never lit: the canopy hides it");
    b.expect(t, 1, 1, "the canopy's shadow falls on the terrain");
    b.expect(SpaceBuilder::terrainKey(0, 0), 0, 0, "nothing below the flat terrain");
    return b;
}

// A 1 m cube on flat terrain under a roof of two slabs with a 2 cm slit between them
// (x in [49.99, 50.01]) above the cube's middle; light straight down. Light falls through
// the slit on a 2 cm strip of the cube's top and the terrain lies 1 m behind it: cube 1.
// The slit is centred on a pixel border of the 1024 px view (x = 50 m of [0, 100]), so
// the nearest pixel centres (49.95, 50.05) both fall on the slabs: the point-sampled
// baseline sees no lit sample. (At other offsets a 2 cm slit meets one pixel column in
// five at ~9.8 cm pixels; the sampled answer depends on luck, never on the geometry.)
inline SpaceBuilder cubeUnderSlit() {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addMesh("slabA", MeshSpec::box({40, 3, 40}, {49.99, 3.2, 60}));
    b.addMesh("slabB", MeshSpec::box({50.01, 3, 40}, {60, 3.2, 60}));
    b.addFlatTerrain(0, 0, 0.0);
    b.addLight(LightSpec::directional("down", kDown).withBias(0.05));
    const std::string cube = b.addModel("cube", Affine::translation({49.5, 0, 49.5}), fixedUuid(1));
    b.addModel("slabA", Affine::translation({0, 0, 0}), fixedUuid(2));
    b.addModel("slabB", Affine::translation({0, 0, 0}), fixedUuid(3));
    b.expect(cube, 0, 1, "lit through the 2 cm slit; the terrain lies 1 m behind");
    return b;
}

// A 2 m rod, 5 mm thick, 2 m above flat terrain, light straight down; the rod's 5 mm
// (z in [49.9975, 50.0025]) lies between two pixel-centre rows of the 1024 px view. (Under
// thinRod()'s tilted sun the baseline's answer is luck: no sample at 256 and 512 px, one
// at 1024, six at 2048.)
inline SpaceBuilder rodBetweenPixelCentres() {
    SpaceBuilder b;
    b.addMesh("rod", MeshSpec::rod(2.0, 0.005));
    b.addFlatTerrain(0, 0, 0.0);
    b.addLight(LightSpec::directional("down", kDown).withBias(0.05));
    const std::string rod = b.addModel("rod", Affine::translation({49, 2, 50}), fixedUuid(1));
    b.expect(rod, 0, 1, "thin, but lit, and the terrain lies 2 m behind it");
    return b;
}

// hiddenUnderRoof's cube and roof, lit by a point lamp or a spot torch (cone 40 degrees, one
// view; or 80 degrees, six cube faces) 2.8 m above the roof's middle: every ray from the
// light to the cube crosses the roof (which spans 10 m around), so the cube is 0; the
// roof's shadow falls on the cube and the terrain: 1.
inline SpaceBuilder lampOverRoof(bool spot, double cone = 40) {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addMesh("roof", MeshSpec::box({-10, 0, -10}, {10, 0.2, 10}));
    b.addFlatTerrain(0, 0, 0.0);
    if (spot) b.addLight(LightSpec::spot("torch", {50.5, 6, 50.5}, {0, -1, 0}, 30, cone));
    else b.addLight(LightSpec::point("lamp", {50.5, 6, 50.5}, 30));
    const std::string cube = b.addModel("cube", Affine::translation({50, 0, 50}), fixedUuid(1));
    const std::string roof = b.addModel("roof", Affine::translation({50.5, 3, 50.5}), fixedUuid(2));
    b.expect(cube, 0, 0, "hidden from the light by the roof");
    b.expect(roof, 0, 1, "the roof's shadow falls on the cube and the terrain");
    return b;
}

// The builder's known-answer scenes and this file's own, each with its expectations.
inline const std::vector<NamedScene>& gpuKnownAnswerScenes() {
    static const std::vector<NamedScene> s = [] {
        std::vector<NamedScene> all = knownAnswerScenes();
        all.insert(all.end(), {
                                  {"trunkUnderCanopy", trunkUnderCanopy},
                                  {"cubeUnderSlit", cubeUnderSlit},
                                  {"rodBetweenPixelCentres", rodBetweenPixelCentres},
                                  {"lampOverRoof", [] { return lampOverRoof(false); }},
                                  {"torchOverRoof", [] { return lampOverRoof(true); }},
                                  {"wideTorchOverRoof", [] { return lampOverRoof(true, 80); }},
                              });
        return all;
    }();
    return s;
}

// --- Light views (no GL) ----------------------------------------------------------------

}  // namespace shadowcull::testing
