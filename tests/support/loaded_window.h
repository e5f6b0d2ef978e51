// A written space loaded into chunk (0, 0)'s bake window, as the analytic bake builds it,
// with the chunk's verdict table: for the tests that run a stage, or ask the window
// itself, on a small scene (gpu_test.cpp, gpu_random_test.cpp, geometry_test.cpp).
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "core/stage.h"
#include "core/scene.h"
#include "core/window.h"
#include "core/window_plan.h"
#include "io/scene_reader.h"
#include "io/space_source.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

namespace shadowcull::testing {

struct Loaded {
    Space space;
    TerrainMeshes terrainMeshes;
    BakeWindow window;
    ChunkVerdicts verdicts;

    // The verdict row of a model (by uuid) or of the terrain ("terrain") of chunk (0, 0).
    std::optional<size_t> find(const std::string& key) const {
        for (size_t oi = 0; oi < verdicts.objects.size(); ++oi) {
            const ObjectVerdicts& ov = verdicts.objects[oi];
            if (key == "terrain" ? ov.terrain : ov.uuid == key) return oi;
        }
        return std::nullopt;
    }
    size_t object(const std::string& key) const {
        if (std::optional<size_t> oi = find(key)) return *oi;
        ADD_FAILURE() << "no object " << key;
        return 0;
    }
    const Decision& at(const std::string& key, int group, int light) const {
        return verdicts.at(object(key), group, light);
    }
};

inline std::unique_ptr<Loaded> load(const SpaceBuilder& b, const std::string& suffix = "") {
    const std::filesystem::path dir = freshTestDir(suffix);
    b.write(dir.string());
    auto l = std::make_unique<Loaded>();
    Expected<Space> space = loadSpace(dir.string(), "");
    EXPECT_TRUE(space) << (space ? "" : space.error().what());
    if (!space) return nullptr;
    l->space = std::move(*space);
    // The window the analytic bake gives chunk (0, 0): what its shadows reach.
    Expected<SpaceSource> source = SpaceSource::scan(dir.string(), "");
    EXPECT_TRUE(source) << (source ? "" : source.error().what());
    if (!source) return nullptr;
    const WindowPlanner planner(source->settings(), source->chunks(), true);
    l->window = buildWindow(l->space, ChunkCoord{0, 0}, planner.plan(ChunkCoord{0, 0}).chunks, l->terrainMeshes);
    l->verdicts = makeChunkVerdicts(l->space, l->window);
    return l;
}

}  // namespace shadowcull::testing
