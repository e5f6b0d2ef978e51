// The chunks a bake window holds (core/window_plan.h).

#include "core/window_plan.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "core/light_reach.h"

namespace shadowcull {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The margin (metres) by which a box is widened before a column test leaves it out: 1 mm
// plus 1e-9 of the largest coordinate, far above the rounding of the few subtractions and
// divisions of the slab test (a relative 1e-15 or so) and far below any size that matters,
// since a chunk loaded for nothing costs only time.
double marginFor(const Aabb& a, const Aabb& b) {
    const glm::dvec3 m = glm::max(glm::max(glm::abs(a.min), glm::abs(a.max)), glm::max(glm::abs(b.min), glm::abs(b.max)));
    return 1e-3 + 1e-9 * std::max({m.x, m.y, m.z});
}

Aabb grown(const Aabb& b, double by) { return Aabb{b.min - glm::dvec3(by), b.max + glm::dvec3(by)}; }

// The parameters [t0, t1] (t >= 0) for which t * dir lies in `box`; t0 > t1 when never.
std::pair<double, double> rayInterval(const Aabb& box, const glm::dvec3& dir) {
    double t0 = 0.0, t1 = kInf;
    for (int a = 0; a < 3; ++a) {
        if (dir[a] == 0.0) {
            if (box.min[a] > 0.0 || box.max[a] < 0.0) return {1.0, 0.0};
            continue;
        }
        double ta = box.min[a] / dir[a], tb = box.max[a] / dir[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return {t0, t1};
}

// The Minkowski difference target - source widened by `pad`: the translations t * dir that
// bring some point of `source` within `pad` of `target` are those that land in it.
Aabb difference(const Aabb& target, const Aabb& source, double pad) {
    return Aabb{target.min - source.max - glm::dvec3(pad), target.max - source.min + glm::dvec3(pad)};
}

// Whether `source` swept along `dir` (t >= 0) comes within `pad` of `target`.
bool sweepMeets(const Aabb& source, const glm::dvec3& dir, const Aabb& target, double pad) {
    const auto [t0, t1] = rayInterval(difference(target, source, pad), dir);
    return t0 <= t1;
}

bool insideRectangle(ChunkCoord c, ChunkCoord centre, const Neighbours& n) {
    return c.x >= centre.x - n.left && c.x <= centre.x + n.right && c.z >= centre.z - n.bottom && c.z <= centre.z + n.top;
}

int ringsOutside(ChunkCoord c, ChunkCoord centre, const Neighbours& n) {
    return std::max({0, c.x - (centre.x + n.right), (centre.x - n.left) - c.x, c.z - (centre.z + n.top), (centre.z - n.bottom) - c.z});
}

}  // namespace

SpaceBounds spaceBoundsOf(const SpaceSettings& settings, const std::map<ChunkCoord, ChunkEntry>& chunks) {
    const double S = settings.chunkSize;
    SpaceBounds b;
    for (const auto& [c, e] : chunks) {
        if (e.wsBounds.empty()) continue;
        b.wsSpace.extend(e.wsBounds);
        // How far the content leaves the chunk's square (objects may be placed past it).
        const double x0 = double(c.x) * S, z0 = double(c.z) * S;
        b.overhang = std::max({b.overhang, x0 - e.wsBounds.min.x, e.wsBounds.max.x - (x0 + S), z0 - e.wsBounds.min.z,
                               e.wsBounds.max.z - (z0 + S)});
    }
    return b;
}

WindowPlanner::WindowPlanner(const SpaceSettings& settings, const std::map<ChunkCoord, ChunkEntry>& chunks, bool wholeSpace)
    : WindowPlanner(settings, chunks, wholeSpace, spaceBoundsOf(settings, chunks)) {}

WindowPlanner::WindowPlanner(const SpaceSettings& settings, const std::map<ChunkCoord, ChunkEntry>& chunks, bool wholeSpace,
                             const SpaceBounds& bounds)
    : settings_(settings), chunks_(chunks), wholeSpace_(wholeSpace), wsSpace_(bounds.wsSpace), overhang_(bounds.overhang) {
    // The grid's extent only bounds the loops over squares (forChunksNear): the chunks held
    // are enough for it.
    bool first = true;
    for (const auto& [c, e] : chunks) {
        gx0_ = first ? c.x : std::min(gx0_, c.x), gx1_ = first ? c.x : std::max(gx1_, c.x);
        gz0_ = first ? c.z : std::min(gz0_, c.z), gz1_ = first ? c.z : std::max(gz1_, c.z);
        first = false;
    }
}

template <class Visit>
void WindowPlanner::forChunksNear(const Aabb& wsQuery, const Visit& visit) const {
    const double S = settings_.chunkSize, reach = overhang_ + 1e-3;
    // Chunk coordinates of the squares the query (widened by the overhang) meets, clipped to
    // the grid; clamped in double first, since a horizontal light's column is unbounded.
    auto cell = [&](double v, int lo, int hi) { return int(std::clamp(std::floor(v / S), double(lo) - 1, double(hi) + 1)); };
    const int x0 = std::max(gx0_, cell(wsQuery.min.x - reach, gx0_, gx1_)), x1 = std::min(gx1_, cell(wsQuery.max.x + reach, gx0_, gx1_));
    const int z0 = std::max(gz0_, cell(wsQuery.min.z - reach, gz0_, gz1_)), z1 = std::min(gz1_, cell(wsQuery.max.z + reach, gz0_, gz1_));
    if (x0 > x1 || z0 > z1) return;
    const double squares = double(x1 - x0 + 1) * double(z1 - z0 + 1);
    if (squares > double(chunks_.size())) {
        for (const auto& [c, e] : chunks_)
            if (c.x >= x0 && c.x <= x1 && c.z >= z0 && c.z <= z1) visit(c, e);
        return;
    }
    for (int x = x0; x <= x1; ++x)
        for (auto it = chunks_.lower_bound({x, z0}); it != chunks_.end() && it->first.x == x && it->first.z <= z1; ++it)
            visit(it->first, it->second);
}

void WindowPlanner::addDirectional(const Light& L, const Aabb& wsCentre, const glm::dvec3& towards,
                                   std::vector<ChunkCoord>& out) const {
    // Receivers: within filterRadius of a ray beyond p, and q' = q + b n within it too, so q
    // within r + b of the column. Occluders (towards the light): on the ray itself.
    const bool receivers = glm::dot(towards, L.direction) > 0;
    const double widen = (receivers ? L.filterRadius + L.normalBias : 0.0) + marginFor(wsCentre, wsSpace_);
    // How far the column runs before it has passed every box of the space.
    const auto [t0, t1] = rayInterval(difference(wsSpace_, wsCentre, widen), towards);
    if (t0 > t1) return;
    Aabb column = grown(wsCentre, widen);
    const double tEnd = std::isfinite(t1) ? t1 : 0.0;
    column.extend(grown(Aabb{wsCentre.min + tEnd * towards, wsCentre.max + tEnd * towards}, widen));
    if (!std::isfinite(t1)) column = grown(wsSpace_, widen);  // (no axis bounds it: cannot happen for a unit direction)
    forChunksNear(column, [&](ChunkCoord c, const ChunkEntry& e) {
        if (!e.wsBounds.empty() && sweepMeets(wsCentre, towards, e.wsBounds, widen)) out.push_back(c);
    });
}

void WindowPlanner::addLocal(const Light& L, std::vector<ChunkCoord>& out) const {
    const Aabb wsRange{L.position - glm::dvec3(L.range), L.position + glm::dvec3(L.range)};
    forChunksNear(wsRange, [&](ChunkCoord c, const ChunkEntry& e) {
        if (!e.wsBounds.empty() && !boxOutOfReach(L, grown(e.wsBounds, marginFor(e.wsBounds, wsRange)))) out.push_back(c);
    });
}

WindowPlan WindowPlanner::plan(ChunkCoord centre) const {
    const Neighbours& n = settings_.neighbours;
    WindowPlan plan;
    plan.lights.resize(settings_.lights.size());
    std::vector<ChunkCoord>& out = plan.chunks;
    if (!wholeSpace_) {
        for (int dx = -n.left; dx <= n.right; ++dx)
            for (int dz = -n.bottom; dz <= n.top; ++dz)
                if (chunks_.count({centre.x + dx, centre.z + dz})) out.push_back({centre.x + dx, centre.z + dz});
        return plan;
    }
    auto self = chunks_.find(centre);
    if (self == chunks_.end()) return plan;
    out.push_back(centre);
    if (self->second.wsBounds.empty()) return plan;
    const Aabb& wsCentre = self->second.wsBounds;
    for (size_t i = 0; i < settings_.lights.size(); ++i) {
        const Light& L = settings_.lights[i];
        std::vector<ChunkCoord> reached;
        if (L.type == LightType::Directional) {
            const glm::dvec3 d = glm::normalize(L.direction);
            addDirectional(L, wsCentre, d, reached);
            addDirectional(L, wsCentre, -d, reached);
        } else if (!boxOutOfReach(L, grown(wsCentre, marginFor(wsCentre, wsCentre)))) {
            addLocal(L, reached);  // (a light that cannot reach the chunk needs nothing: the reach stage culls it)
        }
        std::sort(reached.begin(), reached.end());
        reached.erase(std::unique(reached.begin(), reached.end()), reached.end());
        for (ChunkCoord c : reached) {
            out.push_back(c);
            if (insideRectangle(c, centre, n)) continue;
            ++plan.lights[i].chunksBeyond;
            plan.lights[i].beyond.push_back(c);
            plan.lights[i].ringsBeyond = std::max(plan.lights[i].ringsBeyond, ringsOutside(c, centre, n));
        }
    }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    for (ChunkCoord c : out) plan.chunksBeyond += insideRectangle(c, centre, n) ? 0 : 1;
    return plan;
}

}  // namespace shadowcull
