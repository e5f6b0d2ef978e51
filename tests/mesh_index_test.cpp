// The per-mesh vertex trees (core/mesh_index.h): the placed boxes and linear extremes they
// give are, bit for bit, what the loops over every vertex or triangle corner give, on
// turned, scaled, mirrored and far-off placements (100 km), dense jagged meshes included.

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include "core/mesh_index.h"
#include "core/window.h"

namespace shadowcull {
namespace {

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void expectSameBox(const Aabb& a, const Aabb& b, const std::string& what) {
    for (int k = 0; k < 3; ++k) {
        EXPECT_TRUE(sameBits(a.min[k], b.min[k])) << what << " min[" << k << "] " << a.min[k] << " vs " << b.min[k];
        EXPECT_TRUE(sameBits(a.max[k], b.max[k])) << what << " max[" << k << "] " << a.max[k] << " vs " << b.max[k];
    }
}

// A jagged sheet (a scanned surface: heights zigzag by 3 cm) of n x n cells, two groups
// (left and right half), a few triangles with a repeated vertex, and unused vertices far out.
Mesh jaggedSheet(int n, std::mt19937& rng) {
    Mesh m;
    std::uniform_real_distribution<double> jitter(-1e-3, 1e-3);
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i)
            m.positions.push_back({4.0 * i / n - 2.0 + jitter(rng), ((i + j) % 2 ? 0.03 : 0.0) + jitter(rng),
                                   4.0 * j / n - 2.0 + jitter(rng)});
    auto at = [&](int i, int j) { return uint32_t(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const uint32_t g = i < n / 2 ? 0 : 1;
            m.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i + 1, j)});
            m.triangles.push_back({at(i, j), at(i, j + 1), at(i + 1, j + 1)});
            m.triangleGroup.push_back(g);
            m.triangleGroup.push_back(g);
        }
    // Degenerate triangles reaching beyond the sheet: in the group's box, not in the box of
    // its triangles with area.
    m.positions.push_back({9.0, 5.0, -7.0});
    const uint32_t far = uint32_t(m.positions.size() - 1);
    m.triangles.push_back({far, far, at(0, 0)});
    m.triangleGroup.push_back(0);
    m.positions.push_back({-30.0, -30.0, 30.0});  // used by no triangle
    m.groups.resize(3);  // group 2 has no triangle
    return m;
}

RowTransform randomTransform(std::mt19937& rng, double offset) {
    std::uniform_real_distribution<double> angle(0.0, 6.283185307179586), scale(0.3, 3.0), unit(-1.0, 1.0);
    const double a = angle(rng), b = angle(rng);
    const glm::dvec3 s(scale(rng), scale(rng), scale(rng) * (unit(rng) < 0 ? -1.0 : 1.0));  // mirrored half the time
    RowTransform t;
    // A turn about y, then a tilt about x, scaled per axis.
    const glm::dvec3 r0(std::cos(a), 0.0, -std::sin(a)), r1(0.0, 1.0, 0.0), r2(std::sin(a), 0.0, std::cos(a));
    auto tilt = [&](const glm::dvec3& r) { return glm::dvec3(r.x, r.y * std::cos(b) - r.z * std::sin(b), r.y * std::sin(b) + r.z * std::cos(b)); };
    t.rows[0] = s.x * tilt(r0);
    t.rows[1] = s.y * tilt(r1);
    t.rows[2] = s.z * tilt(r2);
    t.rows[3] = glm::dvec3(offset + 50.0 * unit(rng), 20.0 * unit(rng), -offset + 50.0 * unit(rng));
    return t;
}

TEST(MeshIndex, PlacedBoxesAreTheLoopsBitForBit) {
    std::mt19937 rng(13);
    for (int n : {3, 40, 150}) {
        const Mesh mesh = jaggedSheet(n, rng);
        const MeshVertexIndex& index = vertexIndex(mesh);
        ASSERT_EQ(index.group.size(), 3u);
        EXPECT_EQ(index.groupTriangles[0], uint64_t(n * (n / 2) * 2 + 1));
        EXPECT_TRUE(index.group[2]->empty());
        for (double offset : {0.0, 1e3, 1e5}) {
            for (int rep = 0; rep < 20; ++rep) {
                WindowObject o;
                o.mesh = &mesh;
                o.lsTransform = randomTransform(rng, offset);
                const std::string what = "n " + std::to_string(n) + " offset " + std::to_string(offset);
                for (uint32_t g = 0; g < 3; ++g)
                    for (bool withArea : {false, true}) {
                        const Aabb fast = lsGroupBounds(o, g, withArea), loop = lsGroupBoundsByLoop(o, g, withArea);
                        EXPECT_EQ(fast.empty(), loop.empty());
                        if (!loop.empty()) expectSameBox(fast, loop, what + " group " + std::to_string(g));
                    }
                // Every used vertex, in index order (the window's object bounds).
                Aabb loop;
                std::vector<char> used(mesh.positions.size(), 0);
                for (const auto& tri : mesh.triangles)
                    for (uint32_t v : tri) used[v] = 1;
                for (size_t v = 0; v < used.size(); ++v)
                    if (used[v]) loop.extend(o.lsTransform.apply(mesh.positions[v]));
                const auto fast = placedBox(*index.used, mesh.positions, o.lsTransform);
                ASSERT_TRUE(fast);
                expectSameBox(Aabb{fast->first, fast->second}, loop, what + " used");
                // The unused vertex widens only the box of every position.
                const auto all = placedBox(*index.positions, mesh.positions, o.lsTransform);
                ASSERT_TRUE(all);
                EXPECT_LE(all->first.x, fast->first.x);
                // Linear extremes as the receiver-side search takes them (footprints, depths).
                for (int d = 0; d < 4; ++d) {
                    std::uniform_real_distribution<double> unit(-1.0, 1.0);
                    const glm::dvec3 dir = glm::normalize(glm::dvec3(unit(rng), unit(rng) - 1.5, unit(rng)));
                    double best = -std::numeric_limits<double>::infinity();
                    for (const auto& tri : mesh.triangles)
                        for (uint32_t v : tri)
                            if (mesh.triangleGroup[&tri - mesh.triangles.data()] == 1)
                                best = std::max(best, glm::dot(dir, o.lsTransform.apply(mesh.positions[v])));
                    const double viaTree = index.group[1]->maximum(
                        [&](const glm::dvec3& lo, const glm::dvec3& hi) { return placedDotUpper(o.lsTransform, dir, lo, hi); },
                        [&](uint32_t v) { return glm::dot(dir, o.lsTransform.apply(mesh.positions[v])); });
                    EXPECT_TRUE(sameBits(best, viaTree)) << what << " dot " << best << " vs " << viaTree;
                }
            }
        }
    }
}

// placedBounds (core/window.h) holds every corner of the box as placedCorners places it
// and as placed exactly (long double, from the corner's own coordinates), and is that
// corners' box within a relative 1e-9: tiny to huge boxes, turned, per-axis scaled and
// mirrored placements, near the origin and 100 km out.
TEST(MeshIndex, PlacedBoundsHoldThePlacedCornersTightly) {
    std::mt19937 rng(31);
    std::uniform_real_distribution<double> unit(-1.0, 1.0), exponent(-3.0, 2.0);
    for (int rep = 0; rep < 2000; ++rep) {
        const RowTransform t = randomTransform(rng, rep % 2 ? 1e5 : 0.0);
        const glm::dvec3 centre(100 * unit(rng), 100 * unit(rng), 100 * unit(rng));
        const glm::dvec3 half(std::pow(10.0, exponent(rng)), std::pow(10.0, exponent(rng)), rep % 7 ? std::pow(10.0, exponent(rng)) : 0.0);
        const Aabb box{centre - half, centre + half};
        const Aabb bounds = placedBounds(box, t);
        Aabb corners;
        for (const glm::dvec3& p : placedCorners(box, t)) corners.extend(p);
        for (int k = 0; k < 3; ++k) {
            EXPECT_LE(bounds.min[k], corners.min[k]) << "rep " << rep;
            EXPECT_GE(bounds.max[k], corners.max[k]) << "rep " << rep;
            const double size = std::abs(t.rows[3][k]) + corners.max[k] - corners.min[k] + 1.0;
            EXPECT_LE(corners.min[k] - bounds.min[k], 1e-9 * size) << "rep " << rep << ": too loose";
            EXPECT_LE(bounds.max[k] - corners.max[k], 1e-9 * size) << "rep " << rep << ": too loose";
        }
        for (const glm::dvec3& c : box.corners()) {
            for (int k = 0; k < 3; ++k) {
                long double exact = (long double)t.rows[3][k];
                for (int r = 0; r < 3; ++r) exact += (long double)c[r] * (long double)t.rows[size_t(r)][k];
                EXPECT_LE((long double)bounds.min[k], exact) << "rep " << rep;
                EXPECT_GE((long double)bounds.max[k], exact) << "rep " << rep;
            }
        }
    }
}

// The bounds are conservative: every vertex's placed value lies under them, and so does
// the true value of every point of the box (checked at its corners, in long double).
// Every placed triangle's area lies within the transform's area-scale bounds times its
// mesh area, on turned, mirrored, per-axis scaled and sheared placements; a turn with a
// uniform scale gets bounds that agree up to rounding. The index's group areas are the
// loop's sums.
TEST(MeshIndex, AreaScaleBoundsHoldEveryPlacedTriangle) {
    std::mt19937 rng(29);
    const Mesh mesh = jaggedSheet(24, rng);
    const MeshVertexIndex& index = vertexIndex(mesh);
    auto area = [](const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
        return 0.5 * glm::length(glm::cross(b - a, c - a));
    };
    std::vector<double> sums(mesh.groups.size(), 0.0);
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        const auto& i = mesh.triangles[t];
        sums[mesh.triangleGroup[t]] += area(mesh.positions[i[0]], mesh.positions[i[1]], mesh.positions[i[2]]);
    }
    ASSERT_EQ(index.groupArea.size(), sums.size());
    for (size_t g = 0; g < sums.size(); ++g) EXPECT_NEAR(index.groupArea[g], sums[g], 1e-12 * (sums[g] + 1e-300));
    EXPECT_GT(index.groupArea[0], 3.9);  // half of a 4 m x 4 m sheet, zigzagging
    EXPECT_EQ(index.groupArea[2], 0.0);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    for (int rep = 0; rep < 60; ++rep) {
        RowTransform t = randomTransform(rng, 1e5);
        const bool uniform = rep % 3 == 0, sheared = rep % 3 == 1;
        if (uniform) {  // a turn and one scale, mirrored or not
            const double s = 0.3 + 2.0 * (unit(rng) + 1.0);
            for (int k = 0; k < 3; ++k) t.rows[size_t(k)] = s * glm::normalize(t.rows[size_t(k)]);
        }
        if (sheared) t.rows[1] += 0.7 * unit(rng) * t.rows[0] + 0.4 * unit(rng) * t.rows[2];
        const auto [lo, hi] = areaScaleBounds(t);
        ASSERT_LE(lo, hi);
        if (uniform) {
            EXPECT_LE(hi, lo * (1 + 1e-9)) << "a uniform scale's bounds are tight";
        }
        for (size_t k = 0; k < mesh.triangles.size(); ++k) {
            const auto& i = mesh.triangles[k];
            const double ms = area(mesh.positions[i[0]], mesh.positions[i[1]], mesh.positions[i[2]]);
            if (ms == 0.0) continue;
            const double ls = area(t.applyLinear(mesh.positions[i[0]]), t.applyLinear(mesh.positions[i[1]]),
                                   t.applyLinear(mesh.positions[i[2]]));
            EXPECT_GE(ls, lo * ms * (1 - 1e-9)) << "rep " << rep << " triangle " << k;
            EXPECT_LE(ls, hi * ms * (1 + 1e-9)) << "rep " << rep << " triangle " << k;
        }
    }
}

// The triangle tree's walk (the raycast stage's: leaves of 16 taken whole) visits every
// triangle whose own box the filter accepts, each once, and only triangles of leaves the
// filter accepted; with a filter that accepts everything, every triangle once.
TEST(MeshIndex, ForEachVisitsEveryAcceptedTriangleOnce) {
    std::mt19937 rng(31);
    const Mesh mesh = jaggedSheet(60, rng);
    const BoxTree<>& tree = vertexIndex(mesh).triangles;
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    for (int q = 0; q < 30; ++q) {
        const glm::dvec3 c(u(rng), 0.0, u(rng));
        auto may = [&](const glm::dvec3& lo, const glm::dvec3& hi) {
            return lo.x <= c.x + 0.3 && hi.x >= c.x - 0.3 && lo.z <= c.z + 0.3 && hi.z >= c.z - 0.3;
        };
        std::vector<uint32_t> visited;
        tree.visit(may, [&](uint32_t t) { visited.push_back(t); });
        std::sort(visited.begin(), visited.end());
        EXPECT_TRUE(std::adjacent_find(visited.begin(), visited.end()) == visited.end()) << "a triangle visited twice";
        size_t accepted = 0;
        for (uint32_t t = 0; t < mesh.triangles.size(); ++t) {
            glm::dvec3 lo(1e300), hi(-1e300);
            for (uint32_t v : mesh.triangles[t]) lo = glm::min(lo, mesh.positions[v]), hi = glm::max(hi, mesh.positions[v]);
            if (!may(lo, hi)) continue;
            ++accepted;
            EXPECT_TRUE(std::binary_search(visited.begin(), visited.end(), t)) << "query " << q << " triangle " << t;
        }
        EXPECT_GT(accepted, 0u);
        EXPECT_LE(visited.size(), accepted + size_t(kTriangleLeaf) * (accepted + 1)) << "query " << q;
    }
    std::vector<uint32_t> all;
    tree.visit([](const glm::dvec3&, const glm::dvec3&) { return true; }, [&](uint32_t t) { all.push_back(t); });
    EXPECT_EQ(all.size(), mesh.triangles.size());
}

TEST(MeshIndex, NodeBoundsHoldEveryVertex) {
    std::mt19937 rng(7);
    const Mesh mesh = jaggedSheet(60, rng);
    const VertexTree& tree = *vertexIndex(mesh).used;
    for (int rep = 0; rep < 30; ++rep) {
        const RowTransform t = randomTransform(rng, rep % 2 ? 1e5 : 0.0);
        const glm::dvec3 dir = glm::normalize(glm::dvec3(0.3, -1.0, 0.2 * rep - 3.0));
        for (const VertexTree::Node& n : tree.nodes())
            for (uint32_t k = n.begin; k < n.end; ++k) {
                const glm::dvec3& p = mesh.positions[tree.items()[k]];
                for (int axis = 0; axis < 3; ++axis)
                    for (double s : {1.0, -1.0})
                        EXPECT_LE(s * t.apply(p)[axis], placedCoordinateUpper(t, axis, s, n.lo, n.hi));
                EXPECT_LE(glm::dot(dir, t.apply(p)), placedDotUpper(t, dir, n.lo, n.hi));
            }
    }
}

// The vertex trees keep their vertices in the order the triangle tree first uses them and
// mirror its nodes (no sort): each still holds its subset once, nodes are the exact boxes
// of their items, none is empty, children split their parent's range,
// leaves hold at most a triangle leaf's 48 vertices, the depth is at most the triangle
// tree's, and the maxima are a median-split tree's, bit for bit. The tree of every vertex,
// which holds one no triangle uses, has median splits instead.
TEST(MeshIndex, VertexTreesMirrorTheTriangleTreeExactlyAndCompletely) {
    std::mt19937 rng(21);
    const Mesh mesh = jaggedSheet(90, rng);
    const MeshVertexIndex& index = vertexIndex(mesh);
    for (const VertexTree* tree : {index.used, index.positions, index.group[0], index.group[1], index.groupWithArea[0]}) {
        ASSERT_FALSE(tree->empty());
        std::vector<uint32_t> items = tree->items();
        std::sort(items.begin(), items.end());
        EXPECT_TRUE(std::adjacent_find(items.begin(), items.end()) == items.end()) << "a vertex twice";
        const std::vector<VertexTree::Node>& nodes = tree->nodes();
        int depth = 0;
        std::vector<int> level(nodes.size(), 1);
        for (size_t k = 0; k < nodes.size(); ++k) {
            const VertexTree::Node& n = nodes[k];
            glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
            for (uint32_t i = n.begin; i < n.end; ++i) {
                lo = glm::min(lo, mesh.positions[tree->items()[i]]);
                hi = glm::max(hi, mesh.positions[tree->items()[i]]);
            }
            EXPECT_TRUE(lo == n.lo && hi == n.hi) << "node " << k;
            EXPECT_LT(n.begin, n.end) << "an empty node";
            if (n.left < 0) {
                EXPECT_LE(n.end - n.begin, tree == index.positions ? 16u : 48u);
            } else {
                const VertexTree::Node &a = nodes[size_t(n.left)], &b = nodes[size_t(n.right())];
                EXPECT_GT(n.left, int32_t(k));
                EXPECT_EQ(a.begin, n.begin);
                EXPECT_EQ(a.end, b.begin);
                EXPECT_EQ(b.end, n.end);
                level[size_t(n.left)] = level[size_t(n.right())] = level[k] + 1;
            }
            depth = std::max(depth, level[k]);
        }
        int triangleDepth = 0;
        {
            const std::vector<BoxTree<>::Node>& tn = index.triangles.nodes();
            std::vector<int> tl(tn.size(), 1);
            for (size_t k = 0; k < tn.size(); ++k) {
                if (tn[k].left >= 0) tl[size_t(tn[k].left)] = tl[size_t(tn[k].right())] = tl[k] + 1;
                triangleDepth = std::max(triangleDepth, tl[k]);
            }
        }
        EXPECT_LE(depth, tree == index.positions ? int(std::ceil(std::log2(double(tree->size()) / 16.0))) + 2 : triangleDepth);
        // The same maxima as a tree of median splits over the same vertices.
        const VertexTree median = makeVertexTree(mesh.positions, tree->items());
        for (int rep = 0; rep < 20; ++rep) {
            const RowTransform t = randomTransform(rng, rep % 2 ? 1e5 : 0.0);
            std::uniform_real_distribution<double> unit(-1.0, 1.0);
            const glm::dvec3 dir = glm::normalize(glm::dvec3(unit(rng), unit(rng), unit(rng)));
            auto upper = [&](const glm::dvec3& lo, const glm::dvec3& hi) { return placedDotUpper(t, dir, lo, hi); };
            auto eval = [&](uint32_t v) { return glm::dot(dir, t.apply(mesh.positions[v])); };
            EXPECT_TRUE(sameBits(tree->maximum(upper, eval), median.maximum(upper, eval)));
        }
    }
    EXPECT_EQ(index.positions->size(), mesh.positions.size());
}

// A zero coordinate: -0 and +0 compare equal and the loop keeps the first it met, so the
// tree hands the box back to the loop (which gives the loop's sign).
// A window's object boxes (buildWindow: each object's box under its transform's linear part,
// made once, moved by the window's translation) are the loop's over the placed vertices bit
// for bit, in every window that holds the object, with windows centred near and 100 km from
// the origin, and where the window's translation puts a box coordinate exactly at zero (the
// loop's sign of zero).
TEST(MeshIndex, WindowBoxesAreTheLoopsInEveryWindow) {
    std::mt19937 rng(41);
    auto mesh = std::make_shared<const Mesh>(jaggedSheet(20, rng));
    const MeshVertexIndex& index = vertexIndex(*mesh);
    for (const int far : {0, 1000}) {  // chunks of 100 m: the origin, and 100 km out
        Space space;
        space.settings.chunkSize = 100.0;
        for (int cx = 0; cx < 3; ++cx)
            for (int cz = 0; cz < 3; ++cz) {
                const ChunkCoord c{far + cx, far + cz};
                ChunkFile& cf = space.chunks[c];
                cf.coord = c;
                cf.path = "c" + std::to_string(cx) + std::to_string(cz);
                for (int k = 0; k < 6; ++k) {
                    ChunkObject o;
                    o.mesh = mesh;
                    o.elementIndex = k;
                    o.transform = randomTransform(rng, 0.0);
                    o.transform.rows[3] = glm::dvec3(50.0 + 40.0 * (rng() % 2 ? 1 : -1) * 0.5, 3.0, 50.0);
                    cf.objects.push_back(o);
                }
            }
        TerrainMeshes terrains;
        std::vector<ChunkCoord> all;
        for (const auto& [c, cf] : space.chunks) all.push_back(c);
        for (int round = 0; round < 2; ++round)  // the second: every object's linear box made
            for (const ChunkCoord centre : all) {
                const BakeWindow w = buildWindow(space, centre, all, terrains);
                ASSERT_EQ(w.objects.size(), all.size() * 6);
                for (const WindowObject& o : w.objects) {
                    Aabb loop;
                    std::vector<char> used(mesh->positions.size(), 0);
                    for (const auto& tri : mesh->triangles)
                        for (uint32_t v : tri) used[v] = 1;
                    for (size_t v = 0; v < used.size(); ++v)
                        if (used[v]) loop.extend(o.lsTransform.apply(mesh->positions[v]));
                    expectSameBox(o.lsBounds, loop, "far " + std::to_string(far) + " " + o.label);
                }
            }
    }
    EXPECT_FALSE(index.used->empty());

    // A box coordinate at zero: a triangle from y = 1 to 11 in chunk (0, 0) sets the
    // window's vertical origin at 6 m (the middle, rounded), and the same triangle lifted by
    // 5 m in chunk (1, 0) then has its lowest y at exactly 0 in that window (its box under
    // the linear part alone has none).
    auto tri = std::make_shared<Mesh>();
    tri->positions = {{-0.0, 1.0, 1.0}, {2.0, 11.0, 1.0}, {1.0, 1.0, -0.0}};
    tri->triangles = {{0, 1, 2}};
    tri->triangleGroup = {0};
    tri->groups.resize(1);
    Space space;
    space.settings.chunkSize = 100.0;
    for (int cx = 0; cx < 2; ++cx) {
        ChunkFile& cf = space.chunks[{cx, 0}];
        cf.coord = {cx, 0};
        ChunkObject o;
        o.mesh = tri;
        o.transform.rows[3] = glm::dvec3(10.0, 5.0 * cx, 10.0);
        cf.objects.push_back(o);
    }
    TerrainMeshes terrains;
    const std::vector<ChunkCoord> both{{0, 0}, {1, 0}};
    for (int round = 0; round < 2; ++round) {
        const BakeWindow w = buildWindow(space, {0, 0}, both, terrains);
        ASSERT_EQ(w.objects.size(), 2u);
        EXPECT_TRUE(sameBits(w.objects[1].lsBounds.min.y, 0.0));
        for (const WindowObject& o : w.objects) {
            Aabb loop;
            for (const glm::dvec3& p : tri->positions) loop.extend(o.lsTransform.apply(p));
            expectSameBox(o.lsBounds, loop, "zero " + std::to_string(round));
        }
    }
}

TEST(MeshIndex, ZeroCoordinatesAreTheLoopsToo) {
    Mesh m;
    m.positions = {{0.0, 1.0, 2.0}, {-0.0, -1.0, -1.0}, {0.0, 2.0, 2.0}, {1.0, 1.0, 2.0}};
    m.triangles = {{1, 0, 2}, {0, 3, 2}};
    m.triangleGroup = {0, 0};
    m.groups.resize(1);
    WindowObject o;
    o.mesh = &m;
    o.lsTransform.rows[3] = glm::dvec3(-0.0, 0.0, 0.0);
    EXPECT_FALSE(placedBox(*vertexIndex(m).group[0], m.positions, o.lsTransform));
    const Aabb fast = lsGroupBounds(o, 0, false), loop = lsGroupBoundsByLoop(o, 0, false);
    expectSameBox(fast, loop, "zero");
    EXPECT_TRUE(std::signbit(fast.min.x));  // the first corner met: vertex 1, every term -0
}

TEST(MeshIndex, ACopyOfAMeshBuildsItsOwnIndex) {
    std::mt19937 rng(1);
    Mesh a = jaggedSheet(4, rng);
    const MeshVertexIndex& ia = vertexIndex(a);
    Mesh b = a;
    b.positions[0].x += 100.0;
    const MeshVertexIndex& ib = vertexIndex(b);
    EXPECT_NE(&ia, &ib);
    WindowObject o;
    o.mesh = &b;
    expectSameBox(lsGroupBounds(o, 0, false), lsGroupBoundsByLoop(o, 0, false), "copy");
}


// The terrain's extremes over a rectangle (the receiver-side band's filter relies on them):
// every height under the rectangle lies between them, on two chunks with unmatched edges.
TEST(MeshIndex, TerrainExtremesBoundEveryHeightUnderARectangle) {
    std::mt19937 rng(19);
    std::uniform_real_distribution<double> height(-3.0, 9.0), unit(0.0, 1.0);
    Heightfield a, b;
    for (Heightfield* hf : {&a, &b}) {
        hf->n = 17;
        hf->size = 64.0;
        for (int k = 0; k < 17 * 17; ++k) hf->heights.push_back(height(rng));
    }
    BakeWindow w;
    w.chunkSize = 64.0;
    for (int c = 0; c < 2; ++c) {
        WindowObject o;
        o.kind = ChunkObject::Kind::Terrain;
        o.heightfield = c ? &b : &a;
        o.lsTerrainOrigin = glm::dvec3(64.0 * c, -2.0, 0.0);
        w.terrainObjects.push_back(w.objects.size());
        w.objects.push_back(o);
    }
    for (int rep = 0; rep < 300; ++rep) {
        const double x0 = 120.0 * unit(rng), z0 = 60.0 * unit(rng);
        const double x1 = std::min(127.9, x0 + 10.0 * unit(rng)), z1 = std::min(63.9, z0 + 10.0 * unit(rng));
        const std::optional<double> lo = w.lsTerrainMinOver(x0, z0, x1, z1), hi = w.lsTerrainMaxOver(x0, z0, x1, z1);
        ASSERT_TRUE(lo && hi);
        double seenLo = 1e300, seenHi = -1e300;
        for (int k = 0; k < 200; ++k) {
            const double x = x0 + (x1 - x0) * unit(rng), z = z0 + (z1 - z0) * unit(rng);
            const double h = *w.lsTerrainHeight(x, z);
            EXPECT_LE(h, *hi + 1e-12);
            EXPECT_GE(h, *lo - 1e-12);
            seenLo = std::min(seenLo, h);
            seenHi = std::max(seenHi, h);
        }
        EXPECT_LE(*hi, seenHi + 12.0);  // a bound, not a guess: near what the samples saw
    }
    // Part of the rectangle without terrain: nothing.
    EXPECT_FALSE(w.lsTerrainMaxOver(100.0, 10.0, 130.0, 20.0));
}

}  // namespace
}  // namespace shadowcull
