// GeometryStage: see geometry_stage.h. Per window: gather the bits to examine; per bit, walk
// the caster group's triangles (clusters of its mesh tree first), each triangle's column
// first against the terrain (terrain_column.h: wholly under the ground, no receiver), else its
// frustum against the receivers the broad phase reaches (trees over the window's objects and their
// meshes, in double with margins), those through the double filters and the receiver rules
// (receiver_rules.h) to the exact test (exact_reach.h); then the verdict and its note.
// Every double test here only ever discards a receiver when it clearly cannot receive
// (margins on the side of keeping it), and the exact test decides the rest; so a bit is
// proved 0 only when no receiver can meet the group's shadow volume.

#include "geometry/geometry_stage.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <glm/common.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/light_reach.h"
#include "core/mesh_index.h"
#include "geometry/exact_frustum.h"
#include "geometry/exact_reach.h"
#include "geometry/receiver_rules.h"
#include "geometry/shadow_query.h"
#include "geometry/terrain_column.h"
#include "util/float_mode.h"
#include "util/format.h"
#include "util/stop_request.h"

namespace shadowcull::geometry {

namespace {

// Smallest cluster of caster triangles tested as a whole (smaller ones go triangle by
// triangle: a cluster query costs about as much as a few triangles' queries).
constexpr uint32_t kClusterAtLeast = 8;
// Caster subtrees of at least this many triangles are walked in parallel. Each split walks
// its right half while the left may still find the first candidate (work lost for a bit
// that has one) and waits on both: on 2 cores, R's geometry stage took 1.21-1.23 s at 256
// (a 512-triangle terrain in four pieces), 1.07-1.09 s at 512, 1.54 s at 1,024; M's 10.1
// s at 256 and 9.2 s at 512.
constexpr uint32_t kParallelCasters = 512;

// Where a shadow volume reaches a receiver: the point, window-local, and the receiver's
// window object and mesh triangle.
struct ReceiverPoint {
    glm::dvec3 lsPoint{0.0};
    uint32_t object = 0, triangle = 0;
};

// Closed boxes that share a point.
bool overlaps(const Aabb& a, const Aabb& b) {
    return !(a.max.x < b.min.x || a.min.x > b.max.x || a.max.y < b.min.y || a.min.y > b.max.y || a.max.z < b.min.z ||
             a.min.z > b.max.z);
}

Aabb grown(Aabb b, double by) {
    b.min -= glm::dvec3(by);
    b.max += glm::dvec3(by);
    return b;
}

// A box holding every point of the caster's frustum that lies inside `limits` (the
// loaded window) and, for point and spot lights, within range. Conservative (margins).
Aabb frustumBox(const Triangle& t, const Light& L, const Aabb& limits, double margin) {
    return shadowBox(t.data(), 3, L, limits, margin);
}

std::string worldPoint(const glm::dvec3& ls, const glm::dvec3& origin) {
    const glm::dvec3 p = ls + origin;
    return "(" + formatNumber(p.x) + " " + formatNumber(p.y) + " " + formatNumber(p.z) + ")";
}

std::string worldBox(const Aabb& b, const glm::dvec3& origin) { return worldPoint(b.min, origin) + " .. " + worldPoint(b.max, origin); }

// One (object, group) with some light's bit to examine.
struct Task {
    size_t object;  // index into ChunkVerdicts::objects
    int group;
};

// The bits the stage examines: undecided ones, and in cross-check mode the kept ones too.
bool wanted(const Decision& d, bool crossCheck) {
    return d.verdict == Verdict::Undecided || (crossCheck && d.verdict == Verdict::Kept);
}

// The (object, group)s with a wanted bit, in the verdicts' order; `lightNeeded[l]` tells
// whether any wanted bit is light l's.
std::vector<Task> gatherTasks(const ChunkVerdicts& cv, bool crossCheck, std::vector<bool>& lightNeeded) {
    std::vector<Task> tasks;
    lightNeeded.assign(size_t(cv.lightCount), false);
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        for (int g = 0; g < cv.objects[oi].groupCount; ++g) {
            bool any = false;
            for (int l = 0; l < cv.lightCount; ++l)
                if (wanted(cv.at(oi, g, l), crossCheck)) any = lightNeeded[size_t(l)] = true;
            if (any) tasks.push_back({oi, g});
        }
    return tasks;
}

// What the stage builds once per window and its tasks share, read-only: the broad phase's
// tree over the window's objects, the lights as tested and their receiver rules.
//
// Broad phase, two levels: a tree over the window's objects (window-local boxes), then the
// tree of the object's mesh (mesh coordinates, one per unique mesh, kept across windows),
// both queried with the caster triangle's half-spaces (shadow_query.h). Receivers are made
// only where a query reaches them, so a window's cost follows what its undecided casters'
// shadows can reach, not how many triangles it holds.
struct WindowScene {
    WindowScene(const BakeWindow& w, const GeometryOptions& o, const std::vector<bool>& lightNeeded)
        : window(w), options(o), margin(windowMargin(w)), limits(grown(w.lsBounds, 1.0)), objectBoxes(receiverBoxes()),
          objectTree(objectBoxes), lights(testedLights(w)), ground(w, margin, !o.exhaustive, arena) {
        const size_t count = lightNeeded.size();
        lightGeom.resize(count);
        rules.resize(count);
        for (size_t l = 0; l < count; ++l) {
            const Light& L = lights[l];
            lightGeom[l] = LightGeometry{L.type == LightType::Directional, L.direction, L.position};
            if (lightNeeded[l]) rules[l] = std::make_unique<ReceiverRules>(w, L, lightGeom[l], ground, arena);
        }
    }

    // Triangle `t` of object `k`, window-local (three distinct mesh vertices: the caller checked).
    Receiver makeReceiver(uint32_t k, uint32_t t) const {
        const WindowObject& o = window.objects[k];
        Receiver r;
        r.tri = o.lsTriangle(t);
        r.box = triangleBox(r.tri);
        r.twoSided = o.mesh->groups[o.mesh->triangleGroup[t]].twoSided();
        r.mirrored = o.flipsWinding;
        r.terrain = o.kind == ChunkObject::Kind::Terrain;
        return r;
    }

    const BakeWindow& window;
    const GeometryOptions& options;
    double margin;  // metres: far above the rounding of any placed vertex of the window
    Aabb limits;    // the loaded window, grown
    std::vector<Aabb> objectBoxes;
    ObjectTree objectTree;
    std::vector<Light> lights;  // dilated by the normal bias (testedLights)
    ThreadArena arena;          // the receiver tables and parts below, freed with the window at once
    ReceiverGround ground;      // the terrain rule per receiver, for every light's rules
    std::vector<LightGeometry> lightGeom;
    std::vector<std::unique_ptr<ReceiverRules>> rules;  // for the lights some task needs

private:
    static double windowMargin(const BakeWindow& w) {
        const glm::dvec3 ext = glm::max(glm::abs(w.lsBounds.min), glm::abs(w.lsBounds.max));
        return 1e-9 * (std::max({ext.x, ext.y, ext.z}) + 1.0) + 1e-9;
    }

    // The objects' boxes, grown by the margin. The terrain rule, per object: no point of a
    // model deeper than the tolerance under the lowest ground under its box receives, so its
    // box starts there (a half-buried rock's box is mostly its buried half, which a terrain
    // triangle's column meets first). Wholly under: an empty box, never visited. In blocks
    // in parallel (each box its own; the ground queries were half of the window's setup,
    // which runs before any task).
    std::vector<Aabb> receiverBoxes() const {
        std::vector<Aabb> boxes(window.objects.size());
        const FloatModeScope::Underflow callers = FloatModeScope::current();
        tbb::parallel_for(tbb::blocked_range<size_t>(0, boxes.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
            const FloatModeScope mode(callers);
            for (size_t k = r.begin(); k < r.end(); ++k) boxes[k] = receiverBox(window.objects[k]);
        });
        return boxes;
    }
    Aabb receiverBox(const WindowObject& o) const {
        Aabb box = grown(o.lsBounds, margin);
        if (options.exhaustive || !window.hasTerrain || o.kind == ChunkObject::Kind::Terrain) return box;
        const std::optional<double> ground =
            window.lsTerrainMinOver(o.lsBounds.min.x, o.lsBounds.min.z, o.lsBounds.max.x, o.lsBounds.max.z);
        if (!ground) return box;
        const double level = *ground - window.terrainTolerance - margin;
        if (box.max.y < level) return Aabb{};
        box.min.y = std::max(box.min.y, level);
        return box;
    }

    // The lights as this stage tests them. A normal bias looks a receiver point q's shadow up
    // at q' = q + normalBias * n (semantics.md condition 5): q' within the frustum dilated by
    // filterRadius puts q within it dilated by filterRadius + normalBias (every half-space
    // moved outward by the sum), so the receivers themselves are tested against that: a
    // superset of both offsets, for one- and two-sided receivers alike, with no rounding of
    // its own (facing, range and terrain stay rules on q, as the spec says). The
    // single-occluder rule needs no dilation, so it stays off then.
    static std::vector<Light> testedLights(const BakeWindow& w) {
        std::vector<Light> lights = w.lsLights;
        for (Light& L : lights) L.filterRadius += L.normalBias;
        return lights;
    }
};

// The tasks' shared results (thread-safe).
struct WindowTally {
    explicit WindowTally(std::vector<GeometryStage::Candidate>& c) : candidates(c) {}
    std::atomic<uint64_t> tests{0}, culled{0}, examined{0};
    std::atomic<bool> contradiction{false};
    std::string contradictionAt;  // written once, by the task that set `contradiction`
    std::mutex candidatesMutex;
    std::vector<GeometryStage::Candidate>& candidates;
};

// What one caster triangle's frustum reached: whether some receiver (a candidate), the
// exact tests made on the way, and the candidate's note and point.
struct CasterResult {
    bool found = false;
    uint64_t tests = 0;
    std::string note;
    ReceiverPoint at;
};

// The first candidate in the caster tree's order, whatever the threads did: large subtrees
// run in parallel, and the candidate kept (with its note) is the one a sequential walk finds
// first. Exact tests count only at caster triangles up to it (those after, run ahead in
// parallel, do not), so the count is the same on any number of threads.
class FirstCandidate {
public:
    const std::atomic<uint32_t>& first() const { return first_; }
    // The result of the caster triangle at `position` in the tree's order.
    void offer(uint32_t position, CasterResult&& r) {
        if (!r.found && r.tests == 0) return;
        const std::lock_guard<std::mutex> lock(mutex_);
        if (r.tests > 0) testsAt_.emplace_back(position, r.tests);
        if (r.found && position < first_.load()) {
            first_.store(position);
            note_ = std::move(r.note);
            at_ = r.at;
        }
    }
    // After the walk: the candidate and the tests a sequential walk would have made.
    CasterResult result() {
        CasterResult r;
        r.found = first_.load() != TriangleTree::kNone;
        for (const auto& [position, n] : testsAt_)
            if (position <= first_.load()) r.tests += n;
        r.note = std::move(note_);
        r.at = at_;
        return r;
    }

private:
    std::atomic<uint32_t> first_{TriangleTree::kNone};
    std::mutex mutex_;
    std::vector<std::pair<uint32_t, uint64_t>> testsAt_;  // exact tests per caster triangle that made any
    std::string note_;
    ReceiverPoint at_;
};

// One bit's search: whether some receiver of the window can meet the shadow volume of one
// group of one object for one light (a candidate; its bit stays undecided) or none can (the
// bit is proved 0).
class ShadowSearch {
public:
    ShadowSearch(const WindowScene& scene, const WindowObject& caster, int group, int light)
        : scene_(scene), window_(scene.window), caster_(caster), group_(group), light_(light),
          L_(scene.lights[size_t(light)]), lg_(scene.lightGeom[size_t(light)]), rules_(*scene.rules[size_t(light)]),
          exhaustive_(scene.options.exhaustive), local_(L_.type != LightType::Directional) {
        // Opaque triangles (not alpha-tested, of objects that cast shadows) that may lie
        // between a directional light and a reached part. The exhaustive reference uses the
        // same source, so the two stay comparable.
        if (!local_ && !(L_.filterRadius > 0))
            occluders_.emplace(OccluderSource::Walk(
                [this](const std::array<glm::dvec3, 2>& box, const OccluderSource::Visit& visit) { walkOccluders(box, visit); }));
    }
    ShadowSearch(const ShadowSearch&) = delete;
    ShadowSearch& operator=(const ShadowSearch&) = delete;

    // The first candidate (in the order a sequential walk of the caster's triangles finds
    // it) and the exact tests made.
    CasterResult findCandidate() const { return exhaustive_ ? walkAllCasters() : walkCasterTree(); }

    // True when some reached part was dropped because one opaque triangle shades it.
    bool shadedSome() const { return occluders_ && occluders_->shadedSome.load(); }

    // Calls test(k, tri) for the receivers of the window the query `q` may reach (both levels
    // of the broad phase, within `qBox`), until it returns true. `objectMay(k)`: false when
    // no receiver of object k can be behind the caster (its mesh tree is not walked);
    // `boxMay(lsBox)`: false when no point of the window-local box can be (the mesh-tree
    // node whose receiving part it holds is not walked).
    template <class Test, class ObjectMay, class BoxMay>
    bool forReceivers(const ShadowQuery& q, const Aabb& qBox, const Test& test, const ObjectMay& objectMay,
                      const BoxMay& boxMay) const {
        return scene_.objectTree.visit([&](const Aabb& b) { return overlaps(b, qBox) && q.mayHold(b); },
                                       [&](uint32_t k) { return objectMay(k) && forReceiversIn(k, q, test, boxMay); });
    }

    // Receiver triangle `tri` of object `k` (three distinct vertices), made into `made`
    // unless the rules exclude it, and its bias, or -1 when the rules exclude it. `above`:
    // as ReceiverRules::beta.
    double receiver(uint32_t k, uint32_t tri, std::optional<Receiver>& made,
                    const GroundPart** above = nullptr) const {
        // (`made` may hold it already: the caller's placed receiver.)
        const double beta = rules_.beta(
            k, tri, [&]() -> const Receiver& { return made ? *made : *(made = scene_.makeReceiver(k, tri)); }, above);
        if (beta >= 0 && !made) made = scene_.makeReceiver(k, tri);
        return beta;
    }

    const WindowScene& scene() const { return scene_; }
    const Light& light() const { return L_; }  // as tested (dilated)
    const Light& sceneLight() const { return window_.lsLights[size_t(light_)]; }  // as the scene gives it
    const LightGeometry& lightGeometry() const { return lg_; }
    const ReceiverRules& rules() const { return rules_; }
    bool exhaustive() const { return exhaustive_; }
    // Whether the caster's triangles get columnUnderTerrain first: under a directional
    // light whose frustum is not dilated (filter radius and normal bias 0), in a window with
    // terrain. Terrains' and models' alike: a rock's buried triangles sink too (R's geometry
    // stage on one thread 2.4 -> 2.2 s; a triangle above the ground fails at its first cell).
    bool sinksIntoTerrain() const {
        return !local_ && !(L_.filterRadius > 0) && window_.hasTerrain;
    }
    bool local() const { return local_; }
    const OccluderSource* occluders() const { return occluders_ ? &*occluders_ : nullptr; }

private:
    template <class Test, class BoxMay>
    bool forReceiversIn(uint32_t k, const ShadowQuery& q, const Test& test, const BoxMay& boxMay) const {
        const WindowObject& o = window_.objects[k];
        // Range is a distance: every triangle of a box beyond it is too.
        if (local_ && boxBeyondRange(L_, o.lsBounds)) return false;
        const ShadowQuery::InMesh mq = q.inMesh(o.lsTransform);
        // The terrain rule per node: a subtree whose box lies wholly deeper than the
        // tolerance under the ground holds no receiver (a dense rock's buried half, under
        // every terrain triangle's column), and its receiving points lie in its box from that
        // level up; a node whose box from there up is in front of the caster holds none
        // behind (a rock's ground line, under every terrain triangle's column: its buried
        // side is behind, its receiving side in front). Small meshes skip it
        // (GeometryOptions::nodeTerrainRuleFrom).
        const bool buriable = window_.hasTerrain && o.kind != ChunkObject::Kind::Terrain &&
                              o.mesh->triangles.size() >= scene_.options.nodeTerrainRuleFrom;
        // A triangle the receiver rules excluded already (evaluated once per window and
        // light: a rock's back faces and buried half, met again by every caster triangle's
        // column) fails every test here: its box is not tested either.
        return TriangleTree(*o.mesh).visit(
            [&](const Aabb& b) {
                if (!mq.mayHold(b)) return false;
                return !buriable || nodeMayReceive(o, b, boxMay);
            },
            [&](uint32_t tri) { return rules_.knownExcluded(k, tri); }, [&](uint32_t tri) { return test(k, tri); });
    }

    // The terrain rule on mesh-tree node `msBox` of object `o`: false when its box lies
    // wholly deeper than the tolerance under the lowest ground under it, or boxMay rejects
    // its part from that level up.
    template <class BoxMay>
    bool nodeMayReceive(const WindowObject& o, const Aabb& msBox, const BoxMay& boxMay) const {
        Aabb ls = placedBox(o, msBox);
        const std::optional<double> ground = window_.lsTerrainMinOver(ls.min.x, ls.min.z, ls.max.x, ls.max.z);
        if (!ground) return true;
        const double level = *ground - window_.terrainTolerance - scene_.margin;
        if (ls.max.y < level) return false;
        ls.min.y = std::max(ls.min.y, level);
        return boxMay(ls);
    }

    // A mesh-tree node's box placed in the window: its corners mapped, widened by the margin
    // (far above the rounding of the placed triangles' vertices).
    Aabb placedBox(const WindowObject& o, const Aabb& msBox) const { return grown(placedBounds(msBox, o.lsTransform), scene_.margin); }

    // Caster parts no point of which is within the light's range and cone hold no p
    // (semantics.md, condition 3): a mesh-tree node by its placed box, a triangle by its box.
    bool outOfReach(const Aabb& msBox) const { return boxOutOfReach(L_, placedBox(caster_, msBox)); }
    bool triangleOutOfReach(const Triangle& t) const { return boxOutOfReach(L_, triangleBox(t)); }

    CasterResult walkCasterTree() const;
    CasterResult walkAllCasters() const;
    bool clusterMayCast(const Aabb& msBox, uint32_t items) const;
    void walkOccluders(const std::array<glm::dvec3, 2>& box, const OccluderSource::Visit& visit) const;

    const WindowScene& scene_;
    const BakeWindow& window_;
    const WindowObject& caster_;
    int group_, light_;
    const Light& L_;  // as tested (dilated)
    const LightGeometry& lg_;
    const ReceiverRules& rules_;
    bool exhaustive_, local_;  // local: a point or spot light
    std::optional<OccluderSource> occluders_;
};

// One caster triangle's frustum against the window's receivers: the first receiver, in the
// broad phase's order, it reaches more than the receiver's bias behind the caster.
class CasterProbe {
public:
    CasterProbe(const ShadowSearch& search, const Triangle& t)
        : search_(search), scene_(search.scene()), t_(t), L_(search.light()),
          reach_(scene_.window, t, search.lightGeometry(), search.sceneLight(), scene_.margin, search.occluders()),
          filter_(t, search.lightGeometry(), L_.filterRadius) {
        if (!search.exhaustive()) query_.emplace(t, search.lightGeometry(), L_.filterRadius, scene_.margin);
    }

    CasterResult run() {
        if (!search_.exhaustive()) {
            // A caster triangle whose column runs wholly under the ground beyond the bias
            // (terrain_column.h) reaches no receiver: no walk. (Directional lights without a
            // filter radius or normal bias: the column is then the whole frustum.)
            if (search_.sinksIntoTerrain() &&
                columnUnderTerrain(scene_.window, t_, L_.direction, leastBias(), scene_.limits, scene_.margin))
                return std::move(result_);
            // Point and spot lights: the whole window. The receiver rules exclude only
            // receivers wholly beyond range, and the exact test does not bound the frustum by
            // range, so a range-bounded box would prove more than they do.
            const Aabb qBox = search_.local() ? scene_.limits : frustumBox(t_, L_, scene_.limits, scene_.margin);
            search_.forReceivers(
                *query_, qBox, [&](uint32_t k, uint32_t tri) { return test(k, tri); },
                [&](uint32_t k) { return boxMay(scene_.objectBoxes[k]); }, [&](const Aabb& b) { return boxMay(b); });
            return std::move(result_);
        }
        for (uint32_t k = 0; k < scene_.window.objects.size() && !result_.found; ++k) {
            const Mesh& m = *scene_.window.objects[k].mesh;
            for (uint32_t tri = 0; tri < m.triangles.size(); ++tri) {
                if (!hasRepeatedVertex(m, tri) && test(k, tri)) break;
            }
        }
        return std::move(result_);
    }

private:
    // Receiver triangle `tri` of object `k`: the receiver rules and the double filters, then
    // the exact test. True (and the result filled in) when the shadow reaches it. (The same
    // answer in any order of the rules and filters: only the exact test decides a true.)
    bool test(uint32_t k, uint32_t tri) {
        std::optional<Receiver> made;
        if (!search_.exhaustive()) {
            // The cheap rules first, facing, range and cone (evaluated once per window and
            // light; a rock's back faces, most of what its own front faces' columns reach,
            // were 65 % of the rules' exclusions on world R, each after both filters), and
            // any exclusion already known (a buried half, met again by every caster
            // triangle's column): nothing to place or filter.
            if (search_.rules().excludedByFacing(k, tri, [&]() -> const Receiver& { return *(made = scene_.makeReceiver(k, tri)); }))
                return false;
            // Then the double filters: they hold for every bias >= 0, so with the least one
            // the rest of the rules (the part above the ground: clipped against the terrain,
            // per window and light) are made only for triangles that may meet the frustum (a
            // terrain's columns reach a dense rock's ground line, thousands of triangles per
            // terrain triangle, most of them outside the column).
            if (filtersMiss(made ? made->tri : scene_.window.objects[k].lsTriangle(tri), leastBias())) return false;
        }
        const GroundPart* above = nullptr;  // its part above the ground
        const double beta = search_.receiver(k, tri, made, &above);
        if (beta < 0) return false;
        const Receiver& r = *made;
        if (!search_.exhaustive()) {
            // With the least bias the filters above already answered for these same placed
            // vertices: only a larger bias (a slope term) can reject more.
            if (beta != leastBias() && filtersMiss(r.tri, beta)) return false;
            // The terrain rule, cheaply: the part of the receiver not buried deeper than the
            // tolerance lies wholly in front of the caster (a rock's crown beside a terrain
            // triangle whose column reaches only its buried side).
            if (above && filter_.allInFront(above->data(), above->size(), beta)) return false;
        }
        ++result_.tests;
        std::array<glm::dvec3, 2> part;  // the box of the reached part
        glm::dvec3 at;                   // a point of the receiver the shadow reaches (a target for witness rays)
        if (!reach_.reaches(r, beta, part, at)) return false;
        result_.found = true;
        result_.at = {at, k, tri};
        result_.note = candidateNote(k, tri, part);
        return true;
    }

    bool filtersMiss(const Triangle& r, double beta) const { return query_->misses(r) || filter_.certainlyMisses(r, beta); }

    // The smallest bias the receiver rules give any receiver (biasLowerBound is never below
    // the bias, which is exact).
    double leastBias() const { return L_.bias; }

    // False when the box (an object's, a model's from the lowest ground under it by the
    // terrain rule, or a mesh-tree node's receiving part) lies wholly in front of the caster
    // by the smallest bias any receiver gets: it holds no receiver behind it (a half-buried
    // rock beside a terrain triangle whose column meets only its buried half).
    bool boxMay(const Aabb& b) const {
        const std::array<glm::dvec3, 8> corners = b.corners();
        return !filter_.allInFront(corners.data(), 8, leastBias());
    }

    std::string candidateNote(uint32_t k, uint32_t tri, const std::array<glm::dvec3, 2>& part) const {
        const WindowObject& ro = scene_.window.objects[k];
        const glm::dvec3& origin = scene_.window.wsOrigin;
        return "could not exclude " + ro.label + " group " + std::to_string(ro.mesh->triangleGroup[tri]) + " (triangle " +
               std::to_string(tri) + "): the shadow volume of the caster triangle " + worldPoint(t_[0], origin) + " " +
               worldPoint(t_[1], origin) + " " + worldPoint(t_[2], origin) + " reaches it more than the bias behind, within " +
               worldBox(Aabb{part[0], part[1]}, origin) +
               " (a candidate receiver: the next stages look for a witness ray or an occluder)";
    }

    const ShadowSearch& search_;
    const WindowScene& scene_;
    const Triangle& t_;
    const Light& L_;  // as tested (dilated)
    ExactReach reach_;
    const FrustumFilter filter_;
    std::optional<ShadowQuery> query_;  // the fast path's broad phase
    CasterResult result_;
};

// The caster's triangles by the clusters of its mesh tree, top down. A cluster whose column
// no receiver can be behind (ShadowQuery::ofCluster, clusterMisses) holds no triangle with a
// candidate, and is left whole: a buried or isolated part of a dense mesh costs a few
// cluster queries instead of one query per triangle. Large subtrees run in parallel (a
// window's one dense caster would otherwise hold one core): FirstCandidate keeps the
// result a sequential walk finds.
CasterResult ShadowSearch::walkCasterTree() const {
    const Mesh& cm = *caster_.mesh;
    FirstCandidate first;
    TriangleTree(cm).visitNodesOrdered(
        [&](const Aabb& msBox, uint32_t items) { return clusterMayCast(msBox, items); },
        [&](uint32_t tri, uint32_t position) {
            if (cm.triangleGroup[tri] != uint32_t(group_)) return;
            // Subtrees may run on other TBB threads: gradual underflow there too.
            const FloatModeScope ieeeHere(FloatModeScope::Underflow::Gradual);
            const Triangle placed = caster_.lsTriangle(tri);
            if (local_ && triangleOutOfReach(placed)) return;
            first.offer(position, CasterProbe(*this, placed).run());
        },
        first.first(), kParallelCasters);
    return first.result();
}

// False when no triangle of the caster's mesh-tree node (box `msBox`, `items` triangles)
// can have a candidate.
bool ShadowSearch::clusterMayCast(const Aabb& msBox, uint32_t items) const {
    // p lies within range and cone (semantics.md): a cluster wholly beyond holds no caster
    // point that counts (exact; the margins keep every point within reach).
    if (local_ && outOfReach(msBox)) return false;
    // A few triangles cost about what one cluster query does: test them.
    if (items <= kClusterAtLeast) return true;
    // Subtrees may run on other TBB threads: gradual underflow there too.
    const FloatModeScope ieeeHere(FloatModeScope::Underflow::Gradual);
    const ShadowQuery cq = ShadowQuery::ofCluster(msBox, caster_.lsTransform, lg_, L_.filterRadius, scene_.margin);
    return forReceivers(
        cq, local_ ? scene_.limits : cq.columnBox(L_, scene_.limits),
        [&](uint32_t k, uint32_t tri) {
            std::optional<Receiver> made;
            const double beta = receiver(k, tri, made);
            return beta >= 0 && !cq.clusterMisses(made->tri, beta);
        },
        [](uint32_t) { return true; }, [](const Aabb&) { return true; });
}

// The exhaustive reference: every triangle of the group with three distinct vertices, in
// mesh order, until one has a candidate.
CasterResult ShadowSearch::walkAllCasters() const {
    CasterResult total;
    const Mesh& cm = *caster_.mesh;
    for (size_t t = 0; t < cm.triangles.size(); ++t) {
        if (cm.triangleGroup[t] != uint32_t(group_) || hasRepeatedVertex(cm, t)) continue;
        const Triangle placed = caster_.lsTriangle(t);
        if (local_ && triangleOutOfReach(placed)) continue;
        CasterResult r = CasterProbe(*this, placed).run();
        total.tests += r.tests;
        if (!r.found) continue;
        total.found = true;
        total.note = std::move(r.note);
        total.at = r.at;
        break;
    }
    return total;
}

// The opaque triangles that may shade a reached part (box `box`): the column from the
// part's box back towards the light, walked as a receiver column is (the light reversed).
// The exact tests then drop a part one of them shades wholly (no caster point of it lit):
// each is handed to `visit` as it is found, and the walk ends at the first that shades.
// The first kMaxOccluders in the walk's order are offered, whichever shades.
// Buried parts of the objects are not in the tree's boxes: fewer occluders, never a wrong one.
void ShadowSearch::walkOccluders(const std::array<glm::dvec3, 2>& box, const OccluderSource::Visit& visit) const {
    constexpr size_t kMaxOccluders = 256;  // enough for a part a fraction of a cell wide
    size_t offered = 0;
    LightGeometry back = lg_;
    back.direction = -lg_.direction;
    Light backLight = L_;
    backLight.direction = -L_.direction;
    const ShadowQuery q = ShadowQuery::ofCluster(Aabb{box[0], box[1]}, RowTransform{}, back, 0.0, scene_.margin);
    const Aabb qBox = q.columnBox(backLight, scene_.limits);
    scene_.objectTree.visit([&](const Aabb& b) { return overlaps(b, qBox) && q.mayHold(b); },
                            [&](uint32_t k) {
                                const WindowObject& o = window_.objects[k];
                                if (!o.castsShadow) return false;  // light passes it
                                const Mesh& mesh = *o.mesh;
                                const ShadowQuery::InMesh mq = q.inMesh(o.lsTransform);
                                return TriangleTree(mesh).visit([&](const Aabb& b) { return mq.mayHold(b); },
                                                                [&](uint32_t tri) {
                                                                    if (!o.blocksLight(mesh.triangleGroup[tri])) return false;
                                                                    ++offered;
                                                                    return visit(o.lsTriangle(tri)) || offered >= kMaxOccluders;
                                                                });
                            });
}

// The note of a bit proved 0: a box holding the volume, the frustum box of the group's
// placed box (each caster triangle lies in it, so its frustum in that box's), not the union
// over triangles (one frustum box per triangle and light of a dense mesh's instance, for a
// note).
std::string culledNote(const WindowScene& scene, const WindowObject& wo, int group, const Light& L, bool shadedSome) {
    const Aabb groupBox = lsGroupBounds(wo, uint32_t(group), true);
    const std::array<glm::dvec3, 8> groupCorners = groupBox.corners();
    const Aabb volume = groupBox.empty() ? Aabb{} : shadowBox(groupCorners.data(), 8, L, scene.limits, scene.margin);
    const uint64_t casterCount = vertexIndex(*wo.mesh).groupTrianglesWithArea[size_t(group)];
    return "no receiver in the shadow volume (" + std::to_string(casterCount) + " caster triangles; volume within " +
           worldBox(volume, scene.window.wsOrigin) + ")" +
           (shadedSome ? "; where it reaches a receiver, one opaque triangle shades the caster (p not lit)" : "");
}

// One task: each wanted bit of the group, searched and decided.
void examineGroup(const WindowScene& scene, const Task& task, ChunkVerdicts& cv, WindowTally& tally) {
    const ObjectVerdicts& ov = cv.objects[task.object];
    const WindowObject& wo = scene.window.objects[size_t(ov.windowObject)];
    for (int l = 0; l < cv.lightCount; ++l) {
        Decision& d = cv.at(task.object, task.group, l);
        if (!wanted(d, scene.options.crossCheckWitnesses)) continue;
        ++tally.examined;
        const ShadowSearch search(scene, wo, task.group, l);
        CasterResult found = search.findCandidate();
        tally.tests += found.tests;
        if (found.found) {
            // A candidate: the bit stays undecided, with the receiver for the next stages.
            if (d.verdict == Verdict::Undecided) {
                addNote(d, "geometry", std::move(found.note));
                const std::lock_guard<std::mutex> lock(tally.candidatesMutex);
                tally.candidates.push_back({task.object, task.group, l, found.at.lsPoint, found.at.object, found.at.triangle});
            }
            continue;
        }
        if (d.verdict == Verdict::Kept) {  // cross-check mode: a proof against a witness
            if (!tally.contradiction.exchange(true))
                tally.contradictionAt = wo.label + " group " + std::to_string(task.group) + " light " + std::to_string(l + 1);
            continue;
        }
        decide(d, Verdict::Culled, "geometry",
               culledNote(scene, wo, task.group, scene.lights[size_t(l)], search.shadedSome()));
        ++tally.culled;
    }
}

}  // namespace

Status GeometryStage::run(const BakeWindow& window, ChunkVerdicts& cv, StageStats& stats) {
    const auto t0 = std::chrono::steady_clock::now();
    candidates_.clear();
    if (window.skippedObjects > 0) return Status::ok();  // an unloaded object might receive
    const FloatModeScope ieee(FloatModeScope::Underflow::Gradual);  // see the tasks below
    std::vector<bool> lightNeeded;
    const std::vector<Task> tasks = gatherTasks(cv, options_.crossCheckWitnesses, lightNeeded);
    if (tasks.empty()) return Status::ok();
    try {
        const WindowScene scene(window, options_, lightNeeded);
        WindowTally tally(candidates_);
        tbb::parallel_for(size_t(0), tasks.size(), [&](size_t ti) {
            // A signal: the tasks not begun leave their bits undecided; the stage then stops.
            if (stopRequested()) return;
            // Exact predicates: CGAL's interval filters need gradual underflow, whatever
            // mode an earlier stage's tasks left TBB in (util/float_mode.h).
            const FloatModeScope ieeeHere(FloatModeScope::Underflow::Gradual);
            examineGroup(scene, tasks[ti], cv, tally);
        });
        if (Status s = stopStatus(); !s) return s;
        // In a fixed order whatever the threads did.
        std::sort(candidates_.begin(), candidates_.end(), [](const Candidate& a, const Candidate& b) {
            return std::tie(a.object, a.group, a.light) < std::tie(b.object, b.group, b.light);
        });
        if (tally.contradiction)
            return makeError(ErrorKind::Internal, window.centrePath, 0,
                             "geometry stage would prove 0 for a bit with a witness: " + tally.contradictionAt);
        stats.exactTests += tally.tests;
        stats.bitsExamined += tally.examined;
        stats.provedCulled += tally.culled;
    } catch (const std::exception& e) {
        return makeError(ErrorKind::Internal, window.centrePath, 0, std::string("geometry stage: ") + e.what());
    }
    stats.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return Status::ok();
}

}  // namespace shadowcull::geometry
