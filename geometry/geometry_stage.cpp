// GeometryStage: see geometry_stage.h. Broad phase in double (a grid over the window's
// x/z, boxes with margins, the receiver rules); narrow phase exact (exact_frustum.cpp).
// Every double test here only ever discards a receiver when it clearly cannot receive
// (margins on the side of keeping it), and the exact test decides the rest; so a bit is
// proved 0 only when no receiver can meet the group's shadow volume.

#include "geometry/geometry_stage.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <tuple>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "core/float_mode.h"
#include "core/format.h"
#include "core/light_reach.h"
#include "core/mesh_index.h"
#include "core/rounding.h"
#include "core/stop_request.h"
#include "geometry/exact_frustum.h"
#include "geometry/shadow_query.h"

namespace shadowcull::geometry {

namespace {

// Smallest cluster of caster triangles tested as a whole (smaller ones go triangle by
// triangle: a cluster query costs about as much as a few triangles' queries).
constexpr uint32_t kClusterAtLeast = 8;
// Caster subtrees of at least this many triangles are walked in parallel.
constexpr uint32_t kParallelCasters = 256;

// Where a shadow volume reaches a receiver: the point, window-local, and the receiver's
// window object and mesh triangle.
struct ReceiverPoint {
    glm::dvec3 lsPoint{0.0};
    uint32_t object = 0, triangle = 0;
};

struct Receiver {
    Triangle tri;  // window-local
    Aabb box;
    bool twoSided = false, mirrored = false, terrain = false;
};

// Closed boxes that share a point.
bool overlaps(const Aabb& a, const Aabb& b) {
    return !(a.max.x < b.min.x || a.min.x > b.max.x || a.max.y < b.min.y || a.min.y > b.max.y || a.max.z < b.min.z ||
             a.min.z > b.max.z);
}

Aabb triangleBox(const Triangle& t) {
    Aabb b;
    for (const glm::dvec3& p : t) b.extend(p);
    return b;
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

// True when every point of the box lies deeper than the tolerance under the terrain
// (conservative: the box's top against the lowest terrain sample around it).
bool underTerrain(const BakeWindow& w, const std::array<glm::dvec3, 2>& box, double margin) {
    std::optional<double> ground = w.lsTerrainMinOver(box[0].x, box[0].z, box[1].x, box[1].z);
    return ground && box[1].y < *ground - w.terrainTolerance - margin;
}

// Keeps the part of the convex polygon `poly` where n . (x - o) + k >= -slack (double;
// `slack` covers the rounding of the clip, so the result holds every point of the exact
// part: a superset).
void clipOutward(std::vector<glm::dvec3>& poly, const glm::dvec3& n, const glm::dvec3& o, double k, double slack) {
    thread_local std::vector<glm::dvec3> out;  // scratch: this runs for every reached receiver
    out.clear();
    const size_t count = poly.size();
    for (size_t i = 0; i < count; ++i) {
        const glm::dvec3 &p = poly[i], &q = poly[(i + 1) % count];
        const double fp = glm::dot(n, p - o) + k + slack, fq = glm::dot(n, q - o) + k + slack;
        if (fp >= 0) out.push_back(p);
        if ((fp >= 0) != (fq >= 0)) out.push_back(p + (q - p) * (fp / (fp - fq)));
    }
    poly.swap(out);
}

// The part of receiver triangle `t` (box `box`) that the terrain rule lets receive: over
// each terrain triangle under it, `t` clipped in double to that triangle's vertical prism
// and to not deeper than the tolerance under its plane, every half-space moved outward by
// `margin` (metres; far above the clipping's rounding), so that every point of `t` the
// rule lets receive lies in the convex hull of `out` (a superset: conservative). Empty
// when `t` lies wholly deeper than the tolerance under the ground. False when `t` is not
// wholly over terrain (the rule then says nothing). Depends on the receiver alone: the
// receiver rules compute it once (a rock's crown, not the lowest ground under its box: on
// a slope that left most of a half-buried rock to the exact test, caster by caster).
bool partAboveGround(const BakeWindow& w, const Triangle& t, const Aabb& box, double margin, std::vector<glm::dvec3>& out) {
    out.clear();
    thread_local std::vector<Triangle> ground;  // scratch, as the polygon
    thread_local std::vector<glm::dvec3> poly;
    ground.clear();
    if (!w.lsTerrainTrianglesOver(box.min.x, box.min.z, box.max.x, box.max.z, ground)) return false;
    for (const Triangle& g : ground) {
        const Aabb gb = triangleBox(g);
        if (gb.max.x < box.min.x - margin || gb.min.x > box.max.x + margin || gb.max.z < box.min.z - margin ||
            gb.min.z > box.max.z + margin || box.max.y < gb.min.y - w.terrainTolerance - margin)
            continue;
        glm::dvec3 n = glm::cross(g[1] - g[0], g[2] - g[0]);
        const double len = glm::length(n);
        if (!(len > 0) || !(std::abs(n.y) > 1e-9 * len)) return false;  // a vertical or degenerate cell: no bound
        if (n.y < 0) n = -n;
        n /= len;
        poly.assign(t.begin(), t.end());
        // The vertical prism: three half-spaces through the edges, horizontal normals inward.
        for (int e = 0; e < 3 && !poly.empty(); ++e) {
            const glm::dvec3 &a = g[size_t(e)], &b = g[size_t((e + 1) % 3)], &c = g[size_t((e + 2) % 3)];
            glm::dvec3 side = glm::cross(b - a, glm::dvec3(0, 1, 0));
            const double sl = glm::length(side);
            if (!(sl > 0)) return false;
            side /= sl;
            if (glm::dot(side, c - a) < 0) side = -side;
            clipOutward(poly, side, a, 0.0, margin);
        }
        // Not deeper than the tolerance under the plane: n . (x - g0) + tolerance * n.y >= 0.
        if (!poly.empty()) clipOutward(poly, n, g[0], w.terrainTolerance * n.y, margin);
        out.insert(out.end(), poly.begin(), poly.end());
    }
    return true;
}

// Per receiver triangle (object, triangle) and light, computed on first use (most
// receivers of a window are never tested; an object's table is made when a query first
// reaches it): -1 when the receiver rules exclude it, else a lower bound of the bias
// (metres) that applies to it; and where the terrain rule applies, the receiver's part
// above the ground (partAboveGround: once per receiver, not per caster triangle). Safe
// to call from several threads: a value is computed again at worst, always the same.
class ReceiverRules {
public:
    // `bound`: also compute the part above the ground (off for the exhaustive reference,
    // which uses no double filter beyond the lowest ground under a receiver's box).
    ReceiverRules(const BakeWindow& w, const Light& L, const LightGeometry& lg, double margin, bool bound)
        : w_(w), L_(L), lg_(lg), margin_(margin), bound_(bound), tables_(w.objects.size()) {
        for (auto& t : tables_) t.store(nullptr, std::memory_order_relaxed);
    }
    ~ReceiverRules() {
        for (size_t k = 0; k < tables_.size(); ++k) {
            std::atomic<Block*>* table = tables_[k].load(std::memory_order_relaxed);
            if (!table) continue;
            for (size_t b = 0; b < blockCount(k); ++b) delete table[b].load(std::memory_order_relaxed);
            delete[] table;
        }
    }
    ReceiverRules(const ReceiverRules&) = delete;
    ReceiverRules& operator=(const ReceiverRules&) = delete;

    // `receiver()` makes the receiver when the value is not known yet. `above`, when given,
    // receives the receiver's part above the ground (nullptr: the terrain rule gives no
    // bound there; check it only when the result is >= 0).
    template <class Make>
    double beta(uint32_t object, uint32_t triangle, const Make& receiver, const std::vector<glm::dvec3>** above = nullptr) const {
        // Two levels, each made on first touch: a dense mesh's queries touch a few of its
        // 100k+ triangles, and a table of them all, made and cleared per object, window and
        // light, was most of the stage's time on world D (issue 13).
        std::atomic<Block*>* table = tables_[object].load(std::memory_order_acquire);
        if (!table) {
            const size_t n = blockCount(object);
            auto* fresh = new std::atomic<Block*>[n];
            for (size_t i = 0; i < n; ++i) fresh[i].store(nullptr, std::memory_order_relaxed);
            if (tables_[object].compare_exchange_strong(table, fresh, std::memory_order_acq_rel)) table = fresh;
            else delete[] fresh;  // another thread's table won; `table` now holds it
        }
        std::atomic<Block*>& slot = table[triangle / kBlock];
        Block* block = slot.load(std::memory_order_acquire);
        if (!block) {
            auto* fresh = new Block;
            if (slot.compare_exchange_strong(block, fresh, std::memory_order_acq_rel)) block = fresh;
            else delete fresh;
        }
        Entry& e = block->entries[triangle % kBlock];
        double b = e.beta.load(std::memory_order_acquire);  // after the part it publishes
        if (b == kUnknown) {
            b = compute(receiver(), e);
            e.beta.store(b, std::memory_order_release);
        }
        if (above) *above = e.part.load(std::memory_order_acquire);
        return b;
    }

private:
    static constexpr double kUnknown = -2.0;  // every computed value is -1 or >= 0
    static constexpr size_t kBlock = 64;      // triangles per block of the table
    struct Entry {
        std::atomic<double> beta{kUnknown};
        std::atomic<const std::vector<glm::dvec3>*> part{nullptr};  // owned; set before beta
    };
    struct Block {
        Entry entries[kBlock];
        ~Block() {
            for (Entry& e : entries) delete e.part.load(std::memory_order_relaxed);
        }
    };
    size_t blockCount(size_t object) const { return (w_.objects[object].mesh->triangles.size() + kBlock - 1) / kBlock; }
    double compute(const Receiver& r, Entry& e) const {
        // Facing: a one-sided receiver the light meets from behind or edge-on gets nothing.
        if (!r.twoSided && exactFacing(r.tri, r.mirrored, lg_) <= 0) return -1;
        // Range and cone.
        if (boxOutOfReach(L_, r.box)) return -1;
        // Terrain (terrain itself exempt): wholly deeper than the tolerance under the
        // lowest ground under its box (cheap), then under the ground triangles over it.
        if (w_.hasTerrain && !r.terrain) {
            if (underTerrain(w_, {r.box.min, r.box.max}, margin_)) return -1;
            if (!bound_) return bias(r);
            auto part = std::make_unique<std::vector<glm::dvec3>>();
            if (partAboveGround(w_, r.tri, r.box, margin_, *part)) {
                if (part->empty()) return -1;
                const std::vector<glm::dvec3>* expected = nullptr;
                if (e.part.compare_exchange_strong(expected, part.get(), std::memory_order_acq_rel)) part.release();
            }
        }
        return bias(r);
    }
    // The bias, and for directional lights the slope term (constant over a triangle).
    double bias(const Receiver& r) const { return biasLowerBound(L_, r.tri); }

    const BakeWindow& w_;
    const Light& L_;
    LightGeometry lg_;
    double margin_;
    bool bound_;
    mutable std::vector<std::atomic<std::atomic<Block*>*>> tables_;
};

// A bound on how far a receiver triangle moved by `by` metres along its unit normal, as
// computed in double (offset = (by / |n|) n with n = (b - a) x (c - a), then added to each
// vertex), can lie from the same move in exact arithmetic; infinity where the computed
// normal's direction is not known to within a quarter turn. Derivation (u = 2^-53,
// gamma(n) = n u / (1 - n u), core/rounding.h): each edge is rounded once, each cross
// component is a difference of two products, so |n_c - n| <= E = 2 gamma(4) |e1| |e2|;
// normalising moves a vector by at most twice its error over its length, plus the
// rounding of the length, the division and the scaling, so |offset_c - offset| <= by
// (2 E / |n_c| + gamma(7)); adding it to a vertex rounds by gamma(1) of the sum.
double normalOffsetError(const Triangle& t, double by) {
    const glm::dvec3 e1 = t[1] - t[0], e2 = t[2] - t[0];
    const double nl = glm::length(glm::cross(e1, e2));
    const double E = 2 * gamma(4) * glm::length(e1) * glm::length(e2);
    if (!(E < 0.5 * nl)) return std::numeric_limits<double>::infinity();
    double reach = 0;
    for (const glm::dvec3& v : t) reach = std::max(reach, glm::length(v));
    return by * (2 * E / nl + gamma(7)) + gamma(2) * (reach + by);
}

// The exact test of one receiver against one caster triangle's frustum: whether the shadow
// reaches more than beta behind the caster at a point where the receiver looks its shadow
// up, and the terrain rule on the part it reaches. Without a normal bias the lookup points
// are the receiver itself. With one (semantics.md, condition 5) they are the receiver moved
// by normalBias along its front normal, and against it for a two-sided receiver: each moved
// triangle is tested against the frustum dilated by filterRadius plus a bound on the move's
// rounding (normalOffsetError, at most `slack_` metres), or, where that bound is larger,
// the receiver itself against the frustum dilated by filterRadius + normalBias (every
// lookup point lies within normalBias of it: a superset). Frusta are built on first use.
class ExactReach {
public:
    ExactReach(const BakeWindow& w, const Triangle& caster, const LightGeometry& lg, const Light& L, double margin,
               const OccluderSource* occluders)
        : w_(w), caster_(caster), lg_(lg), L_(L), margin_(margin), occluders_(occluders) {
        const glm::dvec3 ext = glm::max(glm::abs(w.lsBounds.min), glm::abs(w.lsBounds.max));
        slack_ = 1e-9 * (std::max({ext.x, ext.y, ext.z}) + L.normalBias + 1.0);
    }

    // True when the shadow reaches the receiver: `part` is the box of the reached part of
    // the lookup surface, `at` a point of the receiver itself whose lookup is reached.
    bool reaches(const Receiver& r, double beta, std::array<glm::dvec3, 2>& part, glm::dvec3& at) {
        if (!(L_.normalBias > 0)) return reachesSurface(frustum(plain_, L_.filterRadius), r, r.tri, beta, glm::dvec3(0.0), part, at);
        glm::dvec3 n = glm::cross(r.tri[1] - r.tri[0], r.tri[2] - r.tri[0]);
        if (r.mirrored) n = -n;
        const double nl = glm::length(n);
        if (nl > 0 && normalOffsetError(r.tri, L_.normalBias) <= slack_) {
            for (double sign : {1.0, -1.0}) {
                if (sign < 0 && !r.twoSided) break;
                const glm::dvec3 offset = (sign * L_.normalBias / nl) * n;
                const Triangle moved{r.tri[0] + offset, r.tri[1] + offset, r.tri[2] + offset};
                if (reachesSurface(frustum(moved_, L_.filterRadius + slack_), r, moved, beta, offset, part, at)) return true;
            }
            return false;
        }
        return reachesSurface(frustum(broad_, L_.filterRadius + L_.normalBias), r, r.tri, beta, glm::dvec3(0.0), part, at);
    }

private:
    ExactFrustum& frustum(std::optional<ExactFrustum>& f, double dilation) {
        if (!f) f.emplace(caster_, lg_, dilation);
        return *f;
    }

    // `surface` is the receiver's lookup surface: the receiver moved by `offset` (window-
    // local metres, as computed). The terrain rule applies to the receiver's own points:
    // exactly when there is no offset; with one, by the box of the reached part moved back
    // (grown by the slack), against the lowest ground (a superset: the exact clip against
    // the ground triangles is skipped).
    bool reachesSurface(ExactFrustum& f, const Receiver& r, const Triangle& surface, double beta, const glm::dvec3& offset,
                        std::array<glm::dvec3, 2>& part, glm::dvec3& at) {
        if (!f.reaches(surface, beta, &part, &at, occluders_)) return false;
        at -= offset;
        if (!w_.hasTerrain || r.terrain) return true;
        const bool moved = offset != glm::dvec3(0.0);
        const double grow = moved ? slack_ + margin_ : 0.0;
        const std::array<glm::dvec3, 2> own{part[0] - offset - grow, part[1] - offset + grow};
        // The terrain rule on the part of the receiver the shadow reaches: a rock half in
        // the ground receives only with its part above ground. The box of that part against
        // the lowest sample first (cheap), then exactly, the part against the terrain
        // triangles over it (a slope under a small box differs from its lowest sample by the
        // cell's relief, which left most terrains of a hilly map undecided).
        if (underTerrain(w_, own, margin_)) return false;
        if (moved) return true;
        ground_.clear();
        openings_.clear();
        // Squares with no terrain (the world's edge) are openings: the rule holds over the
        // rest of the part.
        if (!w_.lsGroundOver(part[0].x, part[0].z, part[1].x, part[1].z, ground_, &openings_)) return true;
        // Only the ground triangles the part may lie over and not wholly deeper than the
        // tolerance under (both in double with the margin: a triangle left out holds no
        // point of the part, or only points under it).
        const double tol = w_.terrainTolerance;
        ground_.erase(std::remove_if(ground_.begin(), ground_.end(),
                                     [&](const Triangle& g) {
                                         const Aabb gb = triangleBox(g);
                                         return gb.max.x < part[0].x - margin_ || gb.min.x > part[1].x + margin_ ||
                                                gb.max.z < part[0].z - margin_ || gb.min.z > part[1].z + margin_ ||
                                                part[1].y < gb.min.y - tol - margin_;
                                     }),
                      ground_.end());
        return f.reachesAboveGround(r.tri, beta, ground_, openings_, tol, &at, occluders_);
    }

    const BakeWindow& w_;
    const Triangle& caster_;
    const LightGeometry& lg_;
    const Light& L_;  // as the scene gives it (not dilated)
    double margin_;
    const OccluderSource* occluders_;
    double slack_;  // metres: the largest move rounding tested on the moved receiver
    // Built on the first receiver that passes the broad phase and the rules: most caster
    // triangles of a dense mesh never need one.
    std::optional<ExactFrustum> plain_, moved_, broad_;
    std::vector<Triangle> ground_;         // terrain under a reached part (the terrain rule)
    std::vector<GroundOpening> openings_;  // squares with none under it
};

std::string worldPoint(const glm::dvec3& ls, const glm::dvec3& origin) {
    const glm::dvec3 p = ls + origin;
    return "(" + formatNumber(p.x) + " " + formatNumber(p.y) + " " + formatNumber(p.z) + ")";
}

std::string worldBox(const Aabb& b, const glm::dvec3& origin) { return worldPoint(b.min, origin) + " .. " + worldPoint(b.max, origin); }

}  // namespace

namespace {

// A lower bound of slopeBias tan(theta) = slopeBias |n* x d| / |n* . d| (n* the exact normal
// of `tri`, d the light's direction: both exact for the double inputs), even once the caller
// multiplies nothing more; 0 where nothing useful is certain. The cross and dot products
// carry their rounding bounds (core/rounding.h): |n* x d| >= |c| - |c.error()|_1 and
// |n* . d| <= |t| + t.error. Then (u = 2^-53, gamma(n) = n u / (1 - n u)): the length of c
// rounds by gamma(3), so fl-length(c) (1 - gamma(4)) <= |c| once rounded; the error's sum
// times 1 + gamma(3) is at least the exact sum; the subtraction rounds num up by at most
// (1 + u), the denominator is rounded up by its factor 1 + gamma(2); the quotient and the
// two products round by (1 + u) each: (1 + u)^4 (1 - 6u) < 1 leaves the result below.
// A receiver within 1e-6 of edge-on (tan > 1e6) gets no slope term: nothing is lost that a
// witness could show (the raycast stage asks cos(theta) > 1e-6 too).
double slopeTermLowerBound(const Light& L, const Triangle& tri) {
    const Bounded3 n = cross(difference(tri[1], tri[0]), difference(tri[2], tri[0]));
    const Bounded3 c = cross(n, exactly(L.direction));
    const Bounded t = dot(n, exactly(L.direction));
    const glm::dvec3 ce = c.error();
    const double num = glm::length(c.value()) * (1 - gamma(4)) - (ce.x + ce.y + ce.z) * (1 + gamma(3));
    const double den = (std::abs(t.value) + t.error) * (1 + gamma(2));
    if (!(num > 0) || !(num < 1e6 * den)) return 0.0;
    return L.slopeBias * (num / den * (1 - gamma(6)));
}

}  // namespace

// bias + the slope term's lower bound y, rounded down: fl(bias + y) <= (bias + y)(1 + u),
// times the double 1 - gamma(2) (= 1 - 2u) and rounded again: (1 + u)^2 (1 - 2u) < 1.
double biasLowerBound(const Light& L, const Triangle& tri) {
    if (!(L.slopeBias > 0) || L.type != LightType::Directional) return L.bias;  // exact: nothing rounds
    const double y = slopeTermLowerBound(L, tri);
    return std::max(L.bias, (L.bias + y) * (1 - gamma(2)));
}

Status GeometryStage::run(const BakeWindow& window, ChunkVerdicts& cv, StageStats& stats) {
    const auto t0 = std::chrono::steady_clock::now();
    candidates_.clear();
    std::mutex candidatesMutex;
    if (window.skippedObjects > 0) return Status::ok();  // an unloaded object might receive
    const FloatModeScope ieee(FloatModeScope::Underflow::Gradual);  // see the tasks below

    struct Task {
        size_t object;
        int group;
    };
    const bool cross = options_.crossCheckWitnesses;
    const bool exhaustive = options_.exhaustive;
    auto wanted = [&](const Decision& d) { return d.verdict == Verdict::Undecided || (cross && d.verdict == Verdict::Kept); };
    std::vector<Task> tasks;
    std::vector<bool> lightNeeded(size_t(cv.lightCount), false);
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        for (int g = 0; g < cv.objects[oi].groupCount; ++g) {
            bool any = false;
            for (int l = 0; l < cv.lightCount; ++l)
                if (wanted(cv.at(oi, g, l))) any = lightNeeded[size_t(l)] = true;
            if (any) tasks.push_back({oi, g});
        }
    if (tasks.empty()) return Status::ok();

    try {
        const glm::dvec3 ext = glm::max(glm::abs(window.lsBounds.min), glm::abs(window.lsBounds.max));
        const double margin = 1e-9 * (std::max({ext.x, ext.y, ext.z}) + 1.0) + 1e-9;
        const Aabb limits = grown(window.lsBounds, 1.0);

        // Broad phase, two levels: a tree over the window's objects (window-local boxes),
        // then the tree of the object's mesh (mesh coordinates, one per unique mesh, kept
        // across windows), both queried with the caster triangle's half-spaces
        // (shadow_query.h). Receivers are made only where a query reaches them, so a
        // window's cost follows what its undecided casters' shadows can reach, not how many
        // triangles it holds.
        std::vector<Aabb> objectBoxes(window.objects.size());
        for (size_t k = 0; k < window.objects.size(); ++k) {
            const WindowObject& o = window.objects[k];
            objectBoxes[k] = grown(o.lsBounds, margin);
            // The terrain rule, per object: no point of a model deeper than the tolerance
            // under the lowest ground under its box receives, so its box starts there (a
            // half-buried rock's box is mostly its buried half, which a terrain triangle's
            // column meets first). Wholly under: an empty box, never visited.
            if (exhaustive || !window.hasTerrain || o.kind == ChunkObject::Kind::Terrain) continue;
            const std::optional<double> ground =
                window.lsTerrainMinOver(o.lsBounds.min.x, o.lsBounds.min.z, o.lsBounds.max.x, o.lsBounds.max.z);
            if (!ground) continue;
            const double level = *ground - window.terrainTolerance - margin;
            if (objectBoxes[k].max.y < level) objectBoxes[k] = Aabb{};
            else objectBoxes[k].min.y = std::max(objectBoxes[k].min.y, level);
        }
        const ObjectTree objectTree(objectBoxes);

        // The lights as this stage tests them. A normal bias looks a receiver point q's shadow
        // up at q' = q + normalBias * n (semantics.md condition 5): q' within the frustum
        // dilated by filterRadius puts q within it dilated by filterRadius + normalBias (every
        // half-space moved outward by the sum), so the receivers themselves are tested
        // against that: a superset of both offsets, for one- and two-sided receivers alike,
        // with no rounding of its own (facing, range and terrain stay rules on q, as the
        // spec says). The single-occluder rule needs no dilation, so it stays off then.
        std::vector<Light> lights = window.lsLights;
        for (Light& L : lights) L.filterRadius += L.normalBias;
        std::vector<LightGeometry> lightGeom(size_t(cv.lightCount));
        std::vector<std::unique_ptr<ReceiverRules>> rules(size_t(cv.lightCount));
        for (int l = 0; l < cv.lightCount; ++l) {
            const Light& L = lights[size_t(l)];
            lightGeom[size_t(l)] = LightGeometry{L.type == LightType::Directional, L.direction, L.position};
            if (lightNeeded[size_t(l)]) rules[size_t(l)] = std::make_unique<ReceiverRules>(window, L, lightGeom[size_t(l)], margin, !exhaustive);
        }

        // Triangle `t` of object `k`, window-local (three distinct mesh vertices: the caller checked).
        auto makeReceiver = [&](uint32_t k, uint32_t t) {
            const WindowObject& o = window.objects[k];
            Receiver r;
            r.tri = o.lsTriangle(t);
            r.box = triangleBox(r.tri);
            r.twoSided = o.mesh->groups[o.mesh->triangleGroup[t]].twoSided();
            r.mirrored = o.flipsWinding;
            r.terrain = o.kind == ChunkObject::Kind::Terrain;
            return r;
        };

        std::atomic<uint64_t> tests{0}, culled{0}, examined{0};
        std::atomic<bool> contradiction{false};
        std::string contradictionAt;
        tbb::parallel_for(size_t(0), tasks.size(), [&](size_t ti) {
            // A signal: the tasks not begun leave their bits undecided; the stage then stops.
            if (stopRequested()) return;
            // Exact predicates: CGAL's interval filters need gradual underflow, whatever
            // mode an earlier stage's tasks left TBB in (core/float_mode.h).
            const FloatModeScope ieee(FloatModeScope::Underflow::Gradual);
            const Task& task = tasks[ti];
            const ObjectVerdicts& ov = cv.objects[task.object];
            const WindowObject& wo = window.objects[size_t(ov.windowObject)];
            // Calls f(triangle placed in the window) for each triangle of the group with
            // three distinct vertices. Only the exhaustive reference and a proof's note need
            // them all: the walk below maps the ones it reaches (placing and storing a dense
            // rock's 180,000 was most of the stage's time on world D).
            auto forCasterTriangles = [&](const auto& f) {
                for (size_t t = 0; t < wo.mesh->triangles.size(); ++t) {
                    if (wo.mesh->triangleGroup[t] != uint32_t(task.group)) continue;
                    if (!hasRepeatedVertex(*wo.mesh, t) && f(wo.lsTriangle(t))) return;
                }
            };
            for (int l = 0; l < cv.lightCount; ++l) {
                Decision& d = cv.at(task.object, task.group, l);
                if (!wanted(d)) continue;
                ++examined;
                const Light& L = lights[size_t(l)];
                const LightGeometry& lg = lightGeom[size_t(l)];
                const ReceiverRules& rl = *rules[size_t(l)];
                const bool local = L.type != LightType::Directional;
                // The smallest bias the receiver rules give any receiver (biasLowerBound is
                // never below the bias, which is exact).
                const double leastBias = L.bias;
                // Calls test(k, tri) for the receivers of the window the query may reach
                // (both levels of the broad phase), until it returns true.
                // `objectMay(k)`: false when no receiver of object k can be behind (then its
                // mesh tree is not walked).
                // A mesh-tree node's box placed in the window: its corners mapped, widened by
                // the margin (far above the rounding of the placed triangles' vertices).
                auto placedBox = [&](const WindowObject& o, const Aabb& msBox) {
                    return grown(placedBounds(msBox, o.lsTransform), margin);  // the placed triangles' rounding, far inside
                };
                // Caster parts no point of which is within the light's range and cone hold no p
                // (semantics.md, condition 3): a mesh-tree node by its placed box, a triangle
                // by its box.
                auto outOfReach = [&](const Aabb& msBox) { return boxOutOfReach(L, placedBox(wo, msBox)); };
                auto triangleOutOfReach = [&](const Triangle& t) { return boxOutOfReach(L, triangleBox(t)); };
                // `boxMay(lsBox)`: false when no point of the window-local box can be behind
                // the caster (then the mesh tree's node whose receiving part it holds is not
                // walked).
                auto forReceivers = [&](const ShadowQuery& q, const Aabb& qBox, const auto& test,
                                        const auto& objectMay, const auto& boxMay) {
                    return objectTree.visit([&](const Aabb& b) { return overlaps(b, qBox) && q.mayHold(b); },
                                            [&](uint32_t k) {
                                                if (!objectMay(k)) return false;
                                                const WindowObject& o = window.objects[k];
                                                // Range is a distance: every triangle of a box beyond it is too.
                                                if (local && boxBeyondRange(L, o.lsBounds)) return false;
                                                const ShadowQuery::InMesh mq = q.inMesh(o.lsTransform);
                                                // The terrain rule per node: a subtree whose box lies wholly deeper
                                                // than the tolerance under the ground holds no receiver (a dense
                                                // rock's buried half, under every terrain triangle's column), and
                                                // its receiving points lie in its box from that level up; a node
                                                // whose box from there up is in front of the caster holds none
                                                // behind (a rock's ground line, under every terrain triangle's
                                                // column: its buried side is behind, its receiving side in front).
                                                // Small meshes skip it (GeometryOptions::nodeTerrainRuleFrom).
                                                const bool buriable = window.hasTerrain && o.kind != ChunkObject::Kind::Terrain &&
                                                                      o.mesh->triangles.size() >= options_.nodeTerrainRuleFrom;
                                                return TriangleTree(*o.mesh).visit(
                                                    [&](const Aabb& b) {
                                                        if (!mq.mayHold(b)) return false;
                                                        if (!buriable) return true;
                                                        Aabb ls = placedBox(o, b);
                                                        const std::optional<double> ground =
                                                            window.lsTerrainMinOver(ls.min.x, ls.min.z, ls.max.x, ls.max.z);
                                                        if (!ground) return true;
                                                        const double level = *ground - window.terrainTolerance - margin;
                                                        if (ls.max.y < level) return false;
                                                        ls.min.y = std::max(ls.min.y, level);
                                                        return boxMay(ls);
                                                    },
                                                    [&](uint32_t tri) { return test(k, tri); });
                                            });
                };
                // Receiver triangle `tri` of object `k` (three distinct vertices) and its
                // bias, or -1 when the receiver rules exclude it.
                auto receiver = [&](uint32_t k, uint32_t tri, std::optional<Receiver>& made,
                                    const std::vector<glm::dvec3>** above = nullptr) {
                    const double beta =
                        rl.beta(k, tri, [&]() -> const Receiver& { return *(made = makeReceiver(k, tri)); }, above);
                    if (beta >= 0 && !made) made = makeReceiver(k, tri);
                    return beta;
                };
                // Opaque triangles (not alpha-tested, of objects that cast shadows) that may
                // lie between a directional light and a reached part: the column from the part's box back towards the light, walked as a
                // receiver column is (the light reversed). The exact tests then drop a part
                // one of them shades wholly (no caster point of it lit). Buried parts of the
                // objects are not in the tree's boxes: fewer occluders, never a wrong one.
                // The exhaustive reference uses the same source, so the two stay comparable.
                std::optional<OccluderSource> occluders;
                if (!local && !(L.filterRadius > 0))
                    occluders.emplace([&](const std::array<glm::dvec3, 2>& box, std::vector<Triangle>& out) {
                        constexpr size_t kMaxOccluders = 256;  // enough for a part a fraction of a cell wide
                        LightGeometry back = lg;
                        back.direction = -lg.direction;
                        Light backLight = L;
                        backLight.direction = -L.direction;
                        const ShadowQuery q = ShadowQuery::ofCluster(Aabb{box[0], box[1]}, RowTransform{}, back, 0.0, margin);
                        const Aabb qBox = q.columnBox(backLight, limits);
                        objectTree.visit([&](const Aabb& b) { return overlaps(b, qBox) && q.mayHold(b); },
                                         [&](uint32_t k) {
                                             const WindowObject& o = window.objects[k];
                                             if (!o.castsShadow) return false;  // light passes it
                                             const Mesh& mesh = *o.mesh;
                                             const ShadowQuery::InMesh mq = q.inMesh(o.lsTransform);
                                             return TriangleTree(mesh).visit([&](const Aabb& b) { return mq.mayHold(b); },
                                                                            [&](uint32_t tri) {
                                                                                if (!o.blocksLight(mesh.triangleGroup[tri])) return false;
                                                                                out.push_back(o.lsTriangle(tri));
                                                                                return out.size() >= kMaxOccluders;
                                                                            });
                                         });
                    });
                const OccluderSource* occluderSource = occluders ? &*occluders : nullptr;
                // One caster triangle: true when some receiver reaches its frustum (a
                // candidate), described in `seen`. Safe to run for several triangles at once.
                uint64_t tested = 0;  // exact tests, as a sequential walk makes them
                auto castsOnSomething = [&](const Triangle& t, std::string& seen, uint64_t& tests, ReceiverPoint& seenAt) {
                    bool candidate = false;
                    ExactReach reach(window, t, lg, window.lsLights[size_t(l)], margin, occluderSource);
                    const FrustumFilter filter(t, lg, L.filterRadius);
                    std::optional<ShadowQuery> query;
                    if (!exhaustive) query.emplace(t, lg, L.filterRadius, margin);
                    auto test = [&](uint32_t k, uint32_t tri) {
                        // The double filters first: they hold for every bias >= 0, so with
                        // the least one the receiver rules (facing, range, the part above the
                        // ground: clipped against the terrain, per window and light) are made
                        // only for triangles that may meet the frustum. On world D the
                        // terrain's columns reach the dense rocks' ground line, thousands of
                        // triangles per terrain triangle, most of them outside the column.
                        if (!exhaustive) {
                            const Triangle placed = window.objects[k].lsTriangle(tri);
                            if (query->misses(placed) || filter.certainlyMisses(placed, leastBias)) return false;
                        }
                        std::optional<Receiver> made;
                        const std::vector<glm::dvec3>* above = nullptr;  // its part above the ground
                        const double beta = receiver(k, tri, made, &above);
                        if (beta < 0) return false;
                        const Receiver& r = *made;
                        if (!exhaustive && (query->misses(r.tri) || filter.certainlyMisses(r.tri, beta))) return false;
                        // The terrain rule, cheaply: the part of the receiver not buried
                        // deeper than the tolerance lies wholly in front of the caster (a
                        // rock's crown beside a terrain triangle whose column reaches only
                        // its buried side).
                        if (!exhaustive && above && filter.allInFront(above->data(), above->size(), beta)) return false;
                        ++tests;
                        std::array<glm::dvec3, 2> part;  // the box of the reached part
                        glm::dvec3 at;  // a point of the receiver the shadow reaches (a target for witness rays)
                        if (!reach.reaches(r, beta, part, at)) return false;
                        candidate = true;
                        seenAt = {at, k, tri};
                        if (candidate) {
                            const WindowObject& ro = window.objects[k];
                            auto corner = [&](const glm::dvec3& p) { return worldPoint(p, window.wsOrigin); };
                            seen = "could not exclude " + ro.label + " group " + std::to_string(ro.mesh->triangleGroup[tri]) +
                                   " (triangle " + std::to_string(tri) + "): the shadow volume of the caster triangle " +
                                   corner(t[0]) + " " + corner(t[1]) + " " + corner(t[2]) +
                                   " reaches it more than the bias behind, within " + worldBox(Aabb{part[0], part[1]}, window.wsOrigin) +
                                   " (a candidate receiver: the next stages look for a witness ray or an occluder)";
                        }
                        return candidate;
                    };
                    // Point and spot lights: the whole window. The receiver rules exclude only
                    // receivers wholly beyond range, and the exact test does not bound the
                    // frustum by range, so a range-bounded box would prove more than they do.
                    // An object whose box (a model's from the lowest ground under it, the
                    // terrain rule) lies wholly in front of the caster by the smallest bias any
                    // receiver gets holds no receiver behind it: a half-buried rock beside a
                    // terrain triangle whose column meets only its buried half.
                    auto boxMay = [&](const Aabb& b) {
                        const std::array<glm::dvec3, 8> corners = b.corners();
                        return !filter.allInFront(corners.data(), 8, leastBias);
                    };
                    auto objectMay = [&](uint32_t k) { return boxMay(objectBoxes[k]); };
                    if (!exhaustive)
                        return forReceivers(*query, local ? limits : frustumBox(t, L, limits, margin), test, objectMay, boxMay);
                    for (uint32_t k = 0; k < window.objects.size() && !candidate; ++k) {
                        const Mesh& m = *window.objects[k].mesh;
                        for (uint32_t tri = 0; tri < m.triangles.size(); ++tri) {
                            if (!hasRepeatedVertex(m, tri) && test(k, tri)) break;
                        }
                    }
                    return candidate;
                };
                bool candidate = false;
                std::string seen;  // the candidate, for the bit's note
                ReceiverPoint seenAt;  // and where the shadow reaches it
                if (!exhaustive) {
                    // The caster's triangles by the clusters of its mesh tree, top down. A cluster whose column no receiver can be behind
                    // (ShadowQuery::ofCluster, clusterMisses) holds no triangle with a
                    // candidate, and is left whole: a buried or isolated part of a dense
                    // mesh costs a few cluster queries instead of one query per triangle.
                    // Large subtrees run in parallel (a window's one dense caster would
                    // otherwise hold one core); the candidate kept is the first in the tree's
                    // order, as a sequential walk finds it, so notes do not depend on threads.
                    const Mesh& cm = *wo.mesh;
                    std::atomic<uint32_t> first{TriangleTree::kNone};
                    std::mutex firstMutex;
                    // Exact tests per caster triangle that made any: those after the first
                    // candidate (run ahead in parallel) are not counted, so the count is the
                    // same on any number of threads.
                    std::vector<std::pair<uint32_t, uint64_t>> testsAt;
                    TriangleTree(cm).visitNodesOrdered(
                        [&](const Aabb& msBox, uint32_t items) {
                            // p lies within range and cone (semantics.md): a cluster wholly
                            // beyond holds no caster point that counts (exact; the margins
                            // keep every point within reach).
                            if (local && outOfReach(msBox)) return false;
                            // A few triangles cost about what one cluster query does: test them.
                            if (items <= kClusterAtLeast) return true;
                            // Subtrees may run on other TBB threads: gradual underflow there too.
                            const FloatModeScope ieeeHere(FloatModeScope::Underflow::Gradual);
                            const ShadowQuery cq = ShadowQuery::ofCluster(msBox, wo.lsTransform, lg, L.filterRadius, margin);
                            return forReceivers(
                                cq, local ? limits : cq.columnBox(L, limits),
                                [&](uint32_t k, uint32_t tri) {
                                    std::optional<Receiver> made;
                                    const double beta = receiver(k, tri, made);
                                    return beta >= 0 && !cq.clusterMisses(made->tri, beta);
                                },
                                [](uint32_t) { return true; }, [](const Aabb&) { return true; });
                        },
                        [&](uint32_t tri, uint32_t position) {
                            if (cm.triangleGroup[tri] != uint32_t(task.group)) return;
                            const FloatModeScope ieeeHere(FloatModeScope::Underflow::Gradual);  // as above
                            const Triangle placed = wo.lsTriangle(tri);
                            if (local && triangleOutOfReach(placed)) return;
                            std::string note;
                            uint64_t n = 0;
                            ReceiverPoint at;
                            const bool found = castsOnSomething(placed, note, n, at);
                            if (!found && n == 0) return;
                            const std::lock_guard<std::mutex> lock(firstMutex);
                            if (n > 0) testsAt.emplace_back(position, n);
                            if (found && position < first.load()) {
                                first.store(position);
                                seen = std::move(note);
                                seenAt = at;
                            }
                        },
                        first, kParallelCasters);
                    candidate = first.load() != TriangleTree::kNone;
                    for (const auto& [position, n] : testsAt)
                        if (position <= first.load()) tested += n;
                } else {
                    forCasterTriangles([&](const Triangle& t) {
                        if (local && triangleOutOfReach(t)) return false;
                        return candidate = castsOnSomething(t, seen, tested, seenAt);
                    });
                }
                tests += tested;
                if (candidate) {
                    if (d.verdict == Verdict::Undecided) {
                        addNote(d, "geometry", std::move(seen));
                        const std::lock_guard<std::mutex> lock(candidatesMutex);
                        candidates_.push_back({task.object, task.group, l, seenAt.lsPoint, seenAt.object, seenAt.triangle});
                    }
                    continue;
                }
                if (d.verdict == Verdict::Kept) {  // cross-check mode: a proof against a witness
                    if (!contradiction.exchange(true))
                        contradictionAt = wo.label + " group " + std::to_string(task.group) + " light " + std::to_string(l + 1);
                    continue;
                }
                // For the note: a box holding the volume, the frustum box of the group's placed
                // box (each caster triangle lies in it, so its frustum in that box's), not
                // the union over triangles: that cost a dense mesh's instance one frustum box
                // per triangle and light, for a note.
                const Aabb groupBox = lsGroupBounds(wo, uint32_t(task.group), true);
                const std::array<glm::dvec3, 8> groupCorners = groupBox.corners();
                const Aabb volume = groupBox.empty() ? Aabb{} : shadowBox(groupCorners.data(), 8, L, limits, margin);
                const uint64_t casterCount = vertexIndex(*wo.mesh).groupTrianglesWithArea[size_t(task.group)];
                decide(d, Verdict::Culled, "geometry",
                       "no receiver in the shadow volume (" + std::to_string(casterCount) +
                           " caster triangles; volume within " + worldBox(volume, window.wsOrigin) + ")" +
                           (occluders && occluders->shadedSome.load()
                                ? "; where it reaches a receiver, one opaque triangle shades the caster (p not lit)"
                                : ""));
                ++culled;
            }
        });
        if (Status s = stopStatus(); !s) return s;
        // In a fixed order whatever the threads did.
        std::sort(candidates_.begin(), candidates_.end(), [](const Candidate& a, const Candidate& b) {
            return std::tie(a.object, a.group, a.light) < std::tie(b.object, b.group, b.light);
        });
        if (contradiction)
            return makeError(ErrorKind::Internal, window.centrePath, 0,
                             "geometry stage would prove 0 for a bit with a witness: " + contradictionAt);
        stats.exactTests += tests;
        stats.bitsExamined += examined;
        stats.provedCulled += culled;
    } catch (const std::exception& e) {
        return makeError(ErrorKind::Internal, window.centrePath, 0, std::string("geometry stage: ") + e.what());
    }
    stats.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return Status::ok();
}

}  // namespace shadowcull::geometry
