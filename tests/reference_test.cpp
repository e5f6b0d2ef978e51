// Issue 34: every 0 the bake proves is checked by a reference that shares nothing with the
// stages (tests/reference/exact_reference.h: linear programs in exact rationals, written
// from the spec). A bake 0 for which the reference constructs a witness is a false cull:
// the test fails and names it. The reference's own answers are checked against the
// known-answer scenes' true masks, and against each other (a bit is never both a proved
// Zero and a witnessed One).
//
// Scenes: every known-answer scene through the whole bake (cli::runBake), the reference on a
// window that holds the whole space; and SHADOWCULL_REFERENCE_SCENES (default below) random
// small scenes built in memory, baked by the reach and geometry stages directly (no rays:
// every bit not settled by the input goes to the shadow volumes), with near-degenerate
// casters (exactly edge-on, within k x 1e-12 rad of it, needles, slivers), receivers on
// the caster's plane, through its vertices and at exactly the bias, occluders, terrain,
// point lights on the caster's plane, mirrored placements and 100 km offsets.
//
// To replay one scene of a long run: SHADOWCULL_REFERENCE_FIRST=n SHADOWCULL_REFERENCE_SCENES=n+1
// (the scenes before n are drawn, not baked); SHADOWCULL_REFERENCE_DUMP=1 prints a false
// cull's scene (every triangle, the light); SHADOWCULL_REFERENCE_EXHAUSTIVE=1 bakes with
// GeometryOptions::exhaustive (no broad phase, no double filters), to tell the exact test
// from what stands in front of it (LongRunFindingsStayFixed replays what such a run found).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <set>

#include <glm/geometric.hpp>

#include <gtest/gtest.h>

#include "cli/pipeline.h"
#include "core/stage.h"
#include "core/window.h"
#include "geometry/geometry_stage.h"
#include "io/scene_reader.h"
#include "tests/reference/exact_lp.h"
#include "tests/reference/exact_reference.h"
#include "tests/support/bake_lookup.h"
#include "tests/support/point_light_edge_case.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::reference;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

size_t envCount(const char* name, size_t fallback) {
    const char* v = std::getenv(name);
    if (!v || !*v) return fallback;
    return size_t(std::strtoull(v, nullptr, 10));
}

}  // namespace

// The solver alone, on programs whose answers are known.
TEST(ExactReference, LinearProgramsAreSolvedExactly) {
    // max x + y, x + 2y <= 4, 3x + y <= 6: optimum at (8/5, 6/5), value 14/5.
    ExactLp lp(2);
    lp.add({Rational(1), Rational(2)}, ExactLp::Relation::LessEqual, 4);
    lp.add({Rational(3), Rational(1)}, ExactLp::Relation::LessEqual, 6);
    ASSERT_EQ(lp.maximise({Rational(1), Rational(1)}), ExactLp::Outcome::Optimal);
    EXPECT_EQ(lp.value(), Rational(14, 5));
    EXPECT_EQ(lp.solution()[0], Rational(8, 5));
    // Equalities and >=: x + y = 1, x >= 2: infeasible.
    ExactLp bad(2);
    bad.add({Rational(1), Rational(1)}, ExactLp::Relation::Equal, 1);
    bad.add({Rational(1), Rational(0)}, ExactLp::Relation::GreaterEqual, 2);
    EXPECT_EQ(bad.maximise({Rational(0), Rational(1)}), ExactLp::Outcome::Infeasible);
    // Unbounded: max x with x - y <= 1.
    ExactLp open(2);
    open.add({Rational(1), Rational(-1)}, ExactLp::Relation::LessEqual, 1);
    EXPECT_EQ(open.maximise({Rational(1), Rational(0)}), ExactLp::Outcome::Unbounded);
    // Degenerate (redundant equalities, a negative right-hand side): x + y = 1 twice,
    // -x <= -1/3: max y = 2/3.
    ExactLp deg(2);
    deg.add({Rational(1), Rational(1)}, ExactLp::Relation::Equal, 1);
    deg.add({Rational(2), Rational(2)}, ExactLp::Relation::Equal, 2);
    deg.add({Rational(-1), Rational(0)}, ExactLp::Relation::LessEqual, Rational(-1, 3));
    ASSERT_EQ(deg.maximise({Rational(0), Rational(1)}), ExactLp::Outcome::Optimal);
    EXPECT_EQ(deg.value(), Rational(2, 3));
}

namespace {

struct Tally {
    size_t bits = 0, bakeZeros = 0, refZero = 0, refUnsure = 0, falseCulls = 0;
    std::map<std::string, size_t> zerosByStage;
    std::vector<std::string> errors;
};

// The reference on every bake 0 of the window's centre chunk (`cv` as baked; its objects
// in the order makeChunkVerdicts gives them for `window`).
void checkZeros(const BakeWindow& window, const ChunkVerdicts& cv, const std::string& where, Tally& tally) {
    const RefScene scene = referenceScene(window);
    for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
        const ObjectVerdicts& ov = cv.objects[oi];
        if (ov.windowObject < 0) continue;
        for (int g = 0; g < ov.groupCount; ++g)
            for (int l = 0; l < cv.lightCount; ++l) {
                ++tally.bits;
                const Decision& d = cv.at(oi, g, l);
                if (d.verdict != Verdict::Culled) continue;
                ++tally.bakeZeros;
                ++tally.zerosByStage[std::string(d.stage)];
                const RefAnswer a = referenceDecision(scene, uint32_t(ov.windowObject), uint32_t(g), size_t(l));
                if (a.verdict == RefVerdict::Zero) ++tally.refZero;
                if (a.verdict == RefVerdict::Unsure) ++tally.refUnsure;
                if (a.verdict == RefVerdict::One) {
                    if (std::getenv("SHADOWCULL_REFERENCE_DUMP")) {
                        for (const RefTriangle& t : scene.triangles)
                            std::printf("tri obj %u grp %u terrain %d blocks %d: (%.17g %.17g %.17g) (%.17g %.17g %.17g) (%.17g %.17g %.17g)\n",
                                        t.object, t.group, int(t.terrain), int(t.blocksLight), t.v[0].x, t.v[0].y, t.v[0].z,
                                        t.v[1].x, t.v[1].y, t.v[1].z, t.v[2].x, t.v[2].y, t.v[2].z);
                        const Light& L = scene.lights[size_t(l)];
                        std::printf("light dir (%.17g %.17g %.17g) bias %g slope %g filter %g normalBias %g tol %g\n", L.direction.x,
                                    L.direction.y, L.direction.z, L.bias, L.slopeBias, L.filterRadius, L.normalBias, scene.terrainTolerance);
                    }
                    ++tally.falseCulls;
                    tally.errors.push_back("ERROR: a false cull: " + where + " object " + std::to_string(ov.windowObject) + " group " +
                                           std::to_string(g) + " light " + std::to_string(l + 1) + " culled by " +
                                           std::string(d.stage) + " (" + std::string(d.reason()) + "); " + a.why);
                }
            }
    }
}

}  // namespace

// Every known-answer scene through the whole bake: no bake 0 has a reference witness, and
// the reference agrees with each scene's true mask where it decides.
TEST(ExactReference, KnownAnswerScenesHaveNoFalseCull) {
    Tally tally;
    size_t checkedAnswers = 0, refDecidedAnswers = 0;
    for (const NamedScene& sc : knownAnswerScenes()) {
        SCOPED_TRACE(sc.name);
        const SpaceBuilder b = sc.make();
        const fs::path dir = freshTestDir(std::string("-") + sc.name) / "space";
        b.write(dir.string());
        cli::BakeOptions opt;
        opt.spaceDir = dir.string();
        opt.write = false;
        Expected<cli::BakeResult> r = cli::runBake(opt);
        ASSERT_TRUE(r) << r.error().what();
        Expected<Space> space = loadSpace(dir.string(), "");
        ASSERT_TRUE(space) << space.error().what();
        std::vector<ChunkCoord> every;
        for (const auto& [c, f] : space->chunks) every.push_back(c);
        TerrainMeshes terrain;
        const auto where = b.locateObjects();
        for (const ChunkVerdicts& cv : r->chunks) {
            // The whole space in one window: the reference's receivers are every surface.
            const BakeWindow window = buildWindow(*space, cv.coord, every, terrain);
            ChunkVerdicts layout = makeChunkVerdicts(*space, window);
            ASSERT_EQ(layout.objects.size(), cv.objects.size());
            ChunkVerdicts baked = cv;
            for (size_t oi = 0; oi < baked.objects.size(); ++oi) baked.objects[oi].windowObject = layout.objects[oi].windowObject;
            checkZeros(window, baked, std::string(sc.name) + " " + cv.path, tally);
            // The reference against the scene's true masks.
            const RefScene scene = referenceScene(window);
            for (const KnownAnswer& a : b.expectations()) {
                const ObjectLocation& loc = where.at(a.key);
                if (chunkFileName(cv.coord) != loc.chunkFile) continue;
                for (size_t oi = 0; oi < baked.objects.size(); ++oi) {
                    if (baked.objects[oi].elementIndex != loc.elementIndex || baked.objects[oi].windowObject < 0) continue;
                    for (int l = 0; l < baked.lightCount; ++l) {
                        const RefAnswer ra = referenceDecision(scene, uint32_t(baked.objects[oi].windowObject), uint32_t(a.group), size_t(l));
                        const bool truth = (a.mask >> l) & 1u;
                        ++checkedAnswers;
                        if (ra.verdict != RefVerdict::Unsure) ++refDecidedAnswers;
                        if (truth) EXPECT_NE(ra.verdict, RefVerdict::Zero) << a.key << " light " << l + 1 << ": " << a.why << "; " << ra.why;
                        else EXPECT_NE(ra.verdict, RefVerdict::One) << a.key << " light " << l + 1 << ": " << a.why << "; " << ra.why;
                    }
                }
            }
        }
    }
    for (const std::string& e : tally.errors) ADD_FAILURE() << e;
    EXPECT_EQ(tally.falseCulls, 0u);
    EXPECT_GT(tally.bakeZeros, 0u);
    EXPECT_GT(refDecidedAnswers, 0u);
    std::printf("known-answer scenes: %zu bits, %zu bake 0s, reference: %zu also 0, %zu unsure, %zu witnessed (false culls); "
                "%zu of %zu true masks decided by the reference\n",
                tally.bits, tally.bakeZeros, tally.refZero, tally.refUnsure, tally.falseCulls, refDecidedAnswers, checkedAnswers);
}

// --- Random near-degenerate scenes --------------------------------------------------------

namespace {

using Tri3 = std::array<glm::dvec3, 3>;

struct ObjectSpec {
    std::vector<Tri3> tris;
    std::vector<uint32_t> group;
    std::vector<PrimitiveGroup> groups;
    bool castsShadow = true;
    bool mirrored = false;  // placed by a mirroring transform (x -> -x of the mesh)
};

class SceneGenerator {
public:
    // `wide` (the default; SHADOWCULL_REFERENCE_DRAWS=narrow for the first version's
    // draws): SplitMix64 and the property run's wider tilts and sizes. They found a false
    // cull the narrow draws did not (seed 34, scenes 969 and 1084): the geometry stage's
    // occluders were placed in the interval code's upward rounding, and the caster's own
    // triangle, an ulp nearer the light, "shaded" it.
    SceneGenerator(uint64_t seed, bool wide) : rng_(seed), split_(seed), wide_(wide) {}

    double u(double lo, double hi) { return wide_ ? split_.uniform(lo, hi) : std::uniform_real_distribution<double>(lo, hi)(rng_); }
    int below(int n) { return wide_ ? split_.below(n) : int(rng_() % uint64_t(n)); }
    bool chance(double p) { return u(0, 1) < p; }

    // Within k x 1e-12 rad of zero (k = 0..5, either sign), or a few larger angles.
    double tilt() {
        switch (below(6)) {
            case 0: case 1: return 0.0;
            case 2: return double(wide_ ? below(11) - 5 : below(6) - 2) * 1e-12;
            case 3: return (chance(0.5) ? 1 : -1) * (wide_ ? u(1e-12, 1e-9) : 1e-9);
            case 4: return u(-1e-6, 1e-6);
            default: return wide_ ? u(-0.7, 0.7) : u(-0.5, 0.5);
        }
    }
    double size() {
        switch (below(8)) {
            case 0: return 1e-6;
            case 1: return wide_ ? u(1e3, 1e4) : 1e4;
            case 2: return u(1e-3, 1e-2);
            default: return u(0.2, 5.0);
        }
    }

    // One random scene: a space of one chunk holding every object.
    Space make(std::string& description, size_t& edgeOn, size_t& needles) {
        objects_.clear();
        // The canonical frame: the caster lies in the plane z = z0, which holds the light's
        // direction exactly when its z is 0 (an exactly edge-on caster, in double too);
        // axes are permuted and flipped at the end (exact).
        const bool far = chance(0.25);
        const bool terrain = !far && chance(0.25);
        const glm::dvec3 origin = far ? glm::dvec3(1e5 + u(0, 100), u(-5, 5) + (chance(0.3) ? 5000.0 : 0.0), 1e5 + u(0, 100))
                                      : glm::dvec3(u(30, 70), u(1, 8), u(30, 70));
        Light L;
        L.name = "light";
        const int kind = below(10);
        const double phi = chance(0.15) ? (chance(0.5) ? 0.0 : 1.5707963267948966) : u(0.05, 1.5);
        const double dz = tilt() * (chance(0.7) ? 1.0 : 0.0);
        glm::dvec3 d = glm::normalize(glm::dvec3(std::cos(phi), -std::sin(phi), dz));
        const double z0 = chance(0.5) ? 0.0 : u(-1, 1);
        const double s = size();
        // Caster (object 0): a, b in the plane z = z0, c tilted off it by `tilt` (k 1e-12 rad).
        const glm::dvec3 a(u(-1, 1), u(-1, 1), z0);
        glm::dvec3 e1 = glm::dvec3(u(-1, 1), u(-1, 1), 0.0);
        if (glm::length(e1) == 0.0) e1 = glm::dvec3(1, 0, 0);
        e1 = glm::normalize(e1) * s;
        const double needle = chance(0.25) ? 1e-6 : 1.0;
        const double ct = tilt();
        glm::dvec3 c = a + glm::normalize(glm::dvec3(u(-1, 1), u(-1, 1), 0.0) + glm::dvec3(1e-3)) * s * needle;
        c.z = z0 + ct * s * needle;
        const glm::dvec3 b = a + e1;
        edgeOn += (std::abs(ct) <= 1e-9 && std::abs(dz) <= 1e-9);
        needles += needle < 1.0;
        if (kind < 6) {
            L.type = LightType::Directional;
            L.direction = d;
        } else {
            L.type = kind < 8 ? LightType::Point : LightType::Spot;
            // On or near the caster's plane (z = z0 exactly, or tilted), or anywhere above.
            glm::dvec3 pos = a - d * u(0.5, 20.0);
            if (chance(0.5)) pos.z = z0 + (chance(0.5) ? 0.0 : tilt());
            if (chance(0.1)) pos = a;  // on a caster vertex
            L.position = pos;
            L.range = chance(0.3) ? u(0.5, 5.0) : u(5.0, 200.0);
            L.direction = d;
            L.coneHalfAngleDeg = chance(0.2) ? 90.0 : u(3.0, 89.0);
        }
        L.bias = chance(0.4) ? 0.0 : chance(0.3) ? u(1.0, 10.0) : u(1e-4, 0.1);
        L.slopeBias = chance(0.7) ? 0.0 : u(0.0, 0.5);
        L.filterRadius = chance(0.75) ? 0.0 : u(1e-3, 0.5);
        L.normalBias = chance(0.85) ? 0.0 : u(1e-3, 0.2);
        const glm::dvec3 rayAt = L.type == LightType::Directional ? d : glm::normalize(a - L.position + glm::dvec3(1e-9));

        // Object 0: the caster, in one or two groups (the second: a neighbour sharing an edge).
        ObjectSpec caster;
        caster.groups.resize(chance(0.3) ? 2 : 1);
        caster.tris.push_back({a, b, chance(0.5) ? c : c});
        caster.group.push_back(0);
        if (chance(0.5)) {
            const glm::dvec3 f = b + glm::dvec3(u(-1, 1), u(-1, 1), u(-1, 1)) * s;
            caster.tris.push_back({b, a, f});
            caster.group.push_back(uint32_t(caster.groups.size() - 1));
        }
        if (chance(0.1)) caster.groups[0].alphaTested = true;
        if (chance(0.2)) caster.groups[0].doubleSided = true;
        caster.mirrored = chance(0.2);
        objects_.push_back(caster);

        // Receivers and occluders.
        // A third of the scenes hold one receiver on the frustum's boundary and nothing else
        // (through a caster vertex, at exactly the bias, in the caster's plane): there a
        // filter that rejects it wrongly writes a false cull no other receiver hides.
        const bool lone = chance(0.33);
        const int count = lone ? 1 : 2 + below(5);
        for (int k = 0; k < count; ++k) {
            ObjectSpec o;
            o.groups.resize(1);
            o.castsShadow = !chance(0.1);
            o.mirrored = chance(0.2);
            if (chance(0.2)) o.groups[0].doubleSided = true;
            if (chance(0.05)) o.groups[0].alphaTested = true;
            const double depth = L.bias * (chance(0.5) ? 1.0 : u(0.5, 2.0)) + (chance(0.3) ? 0.0 : u(0.0, 3.0));
            const glm::dvec3 behind = a + rayAt * depth;
            const double rs = size() * (chance(0.5) ? 3.0 : 1.0);
            auto around = [&](const glm::dvec3& at, double r) {
                return glm::dvec3(at.x + u(-r, r), at.y + u(-r, r), at.z + u(-r, r));
            };
            Tri3 t;
            static const int kLoneKinds[4] = {0, 1, 4, 5};
            switch (lone ? kLoneKinds[below(4)] : below(8)) {
                case 0:  // through a caster vertex (bitwise), reaching behind
                    t = {a, around(behind, rs), around(behind, rs)};
                    break;
                case 1:  // in the caster's plane z = z0
                    t = {glm::dvec3(u(-2, 2), u(-3, 1), z0), glm::dvec3(u(-2, 2), u(-3, 1), z0), glm::dvec3(u(-2, 2), u(-3, 1), z0)};
                    break;
                case 2:  // a floor across the light behind the caster
                {
                    glm::dvec3 p = glm::cross(rayAt, glm::dvec3(0, 0, 1));
                    if (glm::length(p) == 0.0) p = glm::dvec3(1, 0, 0);
                    p = glm::normalize(p) * rs * 3.0;
                    const glm::dvec3 q = glm::dvec3(0, 0, rs * 3.0);
                    t = {behind - p - q, behind + p - q, behind + q};
                    break;
                }
                case 3:  // an occluder between the light and the caster
                {
                    const glm::dvec3 front = a - rayAt * u(0.01, 2.0);
                    t = {around(front, s), around(front, s), around(front, s)};
                    break;
                }
                case 4:  // a needle behind
                {
                    const glm::dvec3 p = around(behind, rs);
                    t = {p, p + glm::dvec3(rs, rs * 1e-7, 0), around(behind, rs)};
                    break;
                }
                case 5:  // a receiver vertex exactly at depth `bias` behind b along the light
                    t = {b + rayAt * L.bias, around(behind, rs), around(behind, rs)};
                    break;
                default:
                    t = {around(behind, rs), around(behind, rs), around(behind, rs)};
            }
            if (chance(0.5)) std::swap(t[1], t[2]);
            o.tris.push_back(t);
            o.group.push_back(0);
            if (chance(0.3)) {  // a second triangle sharing an edge
                o.tris.push_back({t[1], t[0], around(t[2], rs)});
                o.group.push_back(0);
            }
            objects_.push_back(o);
        }

        // Axes permuted and flipped (exact), then moved.
        const int perm = below(6);
        const glm::dvec3 flip(chance(0.5) ? -1 : 1, chance(0.5) ? -1 : 1, chance(0.5) ? -1 : 1);
        auto place = [&](const glm::dvec3& p) {
            static const int P[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
            const glm::dvec3 q(p[P[perm][0]] * flip.x, p[P[perm][1]] * flip.y, p[P[perm][2]] * flip.z);
            return q;
        };
        // Terrain keeps y up: only permutations that keep the second axis in place.
        auto placeAll = [&](const glm::dvec3& p) { return place(p) + origin; };
        if (L.type == LightType::Directional) L.direction = place(L.direction);
        else L.position = placeAll(L.position), L.direction = place(L.direction);
        L.direction = glm::normalize(L.direction);
        // A permutation of an odd number of swaps, or an odd number of flips, mirrors every
        // winding: the scene is the mirror image, which the spec handles alike.
        for (ObjectSpec& o : objects_)
            for (Tri3& t : o.tris)
                for (glm::dvec3& p : t) p = placeAll(p);

        Space space;
        space.settings.chunkSize = 100.0;
        space.settings.terrainTolerance = chance(0.5) ? 0.01 : u(0.0, 0.5);
        space.settings.lights.push_back(L);
        ChunkFile cf;
        cf.coord = ChunkCoord{0, 0};
        cf.path = "00000000o.chunk";
        int element = 0;
        if (terrain) {
            auto hf = std::make_shared<Heightfield>();
            hf->n = 2 + below(2);
            hf->size = 100.0;
            const double base = origin.y + u(-3, 1);
            for (int k = 0; k < hf->n * hf->n; ++k) hf->heights.push_back(base + (chance(0.5) ? 0.0 : u(-1, 1)));
            ChunkObject t;
            t.kind = ChunkObject::Kind::Terrain;
            t.elementIndex = element++;
            t.heightfield = hf;
            cf.objects.push_back(t);
        }
        for (const ObjectSpec& o : objects_) {
            auto m = std::make_shared<Mesh>();
            m->groups = o.groups;
            for (size_t i = 0; i < o.tris.size(); ++i) {
                const uint32_t base = uint32_t(m->positions.size());
                for (const glm::dvec3& p : o.tris[i]) m->positions.push_back(o.mirrored ? glm::dvec3(-p.x, p.y, p.z) : p);
                m->triangles.push_back({base, base + 1, base + 2});
                m->triangleGroup.push_back(o.group[i]);
            }
            ChunkObject co;
            co.kind = ChunkObject::Kind::Model;
            co.elementIndex = element++;
            co.uuid = fixedUuid(uint32_t(co.elementIndex));
            if (o.mirrored) co.transform.rows[0] = glm::dvec3(-1, 0, 0);
            co.castsShadow = o.castsShadow;
            co.mesh = m;
            cf.objects.push_back(co);
        }
        space.chunks[cf.coord] = cf;
        description = std::string(lightTypeName(L.type)) + (far ? " far" : "") + (terrain ? " terrain" : "");
        return space;
    }

private:
    std::mt19937_64 rng_;
    DeterministicRng split_;
    bool wide_ = false;
    std::vector<ObjectSpec> objects_;
};

}  // namespace

TEST(ExactReference, RandomNearDegenerateScenesHaveNoFalseCull) {
    const size_t sceneCount = envCount("SHADOWCULL_REFERENCE_SCENES", 10000);
    const uint64_t seed = envCount("SHADOWCULL_REFERENCE_SEED", 34);
    const char* draws = std::getenv("SHADOWCULL_REFERENCE_DRAWS");
    SceneGenerator gen(seed, !(draws && std::string(draws) == "narrow"));
    Tally tally;
    size_t edgeOn = 0, needles = 0, consistencyChecked = 0, undecided = 0;
    double bakeSeconds = 0, refSeconds = 0;
    ReachStage reach;
    geometry::GeometryOptions geometryOptions;
    geometryOptions.exhaustive = std::getenv("SHADOWCULL_REFERENCE_EXHAUSTIVE") != nullptr;  // to localise a finding
    geometry::GeometryStage geometryStage(geometryOptions);
    // SHADOWCULL_REFERENCE_FIRST: scenes before it are drawn (the same sequence) but not
    // baked, to replay one scene of a long run.
    const size_t first = envCount("SHADOWCULL_REFERENCE_FIRST", 0);
    for (size_t n = 0; n < sceneCount; ++n) {
        std::string what;
        const Space space = gen.make(what, edgeOn, needles);
        if (n < first) continue;
        TerrainMeshes terrain;
        const auto t0 = std::chrono::steady_clock::now();
        const BakeWindow window = buildWindow(space, ChunkCoord{0, 0}, {ChunkCoord{0, 0}}, terrain);
        ChunkVerdicts cv = makeChunkVerdicts(space, window);
        StageStats stats;
        ASSERT_TRUE(reach.run(window, cv, stats).isOk());
        const Status st = geometryStage.run(window, cv, stats);
        ASSERT_TRUE(st.isOk()) << st.error().what();
        const auto t1 = std::chrono::steady_clock::now();
        checkZeros(window, cv, "scene " + std::to_string(n) + " (seed " + std::to_string(seed) + ", " + what + ")", tally);
        // The reference against itself, on the bits left undecided (a sample): never both a
        // proved Zero and a witness.
        if (consistencyChecked < sceneCount / 4) {
            const RefScene scene = referenceScene(window);
            for (size_t oi = 0; oi < cv.objects.size(); ++oi)
                for (int g = 0; g < cv.objects[oi].groupCount; ++g)
                    for (int l = 0; l < cv.lightCount; ++l) {
                        if (cv.at(oi, g, l).verdict != Verdict::Undecided) continue;
                        ++undecided;
                        const uint32_t wo = uint32_t(cv.objects[oi].windowObject);
                        RefOptions zeroOnly, witnessOnly;
                        zeroOnly.searchWitness = false;
                        witnessOnly.proveZero = false;
                        const RefAnswer z = referenceDecision(scene, wo, uint32_t(g), size_t(l), zeroOnly);
                        const RefAnswer w = referenceDecision(scene, wo, uint32_t(g), size_t(l), witnessOnly);
                        ++consistencyChecked;
                        EXPECT_FALSE(z.verdict == RefVerdict::Zero && w.verdict == RefVerdict::One)
                            << "the reference contradicts itself: scene " << n << " object " << wo << " group " << g << ": " << w.why;
                    }
        }
        refSeconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
        bakeSeconds += std::chrono::duration<double>(t1 - t0).count();
        if (tally.errors.size() > 20) break;
    }
    for (const std::string& e : tally.errors) ADD_FAILURE() << e;
    EXPECT_EQ(tally.falseCulls, 0u);
    EXPECT_GT(tally.bakeZeros, 0u);
    EXPECT_GT(tally.refZero, 0u) << "the reference proves none of the bake's 0s: it checks nothing";
    const RefCounters& rc = refCounters();
    std::printf("random scenes: %zu (seed %llu; %zu with an edge-on caster within 1e-9, %zu needles), %zu bits, %zu bake 0s (",
                sceneCount, (unsigned long long)seed, edgeOn, needles, tally.bits, tally.bakeZeros);
    for (const auto& [stage, k] : tally.zerosByStage) std::printf("%s %zu ", stage.c_str(), k);
    std::printf("); reference: %zu also 0, %zu unsure, %zu witnessed (false culls); %zu undecided bits checked for "
                "self-consistency; pairs %llu (%llu prefiltered), programs %llu, witness tries %llu; bake %.1f s, reference %.1f s\n",
                tally.refZero, tally.refUnsure, tally.falseCulls, consistencyChecked, (unsigned long long)rc.pairs,
                (unsigned long long)rc.prefiltered, (unsigned long long)rc.lps, (unsigned long long)rc.witnessTries, bakeSeconds,
                refSeconds);
    (void)undecided;
}

// The case FilterProperty.PointLightOnACasterEdgeLineIsNotMissed found, as a scene: the
// caster, the receiver (two-sided) and the lamp alone, baked by the reach and geometry
// stages. The reference's verdict on the caster's bit decides whether the filter's
// rejection becomes a false cull.
// Found by the 100,000-scene run (seed 34): false culls where a caster reaches past the
// window's box (a terrain triangle larger than the window's content, a far caster): the
// broad phase's box of a caster's shadow took the farthest ray parameter at the caster's
// vertices only, while the column through its middle reaches further (shadowBox). Each
// failed before the fix; replayed here (the scenes before them are drawn, not baked).
TEST(ExactReference, LongRunFindingsStayFixed) {
    const size_t found[] = {64818, 90172, 93177};
    SceneGenerator gen(34, true);
    Tally tally;
    size_t edgeOn = 0, needles = 0;
    ReachStage reach;
    geometry::GeometryStage geometryStage;
    for (size_t n = 0; n <= found[2]; ++n) {
        std::string what;
        const Space space = gen.make(what, edgeOn, needles);
        if (std::find(std::begin(found), std::end(found), n) == std::end(found)) continue;
        TerrainMeshes terrain;
        const BakeWindow window = buildWindow(space, ChunkCoord{0, 0}, {ChunkCoord{0, 0}}, terrain);
        ChunkVerdicts cv = makeChunkVerdicts(space, window);
        StageStats stats;
        ASSERT_TRUE(reach.run(window, cv, stats).isOk());
        ASSERT_TRUE(geometryStage.run(window, cv, stats).isOk());
        checkZeros(window, cv, "scene " + std::to_string(n) + " (seed 34, " + what + ")", tally);
    }
    for (const std::string& e : tally.errors) ADD_FAILURE() << e;
    EXPECT_EQ(tally.falseCulls, 0u);
    EXPECT_GT(tally.bakeZeros, 0u);
}

TEST(ExactReference, LampOnACasterEdgeLine) {
    using Tri3 = std::array<glm::dvec3, 3>;
    const Tri3& caster = point_light_edge_case::kCaster;
    const Tri3& receiver = point_light_edge_case::kReceiver;
    Space space;
    space.settings.chunkSize = 100.0;
    Light L;
    L.type = LightType::Point;
    L.position = point_light_edge_case::kLamp;
    L.range = 1e5;
    space.settings.lights.push_back(L);
    ChunkFile cf;
    cf.path = "00000000o.chunk";
    int element = 0;
    for (const Tri3* t : {&caster, &receiver}) {
        auto m = std::make_shared<Mesh>();
        m->groups.resize(1);
        m->groups[0].doubleSided = true;
        for (const glm::dvec3& p : *t) m->positions.push_back(p);
        m->triangles.push_back({0, 1, 2});
        m->triangleGroup.push_back(0);
        ChunkObject co;
        co.elementIndex = element++;
        co.mesh = m;
        cf.objects.push_back(co);
    }
    space.chunks[cf.coord] = cf;
    TerrainMeshes terrain;
    // (The window frame lifts y by a whole number of metres, ~3364: its rounding moves the
    // geometry a little; the bake still culls and the reference still finds a witness.)
    const BakeWindow window = buildWindow(space, ChunkCoord{0, 0}, {ChunkCoord{0, 0}}, terrain);
    ChunkVerdicts cv = makeChunkVerdicts(space, window);
    StageStats stats;
    ASSERT_TRUE(ReachStage().run(window, cv, stats).isOk());
    ASSERT_TRUE(geometry::GeometryStage().run(window, cv, stats).isOk());
    const Decision& d = cv.at(0, 0, 0);
    const RefAnswer a = referenceDecision(referenceScene(window), uint32_t(cv.objects[0].windowObject), 0, 0);
    std::printf("lamp on a caster's edge line: bake %s (%s), reference %s (%s)\n", verdictName(d.verdict), std::string(d.reason()).c_str(),
                refVerdictName(a.verdict), a.why.c_str());
    EXPECT_FALSE(d.verdict == Verdict::Culled && a.verdict == RefVerdict::One) << "a false cull";
}
