// Vectors of exact rationals (GMP), independent of CGAL: the reference the tests of the
// double pre-filters and their rounding bounds compare with (every double is a rational).
#pragma once

#include <glm/vec3.hpp>
#include <gmpxx.h>

namespace shadowcull::test {

using Q = mpq_class;
struct QV {
    Q x, y, z;
};
inline QV qv(const glm::dvec3& p) { return {Q(p.x), Q(p.y), Q(p.z)}; }
inline QV sub(const QV& a, const QV& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline QV crossQ(const QV& a, const QV& b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
inline Q dotQ(const QV& a, const QV& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

}  // namespace shadowcull::test
