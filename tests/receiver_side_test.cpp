// The receiver-side witness search (issue 19, raycast/receiver_targets.h): scenes whose
// terrain is a true 1 through a small receiver alone, so that rays through the terrain's
// own samples miss it and rays through the receivers in its shadow find it.

#include <algorithm>
#include <cmath>
#include <random>

#include <tbb/global_control.h>

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include "cli/pipeline.h"
#include "core/window.h"
#include "raycast/raycast_stage.h"
#include "raycast/receiver_targets.h"
#include "tests/support/bake_lookup.h"
#include "tests/support/loaded_window.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

constexpr const char* kReceiverSide = "receiver-side";

// `useGeometry` false: witness rays alone (no proofs of 0, and no rays at the geometry
// stage's candidates).
cli::BakeResult bakeWith(const SpaceBuilder& b, const fs::path& dir, int receiverSamples, bool useGeometry = true) {
    b.write(dir.string());
    cli::BakeOptions opt;
    opt.spaceDir = dir.string();
    opt.write = false;
    opt.useGeometry = useGeometry;
    opt.useGpu = false;  // the GPU stage's dense search could find the witness too
    opt.raycast.receiverSamples = receiverSamples;
    opt.geometry.crossCheckWitnesses = true;  // a witness and a proof of 0 must never meet
    Expected<cli::BakeResult> r = cli::runBake(opt);
    EXPECT_TRUE(r) << (r ? "" : r.error().what());
    return r ? std::move(*r) : cli::BakeResult{};
}

// A ridge: flat ground for x < 50 rising at slope 0.4 to 20 m at the chunk's edge (x =
// 100, no terrain beyond), under a low sun along +x descending 0.3 per metre. Every ray
// that meets the ground runs under it to the edge, and from there only a 30 cm cube 10 m
// beyond the crest is in its way: the terrain is a 1 through the cube alone, whose shadow
// on the slope is about 0.2 m² of the terrain's 10,000.
SpaceBuilder ridgeWithStoneBeyond() {
    SpaceBuilder b;
    b.addLight(LightSpec::directional("sun", {1.0, -0.3, 0.0}));
    b.addTerrain(0, 0, 11, [](double x, double) { return x < 50 ? 0.0 : 0.4 * (x - 50); }, 0.0, 20.0);
    b.addMesh("stone", MeshSpec::box({-0.15, -0.15, -0.15}, {0.15, 0.15, 0.15}));
    // Traced back along the light, (110, -1.69, 36.1) meets the slope at x = 73.3, inside a
    // cell and off its diagonal (no vertex or edge-midpoint sample of the terrain near).
    b.addModel("stone", Affine::translation({110.0, -1.69, 36.1}));
    return b;
}

// Flat ground at y = 0 with a 30 cm plate facing up 5 mm under it (within the terrain
// tolerance of 1 cm, so it receives), a slanted sun without bias: the ground shades the
// plate, and nothing else is behind the ground anywhere.
SpaceBuilder plateInTheBand(double plateY = -0.005) {
    SpaceBuilder b;
    b.addLight(LightSpec::directional("sun", {0.3, -1.0, 0.2}));
    b.addFlatTerrain(0, 0, 0.0);
    b.addMesh("plate", MeshSpec::quad({-0.15, 0, -0.15}, {-0.15, 0, 0.15}, {0.15, 0, 0.15}, {0.15, 0, -0.15}));
    b.addModel("plate", Affine::translation({41.3, plateY, 57.7}));
    return b;
}

// The ridge of ridgeWithStoneBeyond as a model (a cliff or hill modelled as a mesh, no
// terrain): the receiver-side search serves any large continuous caster.
SpaceBuilder meshRidgeWithStoneBeyond(std::string* ridge) {
    SpaceBuilder b;
    b.addLight(LightSpec::directional("sun", {1.0, -0.3, 0.0}));
    MeshSpec m;
    const int g = m.addGroup(GroupSpec{});
    const int n = 10;  // cells of 10 m, as the terrain's 11 x 11 samples
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) m.addVertex({i * 10.0, i * 10.0 < 50 ? 0.0 : 0.4 * (i * 10.0 - 50), j * 10.0});
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const int a = j * (n + 1) + i, c = a + n + 1;
            m.addTriangle(a, c, a + 1, g);  // front up
            m.addTriangle(a + 1, c, c + 1, g);
        }
    b.addMesh("ridge", m);
    *ridge = b.addModel("ridge", Affine::translation({0, 0, 0}));
    b.addMesh("stone", MeshSpec::box({-0.15, -0.15, -0.15}, {0.15, 0.15, 0.15}));
    b.addModel("stone", Affine::translation({110.0, -1.69, 36.1}));
    return b;
}

// The caster's bit (the terrain's by default): undecided with its own samples alone (they
// miss the small receiver's shadow), proved 1 by the receiver-side search; returns its
// witness.
Witness onlyReceiverSideFinds(const SpaceBuilder& b, const std::string& casterKey = SpaceBuilder::terrainKey(0, 0)) {
    const ObjectLocation terrain = b.locateObjects().at(casterKey);
    {
        const cli::BakeResult r = bakeWith(b, freshTestDir("-off") / "space", 0, false);
        const Decision* d = findDecision(r, terrain, 0, 0);
        EXPECT_NE(d, nullptr);
        if (d) {
            EXPECT_EQ(d->verdict, Verdict::Undecided) << d->stage << ": " << d->reason();
        }
    }
    // Without the shadow volumes too: with them, a terrain's search goes on after their
    // candidate receiver had its witness rays, which may find the witness first.
    const cli::BakeResult r = bakeWith(b, freshTestDir("-on") / "space", 2048, false);
    const Decision* d = findDecision(r, terrain, 0, 0);
    EXPECT_NE(d, nullptr);
    if (!d) return {};
    EXPECT_EQ(d->verdict, Verdict::Kept) << d->stage << ": " << d->reason();
    EXPECT_NE(d->reason().find(kReceiverSide), std::string_view::npos) << d->reason();
    EXPECT_NE(d->witness(), nullptr);
    return d->witness() ? *d->witness() : Witness{};
}

}  // namespace

TEST(ReceiverSide, RidgeShadowOnAStoneIsFoundFromTheStone) {
    const Witness w = onlyReceiverSideFinds(ridgeWithStoneBeyond());
    EXPECT_NE(w.receiver.find("model"), std::string::npos) << w.receiver;  // q on the stone
    EXPECT_NEAR(w.wsQ.x, 109.85, 0.2);
    EXPECT_LT(w.wsP.x, 100.0);
}

TEST(ReceiverSide, RidgeModelledAsAMeshIsFoundFromTheStoneToo) {
    std::string ridge;
    const SpaceBuilder b = meshRidgeWithStoneBeyond(&ridge);
    const Witness w = onlyReceiverSideFinds(b, ridge);
    EXPECT_NE(w.receiver.find("model"), std::string::npos) << w.receiver;
    EXPECT_NEAR(w.wsQ.x, 109.85, 0.2);
    EXPECT_LT(w.wsP.x, 100.0);
}

TEST(ReceiverSide, PlateInTheTerrainBandIsFound) {
    const Witness w = onlyReceiverSideFinds(plateInTheBand());
    EXPECT_NEAR(w.wsQ.y, -0.005, 1e-3);  // q on the plate, in the band
}

// Without the receiver-side search, the geometry stage's candidate (the point of the
// plate its shadow volume reaches) is where the witness ray is aimed next.
TEST(ReceiverSide, GeometryCandidateIsWhereTheNextWitnessRayGoes) {
    const SpaceBuilder b = plateInTheBand();
    const cli::BakeResult r = bakeWith(b, freshTestDir() / "space", 0);
    const Decision* d = findDecision(r, b.locateObjects().at(SpaceBuilder::terrainKey(0, 0)), 0, 0);
    ASSERT_NE(d, nullptr);
    ASSERT_EQ(d->verdict, Verdict::Kept) << d->stage << ": " << d->reason();
    EXPECT_NE(d->reason().find("shadow volume reaches"), std::string_view::npos) << d->reason();
    ASSERT_NE(d->witness(), nullptr);
    EXPECT_NEAR(d->witness()->wsQ.y, -0.005, 1e-3);
    const auto timing = std::find_if(r.stages.begin(), r.stages.end(),
                                     [](const cli::StageTiming& t) { return t.name == "raycast (geometry candidates)"; });
    ASSERT_NE(timing, r.stages.end());
    EXPECT_EQ(timing->stats.provedKept, 1u);
}

// Deeper than the tolerance, the plate receives nothing (the terrain rule): no target is
// placed on it, and the terrain is proved 0 as before.
TEST(ReceiverSide, PlateUnderTheBandGetsNoTargetAndTerrainIsCulled) {
    const SpaceBuilder b = plateInTheBand(-0.02);
    const fs::path dir = freshTestDir() / "space";
    const cli::BakeResult r = bakeWith(b, dir, 2048);
    const Decision* d = findDecision(r, b.locateObjects().at(SpaceBuilder::terrainKey(0, 0)), 0, 0);
    ASSERT_NE(d, nullptr);
    EXPECT_EQ(d->verdict, Verdict::Culled) << d->stage << ": " << d->reason();

    const std::unique_ptr<Loaded> l = load(b);
    ASSERT_TRUE(l);
    ASSERT_EQ(l->window.terrainObjects.size(), 1u);
    raycast::GroupSampleCache samples(256, 1024);
    const std::vector<glm::dvec3> targets =
        raycast::receiverTargets(l->window, uint32_t(l->window.terrainObjects[0]), 0, l->window.lsLights[0], 512, samples);
    EXPECT_FALSE(targets.empty());
    for (const glm::dvec3& p : targets) EXPECT_GT(p.y, -0.015) << "a target under the band";
}

// The targets of one (caster, light) are the same on every call (the bake is deterministic),
// at most the budget, and the stone of the ridge scene gets some (its share by the square
// root of its projected area).
TEST(ReceiverSide, TargetsAreDeterministicBoundedAndReachSmallReceivers) {
    const std::unique_ptr<Loaded> l = load(ridgeWithStoneBeyond());
    ASSERT_TRUE(l);
    const BakeWindow& w = l->window;
    ASSERT_EQ(w.terrainObjects.size(), 1u);
    raycast::GroupSampleCache samples(256, 1024);
    const uint32_t t = uint32_t(w.terrainObjects[0]);
    EXPECT_TRUE(raycast::isLargeCaster(w.objects[t], 0, 256, 0.5));
    const auto a = raycast::receiverTargets(w, t, 0, w.lsLights[0], 1000, samples);
    const auto again = raycast::receiverTargets(w, t, 0, w.lsLights[0], 1000, samples);
    EXPECT_EQ(a, again);
    EXPECT_LE(a.size(), 1000u);
    EXPECT_GT(a.size(), 500u);
    size_t onStone = 0;
    for (const glm::dvec3& p : a) onStone += p.x + w.wsOrigin.x > 109.8;
    EXPECT_GE(onStone, 2u);
    // The stone is small: not a large caster (its own samples are 2 cm apart).
    for (size_t k = 0; k < w.objects.size(); ++k) {
        if (w.objects[k].kind == ChunkObject::Kind::Model) {
            EXPECT_FALSE(raycast::isLargeCaster(w.objects[k], 0, 256, 0.5));
        }
    }
}

// Whether a caster is large (the receiver-side search's trigger) is decided from the mesh's
// group area and the transform's area-scale bounds where those decide, and by the loop over
// the placed triangles otherwise: the answer is the loop's, for thresholds a hair either
// side of the placed area, on uniform scales, per-axis scales and shears.
TEST(ReceiverSide, LargeCasterIsTheLoopsAnswer) {
    Mesh m;
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    for (int k = 0; k < 300; ++k) m.positions.push_back({2.0 * unit(rng), 0.5 * unit(rng), 2.0 * unit(rng)});
    for (uint32_t k = 0; k + 2 < 300; k += 3) {
        m.triangles.push_back({k, k + 1, k + 2});
        m.triangleGroup.push_back(k % 2);
    }
    m.groups.resize(2);
    auto placedArea = [&](const WindowObject& o, uint32_t g) {
        double a = 0.0;
        for (size_t t = 0; t < m.triangles.size(); ++t) {
            if (m.triangleGroup[t] != g) continue;
            const auto [p, q, r] = o.lsTriangle(t);
            a += 0.5 * glm::length(glm::cross(q - p, r - p));
        }
        return a;
    };
    const int samples = 256;
    int checked = 0;
    for (int rep = 0; rep < 30; ++rep) {
        WindowObject o;
        o.mesh = &m;
        const double s = 0.5 + unit(rng) * 0.4;
        const double turn = 3.0 * unit(rng);
        o.lsTransform.rows[0] = s * glm::dvec3(std::cos(turn), 0.0, -std::sin(turn));
        o.lsTransform.rows[1] = glm::dvec3(0.0, s, 0.0);
        o.lsTransform.rows[2] = s * glm::dvec3(std::sin(turn), 0.0, std::cos(turn));
        o.lsTransform.rows[3] = glm::dvec3(1e5, 10.0, -1e5);
        if (rep % 3 == 1) o.lsTransform.rows[1] *= 2.5;                     // a per-axis scale
        if (rep % 3 == 2) o.lsTransform.rows[2] += 0.6 * o.lsTransform.rows[0];  // a shear
        for (uint32_t g = 0; g < 2; ++g) {
            const double area = placedArea(o, g);
            for (double f : {0.5, 1.0 - 1e-6, 1.0 - 1e-13, 1.0 + 1e-13, 1.0 + 1e-6, 2.0}) {
                // The spacing whose threshold is f times the placed area.
                const double spacing = std::sqrt(f * area / samples);
                const bool loop = std::sqrt(area / samples) >= spacing;
                EXPECT_EQ(raycast::isLargeCaster(o, g, samples, spacing), loop) << "rep " << rep << " group " << g << " f " << f;
                ++checked;
            }
        }
    }
    EXPECT_EQ(checked, 30 * 2 * 6);
}

// The plate 9.8 mm under the ground: 0.2 mm inside the 1 cm band, less than the float
// margin the raycast stage used to put on Embree's depths (1e-6 of the window's size,
// ~0.5 mm here). Depths recomputed in double find the witness (it was left undecided).
TEST(ReceiverSide, WitnessAFractionOfAMillimetreInsideTheBandIsFound) {
    const SpaceBuilder b = plateInTheBand(-0.0098);
    const cli::BakeResult r = bakeWith(b, freshTestDir() / "space", 2048);
    const Decision* d = findDecision(r, b.locateObjects().at(SpaceBuilder::terrainKey(0, 0)), 0, 0);
    ASSERT_NE(d, nullptr);
    EXPECT_EQ(d->verdict, Verdict::Kept) << d->stage << ": " << d->reason();
    ASSERT_NE(d->witness(), nullptr);
    EXPECT_NEAR(d->witness()->wsQ.y, -0.0098, 1e-6);
}

// A point light's targets lie on what it reaches: q is within range (semantics.md), so a
// receiver wholly beyond it gets none (world D: the lamp's terrain bits aimed at dense rocks
// 40-90 m away, a fifth of the raycast stage). A lamp of range 12 m 10 m over flat ground,
// cubes near it and beyond its range.
TEST(ReceiverSide, APointLightsTargetsLieWithinItsReach) {
    SpaceBuilder b;
    b.addLight(LightSpec::point("lamp", {50, 10, 50}, 12));
    b.addFlatTerrain(0, 0, 0.0, 51);  // cells of 2 m
    b.addMesh("cube", MeshSpec::box({-0.5, -0.5, -0.5}, {0.5, 0.5, 0.5}));
    for (int k = 0; k < 8; ++k) {
        const double a = k * 0.785398, r = k % 2 ? 5.0 : 30.0;  // near, and beyond range
        b.addModel("cube", Affine::translation({50 + r * std::cos(a), 0.2, 50 + r * std::sin(a)}));
    }
    const std::unique_ptr<Loaded> l = load(b);
    ASSERT_TRUE(l);
    const BakeWindow& w = l->window;
    raycast::GroupSampleCache samples(256, 1024);
    const auto targets = raycast::receiverTargets(w, uint32_t(w.terrainObjects[0]), 0, w.lsLights[0], 1000, samples);
    ASSERT_GT(targets.size(), 100u);
    size_t onNearCubes = 0;
    for (const glm::dvec3& p : targets) {
        // Every target within range, give or take a terrain cell's diagonal.
        EXPECT_LT(glm::distance(p, w.lsLights[0].position), 12.0 + 3.0) << p.x << " " << p.y << " " << p.z;
        onNearCubes += p.y > 0.01;
    }
    EXPECT_GT(onNearCubes, 0u);
}

// A long target list (a receiver-side search's thousands) is searched in blocks on every
// thread: the witness kept is still the first target's in order that has one, and the
// rays counted those of the search in order. The ridge's terrain, aimed at through 767
// points on its flat part (the line meets the ground there, and nothing behind it), then
// the stone: its first witness target ends the third block of 256, the ones after it
// start the fourth, then more of the flat part to 2,048 targets. On one thread and on
// every thread: the same witness, on the first stone target, and the same rays.
TEST(ReceiverSide, ALongTargetListKeepsTheFirstWitnessInOrder) {
    const std::unique_ptr<Loaded> l = load(ridgeWithStoneBeyond());
    ASSERT_TRUE(l);
    const BakeWindow& w = l->window;
    const glm::dvec3 first{109.85, -1.69 + 0.1, 36.1 + 0.05};  // on the stone's face to the light
    std::vector<glm::dvec3> targets;
    for (int k = 0; k < 767; ++k) targets.push_back(glm::dvec3(5.0 + 0.05 * k, 0.0, 5.0 + 0.1 * k) - w.wsOrigin);
    targets.push_back(first - w.wsOrigin);
    for (int k = 0; k < 300; ++k)
        targets.push_back(glm::dvec3(109.85, -1.69 - 0.1 + 0.0005 * k, 36.1 - 0.1 + 0.0006 * k) - w.wsOrigin);
    // More of the flat part: blocks that another thread may go through before the witness
    // is known; their rays are not the search's in order.
    for (int k = 0; k < 981; ++k) targets.push_back(glm::dvec3(40.0 - 0.03 * k, 0.0, 90.0 - 0.08 * k) - w.wsOrigin);
    struct Searched {
        Decision decision;
        uint64_t rays = 0;
    };
    auto search = [&](int threads) {
        std::unique_ptr<tbb::global_control> limit;
        if (threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));
        ChunkVerdicts cv = l->verdicts;
        size_t terrain = cv.objects.size();
        for (size_t oi = 0; oi < cv.objects.size(); ++oi)
            if (cv.objects[oi].terrain) terrain = oi;
        EXPECT_LT(terrain, cv.objects.size());
        raycast::RaycastStage stage;
        StageStats stats;
        raycast::WitnessSearch s{terrain, 0, 0, targets};
        EXPECT_TRUE(stage.searchAt(w, cv, {s}, stats, "test"));
        return Searched{cv.at(terrain, 0, 0), stats.raysCast};
    };
    const Searched one = search(1), every = search(0);
    for (const Searched* r : {&one, &every}) {
        ASSERT_EQ(r->decision.verdict, Verdict::Kept);
        ASSERT_NE(r->decision.witness(), nullptr);
        EXPECT_LT(glm::length(r->decision.witness()->wsQ - first), 1e-6) << r->decision.witness()->wsQ.z;
    }
    EXPECT_EQ(one.rays, every.rays);
    EXPECT_GT(one.rays, 767u);  // the flat part's targets were traced
}

namespace {

// Everything a bit's decision says, as text (verdict, stage, reason, witness, notes): two
// searches that end the same way give the same string.
std::string decisionText(const Decision& d) {
    std::string s = std::to_string(int(d.verdict)) + "|" + std::string(d.stage) + "|" + std::string(d.reason());
    if (const Witness* w = d.witness()) {
        for (const glm::dvec3& v : {w->wsOrigin, w->wsDirection, w->wsP, w->wsQ})
            s += "|" + std::to_string(v.x) + "," + std::to_string(v.y) + "," + std::to_string(v.z);
        s += "|" + w->receiver;
    }
    for (const StageNote& n : d.notes()) s += "|" + std::string(n.stage) + ": " + n.text;
    return s;
}

struct StageRun {
    ChunkVerdicts cv;
    StageStats stats;
    size_t terrainUndecidedWithNotes = 0;  // after run(), before finishDeferred
};

// The raycast stage on chunk (0, 0)'s window: in full, or its searches cut short after
// `firstTargets` own samples, then finished.
StageRun runRaycast(const Loaded& l, size_t firstTargets) {
    StageRun r;
    r.cv = l.verdicts;
    raycast::RaycastStage stage;
    if (firstTargets > 0) stage.deferLongSearches(firstTargets);
    EXPECT_TRUE(stage.run(l.window, r.cv, r.stats));
    for (const ObjectVerdicts& ov : r.cv.objects)
        for (const Decision& d : ov.decisions)
            r.terrainUndecidedWithNotes += ov.terrain && d.verdict == Verdict::Undecided && !d.notes().empty();
    EXPECT_TRUE(stage.finishDeferred(l.window, r.cv, r.stats));
    return r;
}

}  // namespace

// A search cut short and finished after the other stages (RaycastStage::deferLongSearches)
// ends every bit as the full search does: the same witness (the first of the same samples
// in order), or the same note with the same counts; and, cut on a packet boundary, with the
// same rays. Every scene of this file, cut after 1, 16 and 256 samples.
TEST(ReceiverSide, ASearchCutShortAndFinishedEndsAsTheFullSearch) {
    std::string ridge;
    const std::vector<std::pair<const char*, SpaceBuilder>> scenes = {
        {"ridge", ridgeWithStoneBeyond()},
        {"plate in the band", plateInTheBand()},
        {"plate under the band", plateInTheBand(-0.02)},
        {"mesh ridge", meshRidgeWithStoneBeyond(&ridge)},
    };
    for (size_t si = 0; si < scenes.size(); ++si) {
        const auto& [name, b] = scenes[si];
        const std::unique_ptr<Loaded> l = load(b, "-" + std::to_string(si));
        ASSERT_TRUE(l) << name;
        const StageRun full = runRaycast(*l, 0);
        size_t undecided = 0;
        for (const ObjectVerdicts& ov : full.cv.objects)
            for (const Decision& d : ov.decisions) undecided += d.verdict == Verdict::Undecided;
        for (const size_t cut : {size_t(1), size_t(16), size_t(256)}) {
            SCOPED_TRACE(std::string(name) + ", cut after " + std::to_string(cut));
            const StageRun cutShort = runRaycast(*l, cut);
            EXPECT_EQ(cutShort.terrainUndecidedWithNotes, 0u);  // the note waits for the rest of the search
            ASSERT_EQ(cutShort.cv.objects.size(), full.cv.objects.size());
            for (size_t oi = 0; oi < full.cv.objects.size(); ++oi)
                for (size_t k = 0; k < full.cv.objects[oi].decisions.size(); ++k)
                    EXPECT_EQ(decisionText(cutShort.cv.objects[oi].decisions[k]),
                              decisionText(full.cv.objects[oi].decisions[k]))
                        << "object " << oi << " bit " << k;
            EXPECT_EQ(cutShort.stats.bitsExamined, full.stats.bitsExamined);
            EXPECT_EQ(cutShort.stats.provedKept, full.stats.provedKept);
            if (cut % 16 == 0) {
                EXPECT_EQ(cutShort.stats.raysCast, full.stats.raysCast);
            }
        }
        if (std::string(name) == "plate under the band") {
            EXPECT_GT(undecided, 0u);  // a note to compare
        }
    }
}

namespace {

// `b` baked with the shadow volumes and without (rays alone): `at`'s first bit proved 0 by
// the volumes, and left undecided without them (`open`, its decision there); the raycast
// stage's row of each.
struct VolumesFirst {
    cli::BakeResult withVolumes, raysAlone;
    const Decision* open = nullptr;
    StageStats shortRays, fullRays;
};

StageStats raycastRow(const cli::BakeResult& r) {
    const auto t = std::find_if(r.stages.begin(), r.stages.end(), [](const cli::StageTiming& s) { return s.name == "raycast"; });
    EXPECT_NE(t, r.stages.end());
    return t == r.stages.end() ? StageStats{} : t->stats;
}

VolumesFirst volumesFirst(const SpaceBuilder& b, const ObjectLocation& at) {
    VolumesFirst r;
    r.withVolumes = bakeWith(b, freshTestDir("-v") / "space", 2048);
    r.raysAlone = bakeWith(b, freshTestDir("-r") / "space", 2048, false);
    const Decision* culled = findDecision(r.withVolumes, at, 0, 0);
    EXPECT_NE(culled, nullptr);
    if (culled) {
        EXPECT_EQ(culled->verdict, Verdict::Culled);
        EXPECT_EQ(culled->stage, "geometry");
    }
    r.open = findDecision(r.raysAlone, at, 0, 0);
    EXPECT_NE(r.open, nullptr);
    if (r.open) {
        EXPECT_EQ(r.open->verdict, Verdict::Undecided);
    }
    r.shortRays = raycastRow(r.withVolumes);
    r.fullRays = raycastRow(r.raysAlone);
    return r;
}

}  // namespace

// A large model's receiver-side search waits for the shadow volumes too: a 20 m plate lying
// 5 mm over flat ground under a 5 cm bias has nothing more than the bias behind it, so its
// own samples find no witness and the volumes prove it 0, and its 2,048 receiver-side
// points are never traced (the same bake without the volumes traces them). Before, that
// search ran right after the own samples, ahead of the volumes.
TEST(ReceiverSide, TheVolumesProveALargeModelBeforeItsReceiverSideSearch) {
    SpaceBuilder b;
    b.addLight(LightSpec::directional("sun", {0.3, -1.0, 0.2}).withBias(0.05));
    b.addFlatTerrain(0, 0, 0.0);
    b.addMesh("plate", MeshSpec::quad({-10, 0, -10}, {-10, 0, 10}, {10, 0, 10}, {10, 0, -10}));
    const std::string plate = b.addModel("plate", Affine::translation({32.0, 0.005, 32.0}));
    const VolumesFirst r = volumesFirst(b, b.locateObjects().at(plate));
    ASSERT_NE(r.open, nullptr);
    bool receiverSide = false;  // the search the volumes spare was made without them
    for (const StageNote& n : r.open->notes()) receiverSide |= n.text.find("receivers in its shadow") != std::string::npos;
    EXPECT_TRUE(receiverSide);
    // The plate's own 268 samples and the terrain's first 256 (1,548 rays here), against
    // those, the terrain's full search and the plate's receiver side (12,262; 6,568 when
    // the plate's receiver side ran ahead of the volumes).
    EXPECT_EQ(r.shortRays.bitsExamined, r.fullRays.bitsExamined);
    EXPECT_LT(r.shortRays.raysCast * 2, r.fullRays.raysCast) << r.shortRays.raysCast << " against " << r.fullRays.raysCast;
}

// In a bake, the shadow volumes come between a terrain's short search and the rest: the
// terrain over the plate deeper than the tolerance is proved 0 by them, and the witness
// rays stop after its first samples, instead of tracing all of them and the receiver side
// for nothing (the same bake without the volumes traces those).
TEST(ReceiverSide, TheVolumesProveATerrainBeforeItsLongSearch) {
    const SpaceBuilder b = plateInTheBand(-0.02);
    const VolumesFirst r = volumesFirst(b, b.locateObjects().at(SpaceBuilder::terrainKey(0, 0)));
    // The short search: at most 256 samples, each a packet lane and at most a closest hit
    // and the surfaces behind it; the full search traced more than 1,000 samples and the
    // receiver side.
    EXPECT_EQ(r.shortRays.bitsExamined, r.fullRays.bitsExamined);
    EXPECT_LT(r.shortRays.raysCast * 3, r.fullRays.raysCast) << r.shortRays.raysCast << " against " << r.fullRays.raysCast;
}
