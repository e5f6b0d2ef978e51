// geometry/: the fast path's double filters against the exact test (they may only reject
// what it rejects) on random and nearly edge-on casters, and the bias's lower bound against
// the exact slope bias.


#include <cmath>
#include <random>

// Exact rationals for the bias test (header-only); GCC warns inside them at -O2.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <boost/multiprecision/cpp_int.hpp>
#pragma GCC diagnostic pop
#include <glm/geometric.hpp>

#include <gtest/gtest.h>

#include "geometry/exact_frustum.h"
#include "geometry/geometry_stage.h"
#include "tests/support/space_builder.h"

using namespace shadowcull;
using namespace shadowcull::testing;
using geometry::ExactFrustum;
using geometry::LightGeometry;
using geometry::Triangle;

// --- The fast path (issue 13): light-space hierarchy and double filters -------------------

namespace {

MeshSpec jaggedSheet(int n, double cell, double zig) { return MeshSpec::jaggedSheet(n, cell, zig); }

}  // namespace

// The double filter may only reject what the exact test rejects, and the exact test's
// interval fast path answers as the exact kernel alone: on random triangles, on
// the neighbours of a jagged sheet (shared edges and vertices, the cases the filter
// decides by vertex identity), on the caster itself and on coplanar copies, for
// directional and point lights, with and without bias and dilation.
TEST(FrustumFilter, NeverMissesWhatTheExactTestReaches) {
    std::mt19937_64 rng(13);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    auto vec = [&](double s) { return glm::dvec3(u(rng), u(rng), u(rng)) * s; };
    const MeshSpec sheet = jaggedSheet(6, 0.02, 0.03);
    std::vector<Triangle> sheetTris;
    for (const auto& t : sheet.triangles) sheetTris.push_back({sheet.positions[size_t(t[0])], sheet.positions[size_t(t[1])], sheet.positions[size_t(t[2])]});
    size_t pairs = 0, filtered = 0, reached = 0;
    for (int trial = 0; trial < 400; ++trial) {
        LightGeometry light;
        light.directional = trial % 3 != 0;
        light.direction = trial % 7 == 0 ? glm::dvec3(0, -1, 0) : glm::normalize(glm::dvec3(u(rng) * 0.6, -1.0, u(rng) * 0.6));
        light.position = glm::dvec3(u(rng) * 0.2, 0.5 + 0.3 * std::abs(u(rng)), u(rng) * 0.2);
        const double dilation = trial % 5 == 0 ? 0.01 : 0.0;
        std::vector<std::pair<Triangle, std::vector<Triangle>>> cases;
        // A sheet triangle against every other sheet triangle.
        const Triangle& t = sheetTris[size_t(trial) % sheetTris.size()];
        cases.push_back({t, sheetTris});
        // A random caster against random receivers around and behind it, and against
        // itself and a coplanar copy sharing an edge.
        const glm::dvec3 c0 = vec(0.5) + glm::dvec3(0, 0.2, 0);
        const Triangle rt = {c0, c0 + vec(0.1), c0 + vec(0.1)};
        std::vector<Triangle> around = {rt, {rt[0], rt[1], rt[0] + (rt[1] - rt[2])}};
        for (int k = 0; k < 20; ++k) {
            const glm::dvec3 p = c0 + vec(0.3) + (light.directional ? light.direction : c0 - light.position) * std::abs(u(rng)) * 0.3;
            around.push_back({p, p + vec(0.1), p + vec(0.1)});
        }
        cases.push_back({rt, around});
        for (const auto& [caster, receivers] : cases) {
            if (hasRepeatedVertex(caster[0], caster[1], caster[2])) continue;
            const ExactFrustum exact(caster, light, dilation);
            const geometry::FrustumFilter filter(caster, light, dilation);
            for (const Triangle& r : receivers) {
                if (hasRepeatedVertex(r[0], r[1], r[2])) continue;
                for (double beta : {0.0, 0.01, 0.05}) {
                    ++pairs;
                    const bool misses = filter.certainlyMisses(r, beta);
                    const bool reaches = exact.reaches(r, beta);
                    // The interval fast path answers as the exact kernel does.
                    ASSERT_EQ(reaches, exact.reachesExactly(r, beta)) << "trial " << trial << " beta " << beta;
                    filtered += misses;
                    reached += reaches;
                    ASSERT_FALSE(misses && reaches) << "trial " << trial << " beta " << beta;
                }
            }
        }
    }
    // The test means something only if both outcomes occur often.
    EXPECT_GT(filtered, pairs / 3) << pairs << " pairs";
    EXPECT_GT(reached, pairs / 50) << pairs << " pairs";
}

// Issue 34: the near plane's bias shift beta (n . d) next to a caster nearly edge-on to the
// sun. n . d comes from two nearly cancelling products, so its absolute error is about
// u |n| |d| however small it is; an allowance relative to the computed n . d (1e-12 of
// it) let the filter put a receiver vertex "in front beyond rounding" that the exact test
// finds 31 um deeper than p + bias. The caster stands 6e-12 rad off vertical; the receiver
// has one vertex 10 m under the caster's middle and two 1 cm in front of its plane.
TEST(FrustumFilter, NearPlaneShiftOfANearlyEdgeOnCasterIsBoundedByItsTerms) {
    const Triangle caster = {glm::dvec3(0, 0, 0), glm::dvec3(-9.39534189038811, 20, 10.570125389900795),
                             glm::dvec3(18.790683781224732, 10, -21.140250779827984)};
    const LightGeometry sun{true, {0, -1, 0}, {0, 0, 0}};
    // The caster's normal away from the light (exact facing), levelled: "in front" is a
    // horizontal step towards the light's side of the near-vertical plane.
    glm::dvec3 n = glm::cross(caster[1] - caster[0], caster[2] - caster[0]);
    if (geometry::exactFacing(caster, false, sun) > 0) n = -n;  // the light meets the ccw side
    const glm::dvec3 front = -glm::normalize(glm::dvec3(n.x, 0, n.z));
    const glm::dvec3 deep(4.749023945024685e-11, 9.999999999999995e-07, 4.221208544279419e-11);
    const Triangle receiver = {deep, deep + 0.01 * front, deep + 0.01 * front + glm::dvec3(0, 0.01, 0)};
    const ExactFrustum exact(caster, sun, 0.0);
    const geometry::FrustumFilter filter(caster, sun, 0.0);
    // Bias 10 m: exactly, and as the stage's lower bounds give it (never above 10).
    for (double beta : {10.0, std::nextafter(10.0, 0.0), 10.0 * (1 - 1e-9) - 1e-12}) {
        // The exact reference (CGAL's exact kernel, no interval fast path): the deep vertex
        // lies inside the frustum's closed sides and strictly beyond the near cap.
        ASSERT_TRUE(exact.reachesExactly(receiver, beta)) << "beta " << beta;
        ASSERT_TRUE(exact.reaches(receiver, beta)) << "beta " << beta;
        EXPECT_FALSE(filter.certainlyMisses(receiver, beta)) << "beta " << beta;
        EXPECT_FALSE(filter.allInFront(receiver.data(), 3, beta)) << "beta " << beta;
        EXPECT_FALSE(filter.allInFront(&deep, 1, beta)) << "beta " << beta;
    }
}

// The same bound on random casters 1e-13 to 1e-5 rad off edge-on to the sun, with receivers
// reaching just past or stopping just short of p + bias (1e-7 to 1e-3 m) right under a
// caster vertex (where x - a is small and the shift's rounding is all there is): the filter
// never rejects what the exact test reaches, and still rejects much of what it does not.
TEST(FrustumFilter, NeverMissesWhatNearlyEdgeOnCastersReach) {
    std::mt19937_64 rng(34);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const LightGeometry sun{true, {0, -1, 0}, {0, 0, 0}};
    size_t reached = 0, rejected = 0, missed = 0;
    for (int trial = 0; trial < 400; ++trial) {
        const double angle = std::pow(10.0, -13 + 8 * u(rng)), turn = 6.283185307179586 * u(rng);
        const glm::dvec3 h(std::cos(turn), 0, std::sin(turn));  // horizontal, in the plane
        const glm::dvec3 across(-h.z, 0, h.x);
        // Up the plane: vertical but for the tilt `angle` across it.
        const glm::dvec3 up = glm::dvec3(0, std::cos(angle), 0) + std::sin(angle) * across;
        const glm::dvec3 a = glm::dvec3(u(rng), u(rng), u(rng)) * 100.0;
        const Triangle caster = {a, a + 20.0 * up + (5 + 10 * u(rng)) * h, a + 20.0 * up - (5 + 10 * u(rng)) * h};
        const ExactFrustum exact(caster, sun, 0.0);
        const geometry::FrustumFilter filter(caster, sun, 0.0);
        for (int k = 0; k < 8; ++k) {
            const double beta = 1 + 15 * u(rng), past = std::pow(10.0, -7 + 4 * u(rng)) * (k % 2 ? 1 : -1);
            // p above a in the caster, q = p + (beta + past) d: next to a.
            const glm::dvec3 p = a + ((beta + past) / up.y) * up;
            const glm::dvec3 q = p + (beta + past) * sun.direction;
            const double side = u(rng) < 0.5 ? 0.01 : -0.01;
            const Triangle r = {q, q + side * across, q + side * across + glm::dvec3(0, 0.01, 0)};
            const bool reaches = exact.reaches(r, beta);
            const bool misses = filter.certainlyMisses(r, beta), inFront = filter.allInFront(r.data(), 3, beta);
            reached += reaches;
            rejected += misses;
            missed += !reaches;
            ASSERT_FALSE(reaches && (misses || inFront)) << "trial " << trial << " k " << k << " angle " << angle << " past " << past;
        }
    }
    EXPECT_GT(reached, 400u);
    EXPECT_GT(rejected, missed / 4);  // the filter is off within 1e-12 rad of edge-on
}

// Issue 34: the slope bias on needle receivers. The computed normal of a triangle whose
// angle is theta carries a relative error of about u / theta, so tan(theta) from it can
// lie well above the exact value; an overestimated bias pushes the near cap too deep (a
// possible false cull). On needles at angles 1e-12 to 1e-7 rad, under random suns, the
// lower bound never exceeds the exact beta = bias + slopeBias |n x d| / |n . d|, decided
// in rational arithmetic (n the exact cross product of the exact edges); and it stays
// useful: on the needles above 1e-9 rad it keeps 99 % of the slope term.
TEST(BiasLowerBound, NeverExceedsTheExactSlopeBiasOnNeedles) {
    using Q = boost::multiprecision::cpp_rational;
    ASSERT_NE(Q(0.1), Q(1) / 10) << "doubles convert to rationals exactly";
    std::mt19937_64 rng(34);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    auto unit = [&] { return glm::normalize(glm::dvec3(u(rng), u(rng), u(rng))); };
    size_t above = 0, cases = 0;
    double keptExact = 0, keptLower = 0;
    for (int trial = 0; trial < 20000; ++trial) {
        Light L;
        L.direction = glm::normalize(glm::dvec3(u(rng), -1.0 - std::abs(u(rng)), u(rng)));
        L.bias = trial % 2 ? 0.05 : 0.0;
        L.slopeBias = 0.01;
        const double angle = std::pow(10.0, -12 + 5 * (0.5 + 0.5 * u(rng)));
        const glm::dvec3 e = unit(), w = glm::normalize(glm::cross(e, unit()));
        const glm::dvec3 a = glm::dvec3(u(rng), u(rng), u(rng)) * 50.0;
        const double l1 = 1 + 9 * std::abs(u(rng)), l2 = 1 + 9 * std::abs(u(rng));
        const Triangle t = {a, a + l1 * e, a + l2 * (std::cos(angle) * e + std::sin(angle) * w)};
        if (hasRepeatedVertex(t[0], t[1], t[2])) continue;
        const double lower = geometry::biasLowerBound(L, t);
        // The exact n x d and n . d.
        Q e1[3], e2[3], d[3];
        for (int k = 0; k < 3; ++k) {
            e1[k] = Q(t[1][k]) - Q(t[0][k]);
            e2[k] = Q(t[2][k]) - Q(t[0][k]);
            d[k] = Q(L.direction[k]);
        }
        const Q n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        const Q nd = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
        const Q c[3] = {n[1] * d[2] - n[2] * d[1], n[2] * d[0] - n[0] * d[2], n[0] * d[1] - n[1] * d[0]};
        const Q cross2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
        ++cases;
        // lower <= bias + s tan <=> lower <= bias, or (lower - bias)^2 (n.d)^2 <= s^2 |n x d|^2.
        const Q y = Q(lower) - Q(L.bias);
        const bool exceeds = y > 0 && y * y * nd * nd > Q(L.slopeBias) * Q(L.slopeBias) * cross2;
        above += exceeds;
        EXPECT_FALSE(exceeds) << "trial " << trial << " angle " << angle << " lower " << lower;
        EXPECT_GE(lower, L.bias) << "trial " << trial;
        if (angle > 1e-9 && nd != 0) {
            const double tanExact = std::sqrt(cross2.convert_to<double>()) / std::abs(nd.convert_to<double>());
            if (tanExact < 1e5) {
                keptExact += L.slopeBias * tanExact;
                keptLower += lower - L.bias;
            }
        }
        if (above > 20) break;  // enough to show it
    }
    EXPECT_EQ(above, 0u) << "of " << cases;
    EXPECT_GT(keptLower, 0.99 * keptExact);
}

// The fast path gives the verdicts of the exhaustive reference, bit for bit: a jagged
// sheet (every triangle a neighbour's receiver) lying on a floor, floating, and buried in
// a terrain, under a slanted sun with and without bias, a filter radius, and a lamp.
