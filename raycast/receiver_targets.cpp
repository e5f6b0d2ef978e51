// Receiver-side targets: see receiver_targets.h. Everything here is in double and only
// chooses where to aim; the witness test decides (nothing here can make a verdict).

#include "raycast/receiver_targets.h"

#include "core/light_reach.h"
#include "core/mesh_index.h"
#include "util/float_mode.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <tbb/parallel_for.h>

namespace shadowcull::raycast {

namespace {

// The radical inverse in a small prime base (the second and third coordinates of a
// target, so that they are not correlated with the first, radicalInverse2). The base a
// constant: its divisions become multiplications (most of a rejected draw's cost).
template <uint32_t Base>
double radicalInverse(uint32_t i) {
    const double inv = 1.0 / Base;
    double f = inv, r = 0.0;
    while (i > 0) {
        r += f * double(i % Base);
        i /= Base;
        f *= inv;
    }
    return r;
}

// radicalInverse2(i) shifted by `offset` (in [0, 1)) and wrapped into [0, 1): as
// std::fmod(x, 1.0), exactly (x < 2, and x - 1 is exact for x in [1, 2)).
double shiftedRadicalInverse2(uint32_t i, double offset) {
    const double x = radicalInverse2(i) + offset;
    return x < 1.0 ? x : x - 1.0;
}

// The light's rays as a 2D projection and a depth along them: orthographic along the
// direction for a directional light; for point and spot lights a central projection onto
// the plane at unit distance along the axis towards the caster (points at or behind the
// plane through the light have no projection).
struct LightFrame {
    bool directional = true;
    glm::dvec3 position{0.0}, axis{0.0, -1.0, 0.0}, u{1.0, 0.0, 0.0}, v{0.0, 0.0, 1.0};

    LightFrame(const Light& L, const glm::dvec3& towards) {
        directional = L.type == LightType::Directional;
        position = L.position;
        axis = directional ? L.direction : towards - L.position;
        const double len = glm::length(axis);
        axis = len > 0 ? axis / len : glm::dvec3(0.0, -1.0, 0.0);
        u = glm::normalize(std::abs(axis.y) < 0.9 ? glm::cross(axis, glm::dvec3(0, 1, 0)) : glm::cross(axis, glm::dvec3(1, 0, 0)));
        v = glm::cross(axis, u);
    }

    // The projection of x (nothing for a point light when x is not well in front of it:
    // within 5 degrees of the plane through the light, where the projection blows up).
    std::optional<glm::dvec2> project(const glm::dvec3& x) const {
        if (directional) return glm::dvec2(glm::dot(u, x), glm::dot(v, x));
        const glm::dvec3 w = x - position;
        const double c = glm::dot(axis, w);
        if (!(c > 0.087 * glm::length(w))) return std::nullopt;
        return glm::dvec2(glm::dot(u, w) / c, glm::dot(v, w) / c);
    }
    double depth(const glm::dvec3& x) const { return directional ? glm::dot(axis, x) : glm::length(x - position); }
    // The direction light travels at x (unit).
    glm::dvec3 rayAt(const glm::dvec3& x) const {
        if (directional) return axis;
        const glm::dvec3 w = x - position;
        const double len = glm::length(w);
        return len > 0 ? w / len : axis;
    }
};

// A 2D box; `all` when it holds every projection (a caster around or beside a point light).
struct Footprint {
    bool all = false;
    glm::dvec2 min{std::numeric_limits<double>::infinity()}, max{-std::numeric_limits<double>::infinity()};
    void extend(const glm::dvec2& p) {
        min = glm::min(min, p);
        max = glm::max(max, p);
    }
    bool holds(const glm::dvec2& p) const { return all || (p.x >= min.x && p.x <= max.x && p.y >= min.y && p.y <= max.y); }
    bool meets(const Footprint& b) const {
        return all || b.all || !(b.max.x < min.x || b.min.x > max.x || b.max.y < min.y || b.min.y > max.y);
    }
};

// The footprint of points (`all` when one has no projection).
template <class Points>
Footprint footprintOf(const LightFrame& f, const Points& points, double grow) {
    Footprint fp;
    for (const glm::dvec3& p : points) {
        const std::optional<glm::dvec2> q = f.project(p);
        if (!q) {
            fp.all = true;
            return fp;
        }
        fp.extend(*q);
    }
    fp.min -= glm::dvec2(grow);
    fp.max += glm::dvec2(grow);
    return fp;
}

// A segment of the terrain band on a receiver that crosses the ground.
struct BandSegment {
    glm::dvec3 a, b;
};

}  // namespace

bool isLargeCaster(const WindowObject& o, uint32_t group, int areaSamples, double minSpacing) {
    if (o.kind == ChunkObject::Kind::Terrain) return true;
    const Mesh& m = *o.mesh;
    auto large = [&](double area) { return std::sqrt(area / double(std::max(1, areaSamples))) >= minSpacing; };
    // The placed area from the mesh's (kept with its index) and bounds on the transform's
    // scale of areas, where those decide as the loop below would: the 1e-9 covers both sums'
    // rounding. Otherwise (a shear or a non-uniform scale near the limit) the loop.
    const MeshVertexIndex& index = vertexIndex(m);
    if (group < index.groupArea.size()) {
        const auto [scaleLo, scaleHi] = areaScaleBounds(o.lsTransform);
        const double msArea = index.groupArea[group];
        if (large(msArea * scaleLo * (1 - 1e-9))) return true;
        if (!large(msArea * scaleHi * (1 + 1e-9))) return false;
    }
    double area = 0.0;
    for (size_t t = 0; t < m.triangles.size(); ++t) {
        if (m.triangleGroup[t] != group) continue;
        const auto [a, b, c] = o.lsTriangle(t);
        area += 0.5 * glm::length(glm::cross(b - a, c - a));
    }
    return large(area);
}

namespace {

// The caster group's footprint, grown by `grow`, and the depth of its nearest point.
struct CasterExtent {
    Footprint fp;
    double nearest = std::numeric_limits<double>::infinity();
};

// A directional light's footprint and depths are linear in the placed point, so the mesh's
// vertex tree gives their extremes exactly (core/mesh_index.h) at the cost of a few leaves:
// the same values as a loop over every triangle corner.
CasterExtent directionalExtent(const WindowObject& caster, const VertexTree& groupVertices, const LightFrame& frame,
                               double grow) {
    const Mesh& cm = *caster.mesh;
    CasterExtent e;
    // The extremes of dot(d, placed p) over the group's vertices, as the loop computes
    // them (a zero extreme's sign is irrelevant: the footprint is grown by a nonzero
    // margin, and the depth is only compared).
    auto extreme = [&](const glm::dvec3& d) {
        return groupVertices.maximum(
            [&](const glm::dvec3& lo, const glm::dvec3& hi) { return placedDotUpper(caster.lsTransform, d, lo, hi); },
            [&](uint32_t v) { return glm::dot(d, caster.lsTransform.apply(cm.positions[v])); });
    };
    // glm::dot(-u, x) is -glm::dot(u, x) exactly (every product changes sign).
    e.fp.max = glm::dvec2(extreme(frame.u), extreme(frame.v));
    e.fp.min = -glm::dvec2(extreme(-frame.u), extreme(-frame.v));
    e.fp.min -= glm::dvec2(grow);
    e.fp.max += glm::dvec2(grow);
    e.nearest = -extreme(-frame.axis);
    return e;
}

// A point light's projection is not linear: the group's vertices are mapped once each (not
// once per corner), and its edges measured once each from those. The nearest depth is
// conservative: a face may come closer than its vertices, by at most its longest edge.
CasterExtent pointExtent(const WindowObject& caster, uint32_t group, const VertexTree& groupVertices,
                         const LightFrame& frame, double grow) {
    const Mesh& cm = *caster.mesh;
    CasterExtent e;
    thread_local std::vector<glm::dvec3> placed;
    placed.resize(cm.positions.size());
    for (uint32_t v : groupVertices.items()) {
        placed[v] = caster.lsTransform.apply(cm.positions[v]);
        e.nearest = std::min(e.nearest, frame.depth(placed[v]));
    }
    // footprintOf over the group's placed vertices (each once).
    for (uint32_t v : groupVertices.items()) {
        const std::optional<glm::dvec2> q = frame.project(placed[v]);
        if (!q) {
            e.fp.all = true;
            break;
        }
        e.fp.extend(*q);
    }
    e.fp.min -= glm::dvec2(grow);
    e.fp.max += glm::dvec2(grow);
    double longestEdge = 0.0;
    for (size_t t = 0; t < cm.triangles.size(); ++t) {
        if (cm.triangleGroup[t] != group) continue;
        const auto& i = cm.triangles[t];
        longestEdge = std::max({longestEdge, glm::length(placed[i[2]] - placed[i[1]]), glm::length(placed[i[1]] - placed[i[0]]),
                                glm::length(placed[i[0]] - placed[i[2]])});
    }
    e.nearest = std::max(0.0, e.nearest - longestEdge);
    return e;
}

// Where a target may lie for one caster group and light: in the caster's footprint, deeper
// than its nearest point plus the bias, within the light's reach and not under the ground.
struct Aim {
    const BakeWindow& w;
    const Light& L;
    const LightFrame& frame;
    const Footprint& fp;
    double deeper;  // a receiver point shallower than this cannot be q
    bool local;     // a point or spot light
    double tol;     // metres: the terrain tolerance
};

// A receiver sampled by area: a terrain by its triangles in the footprint, a model by its
// groups' own sample points.
struct Source {
    uint32_t object;
    bool terrain;
    std::vector<std::array<glm::dvec3, 3>> tris;  // terrain: its triangles that may hold q
    std::vector<double> cumulative;               // terrain: by projected area
    uint32_t next = 0;                            // targets taken so far
    std::vector<const std::vector<glm::dvec3>*> groupPoints;  // model: each group's points, once asked
};

// The receivers found so far, each with a weight, and the band's segments with theirs.
struct Receivers {
    std::vector<Source>& sources;
    std::vector<double>& weights;
    std::vector<BandSegment>& band;
    std::vector<double>& bandWeights;
};

// A terrain's triangles that may hold q, by projected area: the light must meet their front
// (terrain is one-sided). Weighted by the square root of that area.
void addTerrain(const Aim& aim, uint32_t k, Receivers& r) {
    const WindowObject& o = aim.w.objects[k];
    const Mesh& m = *o.mesh;
    Source src{k, true, {}, {}, 0, {}};
    double area = 0.0;
    for (size_t t = 0; t < m.triangles.size(); ++t) {
        const std::array<glm::dvec3, 3> tri = o.lsTriangle(t);
        if (!(std::max({aim.frame.depth(tri[0]), aim.frame.depth(tri[1]), aim.frame.depth(tri[2])}) > aim.deeper)) continue;
        if (aim.local) {
            Aabb tb;
            for (const glm::dvec3& c : tri) tb.extend(c);
            if (boxOutOfReach(aim.L, tb)) continue;
        }
        if (!aim.fp.meets(footprintOf(aim.frame, tri, 0.0))) continue;
        const glm::dvec3 n = glm::cross(tri[1] - tri[0], tri[2] - tri[0]) * (o.flipsWinding ? -1.0 : 1.0);
        const double a2 = glm::length(n);
        if (!(a2 > 0)) continue;
        const double facing = glm::dot(n / a2, aim.frame.rayAt((tri[0] + tri[1] + tri[2]) / 3.0));
        if (!(facing < 0)) continue;
        area += 0.5 * a2 * -facing;
        src.tris.push_back(tri);
        src.cumulative.push_back(area);
    }
    if (area > 0) {
        r.sources.push_back(std::move(src));
        r.weights.push_back(std::sqrt(area));
    }
}

// Whether the band under `ground` can hold a witness: the light's ray, entering a ground
// plane at angle a, is d / sin(a) past p at depth d, so a point of the band (d <= tol) can
// be more than the bias behind p only where sin(a) < tol / bias (twice that here: the
// ground is planar only per cell).
bool grazesGround(const Aim& aim, const std::vector<std::array<glm::dvec3, 3>>& ground) {
    if (aim.L.bias <= 0) return true;
    for (const auto& g : ground) {
        glm::dvec3 n = glm::cross(g[1] - g[0], g[2] - g[0]);
        const double len = glm::length(n);
        if (!(len > 0)) continue;
        n /= len;
        const glm::dvec3 r = aim.frame.rayAt(g[0]);
        if (std::abs(glm::dot(r, n)) < 2 * aim.tol * std::abs(n.y) / aim.L.bias) return true;
    }
    return false;
}

// The model's triangles whose placed heights can meet [bottom, highest] (conservative node
// bounds, core/mesh_index.h), in triangle order: a triangle with every vertex above the highest ground,
// or every vertex under the lowest ground less the level, holds no band.
void crossingTriangles(const Aim& aim, const WindowObject& o, double bottom, double highest, double level,
                       std::vector<uint32_t>& crossing) {
    crossing.clear();
    thread_local std::vector<uint64_t> marked;  // bit t: triangle t may cross
    const size_t words = (o.mesh->triangles.size() + 63) / 64;
    marked.assign(words, 0);
    vertexIndex(*o.mesh).triangles.visit(
        [&](const glm::dvec3& lo, const glm::dvec3& hi) {
            // The node's placed box (conservative: core/mesh_index.h).
            glm::dvec3 pLo, pHi;
            for (int a = 0; a < 3; ++a) {
                pHi[a] = placedCoordinateUpper(o.lsTransform, a, 1.0, lo, hi);
                pLo[a] = -placedCoordinateUpper(o.lsTransform, a, -1.0, lo, hi);
            }
            if (pHi.y < bottom || pLo.y > highest) return false;  // every vertex on one side
            if (aim.local && boxOutOfReach(aim.L, Aabb{pLo, pHi})) return false;
            if (pHi.y - pLo.y > 0.25 * (highest - bottom)) return true;  // large: its children will tell
            // The ground under the node alone: its vertices are all above it (no
            // terrain counts as above), or all under it less the level. Margins: the
            // ground's values and a vertex's height over it are rounded (~1e-15).
            // The rectangle grown by a micrometre per 64 m chunk: a vertex on a chunk's
            // edge is under both chunks' terrains (lsTerrainHeight takes the lower).
            const double margin = 1e-9 * (1.0 + std::abs(pLo.y) + std::abs(pHi.y));
            const double grown = 1e-8 * aim.w.chunkSize;
            pLo -= glm::dvec3(grown);
            pHi += glm::dvec3(grown);
            const std::optional<double> under = aim.w.lsTerrainMinOver(pLo.x, pLo.z, pHi.x, pHi.z);
            if (under && pHi.y < *under - level - margin) return false;
            const std::optional<double> over = aim.w.lsTerrainMaxOver(pLo.x, pLo.z, pHi.x, pHi.z);
            return !(over && pLo.y > *over + margin);
        },
        [&](uint32_t t) { marked[t >> 6] |= uint64_t(1) << (t & 63); });
    // In triangle order: the marks word by word (a sort of the leaves' triangles was a
    // quarter of the band's time).
    for (size_t word = 0; word < words; ++word)
        for (uint64_t bits = marked[word]; bits; bits &= bits - 1)
            crossing.push_back(uint32_t(64 * word + size_t(__builtin_ctzll(bits))));
}

// The band's segments on model `o`, where its triangles cross the level 3/4 of the
// tolerance under the ground (`low`: the lowest ground under its box). Each vertex is above
// or under the level by the ground's range under the box where that settles it (most of a
// rock's vertices), else by the ground under the vertex, looked up once. The triangles come
// from crossingTriangles in triangle order, as a loop over every triangle would take them:
// the same segments, in the same order, at the cost of the triangles near the ground.
void addBand(const Aim& aim, const WindowObject& o, double low, const std::vector<std::array<glm::dvec3, 3>>& ground,
             Receivers& r) {
    const Mesh& m = *o.mesh;
    const BakeWindow& w = aim.w;
    double highest = low;
    for (const auto& g : ground) highest = std::max({highest, g[0].y, g[1].y, g[2].y});
    const double level = 0.75 * aim.tol;
    const double bottom = low - level;
    thread_local std::vector<uint32_t> crossing;
    crossingTriangles(aim, o, bottom, highest, level, crossing);
    // Per vertex, computed on first use (stamp == pass): placed, side, height over the level.
    thread_local std::vector<glm::dvec3> placedVertices;
    thread_local std::vector<double> aboveLevel;
    thread_local std::vector<signed char> vertexSide;
    thread_local std::vector<uint32_t> stamp;
    thread_local uint32_t pass = 0;
    if (stamp.size() < m.positions.size()) stamp.resize(m.positions.size(), 0);
    if (++pass == 0) std::fill(stamp.begin(), stamp.end(), 0), pass = 1;
    placedVertices.resize(std::max(placedVertices.size(), m.positions.size()));
    aboveLevel.resize(std::max(aboveLevel.size(), m.positions.size()));
    vertexSide.resize(std::max(vertexSide.size(), m.positions.size()));
    auto lookUp = [&](size_t v) {
        if (std::isnan(aboveLevel[v])) {
            const std::optional<double> g = w.lsTerrainHeight(placedVertices[v].x, placedVertices[v].z);
            aboveLevel[v] = g ? placedVertices[v].y - (*g - level) : std::numeric_limits<double>::infinity();
        }
        return aboveLevel[v];
    };
    auto place = [&](uint32_t v) {
        if (stamp[v] == pass) return;
        stamp[v] = pass;
        placedVertices[v] = o.lsTransform.apply(m.positions[v]);
        aboveLevel[v] = std::numeric_limits<double>::quiet_NaN();
        const double y = placedVertices[v].y;
        vertexSide[v] = y > highest ? 1 : y < bottom ? -1 : lookUp(v) >= 0 ? 1 : -1;
    };
    const std::vector<signed char>& side = vertexSide;
    const size_t firstBand = r.bandWeights.size();
    double length = 0.0;
    for (uint32_t t : crossing) {
        const auto& i = m.triangles[t];
        for (uint32_t v : i) place(v);
        if (side[i[0]] == side[i[1]] && side[i[1]] == side[i[2]]) continue;
        std::array<glm::dvec3, 3> tri = {placedVertices[i[0]], placedVertices[i[1]], placedVertices[i[2]]};
        const std::array<double, 3> f = {lookUp(i[0]), lookUp(i[1]), lookUp(i[2])};
        if (!std::isfinite(f[0] + f[1] + f[2])) continue;
        glm::dvec3 n = glm::cross(tri[1] - tri[0], tri[2] - tri[0]) * (o.flipsWinding ? -1.0 : 1.0);
        const double a2 = glm::length(n);
        if (!(a2 > 0)) continue;
        const double facing = glm::dot(n / a2, aim.frame.rayAt(tri[0]));
        if (!m.groups[m.triangleGroup[t]].twoSided() && !(facing < 0)) continue;
        glm::dvec3 cross[3];
        size_t crossings = 0;
        for (size_t c = 0; c < 3; ++c) {
            const size_t d = (c + 1) % 3;
            if ((f[c] >= 0) != (f[d] >= 0)) cross[crossings++] = tri[c] + (tri[d] - tri[c]) * (f[c] / (f[c] - f[d]));
        }
        if (crossings != 2) continue;
        const double l = glm::length(cross[1] - cross[0]) * std::abs(facing) + 1e-12;
        r.band.push_back({cross[0], cross[1]});
        r.bandWeights.push_back(l);
        length += l;
    }
    // Across objects by the square root of the band's (projected) length, as for areas.
    for (size_t b = firstBand; b < r.bandWeights.size(); ++b) r.bandWeights[b] /= std::sqrt(length);
}

// A model receiver (footprint `ofp`), weighted by the square root of its bounds' projected
// area, unless the terrain rule puts it wholly deeper than the tolerance under the ground;
// then its band where the light grazes the ground under it.
void addModel(const Aim& aim, uint32_t k, const Footprint& ofp, Receivers& r) {
    const WindowObject& o = aim.w.objects[k];
    const bool ruled = aim.w.hasTerrain;
    std::optional<double> low;  // the lowest ground under the model's box
    if (ruled) {
        low = aim.w.lsTerrainMinOver(o.lsBounds.min.x, o.lsBounds.min.z, o.lsBounds.max.x, o.lsBounds.max.z);
        if (low && o.lsBounds.max.y < *low - aim.tol) return;
    }
    const double projected = ofp.all ? 1.0 : (ofp.max.x - ofp.min.x) * (ofp.max.y - ofp.min.y);
    r.sources.push_back({k, false, {}, {}, 0, {}});
    r.weights.push_back(std::sqrt(std::max(projected, 0.0)) + 1e-12);
    if (!ruled) return;
    thread_local std::vector<std::array<glm::dvec3, 3>> ground;
    ground.clear();
    if (!aim.w.lsTerrainTrianglesOver(o.lsBounds.min.x, o.lsBounds.min.z, o.lsBounds.max.x, o.lsBounds.max.z, ground)) return;
    if (!grazesGround(aim, ground) || !low) return;
    addBand(aim, o, *low, ground, r);
}

// The receivers among objects [begin, end) that may hold q, in object order. A point or
// spot light's q lies within its reach (semantics.md): receivers, terrain triangles and band
// nodes wholly beyond it get no target.
void findReceiversIn(const Aim& aim, uint32_t begin, uint32_t end, Receivers& r) {
    for (uint32_t k = begin; k < end; ++k) {
        const WindowObject& o = aim.w.objects[k];
        if (boxOutOfReach(aim.L, o.lsBounds)) continue;
        const auto oc = o.lsBounds.corners();
        double oDeep = -std::numeric_limits<double>::infinity();
        for (const glm::dvec3& p : oc) oDeep = std::max(oDeep, aim.frame.depth(p));
        if (!(oDeep > aim.deeper)) continue;
        const Footprint ofp = footprintOf(aim.frame, oc, 0.0);
        if (!aim.fp.meets(ofp)) continue;
        if (o.kind == ChunkObject::Kind::Terrain)
            addTerrain(aim, k, r);
        else
            addModel(aim, k, ofp, r);
    }
}

// Every receiver of the window that may hold q, in object order: blocks of objects in
// parallel (a terrain's receivers are hundreds of models near the ground, each with its
// band: most of a receiver-side search's time, and a window has only a few such searches),
// joined in block order, so the same list on any number of threads.
void findReceivers(const Aim& aim, Receivers& r) {
    constexpr uint32_t kBlock = 32;
    const uint32_t n = uint32_t(aim.w.objects.size());
    const uint32_t blocks = (n + kBlock - 1) / kBlock;
    struct Part {
        std::vector<Source> sources;
        std::vector<double> weights, bandWeights;
        std::vector<BandSegment> band;
    };
    std::vector<Part> parts(blocks);
    // Every block in the calling thread's floating-point mode (the stage's tasks flush
    // denormals to zero; another thread running a block may be in another mode).
    const FloatModeScope::Underflow callers = FloatModeScope::current();
    tbb::parallel_for(uint32_t(0), blocks, [&](uint32_t b) {
        const FloatModeScope mode(callers);
        Part& part = parts[b];
        Receivers pr{part.sources, part.weights, part.band, part.bandWeights};
        findReceiversIn(aim, b * kBlock, std::min(n, (b + 1) * kBlock), pr);
    });
    for (Part& part : parts) {
        for (Source& src : part.sources) r.sources.push_back(std::move(src));
        r.weights.insert(r.weights.end(), part.weights.begin(), part.weights.end());
        r.band.insert(r.band.end(), part.band.begin(), part.band.end());
        r.bandWeights.insert(r.bandWeights.end(), part.bandWeights.begin(), part.bandWeights.end());
    }
}

// The index a fraction x of the way through a cumulative weight list.
size_t pick(const std::vector<double>& cum, double x) {
    return std::min(size_t(std::upper_bound(cum.begin(), cum.end(), x * cum.back()) - cum.begin()), cum.size() - 1);
}

// Up to `budget` targets drawn from the receivers by low-discrepancy sequences: every other
// one on the band when there is one; at most four tries per target. A draw outside the
// footprint, not deeper than the caster, or under the ground is dropped.
std::vector<glm::dvec3> drawTargets(const Aim& aim, Receivers& r, int budget, GroupSampleCache& samples) {
    const BakeWindow& w = aim.w;
    std::vector<double> cumulative(r.weights.size()), bandCumulative(r.bandWeights.size());
    double total = 0.0, bandTotal = 0.0;
    for (size_t k = 0; k < r.weights.size(); ++k) cumulative[k] = total += r.weights[k];
    for (size_t k = 0; k < r.bandWeights.size(); ++k) bandCumulative[k] = bandTotal += r.bandWeights[k];

    std::vector<glm::dvec3> out;
    out.reserve(size_t(budget));
    uint32_t areaIndex = 0, bandIndex = 0;
    const double offset = 0.5 / budget;
    for (uint32_t attempt = 0; out.size() < size_t(budget) && attempt < 4u * uint32_t(budget); ++attempt) {
        glm::dvec3 p;
        bool onTerrain = false;
        if (!r.band.empty() && attempt % 2 == 1) {
            const uint32_t s = bandIndex++;
            const BandSegment& seg = r.band[pick(bandCumulative, shiftedRadicalInverse2(s, offset))];
            p = seg.a + (seg.b - seg.a) * radicalInverse<3>(s);
        } else {
            Source& src = r.sources[pick(cumulative, shiftedRadicalInverse2(areaIndex++, offset))];
            const uint32_t s = src.next++;
            const WindowObject& o = w.objects[src.object];
            if (src.terrain) {
                const auto& t = src.tris[pick(src.cumulative, shiftedRadicalInverse2(s, offset))];
                double a = radicalInverse<3>(s), b = radicalInverse<5>(s);
                if (a + b > 1) {
                    a = 1 - a;
                    b = 1 - b;
                }
                p = t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b;
                onTerrain = true;
            } else {
                // The model's groups in turn, each by its own spread points (asked of the
                // shared cache once per group: it takes a lock).
                const uint32_t groups = uint32_t(std::max<size_t>(1, o.mesh->groups.size()));
                if (src.groupPoints.empty()) src.groupPoints.assign(groups, nullptr);
                const std::vector<glm::dvec3>*& known = src.groupPoints[s % groups];
                if (!known) known = &samples.meshPoints(*o.mesh, s % groups);
                const std::vector<glm::dvec3>& pts = *known;
                if (pts.empty()) continue;
                p = o.lsTransform.apply(pts[(s / groups) % pts.size()]);
            }
        }
        const std::optional<glm::dvec2> q = aim.frame.project(p);
        if ((!q && !aim.fp.all) || (q && !aim.fp.holds(*q)) || !(aim.frame.depth(p) > aim.deeper)) continue;
        if (w.hasTerrain && !onTerrain) {
            const std::optional<double> g = w.lsTerrainHeight(p.x, p.z);
            if (g && p.y < *g - aim.tol) continue;
        }
        out.push_back(p);
    }
    return out;
}

}  // namespace

std::vector<glm::dvec3> receiverTargets(const BakeWindow& w, uint32_t object, uint32_t group, const Light& L, int budget,
                                        GroupSampleCache& samples) {
    if (budget <= 0) return {};
    const WindowObject& caster = w.objects[object];
    // The caster group's placed vertices: its box, footprint and nearest depth, computed as
    // over every triangle corner but per unique mesh where the light allows.
    const Aabb cbox = lsGroupBounds(caster, group, false);
    if (cbox.empty()) return {};
    const LightFrame frame(L, 0.5 * (cbox.min + cbox.max));
    // Margins (projection units: metres, or metres per metre of depth for point lights):
    // the footprint only steers the targets, so a small relative margin is enough.
    const double grow = frame.directional ? 1e-6 * (glm::length(cbox.max - cbox.min) + 1.0) : 1e-6;
    const VertexTree& groupVertices = *vertexIndex(*caster.mesh).group[group];
    const CasterExtent extent = frame.directional ? directionalExtent(caster, groupVertices, frame, grow)
                                                  : pointExtent(caster, group, groupVertices, frame, grow);
    const Aim aim{w, L, frame, extent.fp, extent.nearest + L.bias, L.type != LightType::Directional, w.terrainTolerance};

    // The receivers, each with a weight: the square root of its projected area (of its
    // bounds for a model), so that a 1 m rock beside a 64 m terrain chunk still gets a few
    // targets (its share by area alone would be a few in a thousand). Terrains are sampled
    // by their triangles in the footprint, models by their groups' own sample points (a
    // spread prefix, group_samples.h; no per-triangle work for the thousands of rocks a
    // terrain's shadow column holds), the band by segments where a model crosses the level
    // 3/4 of the tolerance under the ground.
    // Not scratch kept by the thread: while findReceivers waits for its blocks, this thread
    // may run another search's blocks, or another search.
    std::vector<Source> sources;
    std::vector<double> weights, bandWeights;
    std::vector<BandSegment> band;
    Receivers receivers{sources, weights, band, bandWeights};
    findReceivers(aim, receivers);
    if (sources.empty()) return {};
    return drawTargets(aim, receivers, budget, samples);
}

}  // namespace shadowcull::raycast
