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
#include <optional>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "core/float_mode.h"
#include "core/format.h"
#include "core/light_reach.h"
#include "geometry/exact_frustum.h"

namespace shadowcull::geometry {

namespace {

struct Receiver {
    Triangle tri;  // window-local
    Aabb box;
    uint32_t object = 0, group = 0;
    bool twoSided = false, mirrored = false, terrain = false;
};

// Closed boxes that share a point.
bool overlaps(const Aabb& a, const Aabb& b) {
    return !(a.max.x < b.min.x || a.min.x > b.max.x || a.max.y < b.min.y || a.min.y > b.max.y || a.max.z < b.min.z ||
             a.min.z > b.max.z);
}

// Receivers bucketed by the x/z cells their boxes touch. A broad phase only: it never
// drops a receiver whose box overlaps the query.
class ReceiverGrid {
public:
    // At most this many cells (a window holding a mesh 65 km wide made 16 M cells of the
    // usual size, and a minute of bucketing), and a receiver that would touch more than
    // kMaxCellsPerReceiver cells is kept in a list of its own, visited by every query.
    static constexpr double kMaxCells = 1 << 20;
    static constexpr int kMaxCellsPerReceiver = 1024;

    ReceiverGrid(const Aabb& bounds, double cellSize, const std::vector<Receiver>& receivers) : receivers_(receivers) {
        origin_ = glm::dvec2(bounds.min.x, bounds.min.z);
        const double w = std::max(bounds.max.x - bounds.min.x, 0.0), d = std::max(bounds.max.z - bounds.min.z, 0.0);
        cell_ = std::max({cellSize, std::sqrt(w * d / kMaxCells), w / 4095.0, d / 4095.0});
        nx_ = std::clamp(int(std::ceil(w / cell_)) + 1, 1, 4096);
        nz_ = std::clamp(int(std::ceil(d / cell_)) + 1, 1, 4096);
        cells_.resize(size_t(nx_) * size_t(nz_));
        for (uint32_t k = 0; k < receivers.size(); ++k) {
            auto [i0, j0, i1, j1] = range(receivers[k].box);
            if (int64_t(i1 - i0 + 1) * int64_t(j1 - j0 + 1) > kMaxCellsPerReceiver) {
                large_.push_back(k);
                continue;
            }
            for (int j = j0; j <= j1; ++j)
                for (int i = i0; i <= i1; ++i) cells_[size_t(j) * size_t(nx_) + size_t(i)].push_back(k);
        }
    }

    // Calls f(index) once for every receiver whose box overlaps `box`.
    template <class F>
    void forEachOverlapping(const Aabb& box, std::vector<uint32_t>& stamp, uint32_t mark, F f) const {
        auto visit = [&](uint32_t k) {
            if (stamp[k] == mark) return false;
            stamp[k] = mark;
            return overlaps(receivers_[k].box, box) && f(k);
        };
        auto [i0, j0, i1, j1] = range(box);
        for (int j = j0; j <= j1; ++j)
            for (int i = i0; i <= i1; ++i)
                for (uint32_t k : cells_[size_t(j) * size_t(nx_) + size_t(i)])
                    if (visit(k)) return;
        for (uint32_t k : large_)
            if (visit(k)) return;
    }

private:
    std::array<int, 4> range(const Aabb& b) const {
        auto idx = [](double v, double o, double c, int n) { return std::clamp(int(std::floor((v - o) / c)), 0, n - 1); };
        return {idx(b.min.x, origin_.x, cell_, nx_), idx(b.min.z, origin_.y, cell_, nz_), idx(b.max.x, origin_.x, cell_, nx_),
                idx(b.max.z, origin_.y, cell_, nz_)};
    }
    const std::vector<Receiver>& receivers_;
    glm::dvec2 origin_{0.0};
    double cell_ = 1;
    int nx_ = 1, nz_ = 1;
    std::vector<std::vector<uint32_t>> cells_;
    std::vector<uint32_t> large_;  // receivers touching more than kMaxCellsPerReceiver cells
};

// A bounding-volume hierarchy over receiver boxes (2D or 3D, `Box` has min/max, extend,
// overlaps) that also knows each receiver's farthest depth: a query visits the receivers
// whose box overlaps the query box and that reach at least a given depth, pruning whole
// subtrees by both. Median splits on the longest axis of the centres; leaves of 8.
template <class Box>
class BoxHierarchy {
public:
    void build(std::vector<Box> boxes, std::vector<double> far) {
        boxes_ = std::move(boxes);
        far_ = std::move(far);
        order_.resize(boxes_.size());
        for (uint32_t k = 0; k < order_.size(); ++k) order_[k] = k;
        nodes_.clear();
        if (order_.empty()) return;
        nodes_.reserve(2 * (order_.size() / kLeafSize + 1));
        nodes_.push_back({});
        struct Job {
            uint32_t node, first, count;
        };
        std::vector<Job> jobs{{0, 0, uint32_t(order_.size())}};
        while (!jobs.empty()) {
            const Job j = jobs.back();
            jobs.pop_back();
            Box box, centres;
            double far = -1e300;
            for (uint32_t i = j.first; i < j.first + j.count; ++i) {
                const uint32_t k = order_[i];
                box.extend(boxes_[k]);
                centres.extend(0.5 * (boxes_[k].min + boxes_[k].max));
                far = std::max(far, far_[k]);
            }
            nodes_[j.node].box = box;
            nodes_[j.node].far = far;
            if (j.count <= kLeafSize) {
                nodes_[j.node].first = j.first;
                nodes_[j.node].count = j.count;
                continue;
            }
            int axis = 0;
            const auto extent = centres.max - centres.min;
            for (int a = 1; a < int(extent.length()); ++a)
                if (extent[a] > extent[axis]) axis = a;
            const uint32_t half = j.count / 2;
            std::nth_element(order_.begin() + j.first, order_.begin() + j.first + half, order_.begin() + j.first + j.count,
                             [&](uint32_t p, uint32_t q) {
                                 return boxes_[p].min[axis] + boxes_[p].max[axis] < boxes_[q].min[axis] + boxes_[q].max[axis];
                             });
            const uint32_t left = uint32_t(nodes_.size());
            nodes_.push_back({});
            nodes_.push_back({});
            nodes_[j.node].first = left;
            nodes_[j.node].count = 0;
            jobs.push_back({left, j.first, half});
            jobs.push_back({left + 1, j.first + half, j.count - half});
        }
    }

    // Calls f(index) once for every receiver whose box overlaps `box` and whose far value
    // is at least `near`, until f returns true. The tree is balanced (depth about
    // log2(n / 8) + 1), far below the stack's 64.
    template <class F>
    void forEach(const Box& box, double near, F f) const {
        if (nodes_.empty()) return;
        uint32_t stack[64];
        int top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const Node& n = nodes_[stack[--top]];
            if (n.far < near || !n.box.overlaps(box)) continue;
            if (n.count > 0) {
                for (uint32_t i = n.first; i < n.first + n.count; ++i) {
                    const uint32_t k = order_[i];
                    if (far_[k] >= near && boxes_[k].overlaps(box) && f(k)) return;
                }
            } else {
                stack[top++] = n.first;
                stack[top++] = n.first + 1;
            }
        }
    }

private:
    struct Node {
        Box box;
        double far = -1e300;
        uint32_t first = 0;  // leaf: first index into order_; inner: index of the left child
        uint32_t count = 0;  // leaf: receivers; inner: 0
    };
    static constexpr uint32_t kLeafSize = 8;
    std::vector<Box> boxes_;
    std::vector<double> far_;
    std::vector<uint32_t> order_;  // receivers, leaf by leaf
    std::vector<Node> nodes_;
};

template <class V>
struct BoxN {
    V min{1e300}, max{-1e300};
    void extend(const V& p) { min = glm::min(min, p); max = glm::max(max, p); }
    void extend(const BoxN& b) { min = glm::min(min, b.min); max = glm::max(max, b.max); }
    bool overlaps(const BoxN& o) const {
        for (int a = 0; a < int(V::length()); ++a)
            if (max[a] < o.min[a] || min[a] > o.max[a]) return false;
        return true;
    }
};
using Box2 = BoxN<glm::dvec2>;
using Box3 = BoxN<glm::dvec3>;

// Receivers of one directional light, by their projection onto the plane across the
// light (coordinates u, v; depth w along it). The frustum {p + s d : p in t, s > 0} of a
// caster triangle t projects onto t's own projection (dilated by the filter radius), and
// every point of it lies deeper than t's shallowest vertex; so a receiver whose projected
// box misses t's, or that lies wholly shallower than t, cannot meet it. A query then costs
// what lies in the caster's shadow column: for a slanted sun the world box of a slender
// extruded triangle spans the whole window, and the world grid returned every receiver of
// a dense mesh for every one of its triangles; a hierarchy, unlike a uniform grid, adapts
// to a dense mesh in a sparse world. Broad phase only: boxes are grown by the rounding
// margin; the filters and the exact test decide the rest.
// Coordinates across a directional light (u, v) and along it (w, depth).
struct LightFrame {
    glm::dvec3 u{1, 0, 0}, v{0, 0, 1}, w{0, -1, 0};
    explicit LightFrame(const glm::dvec3& direction) {
        w = glm::normalize(direction);
        // Any unit vector across the light; the axis least aligned with it keeps u well defined.
        const glm::dvec3 a = std::abs(w.x) < 0.57 ? glm::dvec3(1, 0, 0) : std::abs(w.y) < 0.57 ? glm::dvec3(0, 1, 0) : glm::dvec3(0, 0, 1);
        u = glm::normalize(glm::cross(w, a));
        v = glm::cross(w, u);
    }
    glm::dvec2 across(const glm::dvec3& p) const { return {glm::dot(p, u), glm::dot(p, v)}; }
    double depth(const glm::dvec3& p) const { return glm::dot(p, w); }
};

class LightSpaceGrid {
public:
    LightSpaceGrid(const std::vector<Receiver>& receivers, const glm::dvec3& direction, double margin) : margin_(margin) {
        const LightFrame f(direction);
        u_ = f.u;
        v_ = f.v;
        w_ = f.w;
        std::vector<Box2> boxes(receivers.size());
        std::vector<double> deepest(receivers.size());
        for (size_t k = 0; k < receivers.size(); ++k) {
            boxes[k] = project(receivers[k].tri, 0.0);
            double d = -1e300;
            for (const glm::dvec3& p : receivers[k].tri) d = std::max(d, glm::dot(p, w_));
            deepest[k] = d + margin_;
        }
        tree_.build(std::move(boxes), std::move(deepest));
    }

    // The projection of `t`, grown by the margin and `grow` (metres, the filter radius).
    Box2 project(const Triangle& t, double grow) const {
        Box2 b;
        for (const glm::dvec3& p : t) b.extend(glm::dvec2(glm::dot(p, u_), glm::dot(p, v_)));
        b.min -= glm::dvec2(margin_ + grow);
        b.max += glm::dvec2(margin_ + grow);
        return b;
    }
    // The least depth of `t`, less the margin. With a filter radius r the exact frustum's
    // near plane moves r towards the light too: the caller subtracts r.
    double shallowest(const Triangle& t) const {
        return std::min({glm::dot(t[0], w_), glm::dot(t[1], w_), glm::dot(t[2], w_)}) - margin_;
    }
    template <class F>
    void forEachOverlapping(const Box2& box, double depth, F f) const {
        tree_.forEach(box, depth, f);
    }

private:
    double margin_;
    glm::dvec3 u_{1, 0, 0}, v_{0, 0, 1}, w_{0, -1, 0};
    BoxHierarchy<Box2> tree_;
};

// Receivers of one point or spot light (without filter radius), by the directions in
// which the light sees them. The frustum {L + l (p - L) : p in t, l > 1} of a caster
// triangle t holds only directions in which L sees t, at distances beyond t's nearest
// point; so a receiver seen in no such direction, or wholly nearer than t, cannot meet it.
// Directions are bounded by caps (the spherical triangle of a triangle lies in the cap
// around its mean direction through its farthest vertex, when that cap is under a
// hemisphere) and caps by boxes in 3D around their axis (every point of a cap of angle a
// lies within the chord 2 sin(a/2) of its axis point). A triangle the light sees over
// half the sky or more, or too close to tell, gets the whole sphere.
class DirectionGrid {
public:
    DirectionGrid(const std::vector<Receiver>& receivers, const glm::dvec3& light, double margin) : L_(light), margin_(margin) {
        std::vector<Box3> boxes(receivers.size());
        std::vector<double> farthest(receivers.size());
        for (size_t k = 0; k < receivers.size(); ++k) {
            boxes[k] = cap(receivers[k].tri);
            double f = 0;
            for (const glm::dvec3& p : receivers[k].tri) f = std::max(f, glm::length(p - L_));
            farthest[k] = f * (1 + 1e-9) + margin_;
        }
        tree_.build(std::move(boxes), std::move(farthest));
    }

    Box3 cap(const Triangle& t) const {
        Box3 all;
        all.min = glm::dvec3(-2.0);
        all.max = glm::dvec3(2.0);
        glm::dvec3 u[3];
        for (int i = 0; i < 3; ++i) {
            const glm::dvec3 d = t[size_t(i)] - L_;
            const double len = glm::length(d);
            if (!(len > 1e-6 * (1 + margin_))) return all;
            u[i] = d / len;
        }
        const glm::dvec3 sum = u[0] + u[1] + u[2];
        const double sl = glm::length(sum);
        if (!(sl > 1e-3)) return all;
        const glm::dvec3 axis = sum / sl;
        double minCos = 1.0;
        for (const glm::dvec3& v : u) minCos = std::min(minCos, glm::dot(axis, v));
        if (!(minCos > 0.05)) return all;  // the cap would reach a hemisphere: no bound
        // chord = 2 sin(a/2) = sqrt(2 - 2 cos a), plus room for the rounding of all of it.
        const double chord = std::sqrt(std::max(0.0, 2.0 - 2.0 * minCos)) + 1e-7;
        Box3 b;
        b.min = axis - glm::dvec3(chord);
        b.max = axis + glm::dvec3(chord);
        return b;
    }
    // A lower bound of the distance from the light of every point of t's frustum.
    double nearest(const Triangle& t) const {
        Aabb box;
        for (const glm::dvec3& p : t) box.extend(p);
        return distanceToBox(L_, box) * (1 - 1e-9) - margin_;
    }
    template <class F>
    void forEachOverlapping(const Box3& box, double near, F f) const {
        tree_.forEach(box, near, f);
    }

private:
    glm::dvec3 L_;
    double margin_;
    BoxHierarchy<Box3> tree_;
};

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
    Aabb box = triangleBox(t);
    if (L.type == LightType::Directional) {
        const glm::dvec3& d = L.direction;
        double sMax = 0;
        for (const glm::dvec3& v : t) {
            // Ray parameter where v + s d leaves the window box.
            double exit = std::numeric_limits<double>::infinity();
            for (int a = 0; a < 3; ++a) {
                if (d[a] > 0) exit = std::min(exit, (limits.max[a] - v[a]) / d[a]);
                else if (d[a] < 0) exit = std::min(exit, (limits.min[a] - v[a]) / d[a]);
            }
            sMax = std::max(sMax, exit);
        }
        sMax = sMax * (1 + 1e-9) + margin;
        for (const glm::dvec3& v : t) box.extend(v + sMax * d);
    } else {
        Aabb sphere;
        sphere.min = L.position - glm::dvec3(L.range);
        sphere.max = L.position + glm::dvec3(L.range);
        const double dMin = distanceToBox(L.position, box) * (1 - 1e-9);
        if (dMin > 1e-9) {
            const double lMax = L.range / dMin * (1 + 1e-9) + 1e-9;
            for (const glm::dvec3& v : t) box.extend(L.position + lMax * (v - L.position));
            box.min = glm::max(box.min, sphere.min);
            box.max = glm::min(box.max, sphere.max);
        } else {
            box = sphere;
        }
    }
    return grown(box, margin + L.filterRadius);
}

// True when every point of the box lies deeper than the tolerance under the terrain
// (conservative: the box's top against the lowest terrain sample around it).
bool underTerrain(const BakeWindow& w, const std::array<glm::dvec3, 2>& box, double margin) {
    std::optional<double> ground = w.lsTerrainMinOver(box[0].x, box[0].z, box[1].x, box[1].z);
    return ground && box[1].y < *ground - w.terrainTolerance - margin;
}

// Per receiver and light, computed on first use (most receivers of a window are never
// tested): -1 when the receiver rules exclude it, else a lower bound of the bias
// (metres) that applies to it. Safe to call from several threads: a value is computed
// again at worst, always the same.
class ReceiverRules {
public:
    ReceiverRules(const BakeWindow& w, const std::vector<Receiver>& receivers, const Light& L, const LightGeometry& lg,
                  double margin)
        : w_(w), receivers_(receivers), L_(L), lg_(lg), margin_(margin), beta_(receivers.size()), known_(receivers.size()) {
        for (auto& k : known_) k.store(false, std::memory_order_relaxed);
    }

    double beta(uint32_t k) const {
        if (known_[k].load(std::memory_order_acquire)) return beta_[k].load(std::memory_order_relaxed);
        const double b = compute(receivers_[k]);
        beta_[k].store(b, std::memory_order_relaxed);
        known_[k].store(true, std::memory_order_release);
        return b;
    }

private:
    double compute(const Receiver& r) const {
        // Facing: a one-sided receiver the light meets from behind or edge-on gets nothing.
        if (!r.twoSided && exactFacing(r.tri, r.mirrored, lg_) <= 0) return -1;
        // Range and cone.
        if (boxBeyondRange(L_, r.box) || boxOutsideCone(L_, r.box)) return -1;
        // Terrain: wholly deeper than the tolerance under the terrain (terrain itself exempt).
        if (w_.hasTerrain && !r.terrain && underTerrain(w_, {r.box.min, r.box.max}, margin_)) return -1;
        // Bias, and for directional lights the slope term (constant over a triangle).
        double b = L_.bias;
        if (L_.slopeBias > 0 && L_.type == LightType::Directional) {
            glm::dvec3 n = glm::cross(r.tri[1] - r.tri[0], r.tri[2] - r.tri[0]);
            const double len = glm::length(n);
            const double c = len > 0 ? std::abs(glm::dot(n / len, L_.direction)) : 0.0;
            if (c > 1e-6) b += L_.slopeBias * std::sqrt(std::max(0.0, 1 - c * c)) / c;
        }
        return std::max(0.0, b * (1 - 1e-9) - 1e-12);  // a lower bound: conservative
    }

    const BakeWindow& w_;
    const std::vector<Receiver>& receivers_;
    const Light& L_;
    LightGeometry lg_;
    double margin_;
    mutable std::vector<std::atomic<double>> beta_;
    mutable std::vector<std::atomic<bool>> known_;
};

std::string worldBox(const Aabb& b, const glm::dvec3& origin) {
    auto v = [](const glm::dvec3& p) {
        return "(" + formatNumber(p.x) + " " + formatNumber(p.y) + " " + formatNumber(p.z) + ")";
    };
    return v(b.min + origin) + " .. " + v(b.max + origin);
}

}  // namespace

Status GeometryStage::run(const BakeWindow& window, ChunkVerdicts& cv, StageStats& stats) {
    const auto t0 = std::chrono::steady_clock::now();
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

        // Casters per task, and a box around every frustum any task will query: receivers
        // outside it can never be returned by a query, so they are left out of the grid
        // (for local lights most of the window).
        std::vector<std::vector<Triangle>> tasksCasters(tasks.size());
        Aabb queried;
        for (size_t ti = 0; ti < tasks.size(); ++ti) {
            const ObjectVerdicts& ov = cv.objects[tasks[ti].object];
            const WindowObject& wo = window.objects[size_t(ov.windowObject)];
            for (size_t t = 0; t < wo.mesh->triangles.size(); ++t) {
                if (wo.mesh->triangleGroup[t] != uint32_t(tasks[ti].group)) continue;
                const auto& i = wo.mesh->triangles[t];
                const glm::dvec3 &a = wo.mesh->positions[i[0]], &b = wo.mesh->positions[i[1]], &c = wo.mesh->positions[i[2]];
                if (!hasRepeatedVertex(a, b, c))
                    tasksCasters[ti].push_back({wo.lsTransform.apply(a), wo.lsTransform.apply(b), wo.lsTransform.apply(c)});
            }
            for (int l = 0; l < cv.lightCount; ++l)
                if (wanted(cv.at(tasks[ti].object, tasks[ti].group, l)))
                    for (const Triangle& t : tasksCasters[ti]) queried.extend(frustumBox(t, window.lsLights[size_t(l)], limits, margin));
        }

        // Directional lights: the shadow columns of every caster a task will query, in the
        // light's frame (projected box, least depth). A receiver outside every column (and
        // outside every local light's frustum boxes) is never returned by a query, so it is
        // neither built nor put in a hierarchy: with a few undecided groups in a window of
        // dense meshes, most of the window.
        struct Column {
            int light;
            LightFrame frame;
            Box2 box;
            double depth = 1e300;
        };
        std::vector<Column> columns;
        bool anyLocalLight = false;
        for (int l = 0; l < cv.lightCount; ++l) {
            if (!lightNeeded[size_t(l)]) continue;
            const Light& L = window.lsLights[size_t(l)];
            if (L.type != LightType::Directional) {
                anyLocalLight = true;
                continue;
            }
            Column c{l, LightFrame(L.direction), Box2{}, 1e300};
            for (size_t ti = 0; ti < tasks.size(); ++ti)
                if (wanted(cv.at(tasks[ti].object, tasks[ti].group, l)))
                    for (const Triangle& t : tasksCasters[ti])
                        for (const glm::dvec3& p : t) {
                            c.box.extend(c.frame.across(p));
                            c.depth = std::min(c.depth, c.frame.depth(p));
                        }
            c.box.min -= glm::dvec2(2 * margin + L.filterRadius);
            c.box.max += glm::dvec2(2 * margin + L.filterRadius);
            c.depth -= 2 * margin + L.filterRadius;
            columns.push_back(c);
        }
        // Point and spot lights: the world boxes of their frusta.
        Aabb localQueried;
        if (anyLocalLight)
            for (size_t ti = 0; ti < tasks.size(); ++ti)
                for (int l = 0; l < cv.lightCount; ++l) {
                    const Light& L = window.lsLights[size_t(l)];
                    if (L.type != LightType::Directional && wanted(cv.at(tasks[ti].object, tasks[ti].group, l)))
                        for (const Triangle& t : tasksCasters[ti]) localQueried.extend(frustumBox(t, L, limits, margin));
                }
        // Whether anything among `pts` (a box's corners, or a triangle) can be queried.
        auto inColumns = [&](const glm::dvec3* pts, size_t n) {
            if (exhaustive) return true;  // the reference keeps every receiver
            if (anyLocalLight) {
                Aabb b;
                for (size_t i = 0; i < n; ++i) b.extend(pts[i]);
                if (overlaps(b, localQueried)) return true;
            }
            for (const Column& c : columns) {
                Box2 pb;
                double deepest = -1e300;
                for (size_t i = 0; i < n; ++i) {
                    pb.extend(c.frame.across(pts[i]));
                    deepest = std::max(deepest, c.frame.depth(pts[i]));
                }
                pb.min -= glm::dvec2(margin);
                pb.max += glm::dvec2(margin);
                if (deepest + margin >= c.depth && pb.overlaps(c.box)) return true;
            }
            return false;
        };
        auto corners = [](const Aabb& b) {
            std::array<glm::dvec3, 8> c;
            for (int k = 0; k < 8; ++k) c[size_t(k)] = {k & 1 ? b.max.x : b.min.x, k & 2 ? b.max.y : b.min.y, k & 4 ? b.max.z : b.min.z};
            return c;
        };

        // Receivers: every triangle with three distinct vertices of everything loaded that
        // lies in the queried box and in some shadow column.
        std::vector<char> objectWanted(window.objects.size(), 0);
        std::vector<Receiver> receivers;
        size_t most = 0;
        for (size_t k = 0; k < window.objects.size(); ++k) {
            const WindowObject& o = window.objects[k];
            const auto c = corners(o.lsBounds);
            objectWanted[k] = overlaps(o.lsBounds, queried) && inColumns(c.data(), c.size());
            if (objectWanted[k]) most += o.mesh->triangles.size();
        }
        receivers.reserve(most);
        for (uint32_t k = 0; k < window.objects.size(); ++k) {
            const WindowObject& o = window.objects[k];
            if (!objectWanted[k]) continue;
            for (size_t t = 0; t < o.mesh->triangles.size(); ++t) {
                const auto& i = o.mesh->triangles[t];
                const glm::dvec3 &a = o.mesh->positions[i[0]], &b = o.mesh->positions[i[1]], &c = o.mesh->positions[i[2]];
                if (hasRepeatedVertex(a, b, c)) continue;
                Receiver r;
                r.tri = {o.lsTransform.apply(a), o.lsTransform.apply(b), o.lsTransform.apply(c)};
                r.box = triangleBox(r.tri);
                if (!overlaps(r.box, queried) || !inColumns(r.tri.data(), 3)) continue;
                r.object = k;
                r.group = o.mesh->triangleGroup[t];
                r.twoSided = o.mesh->groups[r.group].twoSided();
                r.mirrored = o.flipsWinding;
                r.terrain = o.kind == ChunkObject::Kind::Terrain;
                receivers.push_back(r);
            }
        }
        // The world grid serves point and spot lights with a filter radius; the others query
        // a hierarchy of their own (built below).
        bool anyLocal = false;
        for (int l = 0; l < cv.lightCount; ++l)
            anyLocal |= lightNeeded[size_t(l)] && window.lsLights[size_t(l)].type != LightType::Directional &&
                        window.lsLights[size_t(l)].filterRadius > 0;
        std::optional<ReceiverGrid> grid;
        if (anyLocal) grid.emplace(limits, std::max(window.chunkSize / 16.0, 1.0), receivers);
        // Per thread: which receivers a query has already returned (reused across tasks).
        struct Stamps {
            std::vector<uint32_t> stamp;
            uint32_t mark = 0;
        };
        tbb::enumerable_thread_specific<Stamps> stamps;

        std::vector<LightGeometry> lightGeom(size_t(cv.lightCount));
        std::vector<std::unique_ptr<ReceiverRules>> rules(size_t(cv.lightCount));
        std::vector<std::unique_ptr<LightSpaceGrid>> lightGrids(size_t(cv.lightCount));  // directional lights
        std::vector<std::unique_ptr<DirectionGrid>> directionGrids(size_t(cv.lightCount));  // point, spot (no filter)
        for (int l = 0; l < cv.lightCount; ++l) {
            const Light& L = window.lsLights[size_t(l)];
            lightGeom[size_t(l)] = LightGeometry{L.type == LightType::Directional, L.direction, L.position};
            if (!lightNeeded[size_t(l)]) continue;
            rules[size_t(l)] = std::make_unique<ReceiverRules>(window, receivers, L, lightGeom[size_t(l)], margin);
            if (L.type == LightType::Directional) lightGrids[size_t(l)] = std::make_unique<LightSpaceGrid>(receivers, L.direction, margin);
            else if (!(L.filterRadius > 0)) directionGrids[size_t(l)] = std::make_unique<DirectionGrid>(receivers, L.position, margin);
        }

        std::atomic<uint64_t> tests{0}, culled{0}, examined{0};
        std::atomic<bool> contradiction{false};
        std::string contradictionAt;
        tbb::parallel_for(size_t(0), tasks.size(), [&](size_t ti) {
            // Exact predicates: CGAL's interval filters need gradual underflow, whatever
            // mode an earlier stage's tasks left TBB in (core/float_mode.h).
            const FloatModeScope ieee(FloatModeScope::Underflow::Gradual);
            const Task& task = tasks[ti];
            const ObjectVerdicts& ov = cv.objects[task.object];
            const WindowObject& wo = window.objects[size_t(ov.windowObject)];
            const std::vector<Triangle>& casters = tasksCasters[ti];
            Stamps& st = stamps.local();
            if (st.stamp.size() != receivers.size() || st.mark > 0xfffff000u) {
                st.stamp.assign(receivers.size(), 0);
                st.mark = 0;
            }
            uint64_t localTests = 0;
            for (int l = 0; l < cv.lightCount; ++l) {
                Decision& d = cv.at(task.object, task.group, l);
                if (!wanted(d)) continue;
                ++examined;
                const Light& L = window.lsLights[size_t(l)];
                const ReceiverRules& lb = *rules[size_t(l)];
                bool candidate = false;
                Aabb volume;
                const LightSpaceGrid* lightGrid = lightGrids[size_t(l)].get();
                const DirectionGrid* directionGrid = directionGrids[size_t(l)].get();
                for (const Triangle& t : casters) {
                    // Built on the first receiver that passes the broad phase and the rules:
                    // most caster triangles of a dense mesh never need one.
                    std::optional<ExactFrustum> frustum;
                    const FrustumFilter filter(t, lightGeom[size_t(l)], L.filterRadius);
                    auto test = [&](uint32_t k) {
                        const double beta = lb.beta(k);
                        if (beta < 0) return false;
                        const Receiver& r = receivers[k];
                        if (!exhaustive && filter.certainlyMisses(r.tri, beta)) return false;
                        ++localTests;
                        if (!frustum) frustum.emplace(t, lightGeom[size_t(l)], L.filterRadius);
                        std::array<glm::dvec3, 2> part;
                        if (!frustum->reaches(r.tri, beta, &part)) return false;
                        // The terrain rule on the part of the receiver the shadow reaches: a
                        // rock half in the ground receives only with its part above ground.
                        candidate = !(window.hasTerrain && !r.terrain && underTerrain(window, part, margin));
                        return candidate;
                    };
                    const Aabb fb = frustumBox(t, L, limits, margin);
                    volume.extend(fb);
                    if (exhaustive) {
                        for (uint32_t k = 0; k < receivers.size(); ++k)
                            if (test(k)) break;
                    } else if (directionGrid) {
                        directionGrid->forEachOverlapping(directionGrid->cap(t), directionGrid->nearest(t), test);
                    } else if (lightGrid)
                        lightGrid->forEachOverlapping(lightGrid->project(t, L.filterRadius),
                                                      lightGrid->shallowest(t) - L.filterRadius, test);
                    else
                        grid->forEachOverlapping(fb, st.stamp, ++st.mark, test);
                    if (candidate) break;
                }
                if (candidate) continue;
                if (d.verdict == Verdict::Kept) {  // cross-check mode: a proof against a witness
                    if (!contradiction.exchange(true))
                        contradictionAt = wo.label + " group " + std::to_string(task.group) + " light " + std::to_string(l + 1);
                    continue;
                }
                decide(d, Verdict::Culled, "geometry",
                       "no receiver in the shadow volume (" + std::to_string(casters.size()) +
                           " caster triangles; volume within " + worldBox(volume, window.wsOrigin) + ")");
                ++culled;
            }
            tests += localTests;
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
